"""Runs of plain lines, read all at once with numpy: the bulk of what CAM post-processors write.

A plain line holds only N, G, M, X, Y, Z, I, J, K, R, F, S, P, E and Q words, spaces and ordinary
comments: G0-G3 moves (I/J/K or R, P turns), G4 dwells, G17-G19, G20/G21, G90/G91, G90.1/G91.1,
spindle S/M3/M4/M5 and outputs M62-M65, M67, M68. The interpreter hands a run of them here, with
its state, when nothing special is in force (no cutter compensation, canned cycle, inverse time,
diameter mode or XY rotation, top level of the program). The result is the same as line by line
(a test holds the two readers to each other): positions, arc centres, feeds, spindle, outputs,
sources and warnings. Whenever a line is anything but ordinary (an unknown code, a missing feed, an
arc LinuxCNC would refuse, two words of one letter), the run stops before it and the interpreter
takes that line: its error messages stay in one place.
"""

from __future__ import annotations

import re
import warnings

import numpy as np

from flowmc.motion.gcode.arcs import _R_REACH_MM, _SPIRAL_ABS, _SPIRAL_REL, SPIRAL_WARN_MM
from flowmc.motion.path import PLANES

__all__ = ["plain_lines", "run_plain"]

_ALLOWED_BYTES = np.zeros(256, dtype=bool)
for _c in b"0123456789.+- \t\r" + b"GMXYZIJKRFSPEQN" + b"gmxyzijkrfspeqn":
    _ALLOWED_BYTES[_c] = True
_ALLOWED = bytes(_c for _c in range(256) if _ALLOWED_BYTES[_c])
_COMMENT = re.compile(r"\([^()\n]*\)")
_SEMICOLON = re.compile(r";[^\n]*")
_ACTIVE = re.compile(r"(?im)[(;]\s*(?:msg|debug|print|log|probe)")
_LINE_NUMBER = re.compile(rb"(?m)^N\d+(?:\.\d*)?")
_NUMBER_CHARS = b"0123456789.+-"
_LETTERS_TO_SPACE = bytes.maketrans(b"GMXYZIJKRFSPEQ\n", b" " * 15)
_SINGLE = "EFIJKPQRSXYZ"
# G code * 10 -> (group, value). Groups: motion 0, plane 1, distance 2, arc distance 3, units 4, dwell 5.
_G = {0: (0, 0), 10: (0, 10), 20: (0, 20), 30: (0, 30), 170: (1, 2), 180: (1, 1), 190: (1, 0), 900: (2, 0),
      910: (2, 1), 901: (3, 0), 911: (3, 1), 200: (4, 1), 210: (4, 0), 40: (5, 1)}
_G_GROUP = np.full(1000, -1, dtype=np.int64)
_G_VALUE = np.zeros(1000, dtype=np.int64)
for _code, (_grp, _val) in _G.items():
    _G_GROUP[_code], _G_VALUE[_code] = _grp, _val
# M code -> (group, value): spindle 0 (direction), io 1 (the code).
_M = {3: (0, 1), 4: (0, -1), 5: (0, 0), 62: (1, 62), 63: (1, 63), 64: (1, 64), 65: (1, 65), 67: (1, 67), 68: (1, 68)}
_M_GROUP = np.full(100, -1, dtype=np.int64)
_M_VALUE = np.zeros(100, dtype=np.int64)
for _code, (_grp, _val) in _M.items():
    _M_GROUP[_code], _M_VALUE[_code] = _grp, _val
_UV = np.array([PLANES[k][1] for k in range(3)])


def plain_lines(lines: list[str]) -> tuple[np.ndarray, list[str]]:
    """For each line: True when it is plain (only the words above, ordinary comments, nothing else);
    and the lines without their comments (what ``run_plain`` reads)."""
    text = "\n".join(lines)
    active = set()
    if "(" in text or ";" in text:
        for opener in "(;":  # str.find to each comment, where _ACTIVE is tried: a regex scan is ten times slower
            pos = text.find(opener)
            while pos >= 0:
                if _ACTIVE.match(text, pos):
                    active.add(pos)
                pos = text.find(opener, pos + 1)
        text = _SEMICOLON.sub("", _COMMENT.sub("", text))
    clean = text.split("\n")
    # What is left of a line once its allowed bytes are deleted: nothing, when it is plain.
    rest = np.frombuffer(text.encode("utf-8", errors="replace").translate(None, _ALLOWED), dtype=np.uint8)
    breaks = np.flatnonzero(rest == 10)
    out = np.diff(np.concatenate(([-1], breaks, [rest.size]))) == 1
    if active:
        starts = np.cumsum([0] + [len(s) + 1 for s in lines[:-1]])
        for pos in active:
            out[int(np.searchsorted(starts, pos, side="right")) - 1] = False
    return out, clean


def _tokenise(lines: list[str]):
    """Lines without comments -> (letters, values, line of each word, number of lines), or None when
    a line does not read."""
    text = "\n".join(lines)
    data = text.upper().encode("ascii", errors="replace").translate(None, b" \t\r")
    if b"N" in data:
        data = _LINE_NUMBER.sub(b"", data)
        if b"N" in data:
            return None
    letter_stream = data.translate(None, _NUMBER_CHARS)
    codes = np.frombuffer(letter_stream, dtype=np.uint8)
    newline = codes == 10
    n_lines = int(np.count_nonzero(newline)) + 1
    letters = codes[~newline]
    if letters.size == 0:
        return letters, np.zeros(0), np.zeros(0, dtype=np.int64), n_lines
    chars = np.frombuffer(data, dtype=np.uint8)
    after = chars[1:]
    if chars[-1] >= 65 or np.any((chars[:-1] >= 65) & ((after >= 65) | (after == 10))):
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            values = np.fromstring(data.translate(_LETTERS_TO_SPACE), sep=" ")
        except (ValueError, DeprecationWarning):
            return None
    if values.size != letters.size or not np.all(np.isfinite(values)):
        return None
    lines_of = np.cumsum(newline)[~newline]
    return letters, values, lines_of, n_lines


def _ffill(n: int, lines: np.ndarray, values, initial) -> np.ndarray:
    """The value in force on each of n lines, given the lines that set it (in order)."""
    values = np.asarray(values)
    init = np.asarray(initial)
    out = np.empty(n, dtype=np.result_type(values.dtype if values.size else init.dtype, init.dtype))
    if lines.size == 0:
        out[:] = initial
        return out
    last = np.full(n, -1, dtype=np.int64)
    last[lines] = np.arange(lines.size)
    np.maximum.accumulate(last, out=last)
    out[:] = values[np.maximum(last, 0)]
    out[last < 0] = initial
    return out


def _walk_incremental(end: np.ndarray, has: np.ndarray, value: np.ndarray, incremental: np.ndarray,
                      start: np.ndarray) -> None:
    """End points (m, 3) of moves some of which are incremental (G91), run by run of one distance
    mode. Increments add up one by one (``np.add.accumulate`` is sequential), so the sums round as
    the line-by-line interpreter's do."""
    m = len(end)
    bounds = [0, *(np.flatnonzero(incremental[1:] != incremental[:-1]) + 1).tolist(), m]
    cur = np.asarray(start, dtype=float)
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        h, v = has[lo:hi], value[lo:hi]
        if incremental[lo]:
            steps = np.empty((hi - lo + 1, 3))
            steps[0] = cur
            steps[1:] = np.where(h, v, 0.0)
            run = np.add.accumulate(steps, axis=0)[1:]
        else:
            last = np.where(h, np.arange(hi - lo)[:, None], -1)
            np.maximum.accumulate(last, axis=0, out=last)
            run = np.where(last >= 0, np.take_along_axis(v, np.maximum(last, 0), axis=0), cur)
        end[lo:hi] = run
        cur = run[-1]


def _first(mask: np.ndarray, n: int) -> int:
    return int(np.argmax(mask)) if mask.any() else n


def run_plain(interp, src, first: int, stop: int) -> int:
    """Read lines ``first``..``stop`` of ``src`` at once; return how many lines were consumed (a
    prefix of the run: the interpreter takes the first line this leaves), or -1 when some line of
    the run does not even read (the interpreter then takes the whole run line by line)."""
    cached = getattr(src, "tokens", None)
    if cached is not None and cached[1] == stop and cached[0] <= first:
        offset = first - cached[0]
        letters, values, lines, _ = cached[2]
        keep = lines >= offset
        letters, values, lines, n = letters[keep], values[keep], lines[keep] - offset, stop - first
    else:
        parsed = _tokenise(src.runs[1][first:stop])
        if parsed is None:
            return -1
        src.tokens = (first, stop, parsed)
        letters, values, lines, n = parsed
    order = np.argsort(letters, kind="stable")
    sorted_letters = letters[order]
    bad = n
    words = {}
    for letter in "GM" + _SINGLE:
        lo, hi = np.searchsorted(sorted_letters, [ord(letter), ord(letter) + 1])
        idx = order[lo:hi]  # a stable argsort keeps each letter in line order
        words[letter] = (lines[idx], values[idx])
    val = {}
    for letter in _SINGLE:
        wl, wv = words[letter]
        if wl.size > 1:
            twice = np.flatnonzero(wl[1:] == wl[:-1])
            if twice.size:
                bad = min(bad, int(wl[twice[0] + 1]))
        arr = np.full(n, np.nan)
        arr[wl] = wv
        val[letter] = arr
    groups = {}
    for letter, table, tvalue, scale, size, ngroups in (("G", _G_GROUP, _G_VALUE, 10.0, 1000, 6),
                                                         ("M", _M_GROUP, _M_VALUE, 1.0, 100, 2)):
        wl, wv = words[letter]
        code = np.rint(wv * scale)
        ok = (np.abs(wv * scale - code) < 1e-3) & (code >= 0) & (code < size)
        code = np.where(ok, code, 0).astype(np.int64)
        grp = np.where(ok, table[code], -1)
        if np.any(grp < 0):
            bad = min(bad, int(wl[np.argmax(grp < 0)]))
        key = np.sort(wl * 8 + np.maximum(grp, 0))
        if np.any(key[1:] == key[:-1]):
            bad = min(bad, int(key[1:][key[1:] == key[:-1]][0] // 8))
        for g in range(ngroups):
            sel = grp == g
            groups[letter, g] = (wl[sel], tvalue[code[sel]])
    return _interpret(interp, src, first, n, val, groups, bad)


def _interpret(interp, src, first: int, n: int, val: dict, groups: dict, bad: int) -> int:
    has = {k: ~np.isnan(v) for k, v in val.items()}
    none = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))
    motion_l, motion_v = groups.get(("G", 0), none)
    start_mode = interp.motion if interp.motion in (0, 10, 20, 30, 800) else -1
    mode = _ffill(n, motion_l, motion_v, start_mode)
    plane = _ffill(n, *groups.get(("G", 1), none), interp.plane)
    incremental = _ffill(n, *groups.get(("G", 2), none), int(interp.incremental)) > 0
    arc_incremental = _ffill(n, *groups.get(("G", 3), none), int(interp.arc_incremental)) > 0
    units_l, units_v = groups.get(("G", 4), none)
    inch = _ffill(n, units_l, units_v, int(interp.scale != 1.0)) > 0
    if np.any(inch) and interp.scale not in (1.0, 25.4):
        return 0
    scale = np.where(inch, 25.4, 1.0)
    scale_before = np.concatenate([[interp.scale], scale[:-1]])
    dwell = np.zeros(n, dtype=bool)
    dwell[groups.get(("G", 5), none)[0]] = True
    spin_l, spin_v = groups.get(("M", 0), none)
    direction = _ffill(n, spin_l, spin_v, interp.spindle_dir)
    io_l, io_v = groups.get(("M", 1), none)
    io = np.zeros(n, dtype=np.int64)
    io[io_l] = io_v
    explicit = np.zeros(n, dtype=bool)
    explicit[motion_l] = True
    has_axis = has["X"] | has["Y"] | has["Z"]
    has_ijk = has["I"] | has["J"] | has["K"]
    arc_mode = (mode == 20) | (mode == 30)
    move = (mode >= 0) & (mode != 800) & (explicit | has_axis | (arc_mode & has_ijk))
    arc = move & arc_mode
    # Lines the line-by-line reader must take (an error to explain, or something unusual).
    trouble = (mode < 0) | ((mode == 800) & has_axis) | (has_ijk & ~arc) | (has["R"] & ~arc)
    trouble |= arc & (has["R"] == has_ijk)
    for normal, letter in ((2, "K"), (1, "J"), (0, "I")):
        trouble |= arc & (plane == normal) & has[letter]
    absolute_arc = arc & ~arc_incremental & ~has["R"]
    for normal, (a, b) in ((2, "IJ"), (1, "KI"), (0, "JK")):
        trouble |= absolute_arc & (plane == normal) & ~(has[a] & has[b])
    f, s_word, p = val["F"], val["S"], val["P"]
    trouble |= (f < 0) | (s_word < 0)
    io_p = (io >= 62) & (io <= 65)
    io_analog = (io == 67) | (io == 68)
    p_users = dwell.astype(int) + arc + io_p
    trouble |= has["P"] & (p_users != 1)
    trouble |= dwell & (~has["P"] | (p < 0))
    trouble |= arc & has["P"] & ~((p >= 1) & (p == np.floor(p)))
    trouble |= io_p & ~(has["P"] & (p >= 0) & (p == np.floor(p)))
    e, q = val["E"], val["Q"]
    trouble |= io_analog & ~(has["E"] & has["Q"] & (e >= 0) & (e == np.floor(e)))
    trouble |= (has["E"] | has["Q"]) & ~io_analog
    f_lines = np.flatnonzero(has["F"])
    feed = _ffill(n, f_lines, f[f_lines] * scale_before[f_lines] / 60.0, interp.feed)
    trouble |= move & (mode != 0) & ~(feed > 0)
    stop = min(bad, _first(trouble, n))
    if stop == 0:
        return 0
    move[stop:] = False
    arc[stop:] = False
    s_lines = np.flatnonzero(has["S"])
    speed = _ffill(n, s_lines, s_word[s_lines], interp.speed)
    spindle = speed * direction + 0.0

    # Where each move ends (program coordinates, mm).
    mi = np.flatnonzero(move)
    m = mi.size
    start0 = np.array([interp.x, interp.y, interp.z])
    end = np.empty((m, 3))
    minc = incremental[mi]
    msc = scale[mi]
    h3 = np.column_stack([has[letter][mi] for letter in "XYZ"])
    v3 = np.column_stack([val[letter][mi] for letter in "XYZ"]) * msc[:, None]
    if np.any(h3 & minc[:, None]):
        _walk_incremental(end, h3, v3, minc, start0)
    else:
        for axis in range(3):
            h = h3[:, axis]
            end[:, axis] = _ffill(m, np.flatnonzero(h), v3[h, axis], float(start0[axis]))
    start = np.vstack([start0[None, :], end[:-1]]) if m else np.zeros((0, 3))

    # Arc centres and LinuxCNC's acceptance rule.
    ai_local = np.flatnonzero(arc[mi])
    ai = mi[ai_local]
    a_start, a_end = start[ai_local], end[ai_local]
    normal = plane[ai]
    uv = _UV[normal]
    rows = np.arange(ai.size)
    iu, iv = uv[:, 0], uv[:, 1]
    su, sv = a_start[rows, iu], a_start[rows, iv]
    eu, ev = a_end[rows, iu], a_end[rows, iv]
    a_scale = scale[ai]
    offsets = np.column_stack([val["I"][ai], val["J"][ai], val["K"][ai]]) * a_scale[:, None]
    wu, wv_ = offsets[rows, iu], offsets[rows, iv]
    absolute = ~arc_incremental[ai]
    cu = np.where(absolute, wu, su + np.nan_to_num(wu))
    cv = np.where(absolute, wv_, sv + np.nan_to_num(wv_))
    r_form = has["R"][ai]
    refused = np.zeros(ai.size, dtype=bool)
    with np.errstate(all="ignore"):
        if np.any(r_form):
            radius = val["R"][ai] * a_scale
            du, dv = eu - su, ev - sv
            chord = np.sqrt(du * du + dv * dv)
            half = chord / 2.0
            refused |= r_form & (((du == 0) & (dv == 0)) | (half - np.abs(radius) > _R_REACH_MM) | (radius == 0))
            ratio = np.clip(half / np.abs(radius), 0.0, 1.0)
            ratio[ratio > 1.0 - 1e-12] = 1.0
            offset = np.abs(radius) * np.sqrt((1.0 - ratio) * (1.0 + ratio))
            right = (mode[ai] == 20) == (radius > 0)
            sign = np.where(right, -1.0, 1.0)
            nu, nv = -dv / chord, du / chord
            cu = np.where(r_form, (su + eu) / 2.0 + sign * offset * nu, cu)
            cv = np.where(r_form, (sv + ev) / 2.0 + sign * offset * nv, cv)
        r0 = np.sqrt((su - cu) ** 2 + (sv - cv) ** 2)
        r1 = np.sqrt((eu - cu) ** 2 + (ev - cv) ** 2)
        diff = np.abs(r1 - r0)
        tol = np.where(a_scale == 1.0, _SPIRAL_ABS[1.0], _SPIRAL_ABS[25.4])
        units = diff / a_scale
        ijk = ~r_form
        refused |= ijk & ((r0 < 1e-9) | (r1 < 1e-9) | (units > 100.0 * tol)
                          | ((diff / np.maximum(r0, r1) > _SPIRAL_REL) & (units > tol)))
    if refused.any():
        stop = int(ai[np.argmax(refused)])
        if stop == 0:
            return 0
        keep_moves = int(np.searchsorted(mi, stop))
        keep_arcs = int(np.searchsorted(ai, stop))
        mi, end, m = mi[:keep_moves], end[:keep_moves], keep_moves
        ai_local, ai, a_start, normal = ai_local[:keep_arcs], ai[:keep_arcs], a_start[:keep_arcs], normal[:keep_arcs]
        rows, iu, iv, cu, cv = rows[:keep_arcs], iu[:keep_arcs], iv[:keep_arcs], cu[:keep_arcs], cv[:keep_arcs]
        diff, ijk = diff[:keep_arcs], ijk[:keep_arcs]
        has = {k: v.copy() for k, v in has.items()}
        has["P"][stop:] = False
    centre = a_start.copy()
    centre[rows, iu] = cu
    centre[rows, iv] = cv
    turns = np.where(has["P"][ai], val["P"][ai], 1.0).astype(np.int64) - 1
    spiral = ijk & (diff > SPIRAL_WARN_MM)

    # Into the canon, in LinuxCNC's order on each line: outputs, dwell, then the move.
    shift = np.array(interp.to_machine(0.0, 0.0, 0.0))
    m_end = end + shift
    m_centre = centre + shift
    m_feed = feed[mi]
    rapid = mode[mi] == 0
    m_spindle = spindle[mi]
    canon = interp.canon
    file = src.index
    spiral_lines = ai[spiral]
    warn_at = np.zeros(n, dtype=bool)
    warn_at[spiral_lines] = True
    special = np.flatnonzero(dwell | (io > 0) | warn_at)
    special = special[special < stop]
    done_moves = 0
    arc_pos = 0
    for line in special.tolist():
        k = int(np.searchsorted(mi, line))
        if k > done_moves:
            a_hi = int(np.searchsorted(ai_local, k))
            canon.extend_moves(m_end[done_moves:k], rapid[done_moves:k], m_feed[done_moves:k],
                               m_spindle[done_moves:k], file, mi[done_moves:k] + (first + 1),
                               ai_local[arc_pos:a_hi] - done_moves, m_centre[arc_pos:a_hi], normal[arc_pos:a_hi],
                               mode[ai[arc_pos:a_hi]] == 30, turns[arc_pos:a_hi])
            arc_pos, done_moves = a_hi, k
        code = int(io[line])
        if code in (62, 63, 64, 65):
            canon.set_output(int(p[line]), code in (62, 64), code in (62, 63), file, first + line + 1)
        elif code in (67, 68):
            canon.set_analog(int(e[line]), float(q[line]), code == 67, file, first + line + 1)
        if dwell[line]:
            canon.dwell(float(p[line]), float(feed[line]), float(spindle[line]), file, first + line + 1)
        if warn_at[line]:
            a = int(np.flatnonzero(ai == line)[0])
            name = "G3" if mode[line] == 30 else "G2"
            interp.warn(src.where(first + line), f"{name} end point is {diff[a]:.6f} mm off the circle through its "
                                                 "start; accepted as LinuxCNC accepts it (the arc blends its radius: "
                                                 "a spiral)")
    if done_moves < m:
        canon.extend_moves(m_end[done_moves:], rapid[done_moves:], m_feed[done_moves:], m_spindle[done_moves:], file,
                           mi[done_moves:] + (first + 1), ai_local[arc_pos:] - done_moves, m_centre[arc_pos:],
                           normal[arc_pos:], mode[ai[arc_pos:]] == 30, turns[arc_pos:])

    # The interpreter's state after the run (its first ``stop`` lines).
    last = stop - 1
    if m:
        interp.x, interp.y, interp.z = (float(v) for v in end[-1])
        interp.mx, interp.my, interp.mz = (float(v) for v in m_end[-1])
        interp.cycle_il = None
    if mode[last] >= 0:
        interp.motion = int(mode[last])
    interp.plane = int(plane[last])
    interp.incremental = bool(incremental[last])
    interp.arc_incremental = bool(arc_incremental[last])
    f_lines = f_lines[f_lines < stop]
    units_l = units_l[units_l < stop]
    if f_lines.size or units_l.size:
        interp.scale = float(scale[last])
        interp.feed = float(feed[last])
        interp.feed_word = float(f[f_lines[-1]]) if (f_lines.size and (not units_l.size or units_l[-1] <= f_lines[-1])) \
            else interp.feed * 60.0 / interp.scale
    interp.speed = float(speed[last])
    interp.spindle_dir = int(direction[last])
    return stop
