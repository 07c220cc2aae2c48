"""Structures: For and While loops (shift registers, auto-indexing), the Case structure, their file format,
validation of every body, iteration events and the per-iteration cache."""

from __future__ import annotations

import json

import numpy as np
import pytest
from pydantic import BaseModel, ConfigDict, Field

import flowmc
import flowmc.budget as budget
from flowmc.errors import GraphError
from flowmc.graph import dumps, loads
from flowmc.registry import NodeType, Out

RUNS: list[float] = []


class CountParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    x: float = Field(0.0, description="value")


class Counted(NodeType):
    """A pure node that records each time it really runs (not when cached)."""

    type_id = "test.counted"
    title = "Counted"
    category = "Test"
    description = "Passes x through and counts its runs."
    Params = CountParams
    outputs = (Out("x", "Number", doc="x"),)

    def run(self, ctx, params):
        RUNS.append(params.x)
        return {"x": params.x}


@pytest.fixture
def reg(registry):
    registry.add(Counted)
    RUNS.clear()
    return registry


def _accumulate_body():
    """Body: total' = total + 2 i; also gives twice = 2 i."""
    b = flowmc.GraphBuilder()
    m = b.add("basic.multiply", id="m", b=2.0)
    a = b.add("basic.add", id="acc")
    b.wire(m.result, a.b)
    b.input("i", "Number", [m.a])
    b.input("total", "Number", [a.a])
    b.output("total", "Number", a.result)
    b.output("twice", "Number", m.result)
    return b.build()


def _for_graph(count=5, body=None, **params):
    g = flowmc.GraphBuilder(title="loop")
    start = g.add("basic.number", id="start", value=1.0)
    loop = g.add("struct.for", id="loop", count=count, shift=["total"], indexed=["twice"],
                 bodies={"body": body or _accumulate_body()}, **params)
    g.wire(start.value, loop.total)
    g.input("n", "Number", [loop.count], default=float(count))
    g.output("total", "Number", loop.total)
    g.output("twice", "Table", loop.twice)
    g.output("iterations", "Number", loop.iterations)
    return g.build()


def test_for_loop_shift_register_and_indexed_numbers(reg):
    rt = flowmc.Runtime(reg)
    seen = []
    rt.subscribe(lambda e: seen.append(e) if e.kind == "iteration" else None)
    result = rt.run(_for_graph(5))
    assert result.ok, result.errors
    assert result.outputs["total"] == 1 + 2 * (0 + 1 + 2 + 3 + 4)
    rows = result.outputs["twice"].to_rows()
    assert [r["i"] for r in rows] == [0, 1, 2, 3, 4] and [r["twice"] for r in rows] == [0, 2, 4, 6, 8]
    assert result.outputs["iterations"] == 5
    assert [e.message for e in seen] == [f"iteration {k} of 5" for k in range(1, 6)]
    assert [e.iteration for e in seen] == [(k, 5) for k in range(1, 6)] and {e.node_id for e in seen} == {"loop"}
    assert [e.message for e in result.events if e.kind == "iteration"][-1] == "iteration 5 of 5"


def test_count_from_the_interface_and_zero_iterations(reg):
    rt = flowmc.Runtime(reg)
    graph = _for_graph(5)
    assert rt.run(graph, inputs={"n": 3.0}).outputs["total"] == 1 + 2 * 3
    zero = rt.run(graph, inputs={"n": 0.0})
    assert zero.ok and zero.outputs["total"] == 1.0 and len(zero.outputs["twice"]) == 0


def test_structures_save_in_the_file_and_load_back_byte_identical(reg, tmp_path):
    graph = _for_graph(4)
    path = flowmc.save(graph, tmp_path / "loop.flowmc.json")
    text = path.read_text()
    data = json.loads(text)
    loop = next(n for n in data["nodes"] if n["id"] == "loop")
    assert list(loop) == ["id", "type", "params", "pos", "bodies"] and list(loop["bodies"]) == ["body"]
    assert [n["id"] for n in loop["bodies"]["body"]["nodes"]] == ["acc", "m"]  # sorted inside bodies too
    assert "bodies" not in next(n for n in data["nodes"] if n["id"] == "start")  # only structures hold any
    assert dumps(flowmc.load(path)) == text
    assert flowmc.run(flowmc.load(path), registry=reg).outputs["total"] == 13.0


def test_a_version_1_file_loads_unchanged(reg):
    graph = _for_graph(2)
    graph.nodes = [n for n in graph.nodes if n.id == "start"]
    graph.interface = None
    text = dumps(graph)
    old = loads(text.replace('"schema_version": 2', '"schema_version": 1'))
    assert old.schema_version == 2 and old.model_dump() == graph.model_dump()


def test_moving_a_node_inside_a_body_does_not_change_the_fingerprint():
    graph = _for_graph(3)
    moved = graph.model_copy(deep=True)
    moved.node("loop").bodies["body"].nodes[0].pos = (500.0, 500.0)
    assert moved.fingerprint_json() == graph.fingerprint_json()
    moved.node("loop").bodies["body"].nodes[0].params["b"] = 7.0
    assert moved.fingerprint_json() != graph.fingerprint_json()


def _collecting(body, name, port_type, count, loop_id="loop"):
    """A graph of one For loop running ``body`` ``count`` times; its output ``name``, collected, is the graph's."""
    g = flowmc.GraphBuilder()
    loop = g.add("struct.for", id=loop_id, count=count, indexed=[name], bodies={"body": body})
    g.output(name, port_type, getattr(loop, name))
    return g.build()


def _counted_body():
    b = flowmc.GraphBuilder()
    c = b.add("test.counted", id="c")
    b.input("i", "Number", [c.x])
    b.output("x", "Number", c.x)
    return b.build()


def test_iterations_of_a_pure_body_are_cached_by_content(reg):
    graph = _collecting(_counted_body(), "x", "Table", 5)
    rt = flowmc.Runtime(reg)
    assert rt.run(graph).ok and RUNS == [0, 1, 2, 3, 4]
    graph.node("loop").params["count"] = 6  # one more iteration: only that one runs
    result = rt.run(graph)
    assert RUNS == [0, 1, 2, 3, 4, 5] and list(result.outputs["x"]["x"]) == [0, 1, 2, 3, 4, 5]
    graph.node("loop").params["count"] = 2
    assert rt.run(graph).ok and RUNS == [0, 1, 2, 3, 4, 5]
    rt.clear_cache()
    assert rt.run(graph).ok and RUNS[6:] == [0, 1]


def test_an_impure_body_runs_every_iteration(reg):
    b = flowmc.GraphBuilder()
    clock = b.add("test.clock", id="clock")
    b.output("v", "Number", clock.value)
    g = flowmc.GraphBuilder()
    g.add("struct.for", id="loop", count=3, indexed=["v"], bodies={"body": b.build()})
    rt = flowmc.Runtime(reg)
    plan = rt.plan(g.build())
    assert plan.ok and not plan.nodes["loop"].pure
    assert len(rt.run(g.build()).output("loop", "v")) == 3


def _square(side, at_x):
    return [[at_x, 0, 0], [at_x + side, 0, 0], [at_x + side, side, 0], [at_x, side, 0], [at_x, 0, 0]]


def test_paths_are_joined_in_order_with_tool_up_rapids_between(reg):
    b = flowmc.GraphBuilder()
    part = b.add("path.polyline", id="part", points=_square(10, 0), feed=5.0)
    step = b.add("basic.multiply", id="step", b=20.0)
    move = b.add("path.translate", id="move")
    b.wire(part.path, move.path)
    b.wire(step.result, move.dx)
    b.input("i", "Number", [step.a])
    b.output("part", "Path", move.path)
    result = flowmc.run(_collecting(b.build(), "part", "Path", 3), registry=reg)
    assert result.ok, result.errors
    path = result.outputs["part"]
    assert len(path) == 3 * 4 + 2
    rapids = [s for s in path.segments if s.rapid]
    assert len(rapids) == 2 and not any(s.tool_down for s in rapids)
    np.testing.assert_allclose([s.start for s in rapids], [[0, 0, 0], [20, 0, 0]])
    np.testing.assert_allclose([s.end for s in rapids], [[20, 0, 0], [40, 0, 0]])
    assert path.length == pytest.approx(3 * 40 + 2 * 20)


def _while_graph(limit):
    """Doubles x until it reaches 100 or more."""
    b = flowmc.GraphBuilder()
    d = b.add("basic.multiply", id="d", b=2.0)
    c = b.add("basic.compare", id="c", b=100.0, op=">=")
    b.wire(d.result, c.a)
    b.input("x", "Number", [d.a])
    b.output("x", "Number", d.result)
    b.output("stop", "Bool", c.result)
    g = flowmc.GraphBuilder()
    one = g.add("basic.number", id="one", value=1.0)
    loop = g.add("struct.while", id="grow", max_iterations=limit, shift=["x"], bodies={"body": b.build()})
    g.wire(one.value, loop.x)
    g.output("x", "Number", loop.x)
    g.output("iterations", "Number", loop.iterations)
    return g.build()


def test_while_loop_stops_on_the_body_condition(reg):
    rt = flowmc.Runtime(reg)
    result = rt.run(_while_graph(50))
    assert result.ok and result.outputs == {"x": 128.0, "iterations": 7.0}
    messages = [e.message for e in result.events if e.kind == "iteration"]
    assert messages[0] == "iteration 1 (at most 50)" and len(messages) == 7


def test_while_loop_at_its_maximum_fails_naming_the_loop(reg):
    result = flowmc.run(_while_graph(5), registry=reg)
    assert not result.ok
    (error,) = result.errors
    assert error.startswith("node 'grow': While loop ran its maximum of 5 iterations")


def test_while_loop_needs_max_iterations_and_a_stop_output(reg):
    graph = _while_graph(5)
    del graph.node("grow").params["max_iterations"]
    issues = flowmc.Runtime(reg).validate(graph)
    assert any(i.location[:4] == ("nodes", "grow", "params", "max_iterations") for i in issues)
    graph = _while_graph(5)
    body = graph.node("grow").bodies["body"]
    body.interface.outputs = [o for o in body.interface.outputs if o.name != "stop"]
    (issue,) = flowmc.Runtime(reg).validate(graph)
    assert issue.code == "structure" and "needs a Bool output 'stop'" in issue.message and "'grow'" in issue.message


def test_a_failing_iteration_is_named(reg):
    b = flowmc.GraphBuilder()
    minus = b.add("basic.subtract", id="minus", b=2.0)
    div = b.add("basic.divide", id="div", a=1.0)
    b.wire(minus.result, div.b)
    b.input("i", "Number", [minus.a])
    b.output("y", "Number", div.result)
    g = flowmc.GraphBuilder()
    g.add("struct.for", id="loop", count=5, bodies={"body": b.build()})
    result = flowmc.run(g.build(), registry=reg)
    (error,) = result.errors
    assert error.startswith("node 'loop': iteration 3 of 5: node 'div': division by zero")


def test_loop_count_is_capped_by_the_budget_with_a_clear_error(reg):
    result = flowmc.run(_for_graph(3), inputs={"n": float(budget.cap("iterations") + 1)}, registry=reg)
    (error,) = result.errors
    assert error.startswith("node 'loop': a loop with count 100,001 needs 100,001 iterations, over the budget of "
                            "100,000: loop over fewer, larger steps"), error
    assert "FLOWMC_BUDGET_ITERATIONS" in error
    with budget.limits(iterations=2):
        assert "over the budget of 2" in flowmc.run(_for_graph(3), registry=reg).errors[0]


def test_bodies_count_towards_the_expansion_budget(reg):
    plan = flowmc.Runtime(reg).plan(_for_graph(3))
    assert plan.size == 2 + 2
    with budget.limits(expansion=3):
        (issue,) = flowmc.Runtime(reg).validate(_for_graph(3))
    assert issue.code == "budget" and "through its sub-graphs and structures" in issue.message


def test_body_problems_name_the_structure_and_point_into_the_body(reg):
    graph = _for_graph(3)
    graph.node("loop").bodies["body"].nodes[0].type = "nope.nothing"
    issues = flowmc.Runtime(reg).validate(graph)
    assert issues and issues[0].code == "unknown-node-type"
    assert issues[0].message.startswith("node 'loop', loop body: node 'm': unknown node type 'nope.nothing'")
    assert issues[0].location == ("nodes", "loop", "bodies", "body", "nodes", "m", "type")


@pytest.mark.parametrize("params, message", [
    ({"shift": ["nope"]}, "shift register 'nope' needs a body input and output of that name"),
    ({"shift": ["twice"]}, "shift register 'twice' needs a body input of that name"),
    ({"indexed": ["total"]}, "indexed output 'total' must be a body output that is not a shift register"),
])
def test_shift_registers_and_indexed_outputs_are_checked(reg, params, message):
    graph = _for_graph(3)
    graph.node("loop").params.update(params)
    issues = flowmc.Runtime(reg).validate(graph)
    assert any(i.code == "structure" and message in i.message for i in issues), issues


def test_only_structures_hold_bodies(reg):
    graph = _for_graph(3)
    graph.node("start").bodies = dict(graph.node("loop").bodies)
    (issue,) = flowmc.Runtime(reg).validate(graph)
    assert issue.code == "bodies" and "a basic.number holds no bodies" in issue.message


def test_nested_loops_announce_inner_iterations_by_path(reg):
    outer = _collecting(_counted_body(), "x", "Table", 3, loop_id="cols")
    result = flowmc.run(_collecting(outer, "x", "Table", 2, loop_id="rows"), registry=reg)
    assert result.ok, result.errors
    table = result.outputs["x"]
    assert table.names == ("j", "i", "x")
    assert table.to_rows()[4] == {"j": 1.0, "i": 1.0, "x": 1.0} and RUNS == [0, 1, 2]  # the second row was cached
    ids = [(e.node_id, e.message) for e in result.events if e.kind == "iteration"]
    assert ids[:4] == [("rows", "iteration 1 of 2"), ("rows/cols", "iteration 1 of 3"),
                       ("rows/cols", "iteration 2 of 3"), ("rows/cols", "iteration 3 of 3")]


def test_3d_views_are_found_around_loops_not_inside_their_bodies(reg):
    """A body runs many times (or not at all): the views of a run are the graph's own."""
    from flowmc.runtime.views import views

    b = flowmc.GraphBuilder()
    part = b.add("path.polyline", id="part", points=_square(5, 0))
    inner_view = b.add("view.view3d", id="inner_view")
    b.wire(part.path, inner_view.path)
    b.input("i", "Number", [])
    b.output("part", "Path", part.path)
    g = flowmc.GraphBuilder()
    loop = g.add("struct.for", id="loop", count=2, indexed=["part"], bodies={"body": b.build()})
    view = g.add("view.view3d", id="view")
    g.wire(loop.part, view.path)
    rt = flowmc.Runtime(reg)
    graph = g.build()
    result = rt.run(graph)
    assert result.ok, result.errors
    found = views(result, rt.plan(graph), rt)
    assert [v.key for v in found] == ["view"] and len(found[0].values["path"]) == 2 * 4


# ---------------------------------------------------------------- case

def _const_body(value, extra_input=False):
    b = flowmc.GraphBuilder()
    add = b.add("basic.add", id="add", a=value)
    if extra_input:
        b.input("offset", "Number", [add.b])
    b.output("y", "Number", add.result)
    return b.build()


def _case_graph(selector_type, bodies, default="", selector=None):
    g = flowmc.GraphBuilder()
    case = g.add("struct.case", id="pick", selector_type=selector_type, default=default, bodies=bodies)
    g.input("which", selector_type, [case.selector], default=selector)
    g.output("y", "Number", case.y)
    return g.build()


def test_case_with_a_text_selector_and_a_default(reg):
    graph = _case_graph("Text", {"trapezoid": _const_body(1.0), "scurve": _const_body(2.0, extra_input=True)},
                        default="scurve", selector="trapezoid")
    rt = flowmc.Runtime(reg)
    assert rt.run(graph).outputs["y"] == 1.0
    result = rt.run(graph, inputs={"which": "scurve"})
    assert result.outputs["y"] == 2.0 and result.nodes["pick"].logs == ["case 'scurve'"]
    assert rt.run(graph, inputs={"which": "other"}).outputs["y"] == 2.0  # the default case
    assert set(rt.plan(graph).ports("pick")[0]) == {"selector", "offset"}  # inputs: the union of the cases'


def test_case_with_number_ranges_and_bool_labels(reg):
    graph = _case_graph("Number", {"..0": _const_body(0.0), "1, 2": _const_body(1.0), "3..5": _const_body(3.0),
                                   "Default": _const_body(9.0)}, default="Default", selector=0.0)
    rt = flowmc.Runtime(reg)
    got = {x: rt.run(graph, inputs={"which": x}).outputs["y"] for x in (-4.0, 0.4, 1.0, 2.4, 4.6, 5.0, 6.0)}
    assert got == {-4.0: 0.0, 0.4: 0.0, 1.0: 1.0, 2.4: 1.0, 4.6: 3.0, 5.0: 3.0, 6.0: 9.0}
    flags = _case_graph("Bool", {"True": _const_body(1.0), "False": _const_body(0.0)}, selector=True)
    assert rt.run(flags).outputs["y"] == 1.0 and rt.run(flags, inputs={"which": False}).outputs["y"] == 0.0


def test_every_case_is_validated_not_only_the_one_that_runs(reg):
    broken = _const_body(2.0)
    broken.nodes[0].params["a"] = "not a number"
    graph = _case_graph("Text", {"a": _const_body(1.0), "b": broken}, default="a", selector="a")
    issues = flowmc.Runtime(reg).validate(graph)
    assert issues and issues[0].message.startswith("node 'pick', case 'b': node 'add': param 'a'")
    assert issues[0].location[:4] == ("nodes", "pick", "bodies", "b")


@pytest.mark.parametrize("selector_type, labels, default, message", [
    ("Text", ("a", "b"), "", "name a default case"),
    ("Text", ("a", "b"), "c", "default case 'c' is not one of the cases"),
    ("Number", ("1..3", "3"), "", "cases '1..3' and '3' both match some values"),
    ("Number", ("one", "2"), "2", "case 'one': a Number case is integers and ranges"),
    ("Bool", ("True", "yes"), "", "case 'yes': a Bool case is 'True' or 'False'"),
])
def test_case_labels_and_default_are_checked(reg, selector_type, labels, default, message):
    graph = _case_graph(selector_type, {label: _const_body(1.0) for label in labels}, default=default)
    issues = flowmc.Runtime(reg).validate(graph)
    assert any(message in i.message for i in issues), issues


def test_cases_share_one_interface(reg):
    other = flowmc.GraphBuilder()
    n = other.add("basic.text", id="t", value="x")
    other.output("y", "Text", n.value)
    graph = _case_graph("Text", {"a": _const_body(1.0), "b": other.build()}, default="a")
    issues = flowmc.Runtime(reg).validate(graph)
    assert any("case 'b': output 'y' is Text, case 'a' gives Number" in i.message for i in issues)


def test_a_body_graph_error_is_a_graph_error_when_run(reg):
    graph = _for_graph(3)
    graph.node("loop").bodies["body"].wires[0].from_ = "m.nope"
    with pytest.raises(GraphError) as info:
        flowmc.run(graph, registry=reg)
    assert "loop body" in info.value.issues[0].message
