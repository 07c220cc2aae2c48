"""Importing G-code: flowmc's reader against LinuxCNC's rs274 on the same files, side by side.

Three programs, each checked against rs274 once (untimed: number of moves, worst end point):

- plain: 100,000 lines of what CAM post-processors write (lines, rapids, I/J/K and R arcs in all
  planes, helices with turns, G91 stretches, feed changes, dwells, outputs, N words, comments);
  target: flowmc at most 0.75 x rs274's time.
- parametric: 100,000 lines full of parameters, expressions and subroutine calls (helical bores
  with a while loop, slots returning their length, parameter arithmetic, moves computed with
  SIN/COS); target: at most 1.0 x rs274's time.
- a 1,000,000-line plain program: flowmc's peak memory (max RSS of a fresh process reading it).

Times are medians of 5 runs after a warm-up, wall-clock and CPU (user + system), the readers taking
turns so a busy moment on a shared machine hits both: ``rs274 -g FILE`` with its output to
/dev/null, and flowmc's ``read_gcode(FILE)`` giving the Path, file reading included. A target is met
when both ratios meet it.

    python3 benchmarks/gcode_import.py [lines]
"""

from __future__ import annotations

import math
import os
import random
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path as FsPath

import numpy as np

import flowmc.budget as budget
from flowmc.devices.linuxcnc.rs274 import run_rs274_file
from flowmc.motion.gcode import read_gcode
from flowmc.motion.path import Dwell

RUNS = 5
MILLION_BUDGET_MB = 4096

def plain_program(n_lines: int, seed: int = 7) -> str:
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


def parametric_program(n_lines: int, seed: int = 11) -> str:
    """Subroutines (a helical bore with a while loop, a slot that returns its length), then lines of
    parameter arithmetic, calls with computed arguments and moves computed with SIN/COS."""
    rng = random.Random(seed)
    out = ["(flowmc benchmark: a parametric program)", "G21 G90 G17 G94 G91.1 G64 P0.01",
           "#<_safe> = 5", "#<_plunge> = 300", "#<_fr> = 1200", "#<_step> = 0.5",
           "o<hole> sub (x, y, depth, radius: a helical bore)",
           "  #<z> = 0",
           "  G0 X[#1 + #4] Y#2",
           "  G1 Z0 F#<_plunge>",
           "  o<h1> while [#<z> GT #3]",
           "    #<z> = [#<z> - #<_step>]",
           "    G2 X[#1 + #4] Y#2 I[-#4] J0 Z#<z> F#<_fr>",
           "  o<h1> endwhile",
           "  G2 X[#1 + #4] Y#2 I[-#4] J0",
           "  G0 Z#<_safe>",
           "o<hole> endsub",
           "o<slot> sub (x1, y1, x2, y2, depth)",
           "  G0 X#1 Y#2",
           "  G1 Z#5 F#<_plunge>",
           "  G1 X#3 Y#4 F#<_fr>",
           "  G0 Z#<_safe>",
           "  o<slot> return [SQRT[[#3 - #1] ** 2 + [#4 - #2] ** 2]]",
           "o<slot> endsub",
           "#100 = 0", "#101 = 0", "#<len> = 0", "S10000 M3", "G0 Z#<_safe>"]
    while len(out) < n_lines - 3:
        r = rng.random()
        if r < 0.25:
            out.append(f"#{rng.randint(102, 120)} = [#{rng.randint(100, 120)} * {rng.uniform(0.2, 0.9):.3f} + "
                       f"{rng.uniform(-20, 20):.3f}]")
        elif r < 0.35:
            out.append(f"#100 = [#100 + {rng.uniform(0.5, 3):.2f}] #101 = [#101 MOD 360 + {rng.randint(5, 40)}]")
        elif r < 0.45:
            out.append(f"o<hole> call [{rng.uniform(-80, 80):.3f}] [#{rng.randint(102, 120)}] "
                       f"[-{rng.choice([1, 1.5, 2])}] [{rng.uniform(1, 4):.2f}]")
        elif r < 0.55:
            out.append(f"o<slot> call [#{rng.randint(102, 120)}] [{rng.uniform(-80, 80):.3f}] "
                       f"[#{rng.randint(102, 120)} + 5] [{rng.uniform(-80, 80):.3f}] [-1]")
            out.append("#<len> = [#<len> + #<_value>]")
        elif r < 0.85:
            out.append(f"G1 X[#100 * COS[#101] + {rng.uniform(-5, 5):.3f}] Y[#100 * SIN[#101]] "
                       f"Z[-0.5 - #{rng.randint(102, 120)} / 100] F#<_fr>")
        else:
            out.append(f"G0 X{rng.uniform(-90, 90):.3f} Y{rng.uniform(-90, 90):.3f} Z#<_safe>")
    out += ["G0 Z#<_safe>", "M5", "M2"]
    return "\n".join(out) + "\n"


def _cpu() -> float:
    """CPU seconds (user + system) of this process and its finished children."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def interleaved_times(fns: list) -> list[tuple[float, float]]:
    """Median (wall, CPU) seconds of each function; runs alternate, so a busy moment hits all alike.
    CPU time is what a loaded machine distorts least: wall time waits for the other processes."""
    for fn in fns:
        fn()
    times: list[list[tuple[float, float]]] = [[] for _ in fns]
    for _ in range(RUNS):
        for k, fn in enumerate(fns):
            c0, t0 = _cpu(), time.perf_counter()
            fn()
            times[k].append((time.perf_counter() - t0, _cpu() - c0))
    return [(statistics.median(w for w, _ in t), statistics.median(c for _, c in t)) for t in times]


def rs274(file: FsPath) -> None:
    subprocess.run(["rs274", "-g", str(file)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   stdin=subprocess.DEVNULL, check=True)


def check(file: FsPath) -> str:
    path = read_gcode(file)
    moves = [s for s in path if not isinstance(s, Dwell)]
    ref = run_rs274_file(file).in_machine_coordinates()
    if len(moves) != len(ref):
        return f"{len(moves)} moves vs rs274's {len(ref)}: DIFFERENT"
    worst = float(np.max(np.abs(np.array([s.end for s in moves]) - ref.end))) if moves else 0.0
    return f"{len(moves)} moves as rs274's, worst end-point difference {worst:.1e} mm"


def peak_memory_mb(file: FsPath) -> tuple[float, int]:
    """Max RSS (MB) of a fresh Python reading the file, and how many segments it made."""
    code = ("import resource, sys; from flowmc.motion.gcode import read_gcode; p = read_gcode(sys.argv[1]); "
            "print(len(p), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)")
    # The default memory budget (256 MB) refuses a file this big before reading it; raise it for the run.
    env = {**os.environ, "FLOWMC_MEMORY_MB": str(MILLION_BUDGET_MB)}
    out = subprocess.run([sys.executable, "-c", code, str(file)], capture_output=True, text=True, check=True, env=env)
    segments, kb = out.stdout.split()
    return int(kb) / 1024.0, int(segments)


def main(n_lines: int = 100_000) -> None:
    with tempfile.TemporaryDirectory(prefix="flowmc-bench-") as tmp:
        files = {"plain": FsPath(tmp) / "plain.ngc", "parametric": FsPath(tmp) / "parametric.ngc"}
        files["plain"].write_text(plain_program(n_lines))
        files["parametric"].write_text(parametric_program(n_lines))
        targets = {"plain": 0.75, "parametric": 1.0}
        head = (f"{'program':<12}{'lines':>9}{'rs274 s':>10}{'flowmc s':>10}{'ratio':>8}{'rs274 cpu':>11}"
                f"{'flowmc cpu':>12}{'ratio':>8}{'target':>8}  check against rs274")
        print(head)
        print("-" * (len(head) + 40))
        for name, file in files.items():
            lines = file.read_text().count("\n")
            note = check(file)
            (t_ref, c_ref), (t_ours, c_ours) = interleaved_times([lambda f=file: rs274(f),
                                                                  lambda f=file: read_gcode(f)])
            ratio, cpu_ratio = t_ours / t_ref, c_ours / c_ref
            verdict = "met" if max(ratio, cpu_ratio) <= targets[name] else "NOT met"
            print(f"{name:<12}{lines:>9}{t_ref:>10.3f}{t_ours:>10.3f}{ratio:>8.2f}{c_ref:>11.3f}{c_ours:>12.3f}"
                  f"{cpu_ratio:>8.2f}{targets[name]:>7.2f}x  {note} (target {verdict})")
        big = FsPath(tmp) / "million.ngc"
        big.write_text(plain_program(10 * n_lines, seed=3))
        mb, segments = peak_memory_mb(big)
        print(f"\npeak memory reading {10 * n_lines:,} plain lines ({big.stat().st_size / 1e6:.0f} MB, "
              f"{segments:,} segments): {mb:.0f} MB max RSS (memory budget raised to {MILLION_BUDGET_MB} MB; "
              f"the default {budget.DEFAULT_MEMORY_MB} MB budget admits G-code files up to "
              f"{budget.cap('bytes'):,} bytes and {budget.cap('segments'):,} segments)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000)
