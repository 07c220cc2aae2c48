"""The lathe threading cycle G76, expanded into passes as LinuxCNC's interpreter expands it.

The drive line runs from the current point to the block's Z (and X, Y); the thread's crest is I
from it (negative I: an outside thread, positive: a bore). The first cut is J deep; cut n reaches
``|I| + J * n ** (1/R)`` (R, degression, >= 1) until the full depth ``|I| + K``, which is then cut
once more for each of H spring passes. Q is the compound-slide angle: each pass starts ``(depth -
|I|) * tan(Q)`` further along Z. E is a taper length and L picks its ends (1 entry, 2 exit, 3 both),
cut at the pitch stretched along the taper. Each pass: rapid back to the start, rapid in (or feed
in along the entry taper), feed along the thread at P per spindle revolution, rapid out, then a
rapid to the block's end point. In lathe diameter mode (G7) I, J and K are diameters.

flowmc cuts the synchronised moves as lines at P x S, as it cuts G33 (it does not wait for the
spindle's index pulse), and says so once.
"""

from __future__ import annotations

import math

import flowmc.budget as budget
from flowmc.motion.gcode.codes import InterpError

__all__ = ["run_g76"]


def run_g76(interp, w: dict, src, i: int) -> None:
    if "P" not in w:
        raise InterpError("G76 needs a P word (the thread pitch, distance per spindle revolution)")
    if not all(k in w for k in "IJK"):
        raise InterpError("G76 needs I, J and K words (crest offset, first cut depth, full thread depth)")
    if not any(k in w for k in "XYZ"):
        raise InterpError("G76 needs an axis word (Z: the end of the drive line)")
    if interp.spindle_dir == 0:
        raise InterpError("G76 needs the spindle turning (M3 or M4)")
    if interp.comp_mode != 400:
        raise InterpError("G76 cannot be used while cutter compensation is on")
    # Depths are counted in program units, as LinuxCNC counts them: the pass count depends on where
    # a depth lands against the full depth, and mm would round differently from inches.
    s = interp.scale
    half = 0.5 if interp.diameter_mode else 1.0
    i_word, j_word, k_word = (w[k] * half for k in "IJK")
    if i_word == 0:
        raise InterpError("in G76, I must not be 0")
    if j_word <= 0:
        raise InterpError("in G76, J must be greater than 0")
    if k_word <= j_word:
        raise InterpError("in G76, K must be greater than J")
    end = interp._axis_targets(w)
    start_x, start_y, start_z = interp.x, interp.y, interp.z
    boring = i_word > 0
    crest = abs(i_word)
    full_depth = crest + abs(k_word)
    height = abs(k_word)
    pitch = w["P"] * s
    angle = 0.0 if w.get("Q", -1.0) == -1.0 else math.radians(w["Q"])
    if end[2] > start_z:
        angle = -angle
    springs = _whole(w.get("H", 0.0), "H") if "H" in w else 0
    degression = w.get("R", 1.0)
    if degression < 1.0:
        degression = 1.0
    taper = max(w.get("E", 0.0) * s, 0.0)
    taper_pitch = pitch * math.hypot(taper, height * s) / taper if taper > 0 else pitch
    if end[2] > start_z:
        taper = -taper
    # cut n reaches full depth once J * n ** (1/R) >= K: refuse a cycle of more passes than the budget
    passes = (abs(k_word) / abs(j_word)) ** degression + springs + 1 if degression < 1e3 else math.inf
    limit = budget.cap("segments") // 5
    if passes > limit:
        raise InterpError(f"this G76 would cut {passes:,.0f} passes (R {degression:g} slows the depth too much), "
                          f"over the budget of {limit:,} (FLOWMC_BUDGET_SEGMENTS raises it)")
    flags = max(_whole(w.get("L", 0.0), "L"), 0)
    entry, exit_ = bool(flags & 1), bool(flags & 2)
    target_z = end[2] + height * s * math.tan(angle)
    if not interp.warned_sync:
        interp.warned_sync = True
        interp.warn(src.where(i), "G76 threading passes are cut as lines at P x S; flowmc does not synchronise "
                                  "them to the spindle's index pulse")
    rpm = interp.speed

    def x_at(depth: float) -> float:
        return start_x + depth * s if boring else start_x - depth * s

    def feed(x: float, z: float, per_rev: float) -> None:
        interp.feed = per_rev * rpm / 60.0
        interp._straight(x, start_y, z, False, src, i)

    def rapid(x: float, z: float) -> None:
        interp._straight(x, start_y, z, True, src, i)

    def one_pass(depth: float) -> None:
        zoff = (depth - crest) * s * math.tan(angle)
        rapid(x_at(depth - full_depth), start_z - zoff)  # back
        if taper and entry:
            feed(x_at(depth - height), start_z - zoff, taper_pitch)  # in, to the taper's start
            feed(x_at(depth), start_z - zoff - taper, taper_pitch)  # in along the taper
        else:
            rapid(x_at(depth), start_z - zoff)  # in
        if taper and exit_:
            feed(x_at(depth), target_z - zoff + taper, pitch)  # along the thread
            feed(x_at(depth - height), target_z - zoff, taper_pitch)  # out along the taper
        else:
            feed(x_at(depth), target_z - zoff, pitch)  # along the thread
        rapid(x_at(depth - full_depth), target_z - zoff)  # out

    saved = interp.feed
    depth, cut = crest + abs(j_word), 1
    while depth < full_depth:
        one_pass(depth)
        cut += 1
        depth = crest + abs(j_word) * cut ** (1.0 / degression)
    for _ in range(springs + 1):
        one_pass(full_depth)
    interp.feed = saved
    interp._straight(*end, True, src, i)


def _whole(value: float, letter: str) -> int:
    n = round(value)
    if abs(value - n) > 1e-4:
        raise InterpError(f"the {letter} word of G76 must be a whole number")
    return int(n)
