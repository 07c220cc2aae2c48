"""Editing beyond click-to-wire, in plain Python: copy and paste, comments and labels in the file's view
section, the interface as terminals, auto-layout, align and distribute, the palette's search."""

from __future__ import annotations

import json
import random

import pytest

import flowmc
from editor_graphs import example_file
from flowmc.errors import GraphError
from flowmc.graph import dumps, load, loads
from flowmc.plugins import default_registry
from flowmc.ui import arrange, clipboard, palette_list
from flowmc.ui.arrange import Rect
from flowmc.ui.palette import PaletteItem, categories, palette_items, search
from flowmc.ui.state import EditorState
from flowmc.ui.text import unescape_md


@pytest.fixture
def state(tmp_path):
    return EditorState.open(example_file(tmp_path))


def wires(state):
    return sorted((w.from_, w.to) for w in state.graph.wires)


# ---------------------------------------------------------------- copy and paste

def test_copy_paste_keeps_inner_wires_and_params_with_fresh_ids(state):
    state.select(nodes=["table", "shift"])
    text = state.copy_selection()
    new = state.paste(text, (1000.0, 500.0))
    assert len(new) == 2 and not {"table", "shift"} & set(new)
    a, b = sorted((state.node(n) for n in new), key=lambda n: n.type != "path.segment_table")
    assert a.type == "path.segment_table" and a.params == state.node("table").params
    assert (f"{a.id}.path", f"{b.id}.path") in wires(state)  # the wire between them came along
    assert not any(w[0].startswith(a.id) and w[1].startswith("both") for w in wires(state))  # not wires leaving
    assert min(state.node(n).pos[0] for n in new) == 1000.0 and min(state.node(n).pos[1] for n in new) == 500.0
    assert state.selected_nodes == new and state.issues() == []
    state.undo()
    assert not any(state.has_node(n) for n in new)


def test_paste_goes_between_graphs_and_refuses_other_text(state, tmp_path):
    state.select(nodes=["edge"])
    text = state.copy_selection()
    other = EditorState(flowmc.Graph(), folder=tmp_path)
    assert other.paste(text, (0.0, 0.0)) == ["edge"]  # the id is free there
    assert other.node("edge").params == state.node("edge").params
    with pytest.raises(GraphError, match="no flowmc nodes"):
        other.paste("x,y\n1,2", (0.0, 0.0))
    assert clipboard.parse('{"kind": "flowmc-fragment/1", "nodes": [{"id": "bad id!"}]}') is None


# ---------------------------------------------------------------- comments and labels

def test_comments_and_labels_are_view_state_saved_in_the_file(state, tmp_path):
    before = state.graph.fingerprint_json()
    c = state.add_note("comment", "Path sources", (-20.0, -40.0), (400.0, 380.0))
    label = state.add_note("label", "feed is mm/s", (700.0, -60.0))
    state.set_note(c, text="Sources of the path")
    assert state.graph.fingerprint_json() == before  # a note never changes a result or a cache key
    state.move_nodes({label: (720.0, -80.0)})
    path = state.save(tmp_path / "noted.flowmc.json")
    data = json.loads(path.read_text())
    assert data["schema_version"] == 2
    assert data["view"]["comments"] == [{"id": "comment1", "text": "Sources of the path", "pos": [-20.0, -40.0],
                                         "size": [400.0, 380.0]}]
    assert data["view"]["labels"] == [{"id": "label1", "text": "feed is mm/s", "pos": [720.0, -80.0]}]
    again = load(path)
    assert dumps(again) == path.read_text()  # load -> save is byte-identical
    state.select(notes=[label])
    state.delete_selection()
    assert [lb.id for lb in state.graph.view.labels] == []


def test_a_version_1_file_migrates_and_saves_without_a_view_section(tmp_path):
    text = dumps(flowmc.load(example_file(tmp_path))).replace('"schema_version": 2', '"schema_version": 1')
    graph = loads(text)
    assert graph.schema_version == 2 and graph.view.empty
    assert '"view"' not in dumps(graph)


# ---------------------------------------------------------------- interface terminals

def test_interface_inputs_and_outputs_are_added_wired_renamed_and_removed(state):
    key = state.add_terminal("in", "offset", "Number")
    assert key == "@in:offset" and state.graph.interface.inputs[-1].to == []  # declared, not wired yet
    assert state.connect("@in:offset", "shift.dx") is None
    assert "shift.dx" in state.graph.interface.inputs[-1].to
    assert "takes Path" in state.connect("@in:offset", "both.path1")  # a Number cannot feed a Path
    assert state.issues() == []
    result = flowmc.Runtime().run(state.graph, inputs={"offset": 7.0}, base_dir=state.base_dir)
    assert result.output("shift", "path").start[0] == pytest.approx(7.0)
    out = state.add_terminal("out", "edge_path", source="edge.path")
    assert out == "@out:edge_path" and state.graph.interface.outputs[-1].type == "Path"
    with pytest.raises(GraphError, match="already has a port"):
        state.add_terminal("in", "offset", "Number")
    state.select(nodes=[key])
    state.rename_terminal(key, "dx_offset")
    assert [i.name for i in state.graph.interface.inputs] == ["dx_offset"]
    assert state.selected_nodes == ["@in:dx_offset"]
    assert state.delete(wires=[("@in:dx_offset", "shift.dx")])
    assert state.graph.interface.inputs[0].to == []
    assert state.delete(["@in:dx_offset", "@out:edge_path"])
    assert [o.name for o in state.graph.interface.outputs] == ["path"]


def test_deleting_the_node_an_input_fed_leaves_the_input_unwired(state):
    state.add_terminal("in", "offset", "Number")
    state.connect("@in:offset", "shift.dx")
    state.delete(["shift"])
    assert [(i.name, i.to) for i in state.graph.interface.inputs] == [("offset", [])]


# ---------------------------------------------------------------- layout

def _random_graph(n: int, seed: int = 3) -> tuple[dict[str, Rect], list[tuple[str, str]]]:
    rng = random.Random(seed)
    rects = {f"n{i}": Rect(rng.uniform(0, 900), rng.uniform(0, 600), rng.choice([150, 210, 300]),
                           rng.choice([54, 90, 180])) for i in range(n)}
    ids = list(rects)
    edges = [(ids[rng.randrange(max(0, i - 9), i)], ids[i]) for i in range(1, n)]
    edges += [(ids[rng.randrange(0, i)], ids[i]) for i in range(1, n) if rng.random() < 0.3]
    return rects, edges


def test_auto_layout_of_120_nodes_leaves_no_overlap_and_flows_left_to_right():
    rects, edges = _random_graph(120)
    assert len(arrange.overlaps(rects)) > 20  # the scattered start overlaps a lot
    places = arrange.auto_layout(rects, edges)
    laid = {k: r.moved(*places[k]) for k, r in rects.items()}
    assert arrange.overlaps(laid, gap=10.0) == []
    assert all(laid[a].x + laid[a].w <= laid[b].x for a, b in edges)  # every wire runs left to right


def test_auto_layout_cuts_crossings():
    rects, edges = _random_graph(60, seed=7)
    places = arrange.auto_layout(rects, edges)
    columns: dict[float, list[str]] = {}
    for k, (x, _y) in sorted(places.items(), key=lambda kv: kv[1][1]):
        columns.setdefault(x, []).append(k)
    order = [columns[x] for x in sorted(columns)]
    shuffled = [sorted(c, key=lambda k: rects[k].y) for c in order]  # the same columns in the old order
    assert arrange.crossings(order, edges) < arrange.crossings(shuffled, edges)


def test_align_and_distribute():
    rects = {"a": Rect(0, 10, 100, 50), "b": Rect(300, 70, 150, 80), "c": Rect(120, 200, 100, 40)}
    assert {k: p[0] for k, p in arrange.align(rects, "left").items()} == {"a": 0, "b": 0, "c": 0}
    assert {k: p[1] + rects[k].h for k, p in arrange.align(rects, "bottom").items()} == {"a": 240, "b": 240, "c": 240}
    spread = arrange.align(rects, "distribute across")
    xs = sorted((spread[k][0], rects[k].w) for k in rects)
    gaps = [xs[i + 1][0] - (xs[i][0] + xs[i][1]) for i in range(2)]
    assert gaps[0] == pytest.approx(gaps[1]) and xs[0][0] == 0 and xs[-1][0] + xs[-1][1] == 450
    with pytest.raises(ValueError, match="unknown alignment"):
        arrange.align(rects, "diagonal")


# ---------------------------------------------------------------- palette

def test_palette_finds_nodes_by_port_type_and_groups_by_category():
    items = palette_items(default_registry())
    takes_trajectory = {i.type_id for i in search(items, "Trajectory")}
    assert {"device.card_output", "device.preflight", "plan.lookahead"} <= takes_trajectory
    assert len(takes_trajectory) >= 8
    assert "path.translate" in {i.type_id for i in search(items, "translate path")}
    groups = categories(items)
    assert list(groups)[0] == "Path" and sum(map(len, groups.values())) == len(items)


def test_the_palette_list_has_an_entry_per_item_and_shows_file_text_as_text():
    items = categories(palette_items(default_registry()))
    page = palette_list.render(items)
    assert page.count("<details open>") == len(items) and page.count("<button ") == sum(map(len, items.values()))
    assert 'data-flowmc-key="path.translate"' in page
    hostile = PaletteItem("subgraph", '<img src=x onerror="alert(1)">', "Graph files", 'said "hi" <b>',
                          {"file": 'a"b.flowmc.json'})
    same = PaletteItem("subgraph", '<img src=x onerror="alert(1)">', "Graph files", "", {"file": "c.flowmc.json"})
    page = palette_list.render({"<i>Graph</i> files": [hostile, same]})
    assert "<img" not in page and "<b>" not in page and "<i>" not in page
    assert page.count("&lt;img src=x onerror=&quot;alert(1)&quot;&gt;") == 2
    assert 'data-flowmc-key="subgraph:a&quot;b.flowmc.json"' in page
    assert palette_list.labels([hostile, same])[1].endswith("(Graph files)")  # the same title twice: told apart


# ---------------------------------------------------------------- a sub-graph's interface and its parents

def test_saving_a_sub_graph_whose_interface_changed_names_every_parent_it_breaks(tmp_path):
    from flowmc.ui.app import Editor

    editor = Editor(example_file(tmp_path), port=0, extensions=False)
    try:
        state = editor.state
        state.make_subgraph(["shift", "both"], "middle")
        state.save()
        other = EditorState.open(tmp_path / "example.flowmc.json")
        other.save(tmp_path / "another.flowmc.json")  # a second graph that uses middle.flowmc.json
        state.select(nodes=[n.id for n in state.graph.nodes if n.type == "subgraph"])
        assert editor.selection.open_subgraph()
        assert state.parents == ["example.flowmc.json"]
        state.rename_terminal("@in:path2", "second")  # the parents wire edge.path into path2
        editor.files.save()
        assert state.dirty and editor.pending_modal is not None  # not saved: it asks first
        text = unescape_md(editor.messages[-1][1])
        assert "would break 2 wire(s)" in text
        modal, go = editor.pending_modal
        go.value = True  # "Save anyway"
        assert not state.dirty and "second" in (tmp_path / "middle.flowmc.json").read_text()
    finally:
        editor.close()


def test_an_added_interface_input_breaks_nothing_and_saves_at_once(tmp_path):
    from flowmc.ui.interface_check import broken_parents

    state = EditorState.open(example_file(tmp_path))
    state.make_subgraph(["shift"], "shifter")
    state.save()
    child = EditorState.open(tmp_path / "shifter.flowmc.json")
    child.add_terminal("in", "extra", "Number")
    assert broken_parents(child.graph, child.path, tmp_path, default_registry()) == []
    child.delete(["@out:path"])
    broken = broken_parents(child.graph, child.path, tmp_path, default_registry())
    assert broken and all("no output 'path'" in line for line in broken)
