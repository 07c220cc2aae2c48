"""Cutter radius compensation (G41/G42, G41.1/G42.1, G40) as LinuxCNC's interpreter does it.

LinuxCNC compensates in the interpreter with one move of look-ahead: each compensated move is held
in a queue until the next move shows how the corner between them is to be cut. A convex corner
gets an arc around the programmed corner point; a concave corner pulls the held move's end back to
where the tool touches both elements (line-line, line-arc, arc-line, arc-arc), and if that would
reverse the held move the program is refused, as LinuxCNC refuses it ("... cannot be reached by the
tool without gouging"). The first move after G41/G42 is the entry move: a line tangent to the tool
at the start, or an arc; it must be longer than the tool radius. After G40 the next move leaves
from the compensated point, and may not be an arc.

Coordinates here are plane coordinates (u, v, w) in mm: (X, Y, Z) in G17, (Z, X, Y) in G18, the
plane's first and second axis and the normal one, as LinuxCNC's comp functions see them. Dwells,
coolant and spindle changes made while a move is held are held behind it, so they keep their place.
"""

from __future__ import annotations

import math

from flowmc.motion.gcode.arcs import ArcError, centre_ijk, centre_r
from flowmc.motion.gcode.codes import InterpError

__all__ = ["CutterComp"]

_CONCAVE = 0.05  # LinuxCNC's TOLERANCE_CONCAVE_CORNER (radians)
_EQUAL = 0.0001  # LinuxCNC's TOLERANCE_EQUAL
_HALF_PI = math.pi / 2.0
_TWO_PI = 2.0 * math.pi
_TO_PLANE = {2: (0, 1, 2), 1: (2, 0, 1)}


class CompError(InterpError):
    """A compensation LinuxCNC refuses (the interpreter adds file and line)."""


def find_turn(x1: float, y1: float, cx: float, cy: float, turn: int, x2: float, y2: float) -> float:
    """Signed swept angle of an arc from (x1, y1) to (x2, y2) about (cx, cy); turn +n ccw, -n cw."""
    if turn == 0:
        return 0.0
    alpha = math.atan2(y1 - cy, x1 - cx)
    beta = math.atan2(y2 - cy, x2 - cx)
    if turn > 0:
        if beta <= alpha:
            beta += _TWO_PI
        return (beta - alpha) + (turn - 1) * _TWO_PI
    if alpha <= beta:
        alpha += _TWO_PI
    return (beta - alpha) + (turn + 1) * _TWO_PI


class _Move:
    __slots__ = ("kind", "rapid", "du", "dv", "u", "v", "w", "cu", "cv", "turn", "sweep", "feed", "spindle",
                 "file", "line")


def _inside(left: bool, turn: int) -> bool:
    """LinuxCNC's TOOL_INSIDE_ARC: the tool is on the centre's side of the arc."""
    return (left and turn > 0) or (not left and turn < 0)


class CutterComp:
    """Compensation while G41/G42 is on. ``interp`` emits the finished moves; ``left`` is G41."""

    def __init__(self, interp, left: bool, radius: float, orientation: int = 0):
        if radius < 0:
            left, radius = not left, -radius  # a negative diameter swaps the side, as in LinuxCNC
        self.interp = interp
        self.left = left
        self.radius = radius
        self.orientation = orientation
        self.plane = interp.plane
        self.first = True
        self.queue: list = []
        self.endpoint: tuple[float, float] | None = None
        self.program = (interp.x, interp.y, interp.z)

    # Coordinates --------------------------------------------------------------------------------
    def _to_plane(self, p) -> tuple[float, float, float]:
        a, b, c = _TO_PLANE[self.plane]
        return p[a], p[b], p[c]

    def _from_plane(self, u: float, v: float, w: float) -> tuple[float, float, float]:
        out = [0.0, 0.0, 0.0]
        a, b, c = _TO_PLANE[self.plane]
        out[a], out[b], out[c] = u, v, w
        return out[0], out[1], out[2]

    def base(self) -> tuple[float, float, float]:
        """Where missing axis words and incremental moves count from: the programmed point."""
        if self.first:
            i = self.interp
            return i.x, i.y, i.z
        return self.program

    def _current(self) -> tuple[float, float, float]:
        i = self.interp
        return self._to_plane((i.x, i.y, i.z))

    def _set_current(self, u: float, v: float, w: float) -> None:
        i = self.interp
        i.x, i.y, i.z = self._from_plane(u, v, w)
        i.mx, i.my, i.mz = i.to_machine(i.x, i.y, i.z)

    # The queue ------------------------------------------------------------------------------------
    def _enqueue_line(self, rapid: bool, du: float, dv: float, u: float, v: float, w: float, src, line: int) -> None:
        m = _Move()
        m.kind, m.rapid, m.du, m.dv, m.u, m.v, m.w = "line", rapid, du, dv, u, v, w
        self._stamp(m, src, line)
        self.queue.append(m)

    def _enqueue_arc(self, sweep: float, u: float, v: float, cu: float, cv: float, turn: int, w: float, src,
                     line: int) -> None:
        m = _Move()
        m.kind, m.rapid, m.u, m.v, m.w, m.cu, m.cv, m.turn, m.sweep = "arc", False, u, v, w, cu, cv, turn, sweep
        self._stamp(m, src, line)
        self.queue.append(m)

    def _stamp(self, m: _Move, src, line: int) -> None:
        i = self.interp
        m.feed, m.spindle, m.file, m.line = i.feed, i._spindle_rpm(), src.index, line

    def hold(self, action) -> bool:
        """Hold a non-move action (a callable) behind the held moves; False when nothing is held."""
        if not self.queue:
            return False
        self.queue.append(action)
        return True

    def _front_is_arc(self) -> bool:
        return bool(self.queue) and isinstance(self.queue[0], _Move) and self.queue[0].kind == "arc"

    def _front(self) -> _Move:
        return self.queue[0]

    def dequeue(self) -> None:
        self.endpoint = None
        queue, self.queue = self.queue, []
        i = self.interp
        for item in queue:
            if not isinstance(item, _Move):
                item()
                continue
            u, v = self._lathe_origin(item.u, item.v)
            end = self._from_plane(u, v, item.w)
            if item.kind == "line":
                i.emit_straight(end, item.rapid, item.feed, item.spindle, item.file, item.line)
            else:
                cu, cv = self._lathe_origin(item.cu, item.cv)
                centre = self._from_plane(cu, cv, item.w)
                turns = abs(item.turn) - 1
                i.emit_arc(end, centre, item.turn > 0, turns, self.plane, item.feed, item.spindle, item.file,
                           item.line)

    def _lathe_origin(self, u: float, v: float) -> tuple[float, float]:
        """Lathe tools control their nose-radius centre, offset from the tool origin (XZ plane only)."""
        o = self.orientation
        if self.plane != 1 or o in (0, 9):
            return u, v
        r = self.radius
        z, x = u, v
        if o in (2, 6, 1):
            x -= r
        if o in (3, 8, 4):
            x += r
        if o in (2, 7, 3):
            z -= r
        if o in (1, 5, 4):
            z += r
        return z, x

    def _set_endpoint(self, u: float, v: float) -> None:
        self.endpoint = (u, v)

    def move_endpoint_and_flush(self, x: float, y: float) -> None:
        if not self.queue:
            return
        for item in self.queue:
            if not isinstance(item, _Move):
                continue
            if item.kind == "arc":
                r1 = math.hypot(item.u - item.cu, item.v - item.cv)
                l1 = item.sweep
                r2 = math.hypot(x - item.cu, y - item.cv)
                l2 = find_turn(self.endpoint[0], self.endpoint[1], item.cu, item.cv, item.turn, x, y) \
                    if self.endpoint is not None else 0.0
                if abs(r1 - r2) > 0.01:
                    raise CompError(f"cutter compensation made an arc with mismatched radii ({r1:.4f}, {r2:.4f})")
                if l1 and self.endpoint is not None and abs(l2) > abs(l1) + 0.001:
                    raise CompError("arc move in a concave corner cannot be reached by the tool without gouging "
                                    "(the tool is too large for this corner)")
                item.u, item.v = x, y
            else:
                dot = item.du * (x - self.endpoint[0]) + item.dv * (y - self.endpoint[1]) \
                    if self.endpoint is not None else 1.0
                if self.endpoint is not None and dot < 0:
                    what = "straight traverse" if item.rapid else "straight feed"
                    raise CompError(f"{what} in a concave corner cannot be reached by the tool without gouging "
                                    f"(the tool is too large for this corner or slot)")
                item.u, item.v = x, y
        self.dequeue()
        self._set_endpoint(x, y)

    # Ending -----------------------------------------------------------------------------------------
    def end(self) -> None:
        """G40: finish the held move at the compensated point; the position is the programmed one again."""
        if not self.first:
            cu, cv, _ = self._current()
            self.move_endpoint_and_flush(cu, cv)
            self.dequeue()
            i = self.interp
            i.x, i.y, i.z = self.program
            i.mx, i.my, i.mz = i.to_machine(*self.program)
            i.arc_not_allowed = True

    def flush(self) -> None:
        """The program ends: what is held is cut as it is."""
        self.dequeue()

    # Straight moves ----------------------------------------------------------------------------------
    def straight(self, target, rapid: bool, src, i: int) -> None:
        px, py, pz = self._to_plane(target)
        line = i + 1
        r = self.radius
        cx, cy, cz = self._current()
        if self.first:
            distance = math.hypot(px - cx, py - cy)
            if distance <= r:
                raise CompError(f"the cutter compensation entry move ({distance:.4f} mm long in the plane) is not "
                                f"longer than the tool radius ({r:.4f} mm)")
            alpha = math.atan2(py - cy, px - cx) + (_HALF_PI if self.left else -_HALF_PI)
            end_x = px + r * math.cos(alpha)
            end_y = py + r * math.sin(alpha)
            self._set_endpoint(cx, cy)
            self._enqueue_line(rapid, math.cos(alpha), math.sin(alpha), end_x, end_y, pz, src, line)
            self.first = False
            self._set_current(end_x, end_y, pz)
            self.program = self._from_plane(px, py, pz)
            return
        opx, opy, opz = self._to_plane(self.program)
        end_x, end_y = cx, cy
        if px == opx and py == opy:
            self._enqueue_line(rapid, px - opx, py - opy, cx, cy, pz, src, line)
        else:
            left = self.left
            theta = math.atan2(cy - opy, cx - opx)
            alpha = math.atan2(py - opy, px - opx)
            if left:
                if theta < alpha:
                    theta += _TWO_PI
                beta = (theta - alpha) - _HALF_PI
                gamma = _HALF_PI
            else:
                if alpha < theta:
                    alpha += _TWO_PI
                beta = (alpha - theta) - _HALF_PI
                gamma = -_HALF_PI
            end_x = px + r * math.cos(alpha + gamma)
            end_y = py + r * math.sin(alpha + gamma)
            mid_x = opx + r * math.cos(alpha + gamma)
            mid_y = opy + r * math.sin(alpha + gamma)
            if beta < -_CONCAVE or beta > math.pi + _CONCAVE:
                concave = True
            elif beta > math.pi - _CONCAVE and self._front_is_arc() and (
                    (not left and self._front().turn > 0) or (left and self._front().turn < 0)):
                concave = True  # an "h" shape: stay above the round part rather than loop around it
            else:
                concave = False
            if not concave and beta > _CONCAVE:
                self.move_endpoint_and_flush(cx, cy)
                if not rapid:
                    self._enqueue_arc(0.0, mid_x, mid_y, opx, opy, -1 if left else 1, cz, src, line)
                else:
                    self._enqueue_line(True, 0.0, 0.0, mid_x, mid_y, cz, src, line)
                self.dequeue()
                self._set_endpoint(mid_x, mid_y)
            elif concave:
                if not self._front_is_arc():
                    half = (beta + math.pi) / 2.0
                    if half == 0.0:
                        raise CompError("a zero-degree inside corner cannot be cut with cutter compensation")
                    retreat = r / math.tan(half)
                    mx = cx + retreat * math.cos(theta + gamma)
                    my = cy + retreat * math.sin(theta + gamma)
                    self.move_endpoint_and_flush(mx, my)
                else:
                    prev = self._front()
                    oldrad = math.hypot(prev.cv - prev.v, prev.cu - prev.u)
                    base_dir = math.atan2(py - opy, px - opx)
                    th = base_dir + _HALF_PI if prev.turn > 0 else base_dir - _HALF_PI
                    phi = math.atan2(prev.cv - opy, prev.cu - opx)
                    inside = _inside(left, prev.turn)
                    oldrad_uncomp = oldrad + r if inside else oldrad - r
                    d = oldrad_uncomp * math.cos(th - phi)
                    if inside:
                        ratio = (d - r) / oldrad
                        self._check_fit(ratio, "arc to straight motion makes a corner the compensated tool cannot "
                                               "fit in without gouging")
                        angle = (-math.acos(ratio) if prev.turn > 0 else math.acos(ratio)) + th + math.pi
                    else:
                        ratio = (d + r) / oldrad
                        self._check_fit(ratio, "arc to straight motion makes a corner the compensated tool cannot "
                                               "fit in without gouging")
                        angle = (math.acos(ratio) if prev.turn > 0 else -math.acos(ratio)) + th + math.pi
                    self.move_endpoint_and_flush(prev.cu + oldrad * math.cos(angle), prev.cv + oldrad * math.sin(angle))
            else:
                self.dequeue()
                self._set_endpoint(cx, cy)
            self._enqueue_line(rapid, px - opx, py - opy, end_x, end_y, pz, src, line)
        self._set_current(end_x, end_y, pz)
        self.program = self._from_plane(px, py, pz)

    @staticmethod
    def _check_fit(ratio: float, message: str) -> None:
        if ratio > 1.0 or ratio < -1.0:
            raise CompError(message)

    # Arcs -----------------------------------------------------------------------------------------------
    def arc(self, ccw: bool, w: dict, target, turns: int, scale: float, absolute: bool, src, i: int) -> None:
        """A G2/G3 under compensation; ``w`` the line's words (I/J/K or R), ``target`` its end point."""
        interp = self.interp
        if getattr(interp, "arc_not_allowed", False):
            raise CompError("the move just after cutter compensation is turned off must be straight, not an arc")
        line = i + 1
        left = self.left
        r = self.radius
        ex, ey, ez = self._to_plane(target)
        letters = ("K", "I") if self.plane == 1 else ("I", "J")
        turn = (turns + 1) * (1 if ccw else -1)
        cx, cy, cz = self._current()
        if self.first:
            if math.hypot(ex - cx, ey - cy) <= r:
                raise CompError("the radius of the cutter compensation entry arc is not greater than the tool "
                                "radius")
            centre_x, centre_y = self._centre(w, letters, cx, cy, ex, ey, ccw, scale, absolute)
            if math.hypot(centre_x - cx, centre_y - cy) <= r and _inside(left, turn):
                raise CompError("the tool radius is not less than the arc radius with cutter compensation")
            if _inside(left, turn):
                gamma = math.atan2(centre_y - ey, centre_x - ex)
            else:
                gamma = math.atan2(ey - centre_y, ex - centre_x)
            self.first = False
            self.program = self._from_plane(ex, ey, ez)
            end_x = ex + r * math.cos(gamma)
            end_y = ey + r * math.sin(gamma)
            b_len = math.hypot(cy - end_y, cx - end_x) / 2.0
            ab_ang = math.atan2(centre_y - end_y, centre_x - end_x)
            a_ang = math.atan2(cy - end_y, cx - end_x) - ab_ang
            if abs(math.cos(a_ang)) < _EQUAL:
                raise CompError("the tool radius is not less than the arc radius with cutter compensation")
            c_len = b_len / math.cos(a_ang)
            centre_x = end_x + c_len * math.cos(ab_ang)
            centre_y = end_y + c_len * math.sin(ab_ang)
            if self.orientation not in (0, 9):
                self._enqueue_line(False, 0.0, 0.0, cx, cy, cz, src, line)
                self._set_endpoint(cx, cy)
            self._enqueue_arc(find_turn(cx, cy, centre_x, centre_y, turn, end_x, end_y), end_x, end_y, centre_x,
                              centre_y, turn, ez, src, line)
            self._set_current(end_x, end_y, ez)
            return
        opx, opy, opz = self._to_plane(self.program)
        centre_x, centre_y = self._centre(w, letters, opx, opy, ex, ey, ccw, scale, absolute)
        arc_radius = math.hypot(centre_x - ex, centre_y - ey)
        theta = math.atan2(cy - opy, cx - opx)
        theta = theta - _HALF_PI if left else theta + _HALF_PI
        delta = math.atan2(centre_y - opy, centre_x - opx)
        alpha = delta - _HALF_PI if ccw else delta + _HALF_PI
        beta = theta - alpha if left else alpha - theta
        if beta > 1.5 * math.pi:
            beta -= _TWO_PI
        elif beta < -_HALF_PI:
            beta += _TWO_PI
        if (left and ccw) or (not left and not ccw):
            gamma = math.atan2(centre_y - ey, centre_x - ex)
            if arc_radius <= r:
                raise CompError(f"the tool radius ({r:.4f} mm) is not less than the arc radius ({arc_radius:.4f} mm) "
                                f"with cutter compensation: the arc is too tight for the tool")
        else:
            gamma = math.atan2(ey - centre_y, ex - centre_x)
            delta = delta + math.pi
        new_end_x = ex + r * math.cos(gamma)
        new_end_y = ey + r * math.sin(gamma)
        sweep = find_turn(opx, opy, centre_x, centre_y, turn, ex, ey)
        inside = _inside(left, turn)
        if beta < -_CONCAVE or beta > math.pi + _CONCAVE or (abs(beta - math.pi) < _CONCAVE and not inside):
            if not self._front_is_arc():
                cyy = arc_radius * math.sin(beta - _HALF_PI)
                if inside:
                    dist = arc_radius - r
                    ratio = (cyy + r) / dist
                    self._check_fit(ratio, "arc move in a concave corner cannot be reached by the tool without "
                                           "gouging")
                    angle = theta + math.asin(ratio) if turn > 0 else theta - math.asin(ratio)
                else:
                    dist = arc_radius + r
                    ratio = (cyy - r) / dist
                    self._check_fit(ratio, "arc move in a concave corner cannot be reached by the tool without "
                                           "gouging")
                    angle = theta + math.pi - math.asin(ratio) if turn > 0 else theta + math.pi + math.asin(ratio)
                self.move_endpoint_and_flush(centre_x + dist * math.cos(angle), centre_y + dist * math.sin(angle))
            else:
                prev = self._front()
                oldrad = math.hypot(prev.cv - prev.v, prev.cu - prev.u)
                newrad = arc_radius - r if inside else arc_radius + r
                arc_cc = math.hypot(prev.cv - centre_y, prev.cu - centre_x)
                if oldrad == 0 or arc_cc == 0:
                    raise CompError("arc to arc motion is invalid because the arcs have the same centre")
                a = (oldrad ** 2 + arc_cc ** 2 - newrad ** 2) / (2 * oldrad * arc_cc)
                self._check_fit(a, "arc to arc motion makes a corner the compensated tool cannot fit in without "
                                   "gouging")
                pullback = math.acos(a)
                cc_dir = math.atan2(centre_y - prev.cv, centre_x - prev.cu)
                if _inside(left, prev.turn):
                    direction = cc_dir + pullback if turn > 0 else cc_dir - pullback
                else:
                    direction = cc_dir - pullback if turn > 0 else cc_dir + pullback
                self.move_endpoint_and_flush(prev.cu + oldrad * math.cos(direction),
                                             prev.cv + oldrad * math.sin(direction))
            self._enqueue_arc(sweep, new_end_x, new_end_y, centre_x, centre_y, turn, ez, src, line)
        elif beta > _CONCAVE:
            mid_x = opx + r * math.cos(delta)
            mid_y = opy + r * math.sin(delta)
            self.dequeue()
            self._enqueue_arc(0.0, mid_x, mid_y, opx, opy, -1 if left else 1, cz, src, line)
            self.dequeue()
            self._set_endpoint(mid_x, mid_y)
            self._enqueue_arc(sweep, new_end_x, new_end_y, centre_x, centre_y, turn, ez, src, line)
        else:
            self.dequeue()
            self._set_endpoint(cx, cy)
            self._enqueue_arc(sweep, new_end_x, new_end_y, centre_x, centre_y, turn, ez, src, line)
        self.program = self._from_plane(ex, ey, ez)
        self._set_current(new_end_x, new_end_y, ez)

    def _centre(self, w: dict, letters, su: float, sv: float, eu: float, ev: float, ccw: bool, scale: float,
                absolute: bool) -> tuple[float, float]:
        try:
            if "R" in w:
                return centre_r(su, sv, eu, ev, w["R"] * scale, not ccw, scale)
            a, b = letters
            if absolute:
                cu, cv = w[a] * scale, w[b] * scale
            else:
                cu, cv = su + w.get(a, 0.0) * scale, sv + w.get(b, 0.0) * scale
            centre_ijk(su, sv, eu, ev, cu, cv, scale)
            return cu, cv
        except ArcError as exc:
            raise CompError(str(exc)) from None
