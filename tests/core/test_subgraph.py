"""Sub-graphs as nodes: file and library types, caching, recursion and path escapes refused."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import flowmc
from flowmc.errors import GraphError


def _double(path, factor=2.0):
    g = flowmc.GraphBuilder(title="Double", description="Multiply by a factor\nsecond line")
    m = g.add("basic.multiply", id="m", b=factor)
    g.input("x", "Number", m.a, description="value")
    g.output("y", "Number", m.result, description="factor * value")
    return g.save(path)


def _user(folder, node_type="subgraph", **params):
    g = flowmc.GraphBuilder(title="user")
    n = g.add("basic.number", id="n", value=4)
    s = g.add(node_type, id="s", **params)
    g.wire(n.value, s.x)
    g.output("out", "Number", s.y)
    return g.save(folder / "user.flowmc.json")


def test_graph_with_interface_is_a_node(registry, tmp_path):
    (tmp_path / "parts").mkdir()
    _double(tmp_path / "parts" / "double.flowmc.json")
    graph = _user(tmp_path, file="parts/double.flowmc.json")
    rt = flowmc.Runtime(registry)
    plan = rt.plan(flowmc.load(tmp_path / "user.flowmc.json"))
    assert plan.ok and set(plan.ports("s")[0]) == {"x"} and set(plan.ports("s")[1]) == {"y"}
    result = rt.run(graph)
    assert result.ok and result.outputs == {"out": 8.0}
    assert [n for n in rt.run(graph).executed] == []  # all cached, inner graph included


def test_editing_the_sub_graph_file_invalidates_the_cache(registry, tmp_path):
    inner = tmp_path / "double.flowmc.json"
    _double(inner)
    graph = _user(tmp_path, file="double.flowmc.json")
    rt = flowmc.Runtime(registry)
    assert rt.run(graph).outputs == {"out": 8.0}
    _double(inner, factor=3.0)
    os.utime(inner, ns=(1, 1))  # a different mtime even on coarse clocks
    result = rt.run(graph)
    assert result.outputs == {"out": 12.0} and result.executed == ["s"]


def test_sub_graph_failure_is_the_node_failure(registry, tmp_path):
    g = flowmc.GraphBuilder()
    c = g.add("basic.check", id="c", max=1, label="x")
    g.input("x", "Number", c.value)
    g.output("y", "Number", c.value)
    g.save(tmp_path / "guard.flowmc.json")
    result = flowmc.run(_user(tmp_path, file="guard.flowmc.json"), registry=registry)
    assert result.errors == ["node 's': sub-graph guard.flowmc.json: node 'c': check failed: x = 4 is outside [-, 1]"]


def test_library_graphs_are_types(registry, tmp_path):
    (tmp_path / "lib").mkdir()
    _double(tmp_path / "lib" / "twice.flowmc.json")
    graph = _user(tmp_path, node_type="lib.twice")
    assert flowmc.run(graph, registry=registry).outputs == {"out": 8.0}
    described = {d["type_id"]: d for d in registry.describe_all(tmp_path)}
    twice = described["lib.twice"]
    assert twice["title"] == "Double" and twice["description"] == "Multiply by a factor"
    # A scalar interface input is a param of the library node (stored, or fed by a wire).
    assert twice["inputs"] == [] and [p["name"] for p in twice["param_inputs"]] == ["x"]
    assert twice["outputs"][0]["doc"] == "factor * value"
    assert "lib.twice" not in {d["type_id"] for d in registry.describe_all(tmp_path / "elsewhere")}


def test_library_node_takes_a_scalar_input_as_a_stored_param(registry, tmp_path):
    (tmp_path / "lib").mkdir()
    _double(tmp_path / "lib" / "twice.flowmc.json", factor=3.0)
    g = flowmc.GraphBuilder()
    s = g.add("lib.twice", id="s", x=5.0)
    g.output("out", "Number", s.y)
    g.save(tmp_path / "stored.flowmc.json")
    assert flowmc.run(flowmc.load(tmp_path / "stored.flowmc.json"), registry=registry).outputs == {"out": 15.0}
    bad = flowmc.GraphBuilder()
    bad.add("lib.twice", id="s", x="five")
    bad.save(tmp_path / "bad.flowmc.json")
    issues = flowmc.validate(flowmc.load(tmp_path / "bad.flowmc.json"), registry=registry)
    assert [(i.code, i.location) for i in issues] == [("invalid-param", ("nodes", "s", "params", "x"))]


def test_interface_input_without_default_is_required_only_when_it_feeds_a_required_input(registry, tmp_path):
    g = flowmc.GraphBuilder()
    k = g.add("test.sink", id="k")
    g.input("path", "Path", k.path)
    g.output("n", "Number", k.n)
    g.save(tmp_path / "needs.flowmc.json")
    user = flowmc.GraphBuilder()
    user.add("subgraph", id="s", file="needs.flowmc.json")
    user.add("subgraph", id="t", file="user_opt.flowmc.json")
    _double(tmp_path / "user_opt.flowmc.json")
    graph = user.build()
    issues = flowmc.validate(graph, base_dir=tmp_path, registry=registry)
    assert [(i.code, i.location) for i in issues] == [("missing-input", ("nodes", "s", "inputs", "path"))]


def test_recursion_is_refused_naming_the_chain(registry, tmp_path):
    for name, other in (("a", "b"), ("b", "a")):
        g = flowmc.GraphBuilder()
        x = g.add("subgraph", id=f"use_{other}", file=f"{other}.flowmc.json")
        g.input("x", "Number", x.x)
        g.output("y", "Number", x.y)
        g.save(tmp_path / f"{name}.flowmc.json")
    issues = flowmc.validate(tmp_path / "a.flowmc.json", registry=registry)
    assert [i.code for i in issues] == ["subgraph-recursion"]
    assert issues[0].message.endswith("sub-graph recursion: a.flowmc.json -> b.flowmc.json -> a.flowmc.json")
    assert issues[0].message.startswith("node 'use_b'")


def test_direct_self_use_is_refused(registry, tmp_path):
    g = flowmc.GraphBuilder()
    x = g.add("subgraph", id="me", file="self.flowmc.json")
    g.output("y", "Number", x.y)
    g.save(tmp_path / "self.flowmc.json")
    issues = flowmc.validate(tmp_path / "self.flowmc.json", registry=registry)
    assert [i.message for i in issues] == ["node 'me': sub-graph recursion: self.flowmc.json -> self.flowmc.json"]


@pytest.mark.parametrize("file", ["../../etc/passwd", "/etc/passwd", "../outside.flowmc.json", "link/outside.flowmc.json"])
def test_files_outside_the_graph_folder_are_refused(registry, tmp_path, file):
    root = tmp_path / "project"
    root.mkdir()
    _double(tmp_path / "outside.flowmc.json")
    os.symlink(tmp_path, root / "link")
    g = flowmc.GraphBuilder()
    g.add("subgraph", id="s", file=file)
    g.save(root / "g.flowmc.json")
    issues = flowmc.validate(root / "g.flowmc.json", registry=registry)
    assert [(i.code, i.location) for i in issues] == [("path-escape", ("nodes", "s", "params", "file"))]
    assert "node 's'" in issues[0].message


def test_sub_graph_folder_may_not_climb_out_either(registry, tmp_path):
    root = tmp_path / "project"
    (root / "sub").mkdir(parents=True)
    _double(tmp_path / "secret.flowmc.json")
    g = flowmc.GraphBuilder()
    x = g.add("subgraph", id="inner", file="../../secret.flowmc.json")  # from sub/: leaves project/
    g.input("x", "Number", x.x)
    g.output("y", "Number", x.y)
    g.save(root / "sub" / "mid.flowmc.json")
    outer = flowmc.GraphBuilder()
    outer.add("subgraph", id="s", file="sub/mid.flowmc.json")
    outer.save(root / "top.flowmc.json")
    issues = flowmc.validate(root / "top.flowmc.json", registry=registry)
    assert len(issues) == 1 and "node 's': sub-graph sub/mid.flowmc.json: node 'inner': file" in issues[0].message


def test_node_context_resolve_stays_inside(registry, tmp_path):
    (tmp_path / "data.txt").write_text("hello")
    g = flowmc.GraphBuilder()
    g.add("test.read", id="ok")
    g.add("test.read", id="bad", file="../etc/hosts")
    g.save(tmp_path / "r.flowmc.json")
    result = flowmc.run(tmp_path / "r.flowmc.json", registry=registry)
    assert result.output("ok", "text") == "hello"
    assert result.errors == [f"node 'bad': '../etc/hosts' leaves the graph's folder {tmp_path.resolve()}"]


@pytest.mark.parametrize("file", ["a\x00b.ngc", "\x1b[2J.ngc", "x" * 5000 + ".ngc"], ids=["nul", "escape", "long"])
def test_unusable_file_names_are_clean_errors(registry, tmp_path, file):
    g = flowmc.GraphBuilder()
    g.add("test.read", id="bad", file=file)
    g.save(tmp_path / "r.flowmc.json")
    result = flowmc.run(tmp_path / "r.flowmc.json", registry=registry)
    assert len(result.errors) == 1 and result.errors[0].startswith("node 'bad': '")
    assert "\x00" not in result.errors[0] and "\x1b" not in result.errors[0] and len(result.errors[0]) < 300


def test_missing_or_interface_less_sub_graph(registry, tmp_path):
    flowmc.GraphBuilder().save(tmp_path / "plain.flowmc.json")
    g = flowmc.GraphBuilder()
    g.add("subgraph", id="gone", file="gone.flowmc.json")
    g.add("subgraph", id="plain", file="plain.flowmc.json")
    messages = sorted(i.message for i in flowmc.validate(g.build(), base_dir=tmp_path, registry=registry))
    assert messages == ["node 'gone': sub-graph gone.flowmc.json: no such graph file",
                        "node 'plain': sub-graph plain.flowmc.json declares no interface, so it cannot be used as a node"]


def test_run_rejects_invalid_graph_with_issues(registry, tmp_path):
    g = flowmc.GraphBuilder()
    g.add("subgraph", id="gone", file="gone.flowmc.json")
    with pytest.raises(GraphError) as info:
        flowmc.run(g.build(), base_dir=tmp_path, registry=registry)
    assert info.value.issues[0].code == "subgraph"


def test_library_graphs_using_each_other_are_refused(registry, tmp_path):
    (tmp_path / "lib").mkdir()
    for name, other in (("ping", "pong"), ("pong", "ping")):
        g = flowmc.GraphBuilder()
        x = g.add(f"lib.{other}", id=f"use_{other}")
        g.input("x", "Number", x.x)
        g.output("y", "Number", x.y)
        g.save(tmp_path / "lib" / f"{name}.flowmc.json")
    g = flowmc.GraphBuilder()
    g.add("lib.ping", id="top")
    issues = flowmc.validate(g.build(), base_dir=tmp_path, registry=registry)
    assert [i.code for i in issues] == ["subgraph-recursion"]
    assert issues[0].message.endswith("ping.flowmc.json -> pong.flowmc.json -> ping.flowmc.json")


def _quad(lib: Path) -> None:
    """``lib.double`` and ``lib.quad``, a library graph made of two of it (its sibling)."""
    lib.mkdir()
    _double(lib / "double.flowmc.json")
    g = flowmc.GraphBuilder(title="Quad")
    x = g.add("lib.double", id="first")
    y = g.add("lib.double", id="second")
    g.wire(x.y, y.x)
    g.input("x", "Number", x.x)
    g.output("y", "Number", y.y)
    g.save(lib / "quad.flowmc.json")


def test_library_graph_uses_its_siblings(registry, tmp_path):
    _quad(tmp_path / "lib")
    assert flowmc.run(_user(tmp_path, node_type="lib.quad"), registry=registry).outputs == {"out": 16.0}


def test_a_library_graph_is_read_and_planned_once_per_validation(registry, tmp_path, monkeypatch):
    """Building the lib type binds its file, and the node using it binds from that (a cold `flowmc validate`
    read each library graph three times and planned it twice)."""
    import flowmc.nodes.subgraph as subgraph

    reads: list[str] = []
    read = subgraph._read
    monkeypatch.setattr(subgraph, "_read", lambda path: reads.append(path.name) or read(path))
    (tmp_path / "lib").mkdir()
    _double(tmp_path / "lib" / "twice.flowmc.json")
    assert flowmc.validate(_user(tmp_path, node_type="lib.twice"), registry=registry) == []
    assert reads == ["twice.flowmc.json"]


def test_a_library_type_follows_the_library_graphs_it_uses(registry, tmp_path):
    _quad(tmp_path / "lib")
    user = _user(tmp_path, node_type="lib.quad")
    assert flowmc.run(user, registry=registry).outputs == {"out": 16.0}
    _double(tmp_path / "lib" / "double.flowmc.json", factor=3.0)  # quad's own file is unchanged
    assert flowmc.run(user, registry=registry).outputs == {"out": 36.0}
