"""Jobs on the simulated card in real-time mode: how soon a Hold starts the deceleration, what
streaming a long job in real time costs in CPU, and how often the editor's DRO changes in the browser.

- hold latency: wall time from ``runner.hold()`` (what the Hold button and Esc call) to the period in
  which the card's loop applied it (``command_times``), median of RUNS holds. Target: at most 50 ms.
- CPU of streaming: process CPU seconds per wall second while a 100,000-segment program (a polyline
  of 100,000 short segments at T = 1 ms, 100 s of motion) streams in real time, times ``SPEED``; the
  job's own ticks go to one listener, as the editor's panel takes them.
- DRO rate in the browser: the editor (Debian's chromium, headless) on the thesis example graph;
  Start at real time, then a MutationObserver in the page counts the changes of the job panel's live
  element (state, progress, DRO, lamps) over ``DRO_SECONDS`` while the card job runs. Target: >= 20 Hz.

Run: python3 benchmarks/jobs.py
"""

from __future__ import annotations

import shutil
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from flowmc.devices.jobs import Job, JobRunner
from flowmc.motion.machine import Axis, Machine
from flowmc.motion.trajectory import Trajectory

ROOT = Path(__file__).resolve().parents[1]
RUNS = 7
DRO_SECONDS = 4.0
SEGMENTS = 100_000
SPEED = 4.0  # 100 s of motion in 25 s of wall time


def _machine() -> Machine:
    return Machine(axes=tuple(Axis(name=n, min=-500, max=500, vmax=200, amax=200) for n in "XY"), period=0.001)


def _program(segments: int, seconds: float) -> Trajectory:
    """A slow circle-ish polyline: ``segments`` segments over ``seconds`` at T = 1 ms."""
    n = int(round(seconds / 0.001)) + 1
    t = np.linspace(0.0, 1.0, n)
    ease = 0.5 - 0.5 * np.cos(np.pi * t)
    xy = np.column_stack([50 * np.cos(2 * np.pi * ease), 50 * np.sin(2 * np.pi * ease)]) - [50, 0]
    segment = np.minimum((t * segments).astype(int), segments - 1)
    return Trajectory(xy, 0.001, segment=segment, axes=("X", "Y"))


def hold_latency() -> list[float]:
    job = Job("sim", _machine(), "program", _program(10, 3.0), name="bench")
    out = []
    for _ in range(RUNS):
        runner = JobRunner(job, pace="realtime")
        thread = threading.Thread(target=runner.run, daemon=True)
        thread.start()
        while runner.status.progress < 0.3:
            time.sleep(0.005)
        runner.hold()
        while runner.state != "held":
            time.sleep(0.005)
        out.append(runner.command_times["applied:hold"] - runner.command_times["hold"])
        runner.stop()
        thread.join(10)
    return out


def streaming_cpu() -> tuple[float, float, int]:
    job = Job("sim", _machine(), "program", _program(SEGMENTS, 100.0), name="bench")
    runner = JobRunner(job, pace="realtime", speed=SPEED)
    ticks = []
    runner.subscribe(lambda e: ticks.append(e.status.t) if e.kind == "tick" else None)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    runner.run()
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    return cpu / wall, wall, len(ticks)


_COUNT = """(seconds) => new Promise(done => { const el = document.querySelector('.flowmc-live');
  let n = 0; const seen = new MutationObserver(() => { n += 1; });
  seen.observe(el.parentElement, {subtree: true, childList: true, characterData: true, attributes: true});
  setTimeout(() => { seen.disconnect(); done(n); }, seconds * 1000); })"""


def dro_rate() -> float:
    """Changes of the job panel's live element per second, as the page saw them."""
    sys.path[:0] = [str(ROOT), str(ROOT / "tests" / "ui")]
    from browser_helpers import EditorPage, chromium, wait_until
    from flowmc.ui.app import Editor

    with tempfile.TemporaryDirectory() as tmp:
        shutil.copy(ROOT / "graphs" / "thesis_3axis.flowmc.json", tmp)
        editor = Editor(Path(tmp) / "thesis_3axis.flowmc.json", port=0)
        try:
            with chromium() as browser:
                ui = EditorPage(browser, editor)
                ui.open()
                panel = editor.job_panel
                panel.start()
                wait_until(lambda: panel.node_id == "card" and panel.runner.status.progress > 0.05, 120, "the card job")
                changes = ui.page.evaluate(_COUNT, DRO_SECONDS)
                panel.stop()
                wait_until(lambda: not panel.active, 60, "the stop")
        finally:
            editor.close()
    return changes / DRO_SECONDS


def main() -> None:
    lat = hold_latency()
    share, wall, ticks = streaming_cpu()
    rate = dro_rate()
    print("| measure | value | target |")
    print("|---|---|---|")
    print(f"| hold -> deceleration starts (median of {RUNS}) | {1000 * statistics.median(lat):.1f} ms "
          f"(max {1000 * max(lat):.1f}) | <= 50 ms |")
    print(f"| CPU while streaming {SEGMENTS:,} segments in real time x{SPEED:g} | {100 * share:.1f} % of one core "
          f"over {wall:.1f} s | - |")
    print(f"| position events from the runner | {ticks / wall:.1f} per s | >= 20 |")
    print(f"| DRO changes in the browser (over {DRO_SECONDS:g} s) | {rate:.1f} per s | >= 20 |")


if __name__ == "__main__":
    main()
