"""Validation reports every problem at once, each naming its node (and port), before anything runs."""

from __future__ import annotations

import pytest

import flowmc
from flowmc.errors import GraphError


def _everything_wrong():
    g = flowmc.GraphBuilder(title="broken")
    g.add("nope.thing", id="u")
    g.add("test.blob", id="b1", feed=-1)
    g.add("test.blob", id="b2", colour="red")
    g.add("test.sink", id="k1")
    num = g.add("basic.number", id="num")
    k2 = g.add("test.sink", id="k2")
    g.wire(num.value, k2.path)  # Number into Path: broken
    a1, a2 = g.add("basic.add", id="a1"), g.add("basic.add", id="a2")
    g.wire(a1.result, a2.a)
    g.wire(a2.result, a1.a)  # cycle a1 -> a2 -> a1
    a3 = g.add("basic.add", id="a3")
    g.wire(num.value, a3.zzz)  # no such port
    g.wire("ghost.value", a3.b)  # no such node
    a4 = g.add("basic.add", id="a4")
    g.wire(num.value, a4.a)
    g.wire(a3.result, a4.a)  # second wire into a4.a
    a5 = g.add("basic.add", id="a5")
    g.wire("u.whatever", a5.a)  # from the unknown-type node: not flagged again
    g.input("i", "Number", a4.nothing)
    g.output("o", "Number", "missing.value")
    graph = g.build()
    graph.nodes.append(graph.nodes[-1].model_copy(update={"pos": (1.0, 1.0)}))  # duplicate id a5
    return graph


EXPECTED = {
    "unknown-node-type": ("u", ("nodes", "u", "type")),
    "invalid-param": ("b1", ("nodes", "b1", "params", "feed")),
    "unknown-param": ("b2", ("nodes", "b2", "params", "colour")),
    "missing-input": ("k1", ("nodes", "k1", "inputs", "path")),
    "broken-wire": ("k2", None),
    "cycle": ("a1", ("nodes", "a1")),
    "unknown-port": ("a3", None),
    "unknown-node": ("ghost", None),
    "input-wired-twice": ("a4", None),
    "interface-port": ("a4", ("interface", "inputs", "i", "to", 0)),
    "duplicate-node-id": ("a5", ("nodes", "a5")),
}


def test_every_problem_is_reported_once_naming_its_node(registry):
    issues = flowmc.validate(_everything_wrong(), registry=registry)
    by_code = {}
    for issue in issues:
        by_code.setdefault(issue.code, []).append(issue)
    assert set(by_code) == set(EXPECTED)
    for code, (node_id, location) in EXPECTED.items():
        assert any(f"'{node_id}'" in i.message for i in by_code[code]), (code, by_code[code])
        if location is not None:
            assert location in [i.location for i in by_code[code]]
    assert len(by_code["interface-port"]) == 2  # the input to a4.nothing and the output from 'missing'
    assert len(by_code["unknown-node"]) == 1 and len(by_code["missing-input"]) == 1
    assert not any("'a5'" in i.message for i in issues if i.code != "duplicate-node-id")


def test_messages_name_the_ports(registry):
    issues = {i.code: i for i in flowmc.validate(_everything_wrong(), registry=registry)}
    assert ("node 'num' output 'value' is Number but node 'k2' input 'path' takes Path or Trajectory"
            in issues["broken-wire"].message)
    assert "node 'a3' has no input 'zzz'" in issues["unknown-port"].message
    assert issues["unknown-port"].location == ("wires", 3, "to")
    assert "node 'a4' input 'a' is already fed by wire num.value -> a4.a" in issues["input-wired-twice"].message
    assert "required input 'path' (Path or Trajectory) is not wired" in issues["missing-input"].message
    assert "(test.blob params: label, feed)" in issues["unknown-param"].message


def test_cycle_names_every_node_in_it(registry):
    g = flowmc.GraphBuilder()
    ids = ["c", "a", "b"]
    refs = [g.add("basic.add", id=i) for i in ids]
    for src, dst in zip(refs, refs[1:] + refs[:1]):
        g.wire(src.result, dst.a)
    other = [g.add("basic.add", id="x"), g.add("basic.add", id="y")]
    g.wire(other[0].result, other[1].a)
    g.wire(other[1].result, other[0].b)
    issues = flowmc.validate(g.build(), registry=registry)
    assert [i.code for i in issues] == ["cycle", "cycle"]
    assert issues[0].message == "node 'a': cycle a -> b -> c -> a"
    assert issues[1].message == "node 'x': cycle x -> y -> x"


def test_nothing_runs_when_the_graph_is_invalid(registry):
    rt = flowmc.Runtime(registry)
    seen = []
    rt.subscribe(seen.append)
    with pytest.raises(GraphError) as info:
        rt.run(_everything_wrong())
    assert len(info.value.issues) == len(flowmc.validate(_everything_wrong(), registry=registry))
    assert seen == []


def test_wired_param_is_not_flagged_for_its_stored_value(registry):
    g = flowmc.GraphBuilder()
    n = g.add("basic.number", id="n", value=5)
    b = g.add("test.blob", id="b", feed=-1)  # stored value invalid, but a wire feeds it
    g.wire(n.value, b.feed)
    assert flowmc.validate(g.build(), registry=registry) == []


def test_plan_gives_the_order_and_ports_without_running(registry):
    g = flowmc.GraphBuilder()
    b, k = g.add("test.blob", id="zz"), g.add("test.sink", id="aa")
    n = g.add("basic.number", id="mm")
    g.wire(b.path, k.path)
    plan = flowmc.Runtime(registry).plan(g.build())
    assert plan.ok and plan.generations == [["mm", "zz"], ["aa"]] and plan.order == ["mm", "zz", "aa"]
    inputs, outputs = plan.ports("zz")
    assert set(inputs) == {"label", "feed"} and set(outputs) == {"path", "feed"}
    assert plan.downstream("zz") == {"aa"} and n.id == "mm"


def test_plan_is_computed_once_per_graph_revision(registry):
    g = flowmc.GraphBuilder()
    g.add("basic.number", id="n", value=1)
    graph = g.build()
    rt = flowmc.Runtime(registry)
    first = rt.plan(graph)
    graph.nodes[0].pos = (500.0, 9.0)  # layout only
    assert rt.plan(graph) is first
    graph.nodes[0].params["value"] = 2
    second = rt.plan(graph)
    assert second is not first and second.nodes["n"].params.value == 2
    assert first.nodes["n"].params.value == 1  # the old plan did not change with the graph


def test_interface_types_and_defaults_are_checked(registry):
    g = flowmc.GraphBuilder()
    add = g.add("basic.add", id="add")
    blob = g.add("test.blob", id="blob")
    g.input("a", "Number", add.a, default="ten")
    g.input("p", "Path", add.b)
    g.output("o", "Number", blob.path)
    issues = {(i.code, i.location): i.message for i in flowmc.validate(g.build(), registry=registry)}
    assert issues == {
        ("interface-type", ("interface", "inputs", "a", "default")):
            "interface input 'a': default 'ten' is not a Number (defaults are Number, Bool or Text)",
        ("interface-type", ("interface", "inputs", "p", "to", 0)):
            "interface input 'p' -> add.b: interface type Path but node 'add' input 'b' takes Number",
        ("interface-type", ("interface", "outputs", "o", "from")):
            "interface output 'o' <- blob.path: interface type Number but node 'blob' output 'path' is Path",
    }


def test_generations_are_networkx_topological_generations():
    import random

    import networkx as nx

    from flowmc.runtime.schedule import generations

    rng = random.Random(7)
    ids = [f"n{i:03d}" for i in range(300)]
    edges = sorted({(ids[a], ids[b]) for a, b in ((rng.randrange(299), rng.randrange(300)) for _ in range(600)) if a < b})
    graph = nx.DiGraph()
    graph.add_nodes_from(ids)
    graph.add_edges_from(edges)
    expected = [sorted(g) for g in nx.topological_generations(graph)]
    assert generations(ids, edges) == expected
    assert generations(["a", "b"], [("a", "b"), ("b", "a")]) is None
