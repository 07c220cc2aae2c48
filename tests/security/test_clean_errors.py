"""Issue 18 item 6 and the smaller defects of item 9: each input that once gave an internal error, a
RuntimeWarning, a hang or a refusal now gives one clean line naming where, with exit 2 for an invalid
graph or argument and 1 for a node that failed (``flowmc.cli.main`` in-process, as the command runs)."""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import pytest

from flowmc.cli import main

REPO = Path(__file__).resolve().parents[2]


def _graph(folder: Path, nodes: list[dict] | None, wires=(), name: str = "g.flowmc.json", raw: str | None = None) -> str:
    path = folder / name
    doc = {"schema_version": 1, "nodes": nodes, "wires": [{"from": a, "to": b} for a, b in wires]}
    path.write_text(raw if raw is not None else json.dumps(doc), encoding="utf-8")
    return str(path)


def _gcode(folder: Path, text: str) -> str:
    (folder / "p.ngc").write_text(text, encoding="utf-8")
    return _graph(folder, [{"id": "gc", "type": "path.gcode_in", "params": {"file": "p.ngc"}},
                           {"id": "m", "type": "path.measure"}], [("gc.path", "m.path")])


def _nested_list(depth: int):
    value: object = 1
    for _ in range(depth):
        value = [value]
    return value


def _chain(folder: Path, depth: int) -> str:
    leaf = {"schema_version": 1, "nodes": [{"id": "n", "type": "basic.number", "params": {"value": 1}}], "wires": [],
            "interface": {"inputs": [], "outputs": [{"name": "y", "type": "Number", "from": "n.value"}]}}
    (folder / f"f{depth}.flowmc.json").write_text(json.dumps(leaf))
    for k in range(depth - 1, -1, -1):
        doc = {"schema_version": 1, "wires": [],
               "nodes": [{"id": "a", "type": "subgraph", "params": {"file": f"f{k + 1}.flowmc.json"}}],
               "interface": {"inputs": [], "outputs": [{"name": "y", "type": "Number", "from": "a.y"}]}}
        (folder / f"f{k}.flowmc.json").write_text(json.dumps(doc))
    return str(folder / "f0.flowmc.json")


def _fifo(folder: Path, name: str) -> Path:
    os.mkfifo(folder / name)
    return folder / name


def _with_bom(folder: Path) -> str:
    path = Path(_graph(folder, [{"id": "n", "type": "basic.number", "params": {"value": 1}}]))
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    return str(path)


def _nurbs(folder: Path, points: list, feed: float = 600.0, node: str = "interp.dda") -> str:
    """A NURBS into an interpolator (cases the fuzz test found)."""
    return _graph(folder, [{"id": "n", "type": "path.nurbs", "params": {"control_points": points, "feed": feed}},
                           {"id": "m", "type": "machine"}, {"id": "i", "type": node}],
                  [("n.path", "i.path"), ("m.machine", "i.machine")])


CUSP = [[0, 0, 0], [10, 20, 0], [-30, 20, 0], [40, 0, 0]]
LONG = [[0, 0, 0], [10, 20, 0], [30, 20, 0], [508669.7, 0, 0]]
XY = str(REPO / "graphs" / "xy_plotter.flowmc.json")
SURROGATE = '{"schema_version": 1, "nodes": [{"id": "n", "type": "basic.number", "title": "\\ud800"}], "wires": []}'

# name: (argv built in a fresh folder, exit code, text the last line must hold)
CASES = {
    "JSON nested 1,000 deep": (lambda d: ["validate", _graph(d, None, raw="[" * 1000 + "]" * 1000)], 2, "nested deeper"),
    "a list param nested 900 deep": (lambda d: ["run", _graph(
        d, [{"id": "n", "type": "basic.number", "params": {"value": _nested_list(900)}}])], 2, "nested deeper"),
    "a 200-deep sub-graph chain": (lambda d: ["run", _chain(d, 200)], 2, "FLOWMC_BUDGET_DEPTH"),
    "a NUL byte in file": (lambda d: ["run", _graph(
        d, [{"id": "gc", "type": "path.gcode_in", "params": {"file": "a\0.ngc"}}])], 1, "node 'gc'"),
    "a lone surrogate in a param": (lambda d: ["run", _graph(d, None, raw=SURROGATE)], 2, "lone surrogate"),
    "--input picture_width_mm=1e308": (lambda d: ["run", XY, "--input", "picture_width_mm=1e308"], 1, "node 'picture'"),
    "--input picture_width_mm=1e400": (lambda d: ["run", XY, "--input", "picture_width_mm=1e400"], 2, "not a finite"),
    "a line to 1e300": (lambda d: ["run", _graph(d, [{"id": "t", "type": "path.segment_table", "params": {
        "rows": [{"type": "line", "end": [1e300, 0, 0]}]}}])], 1, "within +-1e+09 mm"),
    "an arc angle of 1e300": (lambda d: ["run", _graph(d, [{"id": "t", "type": "path.segment_table", "params": {
        "rows": [{"type": "arc", "direction": "ccw", "radius": 10.0, "start_angle": 0.0, "end_angle": 1e300}]}}])],
        1, "budget"),
    "duplicate axis names, at validate": (lambda d: ["validate", _graph(
        d, [{"id": "m", "type": "machine", "params": {"axes": [{"name": "X"}, {"name": "X"}]}}])], 2, "unique"),
    "X1 followed by 300 zeros": (lambda d: ["run", _gcode(d, "G1 X1" + "0" * 300 + " F600\n")], 1, "p.ngc:1"),
    "a FIFO named *.flowmc.json": (lambda d: ["validate", str(_fifo(d, "x.flowmc.json"))], 2, "pipe or device"),
    "a FIFO named *.ngc": (lambda d: ["run", (_fifo(d, "p.ngc"), _graph(
        d, [{"id": "gc", "type": "path.gcode_in", "params": {"file": "p.ngc"}}]))[1]], 1, "pipe or device"),
    "terminal escapes in a G-code line": (lambda d: ["run", _gcode(d, "G1 X1 F600\nG1 \x1b[2J\x1b]0;x\x07 Q5\n")],
                                          1, "p.ngc:2"),
    "a NURBS with a cusp, time division": (lambda d: ["run", _nurbs(d, CUSP, node="interp.time_division")], 0, ""),
    "a 508 km NURBS into DDA": (lambda d: ["run", _nurbs(d, LONG)], 1, "steps, over the budget"),
    "a NURBS at feed 5e-324": (lambda d: ["run", _nurbs(d, CUSP, 5e-324, "interp.time_division")], 1,
                               "unboundedly many setpoints"),
    "a tool radius of 1e184": (lambda d: ["run", _graph(d, [
        {"id": "a", "type": "path.polyline", "params": {"points": [[0, 0, 0], [10, 0, 0], [10, 10, 0]]}},
        {"id": "o", "type": "path.tool_offset", "params": {"radius": 1e184}}], [("a.path", "o.path")])], 1, "node 'o'"),
    "terminal escapes in a param, at validate": (lambda d: ["validate", _graph(d, [{"id": "t", "type": "path.segment_table",
        "params": {"rows": [{"type": "\x1b[2J\x1b]0;t\x07", "end": [1, 0, 0]}]}}])], 2, "\\x1b[2J"),
    "offsetting a piece too short for its size": (lambda d: ["run", _graph(d, [
        {"id": "a", "type": "path.polyline", "params": {"points": [[0, 0, 0], [1e-9, 0, 0], [10, 10, 0]], "closed": True}},
        {"id": "r", "type": "path.rotate", "params": {"degrees": 30.0}},
        {"id": "s", "type": "path.scale", "params": {"factor": 2.0}},
        {"id": "o", "type": "path.tool_offset", "params": {"radius": 36000000.0}}],
        [("a.path", "r.path"), ("r.path", "s.path"), ("s.path", "o.path")])], 1, "node 'o'"),
    "a canned cycle repeated 36,000,000 times": (lambda d: ["run", _gcode(
        d, "G20 G90\nG81 X1 Y1 Z-0.1 R0.1 F10 L36000000\nG80\n")], 1, "p.ngc:2"),
    "a graph file with a UTF-8 BOM": (lambda d: ["run", _with_bom(d)], 0, ""),
}


@pytest.mark.parametrize("name", list(CASES))
def test_bad_input_is_one_clean_line_with_the_right_exit_code(name, tmp_path, capsys, monkeypatch):
    build, code, needle = CASES[name]
    monkeypatch.chdir(tmp_path)
    argv = build(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a RuntimeWarning (overflow, inf) is a failure too
        got = main(argv)
    err = capsys.readouterr().err
    assert got == code, err
    assert "internal error" not in err and "Traceback" not in err
    assert "\x1b" not in err and "\x07" not in err and "\0" not in err  # control characters shown escaped
    last = err.strip().splitlines()[-1] if err.strip() else ""
    assert needle in last, last
    assert len(last) < 2000


def test_one_bad_file_in_lib_does_not_break_the_node_listing(tmp_path, capsys, monkeypatch):
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "bad.flowmc.json").write_text("{ nope")
    (tmp_path / "lib" / "deep.flowmc.json").write_text("[" * 1000 + "]" * 1000)
    monkeypatch.chdir(tmp_path)
    assert main(["nodes"]) == 0
    out = capsys.readouterr().out
    assert "basic.add" in out and "lib.bad" in out and "lib.deep" in out
