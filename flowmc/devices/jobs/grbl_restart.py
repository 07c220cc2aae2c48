"""Starting a GRBL program at segment N: ``restart.plan_start``'s approach as G-code, then the rest.

The plan is the same as the simulated card's (the state the program built before the segment, the
safe approach, what was assumed), made from the program's rows as GRBL gets them. GRBL plans its
own acceleration, so the approach goes to it as its corners: ``G0`` up to the safe Z and ``G0``
across (GRBL's rapid rates), the restored state as M-codes (``M3``/``M4 S``, ``M8`` for output 1,
the pen commands), ``G4`` for the spindle's spin-up, and the plunge as ``G1`` at the plan's speed (a
quarter of Z's vmax); then the program from the segment's first row (``motion_gcode(start_row=)``),
whose lines keep the original program's rows and sources, so the job's ticks name the user's segment
and G-code line. GRBL's own state before the start (spindle, coolant) comes from its status report.
"""

from __future__ import annotations

import numpy as np

from flowmc.devices.grbl_program import ProgramLine, decimate, motion_gcode, program_rows, signal_code
from flowmc.devices.jobs.restart import PLUNGE_SHARE, StartPlan, plan_job_start

__all__ = ["grbl_start", "grbl_outputs"]


def grbl_outputs(status: dict) -> dict[tuple[str, int], float]:
    """The outputs GRBL reports (``A:`` S/C spindle cw/ccw, F flood; ``FS`` rpm), as plan_start keys."""
    acc = str(status.get("A", ""))
    fs = status.get("FS") or [0.0, 0.0]
    rpm = float(fs[1]) if len(fs) > 1 else 0.0
    return {("spindle_rpm", 1): -rpm if "C" in acc else rpm, ("dout", 1): float("F" in acc), ("tool", 0): 0.0}


def _approach(plan: StartPlan, names: tuple[str, ...], vmax_z: float | None, pen, tolerance: float,
              period: float, where: str) -> list[ProgramLine]:
    """The plan's rows up to its junction as G-code: its corners as G0 (the plunge G1), a stand-still
    as G4, its signals as M-codes before the move that follows them."""
    end = plan.junction
    pts = plan.positions[:end + 1]
    codes: dict[int, list[ProgramLine]] = {}
    for row, kind, ch, value in plan.signals:
        if row <= end:
            code = signal_code(kind, ch, value, pen, "the restored state")
            if code:
                codes.setdefault(row, []).append(ProgramLine(code, f"restoring the state at {where}"))
    still = np.linalg.norm(np.diff(pts, axis=0), axis=1) < 1e-12
    starts_or_stops = np.flatnonzero(np.diff(still.astype(int))) + 1  # a stand-still's ends are corners too
    kept = decimate(pts, tolerance, keep=np.concatenate([sorted(codes), starts_or_stops]).astype(int))
    z = names.index("Z") if "Z" in names else None
    lines: list[ProgramLine] = []
    for prev, row in zip(kept[:-1], kept[1:]):
        lines += codes.get(int(prev), [])
        step = pts[row] - pts[prev]
        if float(np.linalg.norm(step)) < 1e-9:
            lines.append(ProgramLine(f"G4 P{(row - prev) * period:.3f}", f"spindle spin-up before {where}"))
            continue
        words = " ".join(f"{a}{v:.4f}".rstrip("0").rstrip(".") for a, v, d in zip(names, pts[row], step)
                         if abs(d) > 1e-12 and a in "XYZ")
        plunge = z is not None and row == end and step[z] < 0 and np.count_nonzero(np.abs(step) > 1e-12) == 1
        if plunge and vmax_z is not None:
            lines.append(ProgramLine(f"G1 {words} F{PLUNGE_SHARE * vmax_z * 60.0:.1f}", f"approach: down to {where}"))
        else:
            lines.append(ProgramLine(f"G0 {words}", f"approach to {where}"))
    return lines + codes.get(end, [])


def grbl_start(job, card, start_segment: int, status: dict, optional_stop: bool = False
               ) -> tuple[list[ProgramLine], list[str]]:
    """The lines that start ``job``'s program at ``start_segment`` (0-based) on a GRBL board whose status
    report is ``status``, and what that assumes (for the job log)."""
    machine, motion, pen = card.machine, job.motion, card.pen
    pos, _dt, seg, _unit, sig, sig_rows, _per_row = program_rows(motion, machine, job.signals)
    names = machine.names
    mpos = status.get("MPos") or status.get("WPos") or []
    here = np.array([mpos["XYZ".index(a)] if a in "XYZ" and "XYZ".index(a) < len(mpos) else 0.0 for a in names])
    nominal = np.tile(here, (len(pos), 1))
    for k, axis in enumerate(motion.axes):
        nominal[:, names.index(axis)] = pos[:, k]
    signals = sorted(((int(r), str(k), int(c), float(v)) for r, k, c, v in
                      zip(sig_rows, sig.kind, sig.channel, sig.value) if k != "tool" or pen is not None),
                     key=lambda s: s[0])
    plan = plan_job_start(job, nominal, np.asarray(seg), signals, np.zeros(len(pos), dtype=bool), here, machine,
                          grbl_outputs(status), start_segment)
    where = job.where(start_segment)
    vmax_z = float(machine.column("vmax")[names.index("Z")]) if "Z" in names else None
    approach = _approach(plan, names, vmax_z, pen, card.tolerance, machine.period, where)
    lines = motion_gcode(motion, machine, job.signals, card.tolerance, pen, optional_stop,
                         start_row=plan.program_row, approach=approach)
    assumptions = list(plan.assumptions)
    if approach:
        assumptions.append(f"sent to GRBL as: {'; '.join(line.text for line in approach)} (G0 at GRBL's own "
                           "rapid rates, which it plans within its own acceleration)")
    return lines, assumptions
