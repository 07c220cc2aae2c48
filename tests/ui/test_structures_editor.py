"""Structures, probes and indicators in the editor, driven through the editor's own objects (no browser):
make a loop or case from a selection, open and edit a body, switch cases, shift registers, collected
outputs, N on the front panel, iteration status, probes saved as view state, indicators after a run."""

from __future__ import annotations

import pytest

import flowmc
from flowmc.errors import GraphError
from flowmc.ui import canvas_draw
from flowmc.ui.text import unescape_md


def _line_graph(tmp_path):
    """A line, moved by dz, measured: the translate is what a loop will repeat."""
    g = flowmc.GraphBuilder(title="line")
    line = g.add("path.polyline", id="line", points=[[0, 0, 0], [10, 0, 0]], pos=(0, 0))
    move = g.add("path.translate", id="move", dz=-1.0, pos=(260, 0))
    measure = g.add("path.measure", id="measure", pos=(520, 0))
    g.wire(line.path, move.path)
    g.wire(move.path, measure.path)
    g.output("length_mm", "Number", measure.length, description="Total length (mm)")
    graph = g.build()
    path = tmp_path / "line.flowmc.json"
    flowmc.save(graph, path)
    return path


@pytest.fixture
def editor(tmp_path, open_editor):
    return open_editor(_line_graph(tmp_path))


def _is_text(handle) -> bool:
    return type(handle).__name__ == "GuiMarkdownHandle"


def _run(editor):
    request = editor.session.run()
    request.wait(60)
    editor.session.wait(60)
    return request.result


def test_make_a_for_loop_from_a_selection_collect_its_path_and_set_n_on_the_front_panel(editor):
    state, ui = editor.state, editor.structure_ui
    state.select(nodes=["move"])
    loop = ui.make_structure("struct.for")
    assert loop == "loop1" and state.node(loop).type == "struct.for"
    body = state.node(loop).bodies["body"]
    assert [n.id for n in body.nodes] == ["move"]
    assert [i.name for i in body.interface.inputs] == ["path"] and [o.name for o in body.interface.outputs] == ["path"]
    assert {(w.from_, w.to) for w in state.graph.wires} == {("line.path", "loop1.path"), ("loop1.path", "measure.path")}
    assert not state.issues()
    state.select(nodes=[loop])
    ui.output.value = "path"
    ui.collect.value = True  # auto-indexing: every iteration's path, joined
    assert state.node(loop).params["indexed"] == ["path"]
    name = ui.count_on_front_panel()
    assert name == "loop1_N" and state.graph.interface.inputs[0].to == ["loop1.count"]
    front = editor.extensions.front
    assert front is not None and "loop1_N" in front.controls
    front.controls["loop1_N"].value = 3.0  # a front-panel change runs the graph
    editor.session.wait(60)
    result = editor.session.last_result
    assert result is not None and result.ok, result and result.errors
    assert result.outputs["length_mm"] == pytest.approx(3 * 10 + 2 * 10)  # three lines, two rapids back
    assert editor.session.status["loop1"][2] == "iteration 3 of 3"
    line = canvas_draw.status_text(editor.session.status["loop1"], [])
    assert line.startswith("done · ") and line.endswith("iteration 3 of 3")
    assert editor.canvas._title(state.node(loop)) == "loop1 · For loop · N = loop1_N"  # fed by the front panel
    assert flowmc.loads(flowmc.dumps(state.graph)).node(loop).bodies["body"].nodes[0].id == "move"


def test_open_a_body_edit_it_and_go_back_as_one_undoable_edit(editor):
    state, ui = editor.state, editor.structure_ui
    state.select(nodes=["move"])
    loop = ui.make_structure("struct.for")
    state.select(nodes=[loop])
    assert ui.open("body")
    assert state.body_place == (loop, "body") and [n.id for n in state.graph.nodes] == ["move"]
    with pytest.raises(GraphError, match="structure's body"):
        state.save()  # a body is saved with the graph that holds it
    state.set_param("move", "dz", -2.5)
    assert ui.go_back()
    assert state.body_place is None and state.selected_nodes == [loop]
    assert state.node(loop).bodies["body"].nodes[0].params["dz"] == -2.5
    assert state.undo() and state.node(loop).bodies["body"].nodes[0].params["dz"] == -1.0


def test_a_case_from_a_selection_switch_cases_and_add_one(editor):
    state, ui = editor.state, editor.structure_ui
    state.select(nodes=["move"])
    case = ui.make_structure("struct.case")
    node = state.node(case)
    assert node.params == {"selector_type": "Bool"} and set(node.bodies) == {"True", "False"}
    state.select(nodes=[case])
    assert ui.open("True")
    state.set_param("move", "dz", -4.0)
    ui.switch.value = "False"  # switch case: the True case goes back, the False case opens
    assert state.body_place == (case, "False")
    assert state.graph.node("move").params["dz"] == -1.0
    assert ui.go_back()
    assert state.node(case).bodies["True"].nodes[0].params["dz"] == -4.0
    state.change(lambda g: g.node(case).params.update(selector_type="Number", default="False"))
    state.select(nodes=[case])
    ui.case.value = "True"
    ui.new_case.value = "3..5"
    assert ui.new_case_from_panel()
    assert list(state.node(case).bodies) == ["True", "False", "3..5"]


def test_a_shift_register_from_a_body_output(editor):
    state, ui = editor.state, editor.structure_ui
    state.select(nodes=["move"])
    loop = ui.make_structure("struct.for")
    state.select(nodes=[loop])
    ui.output.value = "path"
    ui.shift.value = True  # a button: click
    node = state.node(loop)
    assert node.params["shift"] == ["path"]
    assert [(i.name, i.type) for i in node.bodies["body"].interface.inputs] == [("path", "Path")]


def test_probes_show_values_after_a_run_and_are_saved_as_view_state(editor, tmp_path):
    state, ui = editor.state, editor.structure_ui
    state.select(wires=[("move.path", "measure.path")])
    assert ui.toggle_probe() is True
    assert state.graph.view.probes == ["move.path"]
    result = _run(editor)
    assert result.ok
    texts = [h.content for h in ui._shown if _is_text(h)]
    assert any("Path: 1 segments · length 10 mm" in unescape_md(t) for t in texts)
    labels = editor.canvas._texts()
    assert labels["probe/move_path"][0] == "probe: Path · 1 seg · 10 mm"
    indicators = [unescape_md(h.content) for h in ui._indicators if _is_text(h)]
    assert any("length_mm" in t and "**10** mm" in t for t in indicators)
    state.save()
    again = flowmc.load(state.path)
    assert again.view.probes == ["move.path"]
    assert again.fingerprint_json() == flowmc.loads(flowmc.dumps(again)).fingerprint_json()


def test_in_probe_mode_a_click_on_a_wire_probes_it(editor):
    ui, canvas = editor.structure_ui, editor.canvas
    ui.probe_mode.value = True
    curve = canvas.curves[("line.path", "move.path")]
    x, y = curve[len(curve) // 2][:2]
    canvas.click(float(x), float(y))
    assert editor.state.graph.view.probes == ["line.path"]
    canvas.click(float(x), float(y))  # again: the probe goes
    assert editor.state.graph.view.probes == []
