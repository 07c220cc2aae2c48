"""A dense CAM program from G-code to a planned trajectory: the path as columns against the path as
segment objects, side by side.

The program is a 3D finishing raster such as CAM writes for a mould: 0.2 mm G1 steps over a curved
surface, rows 0.5 mm apart joined by G2/G3 half circles, a retract and rapid every 20 rows (100,000
lines by default). The reader hands the planner columns (``Path.from_columns``); the object form is
the same path rebuilt from its Segment objects (``Path(path.segments)``), which is what the planner
received before paths were stored as columns and what sources that build objects still hand it.

Times are medians of 5 warm runs in one process, the two forms taking turns. Memory is the max RSS
of a fresh process reading the file, and of one that also asks for every Segment object.

    python3 benchmarks/path_columns.py [lines]
"""

from __future__ import annotations

import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path as FsPath

from flowmc.motion.gcode import read_gcode
from flowmc.motion.lookahead import plan_lookahead
from flowmc.motion.machine import Machine
from flowmc.motion.path import Path
from flowmc.motion.pieces import build_pieces

RUNS = 5
STEP = 0.2  # mm between points along a row
PITCH = 0.5  # mm between rows


def raster_program(n_lines: int) -> str:
    """About ``n_lines`` lines of a zigzag finishing pass over z = f(x, y), in mm."""
    per_row = 300
    rows = max(2, n_lines // (per_row + 1))
    out = ["(flowmc dense CAM benchmark: finishing raster)", "G21 G90 G17 G94", "S12000 M3", "G0 Z5", "G0 X0 Y0"]

    def z(x: float, y: float) -> float:
        return round(2.0 * math.sin(x / 9.0) * math.cos(y / 7.0) - 3.0, 4)

    out.append(f"G1 Z{z(0.0, 0.0):.4f} F600")
    out.append("F1800")
    width = per_row * STEP
    for r in range(rows):
        y = r * PITCH
        forward = r % 2 == 0
        for k in range(1, per_row + 1):
            x = k * STEP if forward else width - k * STEP
            out.append(f"G1 X{x:.4f} Y{y:.4f} Z{z(x, y):.4f}")
        if r % 20 == 19:
            out.append("G0 Z5")
            out.append(f"G0 Y{y + PITCH:.4f}")
            out.append(f"G1 Z{z(width if forward else 0.0, y + PITCH):.4f} F600")
            out.append("F1800")
        else:
            x = width if forward else 0.0
            out.append(f"{'G3' if forward else 'G2'} X{x:.4f} Y{y + PITCH:.4f} Z{z(x, y + PITCH):.4f} J{PITCH / 2:.4f}")
    out.append("G0 Z5")
    out.append("M5 M2")
    return "\n".join(out) + "\n"


def interleaved(fns: dict) -> dict:
    """Median wall time of each function over RUNS turns, after one warm-up turn each."""
    times = {name: [] for name in fns}
    for turn in range(RUNS + 1):
        for name, fn in fns.items():
            t = time.perf_counter()
            fn()
            if turn:
                times[name].append(time.perf_counter() - t)
    return {name: statistics.median(ts) for name, ts in times.items()}


def peak_rss_mb(file: FsPath, objects: bool) -> float:
    code = ("import resource, sys; from flowmc.motion.gcode import read_gcode; p = read_gcode(sys.argv[1]); "
            + ("len(p.segments); " if objects else "") + "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)")
    out = subprocess.run([sys.executable, "-c", code, str(file)], capture_output=True, text=True, check=True)
    return int(out.stdout) / 1024.0


def main(n_lines: int = 100_000) -> None:
    machine = Machine()
    with tempfile.TemporaryDirectory(prefix="flowmc-bench-") as tmp:
        file = FsPath(tmp) / "raster.ngc"
        file.write_text(raster_program(n_lines))
        path = read_gcode(file)
        objects = Path(path.segments)
        assert objects.digest() == path.digest()
        print(f"{file.stat().st_size / 1e6:.1f} MB, {len(path):,} segments ({path.kind_counts()}), "
              f"{path.length:,.0f} mm")
        times = interleaved({
            "read: columns": lambda: read_gcode(file),
            "read + Segment objects": lambda: read_gcode(file).segments,
            "pieces: columns": lambda: build_pieces(path, machine, 0.05),
            "pieces: objects": lambda: build_pieces(Path(objects.segments), machine, 0.05),
            "plan: columns": lambda: plan_lookahead(path, machine),
            "plan: objects": lambda: plan_lookahead(Path(objects.segments), machine),
        })
        names = list(times)
        head = f"{'step':<26}{'median s':>10}{'ratio':>8}"
        print(head)
        print("-" * len(head))
        for a, b in zip(names[::2], names[1::2]):
            print(f"{a:<26}{times[a]:>10.3f}{times[a] / times[b]:>8.2f}")
            print(f"{b:<26}{times[b]:>10.3f}{1.0:>8.2f}")
        cols_mb, obj_mb = peak_rss_mb(file, False), peak_rss_mb(file, True)
        print(f"\npeak memory reading it (max RSS): columns {cols_mb:.0f} MB, with every Segment object "
              f"{obj_mb:.0f} MB ({cols_mb / obj_mb:.2f})")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000)
