"""Nothing moves without an explicit Start: a run prepares device nodes' jobs (pre-flighted, cached),
re-runs and input changes only mark them stale, and ``Runtime.start`` runs exactly the prepared jobs.

A spy backend counts every card opened and every operation, so "nothing moved" is checked on the
device side, not on what the runtime says."""

import json
from pathlib import Path

import numpy as np
import pytest

import flowmc
from flowmc.devices import backends
from flowmc.devices.sim import SimCard
from flowmc.errors import GraphError
from flowmc.registry import NodeType, Out, register
from flowmc.runtime import Start

ROWS = json.loads((Path(__file__).resolve().parents[1] / "data" / "reference" / "thesis_pattern.json").read_text())[
    "segments"]


class SpyCard(SimCard):
    opened: list = []
    ran: list = []

    def connect(self):
        SpyCard.opened.append(self)

    def run(self, motion, signals=None, *, check=True):
        SpyCard.ran.append(motion.digest())
        return super().run(motion, signals, check=check)

    def home(self, axes=None, method="switch"):
        SpyCard.ran.append("home")
        return super().home(axes, method)


@pytest.fixture
def spy(monkeypatch):
    SpyCard.opened, SpyCard.ran = [], []
    monkeypatch.setitem(backends._BACKENDS, "spy", lambda arg, machine, options, **kw: SpyCard(machine))
    return SpyCard


def _graph(feed_input: bool = True):
    g = flowmc.GraphBuilder(title="pattern on the spy card")
    m = g.add("machine", id="m", period=0.002)
    p = g.add("path.segment_table", id="p", rows=ROWS, feed=20.0)
    plan = g.add("plan.lookahead", id="plan")
    home = g.add("device.home", id="home", device="spy")
    card = g.add("device.card_output", id="card", device="spy")
    report = g.add("device.log_report", id="report")
    g.wire(p.path, plan.path)
    g.wire(m.machine, plan.machine)
    g.wire(m.machine, home.machine)
    g.wire(m.machine, card.machine)
    g.wire(plan.trajectory, card.motion)
    g.wire(home.log, card.after)
    g.wire(card.log, report.log)
    if feed_input:
        g.input("feed", "Number", p.feed)
    g.output("log", "Log", card.log)
    return g.build()


def test_a_run_prepares_jobs_and_moves_nothing(spy):
    rt = flowmc.Runtime()
    result = rt.run(_graph(), {"feed": 20.0})
    assert result.ok
    status = {n: r.status for n, r in result.nodes.items()}
    assert status["home"] == "ready" and status["card"] == "ready" and status["report"] == "waiting"
    assert spy.opened == [] and spy.ran == []  # no card opened, nothing ran
    assert set(result.jobs) == {"home", "card"} and "log" not in result.outputs
    assert result.jobs["card"].report is not None  # pre-flighted


def test_start_runs_exactly_the_prepared_jobs_then_what_waited(spy):
    rt = flowmc.Runtime()
    prepared = rt.run(_graph(), {"feed": 20.0})
    job = prepared.jobs["card"]
    seen = []
    started = rt.start(prepared, Start(on_job=lambda node, runner: seen.append((node, runner.job))))
    assert started.ok, started.errors
    assert [n for n, _ in seen] == ["home", "card"] and seen[1][1] is job
    assert spy.ran == ["home", job.motion.digest()]
    assert started.nodes["report"].status == "done" and started.outputs["log"].outcome == "done"
    with pytest.raises(GraphError, match="started already"):
        rt.start(prepared)


def test_changing_an_input_or_rerunning_marks_jobs_stale_and_moves_nothing(spy):
    rt = flowmc.Runtime()
    rt.start(rt.run(_graph(), {"feed": 20.0}))
    moved = list(spy.ran)
    again = rt.run(_graph(), {"feed": 20.0})  # re-running pure nodes: the same job, ready again
    assert again.nodes["card"].status == "ready" and again.nodes["plan"].status == "cached"
    changed = rt.run(_graph(), {"feed": 30.0})  # a front-panel change
    assert changed.nodes["card"].status == "stale" and changed.nodes["home"].status == "ready"
    assert spy.ran == moved  # the device saw nothing new
    assert changed.jobs["card"].digest() != again.jobs["card"].digest()


def test_preparing_is_cached_like_a_pure_node(spy):
    rt = flowmc.Runtime()
    first = rt.run(_graph(), {"feed": 20.0})
    second = rt.run(_graph(), {"feed": 20.0})
    assert second.jobs["card"] is first.jobs["card"]


def test_a_stopped_start_starts_no_further_job(spy):
    rt = flowmc.Runtime()
    start = Start()
    start.stop()
    result = rt.start(rt.run(_graph(), {"feed": 20.0}), start)
    assert result.nodes["home"].status == "skipped" and "not started" in result.nodes["home"].error
    assert result.nodes["card"].status == "skipped" and result.nodes["report"].status == "skipped"
    assert spy.ran == []


def test_a_program_the_preflight_refuses_fails_when_prepared_not_at_start(spy):
    g = flowmc.GraphBuilder()
    m = g.add("machine", id="m", period=0.002, axes=[{"name": "X", "min": -10, "max": 10}, {"name": "Y"}, {"name": "Z"}])
    p = g.add("path.segment_table", id="p", rows=ROWS, feed=20.0)
    plan = g.add("plan.lookahead", id="plan")
    card = g.add("device.card_output", id="card", device="spy")
    g.wire(p.path, plan.path)
    g.wire(m.machine, plan.machine)
    g.wire(m.machine, card.machine)
    g.wire(plan.trajectory, card.motion)
    result = flowmc.run(g.build())
    assert result.nodes["card"].status == "failed" and "soft limit" in result.nodes["card"].error
    assert spy.opened == []


def test_jobs_inside_a_sub_graph_are_prepared_and_started_with_the_outer_run(spy):
    g = flowmc.GraphBuilder()
    m = g.add("machine", id="m")
    home = g.add("lib.home_all", id="homing", device="spy")
    g.wire(m.machine, home.machine)
    rt = flowmc.Runtime()
    prepared = rt.run(g.build())
    assert prepared.nodes["homing"].status == "ready" and spy.ran == []
    seen = []
    started = rt.start(prepared, Start(on_job=lambda node, runner: seen.append(node)))
    assert started.ok, started.errors
    assert seen == ["homing/home"] and spy.ran == ["home"]


def test_a_moving_node_type_must_prepare_and_start():
    with pytest.raises(TypeError, match="must define prepare"):
        @register
        class Half(NodeType):
            type_id = "test.half"
            title = "Half"
            category = "Test"
            description = "Moves but cannot prepare."
            pure = False
            moves = True
            outputs = (Out("log", "Log"),)

            def start(self, ctx, job):
                return {}


def test_flowmc_run_moves_with_start_true(spy):
    result = flowmc.run(_graph(), {"feed": 20.0}, start=True)
    assert result.ok and result.nodes["card"].status == "done"
    np.testing.assert_allclose(result.outputs["log"].position[-1], [0, 0, 0], atol=0.0025)
