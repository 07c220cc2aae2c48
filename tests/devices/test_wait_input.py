"""The "Wait for input" device node: prepared by a run (nothing waits), it waits at Start on the card's
clock, reports the time waited, orders what comes after it, and fails naming the input on a timeout."""

from __future__ import annotations

import time

import numpy as np
import pytest

import flowmc
from flowmc.devices.card import MotionCard
from flowmc.devices.sim import SimCard


def _graph(**params):
    g = flowmc.GraphBuilder(title="wait then cut")
    wait = g.add("device.wait_input", id="clamp", name="clamp", **{"input": 3, "timeout": 2.0, **params})
    line = g.add("path.polyline", id="line", points=[[0, 0, 0], [10, 0, 0]], feed=10.0)
    plan = g.add("plan.lookahead", id="plan")
    card = g.add("device.card_output", id="card")
    g.wire(line.path, plan.path)
    g.wire(plan.trajectory, card.motion)
    g.wire(wait.log, card.after)
    g.output("waited", "Number", wait.waited)
    g.output("came", "Bool", wait.came)
    g.output("log", "Log", card.log)
    return g.build()


def test_a_run_only_prepares_the_wait_and_start_waits_on_the_card_clock():
    rt = flowmc.Runtime()
    prepared = rt.run(_graph(sim_after=0.8))
    assert prepared.ok
    assert prepared.nodes["clamp"].status == "ready" and prepared.nodes["card"].status == "ready"
    assert "waited" not in prepared.outputs  # nothing waited, nothing moved
    result = rt.start(prepared)
    assert result.ok, result.errors
    assert result.outputs["waited"] == pytest.approx(0.8, abs=0.004) and result.outputs["came"] is True
    wait_log = result.nodes["clamp"].outputs["log"]
    assert [e.message for e in wait_log.events if e.kind == "wait"] == ["input 3 was on (closed) after 0.800 s"]
    assert [(c.kind, c.channel, c.value) for c in wait_log.changes] == [("din", 3, 1.0)]
    cut = result.outputs["log"]
    assert cut.t[0] == pytest.approx(0.8, abs=0.004)  # the cut carries on the card's clock after the wait
    np.testing.assert_allclose(cut.position[-1], [10, 0, 0], atol=0.003)


def test_a_timeout_fails_naming_the_input_and_nothing_after_it_runs():
    result = flowmc.run(_graph(sim_after=3.0), start=True)
    assert not result.ok
    error = result.nodes["clamp"].error
    assert "node 'clamp'" in error and "input 3 (clamp)" in error and "within 2 s" in error
    assert result.nodes["card"].status == "skipped"
    assert "log" not in result.outputs


def test_a_wait_that_may_time_out_says_whether_the_input_came():
    result = flowmc.run(_graph(fail_on_timeout=False), start=True)
    assert result.ok, result.errors
    assert result.outputs["came"] is False and result.outputs["waited"] == pytest.approx(2.0)
    assert result.outputs["log"].t[0] == pytest.approx(2.0, abs=0.004)


def test_an_input_already_at_its_level_waits_no_time():
    result = flowmc.run(_graph(on=False), start=True)  # input 3 is open: waiting for open ends at once
    assert result.ok, result.errors
    assert result.outputs["waited"] == 0.0


def test_a_switch_input_cannot_be_scheduled_by_the_simulated_world():
    result = flowmc.run(_graph(input=9, sim_after=0.5))
    assert not result.ok
    assert "input 9 is axis X's switch" in result.nodes["clamp"].error


def test_the_default_wait_polls_the_inputs_on_the_wall_clock():
    """Backends without a clock of their own (GRBL, LinuxCNC) use MotionCard.wait_input."""
    card = SimCard()
    began = time.monotonic()
    log, waited = MotionCard.wait_input(card, 5, True, 0.05, poll=0.01)
    assert log.outcome == "timeout" and 0.05 <= waited < 1.0 and time.monotonic() - began >= 0.05
    assert "input 5 did not turn on (closed) within 0.05 s" in log.events[-1].message
    log, waited = MotionCard.wait_input(card, 5, False, 0.05)
    assert log.outcome == "done" and waited < 0.05
