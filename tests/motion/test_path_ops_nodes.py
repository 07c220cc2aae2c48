"""The path-operation nodes run through flowmc.run on small graphs, against the motion functions."""

import json
import math
from pathlib import Path as FsPath

import numpy as np
import pytest
from PIL import Image

import flowmc
from flowmc.motion.contour import image_to_path
from flowmc.motion.offset import offset_path
from flowmc.motion.segment_table import path_from_rows

REFERENCE = FsPath(__file__).resolve().parents[1] / "data" / "reference"


def thesis() -> dict:
    return json.loads((REFERENCE / "thesis_pattern.json").read_text())


def picture(folder: FsPath, name: str = "pic.png") -> FsPath:
    """A dark disc and a dark square on white paper, 120 x 80 px."""
    yy, xx = np.mgrid[:80, :120]
    ink = ((yy - 40) ** 2 + (xx - 30) ** 2 <= 20**2) | ((abs(yy - 40) <= 15) & (abs(xx - 90) <= 15))
    file = folder / name
    Image.fromarray(np.where(ink, 0, 255).astype(np.uint8)).save(file)
    return file


def run_saved(g: flowmc.GraphBuilder, folder: FsPath):
    """Save the graph beside its files and run it from disk, as a user would."""
    file = folder / "graph.flowmc.json"
    g.save(file)
    return flowmc.run(file)


# ------------------------------------------------------------------ image contour

@pytest.mark.parametrize("method", [None, "report_4neighbour"])
def test_image_contour_node_traces_a_picture_beside_the_graph(tmp_path, method):
    picture(tmp_path)
    g = flowmc.GraphBuilder()
    params = {"file": "pic.png", "width_mm": 60.0, "origin_x": 10.0, "feed": 12.0}
    if method:
        params["method"] = method
    node = g.add("path.image_contour", id="img", **params)
    g.output("path", "Path", node.path)
    result = run_saved(g, tmp_path)
    assert result.ok, result.errors
    path = result.outputs["path"]
    expected = image_to_path(tmp_path / "pic.png", method or "marching_squares", width_mm=60.0, origin=(10.0, 0.0),
                             feed=12.0)
    assert path.digest() == expected.digest()
    assert sum(s.rapid and not s.tool_down for s in path) == 2
    assert all(s.tool_down and s.feed == 12.0 for s in path if not s.rapid)
    assert result.nodes["img"].logs == [f"2 outlines, {len(path)} moves"]


def test_image_contour_default_method_is_marching_squares():
    from flowmc.plugins import default_registry

    schema = default_registry().describe("path.image_contour")["params_schema"]
    assert schema["properties"]["method"]["default"] == "marching_squares"


def test_unreadable_picture_fails_the_node_naming_the_file(tmp_path):
    (tmp_path / "notes.png").write_text("not a picture")
    g = flowmc.GraphBuilder()
    g.add("path.image_contour", id="img", file="notes.png")
    result = run_saved(g, tmp_path)
    assert not result.ok
    assert result.errors == ["node 'img': notes.png: not an image Pillow can read (PNG, JPEG, BMP, ...)"]


def test_missing_picture_and_paths_outside_the_graph_folder_are_refused(tmp_path):
    inner = tmp_path / "graphs"
    inner.mkdir()
    picture(tmp_path, "outside.png")
    g = flowmc.GraphBuilder()
    g.add("path.image_contour", id="gone", file="gone.png")
    g.add("path.image_contour", id="out", file="../outside.png")
    result = run_saved(g, inner)
    assert result.nodes["gone"].error == "node 'gone': gone.png: image file not found"
    assert "leaves the graph's folder" in result.nodes["out"].error


# ------------------------------------------------------------------ tool-radius offset

def _thesis_table(g: flowmc.GraphBuilder):
    d = thesis()
    return g.add("path.segment_table", id="table", rows=d["segments"], start=d["start"], feed=30.0)


@pytest.mark.parametrize("side", ["left", "right"])
def test_tool_offset_node_compensates_the_thesis_pattern(side):
    g = flowmc.GraphBuilder()
    table = _thesis_table(g)
    off = g.add("path.tool_offset", id="off", side=side, radius=2.0)
    g.wire(table.path, off.path)
    g.output("path", "Path", off.path)
    result = flowmc.run(g.build())
    assert result.ok, result.errors
    d = thesis()
    expected = offset_path(path_from_rows(d["segments"], start=d["start"], feed=30.0), 2.0, side)
    assert result.outputs["path"].digest() == expected.digest()


def test_tool_radius_can_be_fed_by_a_wire():
    g = flowmc.GraphBuilder()
    square = g.add("path.polyline", id="sq", points=[(0, 0, 0), (10, 0, 0), (10, 10, 0), (0, 10, 0)], closed=True)
    r = g.add("basic.number", id="r", value=1.5)
    off = g.add("path.tool_offset", id="off", side="right")
    g.wire(square.path, off.path)
    g.wire(r.value, off.radius)
    g.output("path", "Path", off.path)
    result = flowmc.run(g.build())
    assert result.ok, result.errors
    assert result.outputs["path"].length == pytest.approx(40 + 2 * math.pi * 1.5)


def test_tool_offset_of_an_ellipse_fails_naming_the_row():
    g = flowmc.GraphBuilder()
    table = g.add("path.segment_table", id="table", rows=[
        {"type": "line", "end": [10, 0, 0]},
        {"type": "ellipse", "direction": "ccw", "a": 5, "b": 3, "start_angle": 0, "end_angle": 90}])
    off = g.add("path.tool_offset", id="off", radius=1.0)
    g.wire(table.path, off.path)
    result = flowmc.run(g.build())
    assert result.nodes["off"].error.startswith("node 'off': segment 2 (row 2): tool-radius offset handles lines")


NOTCHED = [(0, 0, 0), (20, 0, 0), (20, 10, 0), (11.5, 10, 0), (11.5, 3, 0), (8.5, 3, 0), (8.5, 10, 0), (0, 10, 0)]


@pytest.mark.parametrize("gouge", ["refuse", "trim"])
def test_tool_offset_node_refuses_or_trims_a_gouge(gouge):
    g = flowmc.GraphBuilder()
    part = g.add("path.polyline", id="part", points=NOTCHED, closed=True)
    off = g.add("path.tool_offset", id="off", side="left", radius=2.0, gouge=gouge)
    g.wire(part.path, off.path)
    g.output("path", "Path", off.path)
    result = flowmc.run(g.build())
    if gouge == "refuse":
        assert not result.ok and "would cut into segment 5" in result.nodes["off"].error
    else:
        assert result.ok, result.errors
        assert any(s.rapid and not s.tool_down for s in result.outputs["path"])


def test_pocket_node_clears_a_square_in_rings():
    g = flowmc.GraphBuilder()
    square = g.add("path.polyline", id="sq", points=[(0, 0, 0), (20, 0, 0), (20, 20, 0), (0, 20, 0)], closed=True)
    pocket = g.add("path.pocket", id="pocket", radius=2.0, stepover=1.5, feed=12.0)
    g.wire(square.path, pocket.path)
    g.output("path", "Path", pocket.path)
    result = flowmc.run(g.build())
    assert result.ok, result.errors
    path = result.outputs["path"]
    box = path.summary()
    assert box["bbox_min"][:2] == pytest.approx([2, 2]) and box["bbox_max"][:2] == pytest.approx([18, 18])
    rings = {s.source for s in path if not s.rapid}
    assert "pocket ring 1 (finish)" in rings and len(rings) == math.ceil((10 - 2) / 1.5)
    assert {s.feed for s in path if not s.rapid} == {12.0}


# ------------------------------------------------------------------ transforms and join

def test_translate_rotate_scale_mirror_chain():
    g = flowmc.GraphBuilder()
    line = g.add("path.polyline", id="line", points=[(0, 0, 0), (10, 0, 0)])
    move = g.add("path.translate", id="move", dx=5.0, dy=1.0, dz=2.0)
    turn = g.add("path.rotate", id="turn", degrees=90.0, about_x=5.0, about_y=1.0)
    grow = g.add("path.scale", id="grow", factor=2.0, about_x=5.0, about_y=1.0, about_z=2.0)
    flip = g.add("path.mirror", id="flip", axis="X", about=1.0)
    g.wire(line.path, move.path)
    g.wire(move.path, turn.path)
    g.wire(turn.path, grow.path)
    g.wire(grow.path, flip.path)
    for ref in (move, turn, grow, flip):
        g.output(ref.id, "Path", ref.path)
    out = flowmc.run(g.build()).outputs
    ends = {k: np.vstack([out[k].start, out[k].end]) for k in out}
    np.testing.assert_allclose(ends["move"], [(5, 1, 2), (15, 1, 2)])
    np.testing.assert_allclose(ends["turn"], [(5, 1, 2), (5, 11, 2)], atol=1e-12)
    np.testing.assert_allclose(ends["grow"], [(5, 1, 2), (5, 21, 2)], atol=1e-12)
    np.testing.assert_allclose(ends["flip"], [(-3, 1, 2), (-3, 21, 2)], atol=1e-12)


def test_mirror_turns_arcs_the_other_way():
    g = flowmc.GraphBuilder()
    table = _thesis_table(g)
    flip = g.add("path.mirror", id="flip", axis="Y")
    g.wire(table.path, flip.path)
    g.output("path", "Path", flip.path)
    path = flowmc.run(g.build()).outputs["path"]
    arcs = [s for s in path if s.kind == "arc"]
    assert [a.ccw for a in arcs] == [False, True]
    np.testing.assert_allclose(arcs[0].center[:2], (-40, -25))


def test_join_links_paths_with_tool_up_rapids_in_order():
    g = flowmc.GraphBuilder()
    parts = [g.add("path.polyline", id=f"p{k}", points=[(10 * k, 0, 0), (10 * k + 5, 0, 0)], feed=7.0) for k in range(3)]
    join = g.add("path.join", id="join", count=3, rapid_feed=100.0)
    for k, part in enumerate(parts, start=1):
        g.wire(part.path, join[f"path{k}"])
    g.output("path", "Path", join.path)
    result = flowmc.run(g.build())
    assert result.ok, result.errors
    path = result.outputs["path"]
    assert [(s.rapid, s.tool_down) for s in path] == [(False, True), (True, False)] * 2 + [(False, True)]
    assert [s.feed for s in path if s.rapid] == [100.0, 100.0]
    assert path.gaps() == [] and path.end[0] == 25.0


def test_join_with_an_unwired_input_is_reported_before_running():
    g = flowmc.GraphBuilder()
    a = g.add("path.polyline", id="a")
    join = g.add("path.join", id="join", count=3)
    g.wire(a.path, join.path1)
    issues = flowmc.validate(g.build())
    assert {i.code for i in issues} == {"missing-input"}
    assert sorted(("path2" in i.message, "path3" in i.message) for i in issues) == [(False, True), (True, False)]
