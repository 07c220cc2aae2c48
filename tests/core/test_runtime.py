"""Execution: order, failures, events, params fed by wires, and the content-signature cache."""

from __future__ import annotations

import numpy as np
import pytest

import flowmc
from flowmc.digest import Undigestable, digest
from flowmc.motion.table import Table
from flowmc.runtime import EVENT_KINDS, Event


def _diamond():
    """n1 -> a1 -> a2 -> chk ; n2 -> a3 (independent) ; blob -> sink ; clock (impure)."""
    g = flowmc.GraphBuilder(title="diamond")
    n1, n2 = g.add("basic.number", id="n1", value=1), g.add("basic.number", id="n2", value=10)
    a1, a2, a3 = (g.add("basic.add", id=i, b=1) for i in ("a1", "a2", "a3"))
    chk = g.add("basic.check", id="chk", min=0, max=100)
    blob, sink = g.add("test.blob", id="blob", label="abc"), g.add("test.sink", id="sink")
    g.add("test.clock", id="clock")
    g.wire(n1.value, a1.a)
    g.wire(a1.result, a2.a)
    g.wire(a2.result, chk.value)
    g.wire(n2.value, a3.a)
    g.wire(blob.path, sink.path)
    g.output("total", "Number", chk.value)
    return g.build()


def _ran(events):
    return sorted(e.node_id for e in events if e.kind == "running")


def test_runs_in_deterministic_topological_order(registry):
    result = flowmc.run(_diamond(), registry=registry)
    assert result.ok and result.outputs == {"total": 3.0}
    assert result.order == ["blob", "clock", "n1", "n2", "a1", "a3", "sink", "a2", "chk"]
    assert [e.node_id for e in result.events if e.kind == "running"] == result.order
    assert result.output("sink", "n") == 3.0 and result.output("a3", "result") == 11.0


def test_unchanged_graph_re_runs_nothing_but_side_effect_nodes(registry):
    rt, graph = flowmc.Runtime(registry), _diamond()
    first = rt.run(graph)
    assert _ran(first.events) == sorted(first.order)
    second = rt.run(graph)
    assert _ran(second.events) == ["chk", "clock"]  # not pure: always run
    assert sorted(second.cached) == ["a1", "a2", "a3", "blob", "n1", "n2", "sink"]
    assert second.outputs == first.outputs


def test_changing_one_param_re_runs_only_its_downstream_cone(registry):
    rt, graph = flowmc.Runtime(registry), _diamond()
    rt.run(graph)
    graph.node("a1").params["b"] = 5
    result = rt.run(graph)
    assert _ran(result.events) == ["a1", "a2", "chk", "clock"]
    assert result.outputs == {"total": 7.0}
    graph.node("blob").params["label"] = "abcd"
    result = rt.run(graph)
    assert _ran(result.events) == ["blob", "chk", "clock", "sink"]
    assert result.output("sink", "n") == 4.0


def test_same_value_upstream_keeps_downstream_cached(registry):
    rt, graph = flowmc.Runtime(registry), _diamond()
    rt.run(graph)
    graph.node("n1").params["value"] = 1.0  # int 1 -> float 1.0: same validated params
    assert _ran(rt.run(graph).events) == ["chk", "clock"]


def test_caches_belong_to_the_runtime(registry):
    graph = _diamond()
    flowmc.Runtime(registry).run(graph)
    assert len(_ran(flowmc.Runtime(registry).run(graph).events)) == 9


def test_failure_skips_downstream_and_independent_branches_still_run(registry):
    g = flowmc.GraphBuilder()
    boom = g.add("test.boom", id="boom")
    after = g.add("basic.add", id="after")
    last = g.add("basic.add", id="last")
    g.wire(boom.value, after.a)
    g.wire(after.result, last.b)
    g.add("basic.number", id="other", value=4)
    result = flowmc.run(g.build(), registry=registry)
    assert not result.ok
    assert {n: r.status for n, r in result.nodes.items()} == {
        "boom": "failed", "other": "done", "after": "skipped", "last": "skipped"}
    assert result.errors == ["node 'boom': ZeroDivisionError: boom from the test node"]
    assert "Traceback" not in result.errors[0]
    assert result.nodes["last"].error == "skipped: upstream node 'boom' failed"
    kinds = [(e.kind, e.node_id) for e in result.events if e.kind in ("failed", "skipped")]
    assert kinds == [("failed", "boom"), ("skipped", "after"), ("skipped", "last")]


def test_check_node_fails_the_run_with_a_clear_message(registry):
    rt, graph = flowmc.Runtime(registry), _diamond()
    graph.node("chk").params.update(max=2.5, label="sum")
    result = rt.run(graph)
    assert result.errors == ["node 'chk': check failed: sum = 3 is outside [0, 2.5]"]
    assert result.outputs == {}


def test_events_are_a_closed_set_delivered_to_this_runtime_only(registry):
    rt, other = flowmc.Runtime(registry), flowmc.Runtime(registry)
    mine, theirs = [], []
    unsubscribe = rt.subscribe(mine.append)
    other.subscribe(theirs.append)
    result = rt.run(_diamond())
    assert mine == result.events and theirs == []
    assert {e.kind for e in mine} <= set(EVENT_KINDS)
    assert all(isinstance(e, Event) for e in mine)
    done = [e for e in mine if e.kind == "done"]
    assert len(done) == 9 and all(e.duration is not None and e.duration >= 0 for e in done)
    assert [e.kind for e in mine[:9]] == ["queued"] * 9
    logs = [e for e in mine if e.kind == "log"]
    assert logs and logs[0].node_id == "chk" and "within [0, 100]" in logs[0].message
    unsubscribe()
    rt.run(_diamond())
    assert len(mine) == len(result.events)


def test_a_failing_listener_is_dropped_not_fatal(registry, capsys):
    rt = flowmc.Runtime(registry)

    def bad(event):
        raise RuntimeError("listener bug")

    rt.subscribe(bad)
    assert rt.run(_diamond()).ok
    assert "listener bug" in capsys.readouterr().err


def test_param_fed_by_wire_overrides_the_stored_value(registry):
    g = flowmc.GraphBuilder()
    n = g.add("basic.number", id="n", value=7)
    add = g.add("basic.add", id="add", a=1, b=100)
    g.wire(n.value, add.b)
    blob = g.add("test.blob", id="blob", feed=10)
    g.wire(n.value, blob.feed)
    graph = g.build()
    rt = flowmc.Runtime(registry)
    result = rt.run(graph)
    assert result.output("add", "result") == 8.0 and result.output("blob", "feed") == 7.0
    graph.node("n").params["value"] = -3  # violates the params model (feed > 0): refused at run time
    result = rt.run(graph)
    assert result.nodes["blob"].status == "failed"
    assert "node 'blob': param 'feed' (fed by wire): Input should be greater than 0" in result.errors[0]
    assert result.nodes["add"].status == "done" and result.output("add", "result") == -2.0


def test_interface_inputs_feed_ports_and_are_checked(registry):
    g = flowmc.GraphBuilder()
    add = g.add("basic.add", id="add", a=1, b=2)
    sink = g.add("test.sink", id="sink")
    g.input("b", "Number", add.b, default=40)
    g.input("p", "Path", sink.path)
    g.output("sum", "Number", add.result)
    graph = g.build()
    rt = flowmc.Runtime(registry)
    from core_helpers import Blob

    assert rt.run(graph, {"p": Blob("q")}).outputs == {"sum": 41.0}
    assert rt.run(graph, {"p": Blob("q"), "b": 5}).outputs == {"sum": 6.0}
    with pytest.raises(flowmc.GraphError) as info:
        rt.run(graph, {"b": "five", "nope": 1})
    messages = sorted(i.message for i in info.value.issues)
    assert messages == ["interface input 'b' must be a Number, got str 'five'",
                        "interface input 'p' (Path) is required by sink.path",
                        "no interface input 'nope' (inputs: b, p)"]


def test_node_returning_wrong_outputs_fails_clearly(registry):
    from flowmc.registry import NodeType, Out

    @registry.add
    class Sloppy(NodeType):
        type_id = "test.sloppy"
        title = "Sloppy"
        category = "Test"
        description = "Returns a str on a Number port."
        outputs = (Out("value", "Number"),)

        def run(self, ctx, params):
            return {"value": "3"}

    g = flowmc.GraphBuilder()
    g.add("test.sloppy", id="s")
    assert flowmc.run(g.build(), registry=registry).errors == ["node 's': output 'value' should be a Number, got str"]


def test_report_collects_named_numbers(registry):
    g = flowmc.GraphBuilder()
    a, b = g.add("basic.number", id="a", value=1.5), g.add("basic.number", id="b", value=2)
    r = g.add("basic.report", id="r", names=["time_s", "err_mm"], title="Run")
    g.wire(a.value, r.time_s)
    g.wire(b.value, r.err_mm)
    result = flowmc.run(g.build(), registry=registry)
    table = result.output("r", "table")
    assert isinstance(table, Table) and table.to_rows() == [{"name": "time_s", "value": 1.5}, {"name": "err_mm", "value": 2.0}]
    assert result.output("r", "text") == "Run\ntime_s = 1.5\nerr_mm = 2"


def test_ratio_and_divide(registry):
    g = flowmc.GraphBuilder()
    g.add("basic.ratio", id="r", value=1.2, reference=1.0)
    g.add("basic.divide", id="d", a=1, b=0)
    result = flowmc.run(g.build(), registry=registry)
    assert result.output("r", "ratio") == pytest.approx(1.2) and result.output("r", "change_percent") == pytest.approx(20.0)
    assert result.errors == ["node 'd': division by zero (b = 0)"]


def test_digest_distinguishes_types_and_hashes_content():
    values = [1, 1.0, True, "1", [1], (1,), {"a": 1}, None, float("nan"), -0.0, 0.0,
              np.array([1, 2], dtype=np.int64), np.array([1, 2], dtype=np.int32), np.array([[1, 2]], dtype=np.int64)]
    digests = [digest(v) for v in values]
    assert len(set(digests)) == len(digests)
    assert digest(float("nan")) == digest(float("nan"))
    assert digest(np.arange(5.0)) == digest(np.arange(5.0).copy())
    assert digest({"b": 1, "a": 2}) == digest({"a": 2, "b": 1})
    assert digest(Table({"x": [1, 2]})) == digest(Table({"x": np.array([1, 2])}))
    assert digest(Table({"x": [1, 2]})) != digest(Table({"x": [1, 3]}))
    with pytest.raises(Undigestable):
        digest(object())


def test_table_is_immutable_and_summarises():
    t = Table({"a": [1.0, 2.0, 3.0], "b": ["x", "y", "z"]})
    with pytest.raises(ValueError):
        t["a"][0] = 5
    assert t.summary()["rows"] == 3 and t.summary()["data"][2] == {"a": 3.0, "b": "z"}
    big = Table({"a": np.arange(100.0)})
    assert big.summary()["stats"]["a"] == {"min": 0.0, "max": 99.0, "mean": 49.5}
    with pytest.raises(flowmc.FlowmcError, match="has 1 rows, expected 3"):
        Table({"a": [1, 2, 3], "b": [1]})


def test_a_node_that_reads_a_file_is_cached_while_the_file_is_unchanged(tmp_path, registry):
    import os

    program = tmp_path / "part.ngc"
    program.write_text("G21 G90\nG1 X10 F600\n")
    g = flowmc.GraphBuilder()
    src = g.add("path.gcode_in", id="gcode", file="part.ngc")
    g.output("path", "Path", src.path)
    graph = g.build()
    graph.path = tmp_path / "g.flowmc.json"
    runtime = flowmc.Runtime(registry)
    first = runtime.run(graph)
    assert first.ok and first.executed == ["gcode"]
    assert runtime.run(graph).cached == ["gcode"]  # the same file: not read again
    program.write_text("G21 G90\nG1 X10 Y5 F600\n")
    os.utime(program, ns=(program.stat().st_atime_ns, program.stat().st_mtime_ns + 10**9))
    changed = runtime.run(graph)
    assert changed.executed == ["gcode"] and changed.outputs["path"].end.tolist() == [10.0, 5.0, 0.0]
    program.unlink()
    assert not runtime.run(graph).ok  # a file gone is read again, and says so
    with pytest.raises(TypeError, match="reads names unknown param 'nope'"):
        registry.add(type("Bad", (registry.lookup("path.gcode_in"),), {"reads": ("nope",), "type_id": "test.bad"}))


def test_values_of_finds_a_runs_paths_by_port_type_in_run_order():
    """One way to find the Path (or Machine, motion) of a run: the CLI's compare, the editor's G-code export
    and its 3D view all ask ``Plan.outputs_of`` / ``RunResult.values_of``."""
    g = flowmc.GraphBuilder(title="paths")
    line = g.add("path.polyline", id="line", points=[(0, 0, 0), (10, 0, 0)])
    shift = g.add("path.translate", id="shift", dx=5.0)
    plan = g.add("plan.lookahead", id="plan")
    g.wire(line.path, shift.path)
    g.wire(shift.path, plan.path)
    g.add("machine", id="mach")
    graph = g.build()
    runtime = flowmc.Runtime()
    assert runtime.plan(graph).outputs_of("Path") == [("line", "path"), ("shift", "path")]
    result = runtime.run(graph)
    paths = result.values_of("Path")
    assert [(n, p) for n, p, _ in paths] == [("line", "path"), ("shift", "path")]
    assert paths[-1][2] is result.output("shift", "path") and paths[-1][2].start.tolist() == [5.0, 0.0, 0.0]
    assert [n for n, _, _ in result.values_of("Machine", "Trajectory")] == [
        n for n in result.order if n in ("mach", "plan")]
    assert result.values_of("Log") == []
