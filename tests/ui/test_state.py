"""Editor logic in plain Python: the rules the canvas and the inspector rely on."""

from __future__ import annotations

import json

import numpy as np
import pytest

import flowmc
from editor_graphs import ROWS, example_builder, example_file
from flowmc.errors import GraphError
from flowmc.plugins import default_registry
from flowmc.ui import layout
from flowmc.ui.palette import palette_items, search
from flowmc.ui.params import field_errors
from flowmc.ui.ports import PortInfo
from flowmc.ui.state import UNSET, EditorState


@pytest.fixture
def state(tmp_path):
    return EditorState.open(example_file(tmp_path))


def wires(state):
    return sorted((w.from_, w.to) for w in state.graph.wires)


# ---------------------------------------------------------------- nodes, undo, dirty

def test_add_node_gets_a_fresh_id_and_undo_redo_restore(state):
    assert not state.dirty
    a = state.add_node("path.translate", (10, 20))
    b = state.add_node("path.translate")
    assert (a, b) == ("translate1", "translate2")
    assert state.node(a).pos == (10.0, 20.0) and state.dirty
    assert state.undo() and not state.has_node(b) and state.has_node(a)
    assert state.undo() and not state.dirty
    assert not state.undo()
    assert state.redo() and state.redo() and state.has_node(b)
    assert not state.redo()


def test_an_edit_after_undo_clears_redo(state):
    state.add_node("basic.number")
    state.undo()
    state.add_node("basic.add")
    assert not state.can_redo


def test_subgraph_file_names_the_node(state):
    assert state.add_node("subgraph", params={"file": "lib/pocket.flowmc.json"}) == "pocket1"


# ---------------------------------------------------------------- wiring

def test_connect_compatible_ports(state):
    n = state.add_node("path.translate")
    assert state.connect("shift.path", f"{n}.path") is None
    assert ("shift.path", f"{n}.path") in wires(state)
    assert state.issues() == []


def test_incompatible_pair_is_refused_with_why(state):
    n = state.add_node("basic.add")
    before = wires(state)
    reason = state.connect("shift.path", f"{n}.a")
    assert reason is not None
    assert "Path" in reason and "Number" in reason and "'a'" in reason
    assert wires(state) == before


@pytest.mark.parametrize("src,dst,words", [
    ("shift.path", "shift.dx", "itself"),
    ("shift.nope", "both.path1", "no output 'nope'"),
    ("shift.path", "table.nope", "no input 'nope'"),
    ("ghost.path", "shift.path", "no node 'ghost'"),
    ("both.path", "shift.path", "loop"),
    ("table.path", "shift.path", "already wired"),
])
def test_refusals(state, src, dst, words):
    before = wires(state)
    reason = state.connect(src, dst)
    assert reason is not None and words in reason
    assert wires(state) == before


def test_loop_message_names_the_loop(state):
    reason = state.connect("both.path", "shift.path")
    assert reason.endswith("would close a loop: both -> shift -> both")


def test_wiring_a_fed_input_replaces_the_old_wire(state):
    assert state.connect("edge.path", "shift.path") is None
    assert ("edge.path", "shift.path") in wires(state)
    assert ("table.path", "shift.path") not in wires(state)
    state.undo()
    assert ("table.path", "shift.path") in wires(state)


def test_interface_fed_input_is_refused(tmp_path):
    g = flowmc.GraphBuilder()
    g.add("basic.number", id="n")
    s = g.add("basic.add", id="s")
    g.input("a", "Number", s.a)
    st = EditorState(g.build(), folder=tmp_path)
    assert "interface input 'a'" in st.connect("n.value", "s.a")


def test_number_output_feeds_a_param_port(tmp_path):
    st = EditorState(folder=tmp_path)
    n = st.add_node("basic.number")
    t = st.add_node("path.translate")
    assert st.connect(f"{n}.value", f"{t}.dx") is None


# ---------------------------------------------------------------- deleting

def test_delete_node_takes_its_wires_and_interface_entries(state):
    assert state.delete(["both"])
    assert not state.has_node("both")
    assert all("both" not in f + t for f, t in wires(state))
    assert state.graph.interface.outputs == []
    state.undo()
    assert state.has_node("both") and ("edge.path", "both.path2") in wires(state)
    assert state.graph.interface.outputs[0].from_ == "both.path"


def test_delete_selection_and_single_wire(state):
    state.select(nodes=["edge"], wires=[("table.path", "shift.path")])
    assert state.delete_selection()
    assert not state.has_node("edge") and ("table.path", "shift.path") not in wires(state)
    assert state.selected_nodes == [] and state.selected_wires == []
    assert not state.delete(["nothing"])


def test_disconnect(state):
    assert state.disconnect(("edge.path", "both.path2"))
    assert ("edge.path", "both.path2") not in wires(state)
    assert any(i.code == "missing-input" for i in state.issues())


# ---------------------------------------------------------------- params

def test_invalid_param_is_kept_and_reported_at_its_field(state):
    errors = state.set_param("table", "feed", -5.0)
    assert ("feed",) in errors and "greater than 0" in errors[("feed",)]
    assert state.node("table").params["feed"] == -5.0
    issue = next(i for i in state.issues() if i.code == "invalid-param")
    assert issue.location == ("nodes", "table", "params", "feed")
    assert state.set_param("table", "feed", 12.5) == {}
    assert state.issues() == []


def test_row_problems_point_into_the_row(state):
    rows = json.loads(json.dumps(ROWS))
    rows[1]["radius"] = -1
    del rows[1]["direction"]
    errors = state.set_param("table", "rows", rows)
    assert set(errors) == {("rows", 1, "radius"), ("rows", 1, "direction")}


def test_unset_param_returns_to_the_default(state):
    state.set_param("shift", "dx", UNSET)
    assert "dx" not in state.node("shift").params
    state.undo()
    assert state.node("shift").params["dx"] == 5.0


def test_shrinking_dynamic_ports_drops_their_wires(state):
    state.set_param("both", "count", 3)
    n = state.add_node("path.polyline")
    assert state.connect(f"{n}.path", "both.path3") is None
    state.plan()  # as the canvas does after every change
    state.set_param("both", "count", 2)
    assert all(t != "both.path3" for _, t in wires(state))
    state.undo()
    assert (f"{n}.path", "both.path3") in wires(state)


def test_wired_param_is_not_reported(state):
    n = state.add_node("basic.number")
    state.set_param("shift", "dx", "oops")
    assert ("dx",) in state.param_errors("shift")
    state.connect(f"{n}.value", "shift.dx")
    assert ("dx",) not in state.param_errors("shift")


def test_field_errors_walk_data_not_union_branches():
    cls = default_registry().lookup("path.segment_table")
    errors = field_errors(cls.Params, {"rows": [{"type": "ellipse", "direction": "cw", "a": 0, "b": 1,
                                                  "start_angle": 0, "end_angle": -90}], "bogus": 1})
    assert set(errors) == {("rows", 0, "a"), ("bogus",)}
    assert errors[("bogus",)] == "unknown param"


# ---------------------------------------------------------------- selection

def test_select_and_toggle(state):
    heard = []
    state.subscribe(heard.append)
    state.select(nodes=["table", "ghost"])
    assert state.selected_nodes == ["table"]
    state.select(nodes=["shift"], toggle=True)
    state.select(nodes=["table"], toggle=True)
    assert state.selected_nodes == ["shift"]
    state.clear_selection()
    assert state.selected_nodes == [] and heard.count("selection") == 4


# ---------------------------------------------------------------- files

def test_save_load_roundtrip_and_dirty_mark(state, tmp_path):
    state.add_node("basic.number", (5, 5))
    assert state.dirty
    state.save()
    assert not state.dirty
    again = EditorState.open(state.path)
    assert flowmc.dumps(again.graph) == flowmc.dumps(state.graph)
    target = state.save(tmp_path / "copy.flowmc.json")
    assert target.read_text() == state.path.read_text() and state.path == target


def test_graph_without_file_needs_save_as(tmp_path):
    st = EditorState(folder=tmp_path)
    st.add_node("basic.number")
    with pytest.raises(GraphError, match="Save as"):
        st.save()


def test_uploaded_text_opens_unsaved_and_bad_text_is_refused(state):
    text = flowmc.dumps(example_builder("uploaded").build())
    with pytest.raises(GraphError, match="up.flowmc.json"):
        state.load_text("{ not json", "up.flowmc.json")
    assert state.graph.title == "example"
    state.load_text(text, "up.flowmc.json")
    assert state.graph.title == "uploaded" and state.dirty and state.path is None
    assert state.suggested_name == "up.flowmc.json" and not state.can_undo


# ---------------------------------------------------------------- sub-graphs

def test_make_subgraph_turns_crossing_wires_into_its_interface(state, tmp_path):
    before = flowmc.Runtime().run(state.graph).outputs["path"]
    new = state.make_subgraph(["shift", "both"], "middle")
    child = flowmc.load(tmp_path / "middle.flowmc.json")
    assert {n.id for n in child.nodes} == {"shift", "both"}
    assert sorted(i.name for i in child.interface.inputs) == ["path", "path2"]
    assert [o.name for o in child.interface.outputs] == ["path"]
    assert state.node(new).type == "subgraph" and state.node(new).params == {"file": "middle.flowmc.json"}
    assert ("table.path", f"{new}.path") in wires(state) and ("edge.path", f"{new}.path2") in wires(state)
    assert state.graph.interface.outputs[0].from_ == f"{new}.path"
    assert state.issues() == []
    after = flowmc.Runtime().run(state.graph, base_dir=tmp_path).outputs["path"]
    assert after.digest() == before.digest()
    state.undo()
    assert state.has_node("shift") and not state.has_node(new)


def test_make_subgraph_refuses_existing_file_and_empty_selection(state, tmp_path):
    (tmp_path / "taken.flowmc.json").write_text("{}")
    with pytest.raises(GraphError, match="already exists"):
        state.make_subgraph(["shift"], "taken.flowmc.json")
    with pytest.raises(GraphError, match="select"):
        state.make_subgraph([], "x")
    with pytest.raises(GraphError, match="leaves"):
        state.make_subgraph(["shift"], "../outside")
    assert state.has_node("shift") and not state.can_undo


# ---------------------------------------------------------------- palette

def test_palette_lists_types_library_graphs_and_graph_files(tmp_path):
    lib = tmp_path / "lib"
    lib.mkdir()
    example_builder("pocket").save(lib / "pocket.flowmc.json")
    example_file(tmp_path, "part.flowmc.json")
    items = palette_items(default_registry(), tmp_path, exclude=tmp_path / "example.flowmc.json")
    keys = {i.key for i in items}
    assert {"path.translate", "path.segment_table", "basic.add", "lib.pocket", "subgraph:part.flowmc.json"} <= keys
    assert search(items, "translate")[0].type_id == "path.translate"
    assert search(items, "segment")[0].type_id == "path.segment_table"
    assert search(items, "pocket")[0].key == "lib.pocket"
    assert [i.type_id for i in search(items, "concatenate paths")] == ["path.join"]
    assert search(items, "zzz-no-such") == []
    assert len(search(items, "")) == len(items)


# ---------------------------------------------------------------- layout

def _box(node_id, pos, ins=(), outs=(), title="node"):
    return layout.node_box(node_id, pos, [(p, p.name) for p in ins], [(p, p.name) for p in outs], title)


def test_hit_testing_prefers_ports_then_nodes_then_notes_then_wires():
    ins = (PortInfo("path", "in", ("Path",)), PortInfo("dx", "in", ("Number",), param=True))
    outs = (PortInfo("path", "out", ("Path",)),)
    a = _box("a", (0, 0), ins, outs)
    b = _box("b", (500, 0), ins, outs)
    spot_out, spot_in = a.port("out", "path"), b.port("in", "path")
    curve = layout.wire_points((spot_out.x, spot_out.y), (spot_in.x, spot_in.y))
    wires = {("a.path", "b.path"): curve}
    assert layout.hit([a, b], wires, spot_out.x + 0.02, spot_out.y).port.kind == "out"
    got = layout.hit([a, b], wires, spot_in.x, spot_in.y - 0.01)
    assert (got.kind, got.node_id, got.port.name, got.port.kind) == ("port", "b", "path", "in")
    assert layout.hit([a, b], wires, *a.centre) == layout.Hit("node", "a")
    mid = curve[len(curve) // 2]
    assert layout.hit([a, b], wires, mid[0], mid[1] + 0.03).wire == ("a.path", "b.path")
    assert layout.hit([a, b], wires, mid[0], mid[1] + 1.0) is None
    comment = layout.NoteBox("#c", "comment", -1.0, 1.0, 9.0, 4.0, "around")
    assert layout.hit([a, b], wires, *a.centre, notes=[comment]) == layout.Hit("node", "a")  # nodes sit above
    assert layout.hit([a, b], wires, -0.5, 0.9, notes=[comment]) == layout.Hit("note", "#c")  # its title strip
    assert layout.hit([a, b], wires, -0.5, -2.0, notes=[comment]) is None  # its body lets clicks through


def test_ray_meets_the_canvas_plane():
    assert layout.ray_to_plane((1.0, 2.0, 10.0), (0.0, 0.0, -1.0)) == (1.0, 2.0)
    x, y = layout.ray_to_plane((0.0, 0.0, 10.0), (0.1, -0.2, -1.0))
    assert np.allclose((x, y), (1.0, -2.0))
    assert layout.ray_to_plane((0.0, 0.0, 10.0), (1.0, 0.0, 0.0)) is None
    assert layout.ray_to_plane((0.0, 0.0, 10.0), (0.0, 0.0, 1.0)) is None


def test_node_box_grows_with_ports_and_text_and_world_flips_y():
    few = _box("a", (100, 50), outs=(PortInfo("v", "out", ("Number",)),))
    many = _box("b", (100, 50), ins=tuple(PortInfo(f"i{k}", "in", ("Number",)) for k in range(5)))
    assert many.h > few.h and (few.x, few.y) == (1.0, -0.5)
    assert few.w == layout.MIN_W * layout.SCALE  # a short title: the narrowest node
    wide = _box("c", (0, 0), title="plan · Look-ahead planner")
    assert wide.w > few.w and wide.title == wide.full_title and not wide.elided
    long = _box("d", (0, 0), title="spindle · " + "Spindle on and wait for speed " * 3)
    assert long.w == layout.MAX_W * layout.SCALE and long.elided and long.title.endswith("…")
    assert layout.text_width(long.title, layout.TITLE_FONT) <= layout.MAX_W - 2 * layout.PAD
    labels = _box("e", (0, 0), ins=(PortInfo("tolerance_when_blending", "in", ("Number",)),),
                  outs=(PortInfo("cycle_time_seconds", "out", ("Number",)),))
    assert labels.w * 100 >= layout.text_width("tolerance_when_blending", layout.PORT_FONT) + layout.text_width(
        "cycle_time_seconds", layout.PORT_FONT)  # the labels of a row fit side by side
    assert layout.to_canvas(*layout.to_world((123.0, 45.0))) == pytest.approx((123.0, 45.0))


def test_new_nodes_go_to_a_free_spot_near_the_middle():
    from flowmc.ui.arrange import Rect, free_spot

    taken = [Rect(0, 0, 200, 120), Rect(260, 0, 200, 120)]
    for _ in range(6):
        x, y = free_spot(taken, (180.0, 90.0), (230.0, 60.0))
        new = Rect(x, y, 180, 90)
        assert not any(new.overlaps(t, 29.0) for t in taken)
        assert abs(x - 140) < 600 and abs(y - 15) < 600
        taken.append(new)
    assert free_spot([], (100.0, 60.0), (50.0, 30.0)) == (0.0, 0.0)  # nothing in the way: centred on the point


def test_text_fields_parse_what_they_hold():
    from flowmc.ui.forms import FieldSpec
    from flowmc.ui.inspector import ParseError, parse_text

    number = FieldSpec("x", "optional", "x", inner=FieldSpec("x", "number", "x"))
    assert parse_text(number, " ") is None and parse_text(number, "2.5") == 2.5
    with pytest.raises(ParseError, match="'abc' is not a number"):
        parse_text(number, "abc")
    names = FieldSpec("names", "list", "names", inner=FieldSpec("item", "string", "item"))
    assert parse_text(names, "a, b,\nc") == ["a", "b", "c"]
    knots = FieldSpec("k", "optional", "k", inner=FieldSpec("k", "list", "k", inner=FieldSpec("item", "number", "item")))
    assert parse_text(knots, "0, 0, 1, 1") == [0, 0, 1, 1]
    points = FieldSpec("p", "points", "p")
    assert parse_text(points, "1, 2, 3\n\n4; 5; 6") == [[1, 2, 3], [4, 5, 6]]
    with pytest.raises(ParseError, match="line 2"):
        parse_text(points, "1, 2, 3\n4, y, 6")
    assert parse_text(FieldSpec("j", "json", "j"), '{"a": [1]}') == {"a": [1]}
    with pytest.raises(ParseError, match="not valid JSON"):
        parse_text(FieldSpec("j", "json", "j"), "{")


def test_form_fields_follow_the_params_schema():
    from flowmc.ui.forms import form_fields, new_row

    table = {f.name: f for f in form_fields(default_registry().lookup("path.segment_table").Params.model_json_schema())}
    assert (table["start"].kind, table["feed"].kind, table["rows"].kind) == ("vector3", "number", "rows")
    assert table["feed"].label == "feed (mm/s)" and table["feed"].minimum == 0
    assert set(table["rows"].variants) == {"line", "arc", "ellipse"}
    arc = new_row(table["rows"], "arc")
    assert arc["type"] == "arc" and arc["direction"] == "ccw" and arc["radius"] > 0
    assert new_row(table["rows"], "line", {"type": "arc", "feed": 3.0})["feed"] == 3.0
    nurbs = {f.name: f for f in form_fields(default_registry().lookup("path.nurbs").Params.model_json_schema())}
    assert nurbs["control_points"].kind == "points" and nurbs["knots"].kind == "optional"
    assert (nurbs["degree"].kind, nurbs["degree"].minimum, nurbs["degree"].maximum) == ("integer", 1, 7)
    mirror = {f.name: f for f in form_fields(default_registry().lookup("path.mirror").Params.model_json_schema())}
    assert mirror["axis"].kind == "dropdown" and mirror["axis"].options == ("X", "Y", "Z")


def test_opening_a_subgraph_keeps_the_parent_unsaved_changes_and_undo(state, tmp_path):
    new = state.make_subgraph(["shift"], "moved")
    state.set_param("table", "feed", 33.0)
    assert state.dirty and state.parents == []
    state.enter(state.subgraph_file(new))
    assert state.path == tmp_path / "moved.flowmc.json" and state.parents == ["example.flowmc.json"]
    assert not state.can_undo
    state.set_param("shift", "dx", 1.0)
    with pytest.raises(GraphError, match="unsaved"):
        state.leave()
    state.undo()
    state.leave()
    assert state.path == tmp_path / "example.flowmc.json" and state.dirty
    assert state.node("table").params["feed"] == 33.0
    state.undo()
    assert state.node("table").params["feed"] == 40.0
    with pytest.raises(GraphError, match="not a sub-graph"):
        state.leave()


def test_history_keeps_at_most_its_limit():
    from flowmc.ui.history import History

    history = History(limit=3)
    graphs = [flowmc.Graph(title=str(k)) for k in range(5)]
    for g in graphs[:4]:
        history.record(g)
    current = graphs[4]
    titles = []
    while (current := history.undo(current)) is not None:
        titles.append(current.title)
    assert titles == ["3", "2", "1"]


def test_a_screen_rectangle_maps_onto_the_canvas_plane():
    from types import SimpleNamespace

    from flowmc.ui.camera import screen_rect_to_world

    cam = SimpleNamespace(position=np.array([2.0, 1.0, 10.0]), fov=2 * np.arctan(0.5), aspect=2.0)
    x0, y0, x1, y1 = screen_rect_to_world(cam, (0.0, 0.0), (1.0, 1.0))  # the whole view: 20 x 10 around (2, 1)
    assert (x0, y0, x1, y1) == pytest.approx((-8.0, -4.0, 12.0, 6.0))
    assert screen_rect_to_world(cam, (0.5, 0.5), (0.75, 1.0)) == pytest.approx((2.0, -4.0, 7.0, 1.0))
