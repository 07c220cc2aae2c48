"""Waiting on a job from a test: jobs run in their own threads, so tests poll their state."""

from __future__ import annotations

import time

from flowmc.errors import FlowmcError


def quiet(run):
    """Run ``run`` (a job's worker) and swallow the FlowmcError its job already reports as a fault."""
    try:
        run()
    except FlowmcError:
        pass


def wait_until(check, timeout=30.0, what="condition"):
    """Poll ``check`` every 10 ms until it is true, or fail naming ``what``."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if check():
            return
        time.sleep(0.01)
    raise AssertionError(f"timed out waiting for {what}")
