"""LinuxCNC's lathe profile cycles: G70 (finishing), G71/G71.1/G71.2 (turning) and G72/G72.1/G72.2 (facing).

The profile is the motion in the subroutine named by Q: its G0/G1/G2/G3 lines (with A fillets and C chamfers
on corners) are read, not run, while its O-words and parameter assignments run as usual. The cycle then
cuts that profile the way LinuxCNC's interp_g7x.cc does, step by step and with the same tolerances, so that
the moves agree with rs274: the profile is turned so that it falls in Z and X, offset by D (and moved by U/W),
and either followed in P passes from D down to E (G70) or roughed in cuts I deep with retracts of R (G71,
G72; .1 leaves the pockets, .2 cuts only them).

Points are complex numbers z + x*1j in program units, as in LinuxCNC.
"""

from __future__ import annotations

import math
from typing import cast

from flowmc.motion.gcode.codes import InterpError

__all__ = ["LATHE_CYCLES", "run_g7x"]

#: The lathe profile cycles (code * 10).
LATHE_CYCLES = frozenset({700, 710, 711, 712, 720, 721, 722})

_TOL = 1e-6
_MAX_STEPS = 1_000_000  # LinuxCNC can loop forever on some profiles; flowmc stops with an error


class G7xError(Exception):
    """The profile cannot be cut (LinuxCNC's "G7X error: ...")."""


def _cross(a: complex, b: complex) -> float:
    """imag(conj(a) * b)."""
    return a.real * b.imag - a.imag * b.real


def _norm(z: complex) -> float:
    return z.real * z.real + z.imag * z.imag


# Segments of the profile ----------------------------------------------------------------------------
class _Segment:
    finish = 0.0

    def __init__(self, start: complex, end: complex):
        self.start = start
        self.end = end

    def copy(self):
        new = object.__new__(type(self))
        new.__dict__.update(self.__dict__)
        return new

    def flip_x(self) -> None:
        self.start, self.end = self.start.conjugate(), self.end.conjugate()

    def flip_z(self) -> None:
        self.start, self.end = -self.start.conjugate(), -self.end.conjugate()

    def rotate(self) -> None:
        self.start, self.end = -self.start * 1j, -self.end * 1j

    def move(self, d: complex) -> None:
        self.start += d
        self.end += d

    def monotonic(self) -> bool:
        return (self.end - self.start).real <= 1e-3

    def do_finish(self, prev: _Segment, nxt: _Segment) -> None:
        pass

    def _corner(self, prev: _Segment, nxt: _Segment) -> complex:
        """Fit this corner piece (fillet or chamfer of size ``finish``) between prev and nxt."""
        p, n = prev.copy(), nxt.copy()
        p.offset(self.finish)
        n.offset(self.finish)
        if (p.end - n.start).real > 1e-2:
            self.finish = -self.finish
            p, n = prev.copy(), nxt.copy()
            p.offset(self.finish)
            n.offset(self.finish)
        if (p.end - n.start).real > 1e-2:
            raise G7xError(f"Corner finish failed at ({prev.end.real:g},{prev.end.imag:g})")
        p.intersect(n)
        centre = (p.end + n.start) / 2.0
        p.offset(-self.finish)
        n.offset(-self.finish)
        self.start = prev.end = p.end
        self.end = nxt.start = n.start
        return centre

    def intersect(self, nxt: _Segment) -> None:
        """Move this segment's end and nxt's start to where they cross."""
        if isinstance(nxt, _Round):
            if isinstance(self, _Round):
                _round_round(self, nxt)
            else:
                _line_round(cast(_Straight, self), nxt)
        elif isinstance(self, _Round):
            _round_line(self, cast(_Straight, nxt))
        else:
            _line_line(cast(_Straight, self), cast(_Straight, nxt))

    # Each kind of segment says how it is drawn, offset, crossed, climbed and dived (LinuxCNC's methods).
    def draw(self, out) -> None:
        raise NotImplementedError

    def offset(self, distance: float) -> None:
        raise NotImplementedError

    def radius(self) -> float:
        raise NotImplementedError

    def crossings(self, x: float) -> list[float]:
        raise NotImplementedError

    def climb(self, at: complex, out) -> tuple[bool, complex]:
        raise NotImplementedError

    def climb_only(self, at: complex, out) -> complex:
        raise NotImplementedError

    def dive(self, at: complex, x: float, out, fast: bool) -> tuple[bool, complex]:
        raise NotImplementedError


class _Straight(_Segment):
    def draw(self, out) -> None:
        out.feed(self.end)

    def offset(self, distance: float) -> None:
        d = 1j * distance * (self.start - self.end) / abs(self.start - self.end)
        self.start += d
        self.end += d

    def radius(self) -> float:
        return abs(self.start - self.end)

    def crossings(self, x: float) -> list[float]:
        s, e = self.start, self.end
        if min(s.imag, e.imag) > x + _TOL or max(s.imag, e.imag) < x - _TOL:
            return []
        if abs((s - e).imag) < _TOL:
            return [s.real, e.real]
        return [(x - s.imag) / (e.imag - s.imag) * (e.real - s.real) + s.real]

    def climb(self, at: complex, out) -> tuple[bool, complex]:
        if self.end.imag + _TOL < self.start.imag:
            return True, at
        if abs(at - self.start) > _TOL:
            raise G7xError("How did we get here?")
        out.feed(self.end)
        return False, self.end

    def climb_only(self, at: complex, out) -> complex:
        if self.end.imag < self.start.imag:
            return at
        found = self.crossings(at.imag)
        if not found:
            return at
        at = complex(found[0], at.imag)
        out.feed(at)
        out.feed(self.end)
        return self.end

    def dive(self, at: complex, x: float, out, fast: bool) -> tuple[bool, complex]:
        if self.start.imag <= self.end.imag + _TOL:
            return True, at
        move = out.rapid if fast else out.feed
        if x < self.end.imag:
            move(self.end)
            return False, self.end
        found = self.crossings(x)
        if not found:
            raise G7xError("x too large in straight dive")
        end = complex(found[0], x)
        move(end)
        return False, end


class _Round(_Segment):
    def __init__(self, ccw: bool, start: complex, centre: complex, end: complex):
        super().__init__(start, end)
        self.ccw = ccw
        self.centre = centre

    def draw(self, out) -> None:
        out.arc(self.ccw, self.centre, self.end)

    def offset(self, distance: float) -> None:
        c = self.centre
        r = abs(self.start - c)
        factor = (r + (distance if self.ccw else -distance)) / r
        self.start = factor * (self.start - c) + c
        self.end = factor * (self.end - c) + c

    def radius(self) -> float:
        return min(abs(self.start - self.end), abs(self.start - self.centre))

    def flip_x(self) -> None:
        super().flip_x()
        self.ccw = not self.ccw
        self.centre = self.centre.conjugate()

    def flip_z(self) -> None:
        super().flip_z()
        self.ccw = not self.ccw
        self.centre = -self.centre.conjugate()

    def rotate(self) -> None:
        super().rotate()
        self.centre = -self.centre * 1j

    def move(self, d: complex) -> None:
        super().move(d)
        self.centre += d

    def monotonic(self) -> bool:
        if self.finish != 0:
            return True
        entry = (self.start - self.centre).imag
        leave = (self.end - self.centre).imag
        dz = (self.end - self.start).real
        if self.ccw:
            return entry >= -1e-3 and leave >= -1e-3 and dz <= -1e-3
        return entry <= 1e-3 and leave <= 1e-3 and dz <= -1e-3

    def _on(self, p: complex) -> bool:
        c = self.centre
        a = _cross(self.start - c, p - c)
        b = _cross(self.end - c, p - c)
        if self.ccw:
            return a >= -_TOL and b <= _TOL
        return a <= _TOL and b >= -_TOL

    def crossings(self, x: float) -> list[float]:
        c = self.centre
        r = abs(self.start - c)
        s = -(x - r - c.imag) * (x + r - c.imag)
        if s < -_TOL:
            return []
        s = math.sqrt(max(s, 0.0))
        out = []
        if self._on(complex(c.real + s, x)):
            out.append(c.real + s)
        if self._on(complex(c.real - s, x)):
            out.append(c.real - s)
        return out

    def _top(self) -> complex:
        end = self.end
        if end.real < self.centre.real:
            return complex(self.centre.real, self.centre.imag + abs(self.start - self.centre))
        return end

    def climb(self, at: complex, out) -> tuple[bool, complex]:
        c = self.centre
        if not self.ccw:
            if at.real > c.real:
                return True, at
            if abs(at - self.end) > 1e-3:
                out.arc(False, c, self.end)
            return False, self.end
        if at.real < c.real:
            return True, at
        end = self._top()
        if abs(at - end) > 1e-3:
            out.arc(True, c, end)
        return True, end

    def dive(self, at: complex, x: float, out, fast: bool) -> tuple[bool, complex]:
        c = self.centre
        if abs(at - self.end) < _TOL or (at - self.end).real <= _TOL:
            return False, self.end
        found = self.crossings(x) or self.crossings(x - _TOL)
        if self.ccw:
            if at.real - _TOL > c.real:
                return True, at
            if not found or found[-1] > c.real:
                out.arc(True, c, self.end)
                return False, self.end
            end = complex(found[-1], x)
            out.arc(True, c, end)
            return False, end
        if at.real <= c.real:
            return True, at
        if not found:
            out.arc(False, c, self.end)
            return False, self.end
        if found[0] < c.real:
            return False, at
        end = complex(found[0], x)
        out.arc(False, c, end)
        return False, end

    def climb_only(self, at: complex, out) -> complex:
        found = self.crossings(at.imag)
        if not found:
            return at
        c = self.centre
        if not self.ccw:
            if found[-1] > c.real:
                return at
            at = complex(found[-1], at.imag)
            out.feed(at)
            if abs(at - self.end) > 1e-3:
                out.arc(False, c, self.end)
            return self.end
        if found[0] < c.real:
            return at
        at = complex(found[0], at.imag)
        out.feed(at)
        end = self._top()
        if abs(at - end) > 1e-3:
            out.arc(True, c, end)
        return end


class _Fillet(_Round):
    """A rounded corner (A word): its arc is fitted between its neighbours."""

    def __init__(self, size: float, at: complex):
        super().__init__(False, at, at, at)
        self.finish = size

    def do_finish(self, prev: _Segment, nxt: _Segment) -> None:
        self.centre = self._corner(prev, nxt)
        self.ccw = (self.start - self.centre).imag > 0 or (self.end - self.centre).imag > 0
        self.finish = 0.0


class _Chamfer(_Straight):
    """A chamfered corner (C word)."""

    def __init__(self, size: float, at: complex):
        super().__init__(at, at)
        self.finish = size

    def do_finish(self, prev: _Segment, nxt: _Segment) -> None:
        self._corner(prev, nxt)


def _line_line(p: _Straight, n: _Straight) -> None:
    rot = (n.start - n.end).conjugate() / abs(n.start - n.end)
    ps = (p.start - n.end) * rot
    pe = (p.end - n.end) * rot
    if (ps - pe).imag == 0:
        raise G7xError("Cannot intersect parallel lines")
    f = ps.imag / (ps - pe).imag
    n.start = p.end = (ps + f * (pe - ps)) / rot + n.end


def _closest(target: complex, pc: complex, pe: complex, rot: complex, origin: complex) -> complex:
    b = _norm(pc - pe) - pc.imag * pc.imag
    b = math.sqrt(b) if b >= 0 else 0.0
    s1 = (pc.real + b) / rot + origin
    s2 = (pc.real - b) / rot + origin
    return s1 if abs(target - s1) < abs(target - s2) else s2


def _round_line(p: _Round, n: _Straight) -> None:
    """An arc followed by a line."""
    if abs(n.start - p.end) < _TOL:
        return
    rot = (n.start - n.end).conjugate() / abs(n.start - n.end)
    n.start = p.end = _closest(n.start, (p.centre - n.end) * rot, (p.end - n.end) * rot, rot, n.end)


def _line_round(p: _Straight, n: _Round) -> None:
    """A line followed by an arc."""
    if abs(n.start - p.end) < _TOL:
        return
    rot = (p.start - p.end).conjugate() / abs(p.start - p.end)
    n.start = p.end = _closest(n.start, (n.centre - p.end) * rot, (n.end - p.end) * rot, rot, p.end)


def _round_round(p: _Round, n: _Round) -> None:
    a = abs(n.start - n.centre)
    b = abs(p.start - p.centre)
    c = abs(n.centre - p.centre)
    cos_b = (c * c + a * a - b * b) / 2.0 / a / c
    rot = complex(cos_b, math.sqrt(1 - min(cos_b * cos_b, 1.0)))
    n.start = p.end = rot * (p.centre - n.centre) / c * a + n.centre


# Output through the flips ----------------------------------------------------------------------------
_MAPS = (
    (lambda p: p, False), (lambda p: -p.conjugate(), True), (lambda p: p.conjugate(), True), (lambda p: -p, False),
    (lambda p: 1j * p, False), (lambda p: (1j * p).conjugate(), True), (lambda p: -(1j * p).conjugate(), True),
    (lambda p: -1j * p, False),
)


class _Unflipped:
    """Moves in the turned profile's frame, sent to ``out`` in the program's frame."""

    def __init__(self, out, state: int):
        self.out = out
        self.map, self.mirror = _MAPS[state]

    def feed(self, p: complex) -> None:
        self.out.feed(self.map(p))

    def rapid(self, p: complex) -> None:
        self.out.rapid(self.map(p))

    def arc(self, ccw: bool, centre: complex, p: complex) -> None:
        self.out.arc(ccw != self.mirror, self.map(centre), self.map(p))


# The profile ------------------------------------------------------------------------------------------
class Profile:
    def __init__(self, segments=None):
        self.segs: list[_Segment] = segments if segments is not None else []
        self.delta = 0.5
        self.escape = complex(0.3, 0.3)
        self.flip = 0
        self.pocket_starts: list[complex] = []
        self.steps = 0

    def copy(self) -> Profile:
        new = Profile([s.copy() for s in self.segs])
        new.delta, new.escape, new.flip = self.delta, self.escape, self.flip
        return new

    def _step(self) -> None:
        self.steps += 1
        if self.steps > _MAX_STEPS:
            raise G7xError(f"the cycle does not finish within {_MAX_STEPS} steps (LinuxCNC would loop here)")

    def rotate(self) -> None:
        for s in self.segs:
            s.rotate()
        self.flip ^= 4

    def swap(self) -> None:
        """Mirror the profile so that Z and X fall along it."""
        d = self.segs[0].end - self.segs[-1].end
        if d.imag > 0:
            for s in self.segs:
                s.flip_x()
            self.flip ^= 2
        if d.real < 0:
            for s in self.segs:
                s.flip_z()
            self.flip ^= 1

    def check_monotonic(self) -> None:
        front = self.segs[0]
        if (front.end - front.start).real > 0:
            front.start = complex(front.end.real, front.start.imag)
        for s in self.segs:
            if not s.monotonic():
                raise G7xError("Not monotonic")

    def do_finish(self) -> None:
        segs = self.segs
        for h in range(1, len(segs) - 1):
            segs[h].do_finish(segs[h - 1], segs[h + 1])
        self.segs = [s for s in segs if s.radius() >= 1e-3]

    def add_distance(self, distance: float) -> None:
        """Offset the profile (all but its lead-in) by ``distance`` away from the stock side."""
        segs = self.segs
        angle = (segs[0].end - segs[0].start) / (segs[-1].start - segs[0].start)
        if angle.imag < 0:
            distance = -distance
        lead = segs.pop(0)
        done = 0.0
        while done != distance:
            self._step()
            step = min(min((s.radius() / 2 for s in segs), default=1e9), 1e9, abs(distance - done))
            if distance < 0:
                step = -step
            kept = []
            for s in segs:
                s.offset(step)
                if s.radius() >= 1e-3:
                    kept.append(s)
            segs[:] = kept
            p = 0
            while p < len(segs) - 1:
                n = p + 1
                if (segs[p].end - segs[n].start).real > 1e-2:
                    a, b = segs[p].copy(), segs[n].copy()
                    a.offset(-step)
                    b.offset(-step)
                    segs.insert(n, _Round(distance > 0, segs[p].end, (a.end + b.start) / 2.0, segs[n].start))
                    p += 1
                p += 1
            p = 0
            while p < len(segs) - 1:
                self._step()
                if not segs[p].monotonic():
                    if p == 0:
                        raise G7xError("Not monotonic")
                    if segs[p].radius() < segs[p - 1].radius():
                        del segs[p]
                    else:
                        del segs[p - 1]
                    p = 0
                    if len(segs) < 2:
                        break
                if segs[p].radius() < 1e-3:
                    del segs[p]
                    p = 0
                else:
                    segs[p].intersect(segs[p + 1])
                p += 1
            done += step
        for p in range(len(segs) - 1):
            mid = (segs[p].end + segs[p + 1].start) / 2.0
            segs[p].end = segs[p + 1].start = mid
        lead.end = segs[0].start
        segs.insert(0, lead)

    def g70(self, out, x: float, z: float, d: float, e: float, passes: float) -> None:
        self.segs[0].start = complex(z, x)
        trial = self.copy()
        trial.segs.pop(0)
        trial.swap()
        if any(not s.monotonic() for s in trial.segs):
            trial.rotate()
            trial.swap()
        trial.check_monotonic()
        if trial.flip & 4:
            self.rotate()
        self.swap()
        self.do_finish()
        self.check_monotonic()
        moves = _Unflipped(out, self.flip)
        for k in range(int(passes), 0, -1):
            path = self.copy()
            path.add_distance((k - 1) * (d - e) / passes + e)
            moves.rapid(path.segs[0].start)
            moves.rapid(path.segs[0].end)
            for s in path.segs[1:]:
                s.draw(moves)

    def g71(self, out, cycle: int, x: float, z: float, u: float, w: float, d: float, i: float, r: float,
            rotate: bool = False) -> None:
        segs = self.segs
        segs[0].start = complex(z, x)
        if rotate:
            self.rotate()
        self.swap()
        self.do_finish()
        self.check_monotonic()
        self.add_distance(d)
        segs = self.segs
        shift = complex(w, u)
        for s in segs:
            s.move(shift)
        moves = _Unflipped(out, self.flip)
        self.delta = max(i, 2 * _TOL)
        self.escape = r * complex(1, 1)
        moves.rapid(segs[0].start)
        if segs[-1].end.imag < segs[0].start.imag:
            last = segs[-1].end
            segs.append(_Straight(last, complex(last.real, segs[0].start.imag)))
        self.pocket_starts.append(segs[0].start)
        self._pockets(cycle, segs[0].start, 0, moves)

    def _pockets(self, cycle: int, at: complex, p: int, out) -> None:
        segs = self.segs
        starts = self.pocket_starts
        if cycle == 2:  # skip the first roughing pass
            while p < len(segs):
                stop, at = segs[p].dive(at, -1e9, out, p == 0)
                if stop:
                    break
                p += 1
            cycle = 3
        while True:  # each pocket (LinuxCNC recurses here)
            x = starts[-1].imag
            again = False
            while p < len(segs):
                self._step()
                while x - _TOL > at.imag:
                    x -= self.delta
                stop, at = segs[p].dive(at, x, out, p == 0)
                if stop:
                    if cycle == 1:
                        for s in segs[p:]:
                            at = s.climb_only(at, out)
                        return
                    while p < len(segs):
                        stop, at = segs[p].climb(at, out)
                        if stop:
                            if cycle == 3:
                                if at.imag > starts[-1].imag and len(starts) > 1:
                                    starts.pop()
                                if len(starts) == 1:
                                    starts.append(at)
                            again = True
                            break
                        p += 1
                    break
                if abs(at.imag - x) > _TOL:
                    p += 1
                    continue
                for ip in range(p, len(segs)):
                    found = segs[ip].crossings(at.imag)
                    if not found:
                        continue
                    dz = found[0] if ip != p else found[-1]
                    distance = abs(dz - at.real)
                    if dz - _TOL > at.real:
                        continue
                    if distance < _TOL:
                        if p == ip:
                            continue
                        if abs(at - segs[ip].start) < _TOL:
                            p = ip
                        else:
                            x -= self.delta
                        break
                    dest = complex(dz, at.imag)
                    out.feed(dest)
                    scale = min(1.0, distance / 2 / self.escape.real)
                    out.rapid(dest + scale * self.escape)
                    out.rapid(at - (scale * self.escape).conjugate())
                    if p == 0:
                        out.rapid(at)
                    else:
                        out.feed(at)
                    x -= self.delta
                    break
            if not again:
                return


# The interpreter's side ------------------------------------------------------------------------------
class _Machine:
    """The cycle's moves, run as G0/G1/G2/G3 lines in absolute program units on the cycle's line."""

    def __init__(self, interp, src, i: int):
        self.interp, self.src, self.i = interp, src, i

    def feed(self, p: complex) -> None:
        self.interp._motion(10, {"X": p.imag, "Z": p.real}, False, self.src, self.i)

    def rapid(self, p: complex) -> None:
        self.interp._motion(0, {"X": p.imag, "Z": p.real}, False, self.src, self.i)

    def arc(self, ccw: bool, centre: complex, p: complex) -> None:
        interp = self.interp
        s = interp.scale
        if abs(interp.z / s - p.real) < 1e-4 and abs(interp.x / s - p.imag) < 1e-4:
            return  # LinuxCNC drops arcs that end where they start
        interp._motion(30 if ccw else 20, {"X": p.imag, "Z": p.real, "I": centre.imag, "K": centre.real}, False,
                       self.src, self.i)


def _name(motion: int) -> str:
    cycle, sub = divmod(motion, 10)
    return f"G{cycle}.{sub}" if sub else f"G{cycle}"


def run_g7x(interp, motion: int, w: dict, src, i: int) -> None:
    """G70/G71/G72 on line i: read the profile in subroutine Q, then cut it."""
    name = _name(motion)
    cycle, sub = divmod(motion, 10)
    if "Q" not in w:
        raise InterpError(f"{name} needs a Q word (the number of the subroutine with the profile)")
    if interp.comp_mode != 400 and cycle != 70:
        raise InterpError(f"{name} cannot be used with cutter compensation on")
    if interp.plane != 1:
        raise InterpError(f"{name} can only be used in the XZ plane (G18)")
    s = interp.scale
    incremental, arc_incremental = interp.incremental, interp.arc_incremental
    x, z = interp.x / s, interp.z / s
    if "X" in w:
        x = x + w["X"] if incremental else w["X"]
    if "Z" in w:
        z = z + w["Z"] if incremental else w["Z"]
    interp.incremental = interp.arc_incremental = False
    try:
        # To the cycle's start point, the line's own X and Z taken as absolute (as LinuxCNC).
        interp._motion(0, {k: w[k] for k in "XYZ" if k in w}, False, src, i)
        # Reading the profile leaves LinuxCNC's idea of the tool's position at the profile's end point; only
        # cutter compensation notices, as it starts the next move from there.
        segs = _read_profile(interp, w["Q"], complex(z, x), incremental, arc_incremental, src, i)
        interp.mx, interp.my, interp.mz = interp.to_machine(interp.x, interp.y, interp.z)
        if len(segs) <= 1:
            return
        d, e, depth, passes = w.get("D", 0.0), w.get("E", 0.0), w.get("I", 1.0), w.get("P", 1.0)
        r, u, wz = w.get("R", 0.5), w.get("U", 0.0), w.get("W", 0.0)
        if depth <= 0:
            raise InterpError(f"{name}: I (the depth of cut) must be greater than zero")
        profile = Profile(segs)
        out = _Machine(interp, src, i)
        try:
            if cycle == 70:
                profile.g70(out, x, z, d, e, passes)
            else:
                profile.g71(out, sub, x, z, u, wz, d, depth, r, rotate=cycle == 72)
        except (G7xError, ZeroDivisionError, ValueError) as exc:
            raise InterpError(f"{name} cannot cut this profile: {exc}") from None
    finally:
        interp.incremental, interp.arc_incremental = incremental, arc_incremental


def _read_profile(interp, q: float, start: complex, incremental: bool, arc_incremental: bool, src, i: int):
    """Run subroutine q's control flow and parameters; collect its moves as the profile."""
    from flowmc.motion.gcode.arcs import ArcError
    from flowmc.motion.gcode.expr import EvalError, label_number

    depth = len(interp.frames)
    try:
        label = label_number(q)
    except EvalError as exc:
        raise InterpError(f"Q word: {exc}") from None
    interp._call(label, [], src, i)
    s = interp.scale
    segs: list[_Segment] = []
    block_delete = interp.options.block_delete
    while len(interp.frames) > depth:
        where, k = interp.src, interp.pc
        if k >= where.end:
            raise interp._error(where, max(where.end - 1, 0), f"the file ends inside the profile subroutine "
                                                              f"o{label} (its endsub is missing)")
        interp.pc = k + 1
        block = where.cache.get(k, False)
        if block is False:
            block = where.parse(k)
            where.cache[k] = block
        if block is None or (block.delete and block_delete):
            continue
        interp.count_block(where, k)
        interp.line_no = k + 1
        try:
            if block.oword is not None:
                interp._oword(block, where, k)
                continue
            words, gvals, _m = interp.values(block)
            start = _profile_step(interp, words, gvals, start, incremental, arc_incremental, segs, s)
        except (InterpError, EvalError, ArcError, G7xError) as exc:
            raise interp._error(where, k, f"in the profile for line {i + 1}: {exc}") from None
    return segs


def _profile_step(interp, words: dict, gvals: list, start: complex, incremental: bool, arc_incremental: bool,
                  segs: list, s: float) -> complex:
    import flowmc.motion.gcode.codes as C

    end = 0j if incremental else start
    if "U" in words:
        if incremental:
            raise G7xError("U cannot be used in incremental mode (G91)")
        if "X" in words:
            raise G7xError("U and X cannot be used on the same line")
        u = words["U"] / 2 if interp.diameter_mode else words["U"]
        end += 1j * u
    elif "X" in words:
        end = complex(end.real, words["X"])
    if "W" in words:
        if incremental:
            raise G7xError("W cannot be used in incremental mode (G91)")
        if "Z" in words:
            raise G7xError("W and Z cannot be used on the same line")
        end += words["W"]
    elif "Z" in words:
        end = complex(words["Z"], end.imag)
    centre = complex(words.get("K", 0.0), words.get("I", 0.0))
    if incremental:
        end += start
    for value in gvals:
        code = round(value * 10)
        if C.G_GROUP.get(code) == C.MOTION:
            interp.motion = code
    motion = interp.motion
    if start == end:
        return start
    if motion in (0, 10):
        segs.append(_Straight(start, end))
    elif motion in (20, 30):
        if "R" in words:
            if "I" in words or "K" in words:
                raise G7xError("an arc with both R and I or K")
            r = words["R"]
            chord = _norm(end - start)
            ratio = (r * r - chord / 4) / chord
            if ratio < 0:
                raise G7xError(f"the arc radius R{r:g} is too small to reach its end point")
            d = 1j * math.sqrt(ratio) * (end - start)
            centre = (start + end) / 2.0 + (d if motion == 30 else -d)
        else:
            if "I" not in words and "K" not in words:
                raise G7xError("an arc needs I or K (or R)")
            if arc_incremental:
                centre += start
        segs.append(_Round(motion == 30, start, centre, end))
    if motion in (0, 10, 20, 30):
        if "A" in words and "C" in words:
            raise G7xError("both A and C on a corner")
        if "A" in words:
            segs.append(_Fillet(words["A"], end))
        if "C" in words:
            segs.append(_Chamfer(words["C"], end))
    interp.x, interp.z = end.imag * s, end.real * s  # #<_x> and #<_z> follow the profile, as in LinuxCNC
    return end
