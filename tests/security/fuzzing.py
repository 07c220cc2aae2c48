"""Seeded fuzzing of what flowmc reads from outside: graph files, G-code programs (issue 18).

Mutations start from small, valid seeds (graphs of every kind of path source, planners, interpolators,
sub-graphs and pictures; G-code programs using most of the language) and change values, structure and
bytes: hostile numbers (1e308, -0, NaN spelled out), hostile text (markup, control characters, lone
surrogates, ``../`` paths, long names), deep nesting, deleted and duplicated keys, truncation, flipped
bytes. Each case runs through ``flowmc.cli.main`` exactly as ``flowmc run`` would, with warnings as
errors; it is *clean* when it exits 0, 1 or 2 with at most one-line messages and no traceback, no
``internal error`` and no Python exception name in a node's message.

Shared by tests/security/test_fuzz.py (a few hundred cases, in-process) and benchmarks/security.py
(10,000 of each, in child processes whose peak RSS is measured).
"""

from __future__ import annotations

import contextlib
import copy
import io
import json
import random
import re
import shutil
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

GRAPH = "fuzz.flowmc.json"
PROGRAM = "fuzz.ngc"
_BUG = re.compile(r"\b[A-Z][A-Za-z]*(Error|Exception|Warning)\b(?!\))|Traceback|internal error")

# ---------------------------------------------------------------------------------------- seeds

_TABLE = [{"type": "line", "end": [40.0, 0.0, 0.0]},
          {"type": "arc", "direction": "ccw", "radius": 10.0, "start_angle": -90.0, "end_angle": 90.0},
          {"type": "line", "end": [0.0, 20.0, 0.0], "feed": 300.0},
          {"type": "dwell", "seconds": 0.1}]


def _doc(nodes: list[dict], wires: list[tuple[str, str]], interface: dict | None = None) -> dict:
    doc: dict[str, Any] = {"schema_version": 1, "title": "fuzz", "nodes": nodes,
                           "wires": [{"from": a, "to": b} for a, b in wires]}
    if interface is not None:
        doc["interface"] = interface
    return doc


def graph_seeds() -> list[dict]:
    """Small graphs that run in milliseconds, together using most node kinds (no device that moves)."""
    machine = {"id": "m", "type": "machine", "params": {"axes": [
        {"name": "X", "min": -200.0, "max": 200.0}, {"name": "Y", "min": -200.0, "max": 200.0},
        {"name": "Z", "min": -50.0, "max": 50.0}], "period": 0.004}}
    return [
        _doc([{"id": "t", "type": "path.segment_table", "params": {"rows": _TABLE, "feed": 600.0}}, machine,
              {"id": "p", "type": "plan.lookahead", "params": {"tolerance": 0.05}},
              {"id": "k", "type": "plan.metrics"}],
             [("t.path", "p.path"), ("m.machine", "p.machine"), ("p.trajectory", "k.trajectory"),
              ("t.path", "k.path"), ("m.machine", "k.machine")]),
        _doc([{"id": "gc", "type": "path.gcode_in", "params": {"file": PROGRAM}}, machine,
              {"id": "s", "type": "plan.stop_and_go"}],
             [("gc.path", "s.path"), ("m.machine", "s.machine")]),
        _doc([{"id": "a", "type": "path.polyline", "params": {"points": [[0, 0, 0], [10, 0, 0], [10, 10, 0]],
                                                               "feed": 300.0, "closed": True}},
              {"id": "r", "type": "path.rotate", "params": {"degrees": 30.0}},
              {"id": "s", "type": "path.scale", "params": {"factor": 2.0}},
              {"id": "o", "type": "path.tool_offset", "params": {"side": "left", "radius": 1.0}},
              {"id": "j", "type": "path.join", "params": {"rapid_feed": 1000.0}},
              {"id": "me", "type": "path.measure"}],
             [("a.path", "r.path"), ("r.path", "s.path"), ("s.path", "o.path"), ("o.path", "j.path1"),
              ("a.path", "j.path2"), ("j.path", "me.path")]),
        _doc([{"id": "n", "type": "path.nurbs", "params": {
                  "control_points": [[0, 0, 0], [10, 20, 0], [30, 20, 0], [40, 0, 0]], "degree": 3, "feed": 600.0}},
              machine, {"id": "i", "type": "interp.time_division", "params": {"profile": "trapezoid"}},
              {"id": "d", "type": "interp.dda", "params": {"chord_tol": 0.01}}],
             [("n.path", "i.path"), ("m.machine", "i.machine"), ("n.path", "d.path"), ("m.machine", "d.machine")]),
        _doc([{"id": "x", "type": "basic.number", "params": {"value": 2.0}},
              {"id": "sub", "type": "subgraph", "params": {"file": "inner.flowmc.json"}},
              {"id": "q", "type": "basic.divide"}, {"id": "rep", "type": "basic.report", "params": {"names": ["q"]}}],
             [("x.value", "sub.a"), ("sub.y", "q.a"), ("x.value", "q.b"), ("q.result", "rep.value")]),
        _doc([{"id": "img", "type": "path.image_contour", "params": {"file": "fuzz.png", "mm_per_pixel": 0.5}},
              {"id": "me", "type": "path.measure"}], [("img.path", "me.path")]),
    ]


INNER = _doc([{"id": "s", "type": "basic.add", "params": {"b": 1.0}}], [],
             {"inputs": [{"name": "a", "type": "Number", "to": ["s.a"]}],
              "outputs": [{"name": "y", "type": "Number", "from": "s.result"}]})

GCODE_SEEDS = [
    "%\n(a frame and a circle)\nG21 G90 G17\nG0 X0 Y0 Z5\nG1 Z-1 F300\nG1 X40 F600\nG1 Y20\nG2 X40 Y40 I0 J10\n"
    "G3 X20 Y40 R10\nG1 X0 Y0\nG4 P0.5\nG0 Z5\nM2\n%\n",
    "G21 G91\n#1 = 5\n#<step> = [#1 * 2]\nG1 X#<step> Y[SIN[30] * 10] F[600 + #1]\nG1 X-#1\nG90\n"
    "o100 if [#1 GT 2]\n  G1 X10\no100 else\n  G1 X20\no100 endif\n"
    "o101 repeat [3]\n  G1 Y[#1]\no101 endrepeat\nM2\n",
    "G20 G90 G54\nG10 L2 P1 X1 Y1\nG0 X0 Y0\nG1 X1 Y1 F20\nG18 G2 X2 Z0 I0.5 K0\nG17\nG81 X1 Y1 Z-0.1 R0.1 F10\n"
    "G80\nS1000 M3\nG1 X0 Y0\nM5\nM30\n",
]

_NUMBERS = ["0", "-0", "1e308", "-1e308", "1e-320", "0.0008", "nan", "inf", "1" + "0" * 300, "-1", "36000000",
            "100000", "9999999999", "3.5", "[1/0]", "[SQRT[-1]]", "#5000", "#<nope>", "[ATAN[1]/[0]]", "1.e", "--1"]
_TEXTS = ["", " ", "../../etc/passwd", "/etc/passwd", "a" * 300, "<img src=x onerror=alert(1)>",
          "![x](/etc/passwd)", "\x1b[2J\x1b]0;t\x07", "\0", "\ud800", "%s%n{0}", "fuzz.flowmc.json", "inner.flowmc.json",
          "fuzz.ngc", "fuzz.png", "lib/x.flowmc.json", "C:\\x", "\u202etxt.ngc"]
_WORDS = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"


def _random_value(rng: random.Random, depth: int = 0) -> Any:
    kind = rng.randrange(10)
    if kind == 0:
        return rng.choice([0, -1, 1, 2**31, 2**63, -(2**63), 10**30])
    if kind == 1:
        return rng.choice([0.0, -0.0, 1e308, -1e308, 1e-320, 0.0008, 36_000_000.0, 1e300, 5e-324])
    if kind == 2:
        return rng.choice(_TEXTS)
    if kind == 3:
        return rng.choice([True, False, None])
    if kind == 4 and depth < 3:
        return [_random_value(rng, depth + 1) for _ in range(rng.randrange(5))]
    if kind == 5 and depth < 3:
        return {rng.choice(["type", "end", "x", "name", "file", "value", "a"]): _random_value(rng, depth + 1)
                for _ in range(rng.randrange(4))}
    if kind == 6:
        nested: Any = 1
        for _ in range(rng.choice([10, 63, 65, 200])):
            nested = [nested]
        return nested
    if kind == 7:
        return [[rng.uniform(-1e3, 1e3) for _ in range(3)] for _ in range(rng.randrange(1, 6))]
    if kind == 8:
        return rng.uniform(-1e6, 1e6)
    return rng.choice(["line", "arc", "dwell", "ccw", "cw", "trapezoid", "s_curve", "left", "right", "X", "sim"])


def _like(old: Any, rng: random.Random) -> Any:
    """A hostile value of the same type as ``old``: what passes the schema and reaches the node."""
    if isinstance(old, bool):
        return not old
    if isinstance(old, (int, float)):
        return rng.choice([0, -old, old * 10 ** rng.randint(1, 300), old * 10 ** -rng.randint(1, 300), 1e-9,
                           36_000_000.0, 2**31 - 1, -1e308, old + rng.uniform(-1, 1)])
    if isinstance(old, str):
        return rng.choice(_TEXTS + ["trapezoid", "s_curve", "ccw", "cw", "left", "right", "line", "arc"])
    if isinstance(old, list) and old:
        new = copy.deepcopy(old)
        i = rng.randrange(len(new))
        new[i] = _like(new[i], rng) if rng.random() < 0.8 else copy.deepcopy(new[i])
        if len(new) <= 64 and rng.random() < 0.2:  # longer lists, but a case stays a small file
            return new * rng.choice([0, 2, 50])
        return new
    if isinstance(old, dict) and old:
        new = dict(old)
        key = rng.choice(list(new))
        new[key] = _like(new[key], rng)
        return new
    return _random_value(rng)


def _walk(value: Any, path: tuple = ()) -> Iterator[tuple[tuple, Any]]:
    yield path, value
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _walk(v, path + (k,))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _walk(v, path + (i,))


def _parent(doc: Any, path: tuple) -> Any:
    for key in path[:-1]:
        doc = doc[key]
    return doc


def mutate_graph(doc: dict, rng: random.Random) -> str:
    """The text of a mutated copy of ``doc``: one to three structural or value mutations, sometimes then
    a byte-level one on the JSON text."""
    doc = copy.deepcopy(doc)
    for _ in range(rng.randint(1, 3)):
        places = [p for p, _ in _walk(doc) if p]
        if not places:
            break
        in_params = [p for p in places if len(p) > 3 and p[0] == "nodes" and p[2] == "params"]
        value_only = bool(in_params) and rng.random() < 0.75  # mostly values the nodes see, so runs go deep
        path = rng.choice(in_params if value_only else places)
        parent, key = _parent(doc, path), path[-1]
        op = rng.randrange(3) if value_only else rng.randrange(7)
        if op <= 2:
            parent[key] = _like(parent[key], rng) if value_only and rng.random() < 0.7 else _random_value(rng)
        elif op == 3:
            del parent[key]
        elif op == 4 and isinstance(parent, list):
            parent.insert(rng.randrange(len(parent) + 1), copy.deepcopy(parent[key]))  # duplicate (ids too)
        elif op == 5 and isinstance(parent, dict):
            parent[rng.choice(["extra", "type", "id", "params", "from", "to", "pos", "interface"])] = _random_value(rng)
        else:
            nodes = doc.get("nodes") if isinstance(doc, dict) else None
            if isinstance(nodes, list) and nodes and isinstance(nodes[0], dict):
                node = rng.choice([n for n in nodes if isinstance(n, dict)] or [{}])
                node["type"] = rng.choice(["subgraph", "lib.nope", "path.gcode_out", "basic.check", "<b>x</b>",
                                           "path.image_contour", "plan.lookahead", "path.segment_table", ""])
    text = json.dumps(doc, ensure_ascii=rng.random() < 0.5)
    if rng.random() < 0.15:  # bytes: truncation, a flipped character, a stray BOM
        cut = rng.randrange(len(text) + 1)
        text = rng.choice([text[:cut], text[:cut] + rng.choice("{}[],:\"\\x\0") + text[cut + 1:], "\ufeff" + text])
    return text


def mutate_gcode(text: str, rng: random.Random) -> str:
    """A mutated G-code program: words, numbers, lines and characters changed."""
    lines = text.splitlines()
    for _ in range(rng.randint(1, 4)):
        i = rng.randrange(len(lines)) if lines else 0
        op = rng.randrange(8)
        if op <= 2:  # a new or changed word
            word = rng.choice(_WORDS) + rng.choice(_NUMBERS + [str(rng.randint(0, 99)), str(rng.uniform(-500, 500))])
            line = lines[i] if lines else ""
            lines[i:i + 1] = [f"{line} {word}" if rng.random() < 0.5 else f"G1 {word}"]
        elif op == 3 and lines:
            del lines[i]
        elif op == 4 and lines:
            lines.insert(i, lines[i])
        elif op == 5:
            lines.insert(i, rng.choice(["o<x> call", "o200 while [1]", "o200 endwhile", "#1 = [#1 + 1]", "M98 P1",
                                        "G2 X0 Y0 I10 J0 P" + rng.choice(["100000", "3", "-1"]), "(unclosed",
                                        ";" + "x" * 500, "N" + "9" * 30 + " G1 X1", "G33 K1 Z-1", "G76 P1 Z-1",
                                        "G41 D1", "M6 T" + rng.choice(["1", "9999", "-1"]), "G5.2 X0 Y0 L3",
                                        "%", "G64 P" + rng.choice(_NUMBERS), "F" + rng.choice(_NUMBERS)]))
        elif lines:
            line = lines[i]
            cut = rng.randrange(len(line) + 1)
            lines[i] = line[:cut] + rng.choice(["\x1b[31m", "\0", "\ud800", "[", "]", "#", "*", "\u00e9", "\t", "\r"]) \
                + line[cut + 1:]
    return "\n".join(lines) + rng.choice(["\n", ""])


# ---------------------------------------------------------------------------------------- running

@dataclass
class Case:
    kind: str  # "graph" or "gcode"
    index: int
    text: str
    seed: int  # which seed it grew from


def cases(kind: str, count: int, seed: int) -> Iterator[Case]:
    """``count`` mutated graph files or G-code programs, the same for the same ``seed``."""
    rng = random.Random(f"{kind}:{seed}")
    graphs = graph_seeds()
    for index in range(count):
        if kind == "graph":
            pick = rng.randrange(len(graphs))
            yield Case(kind, index, mutate_graph(graphs[pick], rng), pick)
        else:
            pick = rng.randrange(len(GCODE_SEEDS))
            yield Case(kind, index, mutate_gcode(GCODE_SEEDS[pick], rng), pick)


def prepare(folder: Path) -> None:
    """What the seed graphs read, written once into ``folder``: the program, the sub-graph, a picture."""
    from PIL import Image

    folder.mkdir(parents=True, exist_ok=True)
    (folder / PROGRAM).write_text(GCODE_SEEDS[0], encoding="utf-8")
    (folder / "inner.flowmc.json").write_text(json.dumps(INNER), encoding="utf-8")
    pixels = np.full((40, 40), 255, np.uint8)
    pixels[10:30, 8:32] = 0
    Image.fromarray(pixels).save(folder / "fuzz.png")


@dataclass
class Verdict:
    case: Case
    code: int
    seconds: float
    stderr: str
    grew_mb: float = 0.0  # how much the process's peak RSS grew during this case

    @property
    def clean(self) -> bool:
        return self.code in (0, 1, 2) and not _BUG.search(self.stderr) and "\x1b" not in self.stderr


def run_case(case: Case, folder: Path, main: Callable[[list[str]], int]) -> Verdict:
    """Write the case into ``folder`` (with what seeds read) and run it as ``flowmc run`` does."""
    if case.kind == "graph":
        target = folder / GRAPH
        target.write_text(case.text, encoding="utf-8", errors="surrogatepass")
    else:
        (folder / PROGRAM).write_text(case.text, encoding="utf-8", errors="surrogatepass")
        target = folder / "gcode.flowmc.json"
        if not target.exists():
            target.write_text(json.dumps(graph_seeds()[1]), encoding="utf-8")
    err = io.StringIO()
    start = time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            code = main(["run", "-q", str(target)])
        except BaseException as exc:  # noqa: BLE001  anything escaping main is the bug to report
            code, _ = -1, err.write(f"escaped main: {type(exc).__name__}: {exc}\n")
    verdict = Verdict(case, code, time.perf_counter() - start, err.getvalue())
    for leftover in folder.iterdir():  # what a mutated graph wrote (gcode_out) does not feed the next case
        if leftover.name not in (PROGRAM, "inner.flowmc.json", "fuzz.png", GRAPH, "gcode.flowmc.json"):
            if leftover.is_dir() and not leftover.is_symlink():
                shutil.rmtree(leftover, ignore_errors=True)
            else:
                leftover.unlink(missing_ok=True)
    if case.kind == "gcode":
        (folder / PROGRAM).write_text(GCODE_SEEDS[0], encoding="utf-8")
    return verdict


def run_batch(kind: str, start: int, count: int, seed: int, folder: Path) -> list[Verdict]:
    """Cases ``start`` .. ``start + count`` of one kind, in this process."""
    import resource

    from flowmc.cli import main

    prepare(folder)
    out = []
    for case in cases(kind, start + count, seed):
        if case.index >= start:
            before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
            verdict = run_case(case, folder, main)
            verdict.grew_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
            out.append(verdict)
    return out


# ---------------------------------------------------------------------------------------- in a child process

ADDRESS_SPACE = 6 * 1024**3  # a runaway case fails fast in its child, not the machine


@dataclass
class BatchOutcome:
    bad: list[dict]  # the cases that were not clean: kind, index, exit code, last line
    count: int
    exit: int | None  # the child's exit code (None: killed at the time limit)
    peak_mb: float  # the child's peak RSS: an upper bound for every case in it
    seconds: float
    slowest: float


def run_child(kind: str, start: int, count: int, seed: int, folder: Path, timeout: float = 1800.0) -> BatchOutcome:
    """``run_batch`` in a child ``python`` (address space capped, peak RSS from ``os.wait4``)."""
    import os
    import resource
    import subprocess
    import sys
    import tempfile

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))

    begin = time.perf_counter()
    with tempfile.TemporaryFile() as out:
        proc = subprocess.Popen([sys.executable, __file__, kind, str(start), str(count), str(seed), str(folder)],
                                stdout=out, stderr=subprocess.DEVNULL, preexec_fn=limit)
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                code: int | None = os.waitstatus_to_exitcode(status)
                break
            if time.perf_counter() - begin > timeout:
                proc.kill()
                _pid, status, usage = os.wait4(proc.pid, 0)
                code = None
                break
            time.sleep(0.05)
        proc.returncode = -9 if code is None else code
        out.seek(0)
        text = out.read().decode("utf-8", "replace").strip()
    report = json.loads(text.splitlines()[-1]) if text else {"bad": [], "count": 0, "slowest": 0.0}
    return BatchOutcome(report["bad"], report["count"], code, usage.ru_maxrss / 1024,
                        time.perf_counter() - begin, report["slowest"])


def fuzz_table(count: int, seed: int, target_mb: float, batch: int = 500, workers: int = 2) -> bool:
    """Run ``count`` graph and ``count`` G-code mutations in batches over ``workers`` child processes; print
    a table (cases, not clean, killed batches, peak MB of the largest batch, slowest case) and the first
    bad cases. True when every case was clean and no batch reached ``target_mb``."""
    import tempfile
    from concurrent.futures import ThreadPoolExecutor

    ok = True
    print(f"\n{'fuzz':8s} {'cases':>7s} {'unclean':>8s} {'killed':>7s} {'peak MB':>8s} {'ms/case':>8s} "
          f"{'slowest s':>9s} {'wall s':>7s}")
    with tempfile.TemporaryDirectory() as root:
        for kind in ("graph", "gcode"):
            begin = time.perf_counter()
            starts = list(range(0, count, batch))
            with ThreadPoolExecutor(workers) as pool:
                outcomes = list(pool.map(lambda s: run_child(kind, s, min(batch, count - s), seed,
                                                             Path(root) / f"{kind}-{s}"), starts))
            bad = [b for o in outcomes for b in o.bad]
            killed = sum(o.exit != 0 for o in outcomes)
            done = sum(o.count for o in outcomes)
            peak = max(o.peak_mb for o in outcomes)
            busy = sum(o.seconds for o in outcomes)
            ok &= not bad and not killed and done == count and peak < target_mb
            print(f"{kind:8s} {done:7d} {len(bad):8d} {killed:7d} {peak:8.0f} {1000 * busy / max(done, 1):8.1f} "
                  f"{max(o.slowest for o in outcomes):9.2f} {time.perf_counter() - begin:7.1f}")
            for b in bad[:10]:
                print(f"   {b['kind']} #{b['index']} exit {b['code']}: {b['last'][:150]}")
    return ok


def _child_main(argv: list[str]) -> int:
    kind, start, count, seed, folder = argv[0], int(argv[1]), int(argv[2]), int(argv[3]), Path(argv[4])
    verdicts = run_batch(kind, start, count, seed, folder)
    bad = [{"kind": v.case.kind, "index": v.case.index, "code": v.code,
            "last": (v.stderr.strip().splitlines() or [""])[-1][:300]} for v in verdicts if not v.clean]
    grew = max(verdicts, key=lambda v: v.grew_mb, default=None)
    print(json.dumps({"bad": bad, "count": len(verdicts), "slowest": max((v.seconds for v in verdicts), default=0),
                      "grew": [grew.case.index, round(grew.grew_mb, 1)] if grew else None}))
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(_child_main(sys.argv[1:]))
