"""The flowmc command, run as a real subprocess: exit codes, messages (never tracebacks), outputs."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import flowmc
from core_helpers import run_cli


def _graph(folder, max_value=100.0):
    g = flowmc.GraphBuilder(title="cli")
    a = g.add("basic.number", id="a", value=2)
    s = g.add("basic.add", id="s", b=3)
    c = g.add("basic.check", id="chk", min=0, max=max_value, label="sum")
    r = g.add("basic.report", id="rep", names=["sum"])
    g.wire(a.value, s.a)
    g.wire(s.result, c.value)
    g.wire(c.value, r.sum)
    g.input("offset", "Number", s.b)
    g.output("sum", "Number", c.value)
    g.output("table", "Table", r.table)
    return g.save(folder / "cli.flowmc.json").path


def _no_traceback(proc):
    assert "Traceback" not in proc.stderr and "Traceback" not in proc.stdout


def test_run_success_writes_results_and_progress(tmp_path):
    path = _graph(tmp_path)
    out = tmp_path / "results.json"
    proc = run_cli("run", str(path), "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "sum = 5.0" in proc.stdout
    assert "[4/4] rep" in proc.stderr and "chk: sum = 5 within [0, 100]" in proc.stderr
    results = json.loads(out.read_text())
    assert results["ok"] is True and results["outputs"]["sum"] == 5.0
    assert results["outputs"]["table"]["data"] == [{"name": "sum", "value": 5.0}]
    assert results["nodes"]["s"]["status"] == "done" and results["nodes"]["s"]["outputs"] == {"result": 5.0}
    assert list(results["nodes"]) == ["a", "s", "chk", "rep"]


def test_set_and_input_change_the_run(tmp_path):
    path = _graph(tmp_path)
    proc = run_cli("run", str(path), "-q", "--set", "a.value=10", "--input", "offset=0.5")
    assert proc.returncode == 0 and "sum = 10.5" in proc.stdout and proc.stderr == ""


def test_failed_run_exits_1_with_the_node_message(tmp_path):
    proc = run_cli("run", str(_graph(tmp_path, max_value=4)))
    assert proc.returncode == 1
    assert "error: node 'chk': check failed: sum = 5 is outside [0, 4]" in proc.stderr
    assert "skipped: upstream node 'chk' failed" in proc.stderr
    _no_traceback(proc)


def test_invalid_graph_exits_2_listing_every_problem(tmp_path):
    path = _graph(tmp_path)
    data = json.loads(path.read_text())
    nodes = {n["id"]: n for n in data["nodes"]}
    nodes["a"]["type"] = "basic.nope"
    nodes["chk"]["params"]["feed"] = 1
    path.write_text(json.dumps(data))
    for command in ("run", "validate"):
        proc = run_cli(command, str(path))
        assert proc.returncode == 2
        lines = proc.stderr.strip().splitlines()
        assert lines[0] == f"{path}: graph is invalid (2 problems):"
        assert "node 'a': unknown node type 'basic.nope'" in lines[1]
        assert "node 'chk': unknown param 'feed'" in lines[2]
        _no_traceback(proc)


def test_bad_set_targets_exit_2(tmp_path):
    path = _graph(tmp_path)
    cases = {
        "zz.value=1": "--set zz.value: no node 'zz' (nodes: a, chk, rep, s)",
        "a.colour=1": "--set a.colour: node 'a' (basic.number) has no param 'colour' (params: value)",
        "a.value=abc": "--set a.value: 'abc' is not a number",
        "novalue": "--set 'novalue': expected NAME=VALUE",
    }
    for arg, message in cases.items():
        proc = run_cli("run", str(path), "--set", arg)
        assert proc.returncode == 2 and message in proc.stderr, (arg, proc.stderr)
        _no_traceback(proc)
    proc = run_cli("run", str(path), "--input", "speed=3")
    assert proc.returncode == 2 and "the graph has no input 'speed' (inputs: offset)" in proc.stderr
    proc = run_cli("run", str(path), "--set", "chk.max=-1", "--set", "chk.min=oops")
    assert proc.returncode == 2 and "'oops' is not a number" in proc.stderr


def test_bad_files_exit_2_with_location(tmp_path):
    broken = tmp_path / "broken.flowmc.json"
    broken.write_text('{"schema_version": 1,\n "nodes": [}')
    proc = run_cli("validate", str(broken))
    assert proc.returncode == 2 and f"{broken}:2:" in proc.stderr and "line 2, column" in proc.stderr
    proc = run_cli("run", str(tmp_path / "missing.flowmc.json"))
    assert proc.returncode == 2 and "missing.flowmc.json: no such graph file" in proc.stderr
    unknown = tmp_path / "unknown.flowmc.json"
    unknown.write_text('{"schema_version": 1, "nodes": [{"id": "a", "type": "basic.number", "size": 3}]}')
    proc = run_cli("validate", str(unknown))
    assert proc.returncode == 2 and "$.nodes[0].size (node 'a'): unknown field 'size'" in proc.stderr
    _no_traceback(proc)


def test_validate_ok_shows_order(tmp_path):
    proc = run_cli("validate", str(_graph(tmp_path)))
    assert proc.returncode == 0 and "ok, 4 nodes; order: a, s, chk, rep" in proc.stdout


def test_schema_and_nodes(tmp_path):
    proc = run_cli("schema")
    assert proc.returncode == 0
    schema = json.loads(proc.stdout)
    assert schema == flowmc.graph.json_schema()
    proc = run_cli("nodes")
    assert proc.returncode == 0
    assert "basic.check  [Basic] Check  (not cached)" in proc.stdout
    assert "    in    value: Number  (Number to check)" in proc.stdout
    proc = run_cli("nodes", "--json")
    ids = [d["type_id"] for d in json.loads(proc.stdout)]
    assert {"basic.add", "basic.report", "subgraph"} <= set(ids)


def test_delegated_commands_fail_cleanly_when_missing(tmp_path):
    proc = run_cli("compare", str(tmp_path / "g.flowmc.json"), "--with", "nothing")
    assert proc.returncode == 2 and "invalid choice" in proc.stderr
    _no_traceback(proc)


def test_unwritable_results_file_is_one_line(tmp_path):
    proc = run_cli("run", str(_graph(tmp_path)), "-q", "--out", str(tmp_path / "no" / "such" / "dir.json"))
    assert proc.returncode == 1
    assert proc.stderr.startswith("error: ") and len(proc.stderr.strip().splitlines()) == 1
    _no_traceback(proc)


def test_every_help_text_speaks_to_users_not_about_the_code():
    """Every command and option explains itself, with no code in the words (``args.with_``, module paths)."""
    import argparse
    import re

    from flowmc.cli import build_parser

    parser = build_parser()
    subparsers = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    code = re.compile(r"args\.|getattr|importlib|\bwith_\b|\b[a-z_]+\(|flowmc\.[a-z_]+\.[a-z_]+|__\w+__")
    problems = []
    for name, sub in [("flowmc", parser), *subparsers.choices.items()]:
        text = sub.format_help()
        problems += [f"{name}: {m.group()!r}" for m in code.finditer(text)]
        for action in sub._actions:
            if not isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)) and not action.help:
                problems.append(f"{name}: {'/'.join(action.option_strings) or action.dest} has no help")
    assert subparsers.choices.keys() >= {"run", "validate", "nodes", "schema", "serve", "compare"}
    assert problems == []


def test_a_command_builds_only_its_own_arguments_and_helps_alike():
    """``flowmc validate`` builds validate's arguments, not run's or sweep's (a cold start pays for each
    ``add_argument``); every command's help, and the list of commands, read as with the whole parser."""
    import argparse

    from flowmc.cli import build_parser

    def commands(parser):
        return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices

    whole = build_parser()
    for name, sub in commands(whole).items():
        only = build_parser(name)
        assert only.format_help() == whole.format_help()
        assert commands(only)[name].format_help() == sub.format_help()
        others = {n: len(p._actions) for n, p in commands(only).items() if n != name}
        assert others == dict.fromkeys(others, 1)  # -h alone


def test_the_command_loads_pydantic_plugins_only_when_asked(tmp_path):
    """A cold ``flowmc`` skips pydantic's scan of every installed distribution for plugins; setting
    PYDANTIC_DISABLE_PLUGINS (empty: none disabled) brings them back."""
    from core_helpers import REPO

    (tmp_path / "spyplugin.py").write_text(
        "import sys\n"
        "class Spy:\n"
        "    def new_schema_validator(self, *args, **kwargs):\n"
        "        print('pydantic plugin called', file=sys.stderr)\n"
        "        return None, None, None\n"
        "plugin = Spy()\n")
    info = tmp_path / "spyplugin-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: spyplugin\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[pydantic]\nspy = spyplugin:plugin\n")
    graph = REPO / "graphs" / "thesis_3axis.flowmc.json"
    env = {k: v for k, v in os.environ.items() if k != "PYDANTIC_DISABLE_PLUGINS"}
    env["PYTHONPATH"] = str(tmp_path)
    runs = {}
    for setting in (None, ""):
        if setting is not None:
            env["PYDANTIC_DISABLE_PLUGINS"] = setting
        proc = subprocess.run([sys.executable, "-m", "flowmc", "validate", str(graph)], env=env, cwd=tmp_path,
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stderr
        runs[setting] = "pydantic plugin called" in proc.stderr
    assert runs == {None: False, "": True}
