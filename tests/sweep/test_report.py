"""The report: the Pareto front against a brute-force check, what to plot, and the page it writes."""

from __future__ import annotations

import numpy as np
import pytest

from flowmc.settings import UsageError
from flowmc.sweep.report import choose, pareto_front, write_report
from flowmc.sweep.results import flatten_outputs


def brute_front(a, b):
    return np.array([not any((a[j] <= a[i] and b[j] <= b[i]) and (a[j] < a[i] or b[j] < b[i]) for j in range(len(a)))
                     for i in range(len(a))])


def test_pareto_front_matches_brute_force():
    rng = np.random.default_rng(7)
    for _ in range(50):
        a, b = rng.integers(0, 12, 40).astype(float), rng.random(40)  # ties in a, none in b
        assert np.array_equal(pareto_front(a, b), brute_front(a, b))
        assert np.array_equal(pareto_front(a, b, (True, True)), brute_front(-a, -b))
    same = np.array([1.0, 1.0, 2.0])
    assert pareto_front(same, np.array([5.0, 5.0, 1.0])).tolist() == [True, False, True]  # one of two equal points
    assert pareto_front(np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 3.0]), (False, True)).tolist() == [True, True, True]


ROWS = [
    {"variant": 0, "status": "done", "tol": 0.01, "out.t": 9.0, "out.m.err": 0.01},
    {"variant": 1, "status": "done", "tol": 0.05, "out.t": 8.5, "out.m.err": 0.04},
    {"variant": 2, "status": "failed", "tol": 0.1, "out.t": 8.2, "out.m.err": 0.09, "error": "node 'x': <b>bad</b>"},
]
COLUMNS = ["variant", "status", "error", "tol", "out.t", "out.m.err"]


def test_choose_resolves_names_and_says_what_exists():
    choice = choose(COLUMNS, ROWS, ["tol"], pareto=["t", "m.err"])
    assert choice.outputs == ("out.t", "out.m.err") and choice.params == ("tol",)
    assert choice.pareto == ("out.t", "out.m.err") and choice.maximize == (False, False)
    assert choose(COLUMNS, ROWS, ["tol"], pareto=["t", "max:m.err"]).maximize == (False, True)
    with pytest.raises(UsageError, match=r"--plot: no output 'speed' \(outputs: t, m.err\)"):
        choose(COLUMNS, ROWS, ["tol"], outputs=["speed"])
    with pytest.raises(UsageError, match="--against feed: not a swept setting"):
        choose(COLUMNS, ROWS, ["tol"], against=["feed"])
    with pytest.raises(UsageError, match="two objectives"):
        choose(COLUMNS, ROWS, ["tol"], pareto=["t"])


def test_the_page_escapes_what_it_shows(tmp_path):
    choice = choose(COLUMNS, ROWS, ["tol"], pareto=["t", "m.err"])
    page = write_report(tmp_path / "r.html", title="<sweep>", summary=["3 variants"], choice=choice, rows=ROWS,
                        params=["tol"]).read_text()
    assert "&lt;sweep&gt;" in page and "<b>bad</b>" not in page and "&lt;b&gt;bad&lt;/b&gt;" in page
    assert "On the Pareto front (2)" in page and "Not done (1)" in page


def test_flattened_outputs():
    metrics = {"type": "Table", "rows": 2, "columns": ["name", "value", "unit"],
               "data": [{"name": "cycle_time", "value": 8.9, "unit": "s"}, {"name": "peak", "value": 1.0, "unit": ""}]}
    log = {"type": "Log", "device": "sim", "end_position": [1.0, 2.0, 0.0], "outcome": "done"}
    big = {"type": "Table", "rows": 50, "columns": ["x"], "stats": {"x": {"min": 0.0, "max": 2.0, "mean": 1.0}}}
    assert flatten_outputs({"t": 3.5, "metrics": metrics, "log": log, "table": big}) == {
        "out.t": 3.5, "out.metrics.cycle_time": 8.9, "out.metrics.peak": 1.0,
        "out.log.device": "sim", "out.log.end_position": "[1.0, 2.0, 0.0]", "out.log.outcome": "done",
        "out.table.rows": 50, "out.table.x.min": 0.0, "out.table.x.max": 2.0, "out.table.x.mean": 1.0}
