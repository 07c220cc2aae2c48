"""G2/G3 arc centres from I/J/K or R, with LinuxCNC's acceptance rule.

LinuxCNC (measured with rs274 2.9, and its G2/G3 reference) refuses an I/J/K arc whose end radius
differs from its start radius by more than 100 x the tolerance, or by more than the tolerance and
0.1 % of the radius; the tolerance is 0.02 x sqrt(2) mm in G21 and 0.002 x sqrt(2) inch in G20.
It accepts smaller differences and cuts a spiral; so does flowmc (``Arc`` blends the radius along
the sweep), and a difference over 0.0001 mm is reported as a warning. An R arc may fall short of
half its chord by 0.00127 mm and is then a semicircle.
"""

from __future__ import annotations

import math

__all__ = ["ArcError", "centre_ijk", "centre_r", "SPIRAL_WARN_MM"]

_SPIRAL_ABS = {1.0: 0.02 * math.sqrt(2.0), 25.4: 0.002 * math.sqrt(2.0)}
_SPIRAL_REL = 0.001
_R_REACH_MM = 0.00005 * 25.4
#: Radius differences above this (mm) are accepted with a warning.
SPIRAL_WARN_MM = 1e-4


def _norm(a: float, b: float) -> float:
    """sqrt(a^2 + b^2), written out so numpy (fastpath) and this give the same last bit."""
    return math.sqrt(a * a + b * b)


class ArcError(Exception):
    """An arc LinuxCNC refuses (the interpreter adds file and line)."""


def centre_ijk(su: float, sv: float, eu: float, ev: float, cu: float, cv: float, scale: float):
    """Check an I/J/K arc in plane coordinates (mm). Returns the radius difference (mm) it accepts."""
    r0 = _norm(su - cu, sv - cv)
    r1 = _norm(eu - cu, ev - cv)
    if r0 < 1e-9 or r1 < 1e-9:
        raise ArcError("zero-radius arc: the centre is on the start or end point")
    diff = abs(r1 - r0)
    tol = _SPIRAL_ABS.get(scale, _SPIRAL_ABS[1.0] / 25.4 * scale)
    units = diff / scale
    if units > 100.0 * tol or (diff / max(r0, r1) > _SPIRAL_REL and units > tol):
        unit = "mm" if scale == 1.0 else "in"
        raise ArcError(f"radius to the end of the arc differs from radius to its start: start radius "
                       f"{r0 / scale:.6f} {unit}, end radius {r1 / scale:.6f} {unit}")
    return diff


def centre_r(su: float, sv: float, eu: float, ev: float, radius: float, clockwise: bool, scale: float):
    """Centre (u, v) of an R arc (mm); negative R takes the long way round, as in RS274/NGC."""
    du, dv = eu - su, ev - sv
    if du == 0.0 and dv == 0.0:
        raise ArcError("an R arc cannot end where it starts: give the centre (I, J, K) for a full circle")
    chord = _norm(du, dv)
    half = chord / 2.0
    r = abs(radius)
    if r == 0.0 or half - r > _R_REACH_MM:
        raise ArcError(f"arc radius R{r / scale:g} is too small to reach the end point (half the chord is "
                       f"{half / scale:.6f})")
    ratio = min(half / r, 1.0)
    if ratio > 1.0 - 1e-12:
        ratio = 1.0  # LinuxCNC's allowance for a semicircle
    offset = r * math.sqrt((1.0 - ratio) * (1.0 + ratio))
    right = clockwise == (radius > 0)  # cw with R > 0, or ccw with R < 0: centre right of travel
    sign = -1.0 if right else 1.0
    nu, nv = -dv / chord, du / chord  # left normal of the chord
    return (su + eu) / 2.0 + sign * offset * nu, (sv + ev) / 2.0 + sign * offset * nv
