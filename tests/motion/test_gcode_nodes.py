"""The G-code in / G-code out nodes, run through flowmc.run on graphs saved beside their files."""

from pathlib import Path as FsPath

import numpy as np

import flowmc
from flowmc.motion.gcode import parse_gcode, read_gcode
from flowmc.motion.gcode_write import path_to_gcode

PROGRAM = """\
G21 G90 F600
G0 X5 Y5
G1 Z-1
G2 X15 Y5 I5 J0
G18 G3 X25 Z-1 R5
S1000 M3
G4 P0.5
G17 G1 X0 Y0
M2
"""


def run_saved(g: flowmc.GraphBuilder, folder: FsPath, runtime=None):
    file = folder / "graph.flowmc.json"
    g.save(file)
    return flowmc.run(file, runtime=runtime)


def test_gcode_in_reads_typed_text(tmp_path):
    g = flowmc.GraphBuilder()
    node = g.add("path.gcode_in", id="gin", text=PROGRAM)
    g.output("path", "Path", node.path)
    result = run_saved(g, tmp_path)
    assert result.ok, result.errors
    path = result.outputs["path"]
    assert path.digest() == parse_gcode(PROGRAM, "text").digest()
    # M2 stops the spindle: a last zero-second dwell carries that.
    assert [s.kind for s in path] == ["line", "line", "arc", "arc", "dwell", "line", "dwell"]
    assert path[0].source == "text:2" and path[-1].spindle == 0.0 and path[-2].spindle == 1000.0
    assert result.nodes["gin"].logs == [f"7 segments (2 arcs, 2 dwells, 0 pauses and tool changes), "
                                        f"{path.length:.3f} mm"]


def test_gcode_in_reads_a_file_beside_the_graph_and_rereads_it_when_it_changes(tmp_path):
    (tmp_path / "parts").mkdir()
    program = tmp_path / "parts" / "a.ngc"
    program.write_text(PROGRAM)
    g = flowmc.GraphBuilder()
    node = g.add("path.gcode_in", id="gin", file="parts/a.ngc", rapid_feed=50.0)
    g.output("path", "Path", node.path)
    runtime = flowmc.Runtime()
    first = run_saved(g, tmp_path, runtime)
    assert first.ok, first.errors
    expected = read_gcode(program, rapid_feed=50.0, source="parts/a.ngc")
    assert first.outputs["path"].digest() == expected.digest()
    assert first.outputs["path"][0].source == "parts/a.ngc:2" and first.outputs["path"][0].feed == 50.0
    program.write_text(PROGRAM.replace("X15 Y5 I5", "X15 Y5 I5 P2"))
    second = run_saved(g, tmp_path, runtime)
    assert second.ok, second.errors
    assert second.outputs["path"][2].turns == 1


def test_gcode_text_can_come_from_a_wire(tmp_path):
    g = flowmc.GraphBuilder()
    text = g.add("basic.text", id="src", value="G1 X3 F60\nG1 Y4\n")
    node = g.add("path.gcode_in", id="gin")
    g.wire(text.value, node.text)
    g.output("path", "Path", node.path)
    result = run_saved(g, tmp_path)
    assert result.ok, result.errors
    assert result.outputs["path"].length == 7.0


def test_bad_gcode_fails_the_node_naming_the_line(tmp_path):
    g = flowmc.GraphBuilder()
    g.add("path.gcode_in", id="gin", text="G1 X1 F60\nG38.2 Z-1\n")
    result = run_saved(g, tmp_path)
    assert not result.ok
    assert result.errors == ["node 'gin': text:2: G38.2 is not supported (probing (G38.x) is not supported: flowmc "
                             "plans paths ahead of time and cannot wait for a probe to trip) (in: G38.2 Z-1)"]
    (tmp_path / "b.ngc").write_text("G1 X1 F60\n\nG2 X30 R2\n")
    g = flowmc.GraphBuilder()
    g.add("path.gcode_in", id="gin", file="b.ngc")
    result = run_saved(g, tmp_path)
    assert not result.ok
    assert result.errors[0].startswith("node 'gin': b.ngc:3: arc radius R2 is too small")


def test_empty_gcode_and_files_outside_the_graph_folder_are_refused(tmp_path):
    inner = tmp_path / "graphs"
    inner.mkdir()
    (tmp_path / "outside.ngc").write_text(PROGRAM)
    for params, message in [({}, "no G-code"), ({"file": "../outside.ngc"}, "leaves the graph's folder"),
                            ({"file": "missing.ngc"}, "missing.ngc")]:
        g = flowmc.GraphBuilder()
        g.add("path.gcode_in", id="gin", **params)
        result = run_saved(g, inner)
        assert not result.ok
        assert result.errors[0].startswith("node 'gin'") and message in result.errors[0], result.errors


def test_gcode_out_gives_text_and_writes_the_file_atomically(tmp_path):
    (tmp_path / "out").mkdir()
    g = flowmc.GraphBuilder()
    src = g.add("path.gcode_in", id="gin", text=PROGRAM)
    out = g.add("path.gcode_out", id="gout", file="out/part.ngc", blend_tolerance=0.05)
    g.wire(src.path, out.path)
    g.output("text", "Text", out.text)
    result = run_saved(g, tmp_path)
    assert result.ok, result.errors
    text = result.outputs["text"]
    path = parse_gcode(PROGRAM, "text")
    assert text == path_to_gcode(path, blend_tolerance=0.05)
    assert (tmp_path / "out" / "part.ngc").read_text() == text
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["part.ngc"]
    back = read_gcode(tmp_path / "out" / "part.ngc")
    assert len(back) == len(path)
    for a, b in zip(path, back):
        np.testing.assert_allclose(a.end, b.end, atol=1e-6)
    assert result.nodes["gout"].logs == [f"wrote {text.count(chr(10))} lines to out/part.ngc"]


def test_gcode_out_round_trips_through_gcode_in_by_wire(tmp_path):
    g = flowmc.GraphBuilder()
    src = g.add("path.gcode_in", id="a", text=PROGRAM)
    out = g.add("path.gcode_out", id="out")
    back = g.add("path.gcode_in", id="b")
    g.wire(src.path, out.path)
    g.wire(out.text, back.text)
    g.output("first", "Path", src.path)
    g.output("again", "Path", back.path)
    result = run_saved(g, tmp_path)
    assert result.ok, result.errors
    first, again = result.outputs["first"], result.outputs["again"]
    assert [s.kind for s in first] == [s.kind for s in again]
    for a, b in zip(first, again):
        np.testing.assert_allclose(a.end, b.end, atol=1e-6)
        assert (a.feed == b.feed) or a.rapid


def test_gcode_out_refuses_files_outside_the_folder_and_missing_folders(tmp_path):
    for file, message in [("../x.ngc", "leaves the graph's folder"), ("nodir/x.ngc", "nodir/x.ngc: cannot write")]:
        g = flowmc.GraphBuilder()
        src = g.add("path.gcode_in", id="gin", text=PROGRAM)
        out = g.add("path.gcode_out", id="gout", file=file)
        g.wire(src.path, out.path)
        result = run_saved(g, tmp_path)
        assert not result.ok
        assert result.errors[0].startswith("node 'gout'") and message in result.errors[0], result.errors
    assert not (tmp_path.parent / "x.ngc").exists()


def test_gcode_in_uses_the_tool_table_parameter_file_and_subroutine_folder_beside_the_graph(tmp_path):
    (tmp_path / "subs").mkdir()
    (tmp_path / "subs" / "square.ngc").write_text(
        "o<square> sub\nG1 X#1 F600\nG1 Y#1\no<square> endsub\n")
    (tmp_path / "tools.tbl").write_text("T1 P1 Z10 D6 ;6 mm end mill\n")
    (tmp_path / "machine.var").write_text("5221 100\n5222 50\n")
    program = "G54 T1 M6 G43\nG0 X0 Y0 Z0\no<square> call [20]\nM0\nM2\n"
    g = flowmc.GraphBuilder()
    node = g.add("path.gcode_in", id="gin", text=program, tool_table="tools.tbl", parameter_file="machine.var",
                 subroutine_folder="subs")
    g.output("path", "Path", node.path)
    result = run_saved(g, tmp_path)
    assert result.ok, result.errors
    path = result.outputs["path"]
    moves = [s for s in path if s.kind == "line"]
    np.testing.assert_allclose(moves[0].end, [100, 50, 10])  # G54 offset and the 10 mm tool length
    np.testing.assert_allclose(moves[-1].end, [120, 70, 10])
    assert moves[-1].source == "square.ngc:3"
    events = path.events()
    assert [e.kind for _, e in events] == ["tool_change", "pause"]
    assert events[0][1].tool == 1 and "6 mm end mill" in events[0][1].message


def test_a_subroutine_file_linked_from_outside_the_folder_is_not_read(tmp_path):
    (tmp_path / "graph").mkdir()
    (tmp_path / "graph" / "subs").mkdir()
    (tmp_path / "secret.ngc").write_text("o<secret> sub\nG1 X1 F60\no<secret> endsub\n")
    (tmp_path / "graph" / "subs" / "secret.ngc").symlink_to(tmp_path / "secret.ngc")
    g = flowmc.GraphBuilder()
    g.add("path.gcode_in", id="gin", text="o<secret> call\nM2\n", subroutine_folder="subs")
    result = run_saved(g, tmp_path / "graph")
    assert not result.ok and "no file secret.ngc" in result.errors[0]
