"""Importing a 100,000-line G-code program: flowmc's reader against LinuxCNC's rs274 on the same file.

Target: flowmc is no slower than ``rs274 -g FILE`` (LinuxCNC's C++ interpreter printing its
canonical calls, output to /dev/null). Both are timed in the same run on the same file: medians of
5 runs after a warm-up (the readers take turns, so a busy moment on a shared machine hits both),
wall time, file reading included; a last row shows how much of flowmc's time goes into reading the
text into words (the rest is the modal interpretation and making the segment objects). The result
is checked against rs274 once, untimed: number of moves and the worst end-point difference.

    python3 benchmarks/gcode_import.py [lines]
"""

from __future__ import annotations

import math
import random
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path as FsPath

import numpy as np

from flowmc.devices.linuxcnc.rs274 import run_rs274_file
from flowmc.motion import gcode_read as gcode
from flowmc.motion.path import Dwell

RUNS = 5


def program(n_lines: int, seed: int = 7) -> str:
    """Lines, rapids, I/J/K and R arcs in all planes, helices with turns, G91 stretches, feed changes,
    dwells, outputs, N words and comments: ``n_lines`` lines in all, in mm."""
    rng = random.Random(seed)
    out = ["(flowmc benchmark program)", "G21 G90 G17 G94 G91.1", "F1200", "S8000 M3"]
    pos = [0.0, 0.0, 0.0]
    plane, incremental = 2, False

    def q(v):
        return round(v, 4)

    def words(new):
        return " ".join(f"{'XYZ'[k]}{q(new[k] - pos[k]) if incremental else q(new[k]):.4f}" for k in range(3))

    while len(out) < n_lines - 2:
        r = rng.random()
        prefix = f"N{len(out) * 10} " if rng.random() < 0.2 else ""
        suffix = " (cut)" if rng.random() < 0.05 else ""
        if r < 0.01:
            plane = rng.choice([0, 1, 2])
            out.append(prefix + {2: "G17", 1: "G18", 0: "G19"}[plane])
            continue
        if r < 0.02:
            incremental = not incremental
            out.append(prefix + ("G91" if incremental else "G90"))
            continue
        if r < 0.04:
            out.append(f"{prefix}F{rng.choice([600, 900, 1200, 2400])}")
            continue
        if r < 0.045:
            out.append(f"{prefix}G4 P0.1")
            continue
        if r < 0.05:
            out.append(f"{prefix}M6{rng.choice([2, 3])} P{rng.randrange(4)}")
            continue
        new = list(pos)
        if r < 0.72:
            code = "G0" if r < 0.15 else "G1"
            for k in range(3):
                new[k] = q(rng.uniform(-100, 100) if k < 2 else rng.uniform(-10, 5))
            out.append(f"{prefix}{code} {words(new)}{suffix}")
            pos = new
            continue
        iu, iv = {2: (0, 1), 1: (2, 0), 0: (1, 2)}[plane]
        code = rng.choice(["G2", "G3"])
        radius = rng.uniform(2, 40)
        a = rng.uniform(0, 2 * math.pi)
        cu, cv = q(pos[iu] + radius * math.cos(a)), q(pos[iv] + radius * math.sin(a))
        radius = math.hypot(pos[iu] - cu, pos[iv] - cv)
        b = rng.uniform(0, 2 * math.pi)
        new[iu], new[iv] = q(cu + radius * math.cos(b)), q(cv + radius * math.sin(b))
        extra = ""
        if r > 0.97:  # helix with turns
            new[plane] = q(pos[plane] + rng.uniform(-3, 3))
            extra = f" P{rng.choice([2, 3])}"
        if r < 0.82:
            chord = math.hypot(new[iu] - pos[iu], new[iv] - pos[iv])
            if chord < 1e-3:
                continue
            out.append(f"{prefix}{code} {words(new)} R{max(radius, chord / 2 + 0.001):.4f}{extra}{suffix}")
        else:
            centre = {iu: cu - pos[iu], iv: cv - pos[iv]}
            ijk = " ".join(f"{'IJK'[k]}{centre[k]:.4f}" for k in (iu, iv))
            out.append(f"{prefix}{code} {words(new)} {ijk}{extra}{suffix}")
        pos = new
    out += ["M5", "M2"]
    return "\n".join(out) + "\n"


def interleaved_times(fns: list) -> list[tuple[float, float]]:
    """(median, min) wall time of each function; runs alternate, so a busy moment hits all alike."""
    for fn in fns:
        fn()
    times: list[list[float]] = [[] for _ in fns]
    for _ in range(RUNS):
        for k, fn in enumerate(fns):
            t0 = time.perf_counter()
            fn()
            times[k].append(time.perf_counter() - t0)
    return [(statistics.median(t), min(t)) for t in times]


def main(n_lines: int = 100_000) -> None:
    with tempfile.TemporaryDirectory(prefix="flowmc-bench-") as tmp:
        file = FsPath(tmp) / "bench.ngc"
        file.write_text(program(n_lines))
        text = file.read_text()
        n = text.count("\n")
        path = gcode.read_gcode(file)
        moves = [s for s in path if not isinstance(s, Dwell)]
        ref = run_rs274_file(file)
        worst = max(np.max(np.abs(np.array([s.end for s in moves]) - ref.end)), 0.0) if len(moves) == len(ref) else None
        print(f"program: {n} lines, {file.stat().st_size / 1e6:.2f} MB, {len(path)} segments "
              f"({sum(s.kind == 'arc' for s in path)} arcs, {sum(s.kind == 'dwell' for s in path)} dwells)")
        print(f"check against rs274: {len(moves)} moves vs {len(ref)}; worst end-point difference "
              f"{'n/a' if worst is None else f'{worst:.2e} mm'}\n")

        def rs274():
            subprocess.run(["rs274", "-g", str(file)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                           stdin=subprocess.DEVNULL, check=True)

        def words():
            raw = file.read_bytes().decode("utf-8", errors="replace")
            return gcode._tokenise(gcode._clean(raw, False), raw, file.name)

        names = ["rs274 -g FILE > /dev/null (LinuxCNC)", "flowmc read_gcode(FILE) -> Path",
                 "  of which: text -> words"]
        timed = interleaved_times([rs274, lambda: gcode.read_gcode(file), words])
        rows = [(name, med, best) for name, (med, best) in zip(names, timed)]
        base = rows[0][1]
        head = f"{'reader':<40}{'median s':>10}{'min s':>9}{'lines/s':>12}{'ratio to rs274':>16}"
        print(head)
        print("-" * len(head))
        for name, med, best in rows:
            print(f"{name:<40}{med:>10.3f}{best:>9.3f}{n / med:>12.3g}{med / base:>16.2f}")
        ratio = rows[1][1] / base
        print(f"\ntarget: flowmc no slower than rs274 -> ratio {ratio:.2f} "
              f"({'met' if ratio <= 1.0 else 'NOT met'})")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000)
