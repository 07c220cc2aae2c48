"""Tests of real parts never skip: a skipped ``linuxcnc``, ``browser`` or ``packaging`` test is a failure
(install what it needs with ``bash scripts/setup.sh --test``). Deselect them with ``-m`` instead."""

import pytest

REAL_PARTS = ("linuxcnc", "browser", "packaging")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    marked = [m for m in REAL_PARTS if item.get_closest_marker(m)]
    if report.skipped and marked:
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        report.outcome = "failed"
        report.longrepr = (f"{item.nodeid}: a {marked[0]} test may not skip ({reason}); "
                           "install what it needs: bash scripts/setup.sh --test")


def pytest_ignore_collect(collection_path, config):
    """Doctests are flowmc's (``--doctest-modules``): test helpers and conftest files are not collected
    as modules (two conftest.py files would clash by name)."""
    if collection_path.suffix == ".py" and not collection_path.name.startswith("test_"):
        return True
    return None
