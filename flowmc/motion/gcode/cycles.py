"""Canned cycles G73, G81-G89 (with G98/G99 and L repeats), expanded into moves as LinuxCNC expands them.

All cycles run in the selected plane: in G17 the hole axis is Z and positions are X/Y; in G18 the
hole axis is Y (positions Z/X); in G19 it is X (positions Y/Z). R, Z, P, Q (and G87's I, J, K) are
sticky while the same cycle continues. The "initial level" is where the hole axis was when the
first block of a run of cycles started; G98 retracts to it (when it is above R), G99 to R. Before
the first hole, a hole axis below R rapids up to R. In G91, X/Y (and R, from the initial level) are
increments and Z counts from R; L repeats step by the X/Y increment. G83 and G73 back off by
0.254 mm (0.010 inch) before each new peck; G84 and G74 (left-hand) reverse the spindle at the bottom;
G86, G87 and G88 stop it (G88 then waits for the operator: a pause event) and start it again.
"""

from __future__ import annotations

import math

import flowmc.budget as budget
from flowmc.motion.gcode.codes import InterpError
from flowmc.motion.path import PLANES, PathEvent

__all__ = ["run_cycle"]

_RAPID_DELTA_MM = 0.010 * 25.4
_NAME = {730: "G73", 740: "G74", 810: "G81", 820: "G82", 830: "G83", 840: "G84", 850: "G85", 860: "G86", 870: "G87", 880: "G88",
         890: "G89"}


def run_cycle(interp, motion: int, w: dict, src, i: int) -> None:
    name = _NAME[motion]
    if interp.feed_mode == 930:
        raise InterpError("inverse time feed (G93) cannot be used with canned cycles")
    if not interp.feed > 0:
        raise InterpError(f"{name} with no feed rate: program an F word first")
    if interp.comp_mode != 400:
        raise InterpError("canned cycles cannot be used while cutter compensation is on")
    same = interp.motion == motion
    s = interp.scale
    plane = interp.plane
    iu, iv = PLANES[plane][1]
    normal = plane
    cycle = interp.cycle
    hole = "XYZ"[normal]
    if "R" in w:
        r_word = w["R"] * s
    elif same and "r" in cycle:
        r_word = cycle["r"]
    else:
        raise InterpError(f"{name} needs an R word (the retract plane) when the cycle starts")
    if "L" in w:
        repeats = round(w["L"])
        if abs(w["L"] - repeats) > 1e-4 or repeats < 1:
            raise InterpError(f"the L word (repeats) of {name} must be a whole number, 1 or more")
        cap = budget.cap("segments")
        if 3 * repeats > cap:  # each repeat is three moves or more, all made by this one block
            raise InterpError(f"L{repeats} repeats {name} into {3 * repeats:,} moves or more, over the budget of "
                              f"{cap:,} segments: use fewer repeats, or raise the memory budget (flowmc run "
                              "--memory-mb, FLOWMC_MEMORY_MB)")
    else:
        repeats = 1
    if hole in w:
        cc_word = w[hole] * s
    elif same and "cc" in cycle:
        cc_word = cycle["cc"]
    else:
        raise InterpError(f"{name} needs a {hole} word (the bottom of the hole) when the cycle starts")
    pos = [interp.x, interp.y, interp.z]
    current_cc = pos[normal]
    if interp.cycle_il is None:
        interp.cycle_il = current_cc
    old_cc = interp.cycle_il
    au, bu = "XYZ"[iu], "XYZ"[iv]
    polar = "@" in w or "^" in w
    if polar and plane != 2:
        raise InterpError("polar coordinates (@ ^) in canned cycles work in the XY plane (G17) only")
    if polar and (au in w or bu in w):
        raise InterpError("X or Y words cannot be mixed with polar coordinates (@ ^)")
    radius_inc = theta_inc = 0.0
    if interp.incremental:
        aa_inc = w[au] * s if au in w else 0.0
        bb_inc = w[bu] * s if bu in w else 0.0
        radius_inc = w.get("@", 0.0) * s
        theta_inc = math.radians(w.get("^", 0.0))
        r = r_word + old_cc
        cc = r + cc_word
        aa, bb = pos[iu], pos[iv]
    else:
        aa_inc = bb_inc = 0.0
        r = r_word
        cc = cc_word
        if polar:
            radius = w["@"] * s if "@" in w else math.hypot(pos[1], pos[0])
            theta = math.radians(w["^"]) if "^" in w else math.atan2(pos[1], pos[0])
            aa, bb = radius * math.cos(theta), radius * math.sin(theta)
        else:
            aa = w[au] * s if au in w else pos[iu]
            bb = w[bu] * s if bu in w else pos[iv]
    if r < cc:
        raise InterpError(f"the R plane ({r / s:g}) is below the bottom of the hole ({hole}{cc / s:g}) in {name}")

    def point(a: float, b: float, c: float) -> tuple[float, float, float]:
        p = [0.0, 0.0, 0.0]
        p[iu], p[iv], p[normal] = a, b, c
        return p[0], p[1], p[2]

    def traverse(a, b, c):
        interp._straight(*point(a, b, c), True, src, i)

    def feed(a, b, c):
        interp._straight(*point(a, b, c), False, src, i)

    def dwell(seconds: float) -> None:
        interp.canon.dwell(seconds, interp.feed, interp._spindle_rpm(), src.index, i + 1)

    if old_cc < r:
        traverse(pos[iu], pos[iv], r)
        old_cc = r
        current_cc = old_cc
    clear = r if interp.retract_mode == 990 else old_cc

    def sticky(letter: str, key: str, what: str) -> float:
        if letter in w:
            value = w[letter] * (1.0 if key == "p" else s)  # P is seconds, the rest lengths
            cycle[key] = value
            return value
        if same and key in cycle:
            return cycle[key]
        raise InterpError(f"{name} needs a {letter} word ({what}) when the cycle starts")

    p = q = 0.0
    if motion in (820, 860, 880, 890):
        p = sticky("P", "p", "the dwell in seconds")
        if p < 0:
            raise InterpError(f"{name} dwell time (P) must be >= 0")
    elif motion in (740, 840):
        p = w.get("P", cycle.get("p", 0.0))
        cycle["p"] = p
    if motion in (730, 830):
        q = sticky("Q", "q", "the peck depth")
        if q <= 0:
            raise InterpError(f"{name} peck depth (Q) must be > 0")
    direction = interp.spindle_dir
    if motion in (740, 840, 860, 870, 880) and direction == 0:
        raise InterpError(f"the spindle is not turning in {name}: start it with M3 or M4 first")
    if motion == 840 and direction < 0:
        raise InterpError("the spindle turns counter-clockwise in G84 (right-hand tapping needs M3)")
    if motion == 740 and direction > 0:
        raise InterpError("the spindle turns clockwise in G74 (left-hand tapping needs M4)")
    if motion == 870:
        ci = sticky("I", "i", "the X offset")
        cj = sticky("J", "j", "the Y offset")
        ck = sticky("K", "k", "the top of the back bore")
        k_abs = cc + ck if interp.incremental else ck

    for repeat in range(repeats, 0, -1):
        aa += aa_inc
        bb += bb_inc
        if radius_inc or theta_inc:
            if aa == 0.0 and bb == 0.0:
                raise InterpError("an incremental polar move (G91 @ ^) cannot start at the origin")
            radius, theta = math.hypot(bb, aa) + radius_inc, math.atan2(bb, aa) + theta_inc
            aa, bb = radius * math.cos(theta), radius * math.sin(theta)
        if repeat == repeats and current_cc > r:
            traverse(aa, bb, current_cc)
            traverse(aa, bb, r)
        else:
            traverse(aa, bb, clear)
            if clear > r:
                traverse(aa, bb, r)
        if motion == 810:
            feed(aa, bb, cc)
            traverse(aa, bb, clear)
        elif motion == 820:
            feed(aa, bb, cc)
            dwell(p)
            traverse(aa, bb, clear)
        elif motion in (730, 830):
            depth = r - q
            while depth > cc:
                feed(aa, bb, depth)
                if motion == 830:
                    traverse(aa, bb, r)
                traverse(aa, bb, depth + _RAPID_DELTA_MM)
                depth -= q
            feed(aa, bb, cc)
            traverse(aa, bb, clear)
        elif motion in (740, 840):
            feed(aa, bb, cc)
            interp.spindle_dir = -direction
            dwell(p)
            feed(aa, bb, clear)
            interp.spindle_dir = direction
        elif motion == 850:
            feed(aa, bb, cc)
            feed(aa, bb, r)
            traverse(aa, bb, clear)
        elif motion == 860:
            feed(aa, bb, cc)
            dwell(p)
            interp.spindle_dir = 0
            traverse(aa, bb, clear)
            interp.spindle_dir = direction
        elif motion == 870:
            ou, ov = aa + ci, bb + cj
            traverse(ou, ov, r)
            interp.spindle_dir = 0
            traverse(ou, ov, cc)
            traverse(aa, bb, cc)
            interp.spindle_dir = direction
            feed(aa, bb, k_abs)
            feed(aa, bb, cc)
            interp.spindle_dir = 0
            traverse(ou, ov, cc)
            traverse(ou, ov, clear)
            traverse(aa, bb, clear)
            interp.spindle_dir = direction
        elif motion == 880:
            feed(aa, bb, cc)
            dwell(p)
            interp.spindle_dir = 0
            interp.canon.dwell(0.0, interp.feed, 0.0, src.index, i + 1,
                               PathEvent("pause", "G88: retract the spindle by hand, then resume"))
            interp.spindle_dir = direction
        elif motion == 890:
            feed(aa, bb, cc)
            dwell(p)
            feed(aa, bb, clear)
    end = point(aa, bb, clear)
    interp.x, interp.y, interp.z = end
    interp.mx, interp.my, interp.mz = interp.to_machine(*end)
    cycle["r"] = r_word
    cycle["cc"] = cc_word
