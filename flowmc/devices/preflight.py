"""Pre-flight: check a whole program against the machine before a device is sent anything.

The XY plotter report (004_*.txt) checks for out-of-bounds moves while drawing; flowmc does the same
check before motion, so a bad program moves nothing. Every check is vectorised over the whole
program; the earliest violation is reported as a ``LimitError`` naming the segment as the user knows
it (1-based, with where it came from: ``describe_segment`` over the program's ``segment_names``), the
time, the axis and the value, e.g. ``segment 5 (row 4): X = -60.05 mm beyond soft limit min -60 mm at
t=6.712 s``.

Checked, per axis: soft limits; velocity (|dp|/T <= vmax); acceleration (|d2p|/T^2 <= amax with
1 % slack for sampling, as the reference README measures it); step rate (pulses per period / T
<= max_step_rate, counting pulses the way the card does: by rounding positions to steps). Signals:
digital output channels and levels, PWM frequency and duty, DA volts and spindle rpm against the
card's ranges, the tool (pen) state being 0 or 1, and that the shared PWM/DA terminal is set for
what the program uses.

Step streams (``Steps``) are checked for soft limits and, when timed, for step rate and velocity
over windows of one period; their sampled acceleration is pulse quantisation noise and is not
checked. Untimed streams are paced by the device, so only their soft limits are checked here; they
have no seconds, so their signal times are tick indices (the ``Steps`` convention) and a violation
is reported ``at tick N``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flowmc.devices.ranges import CARD_6050, CardRanges
from flowmc.errors import DeviceError, LimitError
from flowmc.motion.limits import AxisLimits
from flowmc.motion.machine import Machine
from flowmc.motion.path import describe_segment
from flowmc.motion.table import Table
from flowmc.motion.trajectory import Signal, Steps, Trajectory

__all__ = ["preflight", "PreflightReport", "program_signals", "axis_columns"]

#: Slack on the acceleration limit for the sampled second difference (reference README: 1.01 x).
ACCEL_SLACK = 0.01
_TOL = 1e-9  # relative tolerance for floating-point noise on velocity, step rate and soft limits


@dataclass(frozen=True)
class PreflightReport:
    """What the program asks of each axis: travel, peak velocity, acceleration and step rate."""

    axes: tuple[str, ...]
    duration: float
    low: np.ndarray
    high: np.ndarray
    peak_velocity: np.ndarray
    peak_accel: np.ndarray
    peak_step_rate: np.ndarray
    signal_events: int

    def table(self, machine: Machine) -> Table:
        cols = [machine.axes[machine.names.index(a)] for a in self.axes]
        return Table({
            "axis": list(self.axes),
            "min_mm": self.low, "max_mm": self.high,
            "soft_min_mm": [c.min for c in cols], "soft_max_mm": [c.max for c in cols],
            "peak_v_mm_s": self.peak_velocity, "vmax_mm_s": [c.vmax for c in cols],
            "peak_a_mm_s2": self.peak_accel, "amax_mm_s2": [c.amax for c in cols],
            "peak_step_hz": self.peak_step_rate, "max_step_hz": [c.max_step_rate for c in cols],
        })


def axis_columns(axes, machine: Machine) -> np.ndarray:
    """Machine column of each named axis; DeviceError if an axis is not on the machine."""
    missing = [a for a in axes if a not in machine.names]
    if missing:
        raise DeviceError(f"axis {', '.join(missing)} is not on the machine (its axes: {', '.join(machine.names)})",
                          where="pre-flight")
    return np.array([machine.names.index(a) for a in axes], dtype=int)


def program_signals(motion, signals: Signal | None) -> Signal:
    """The program's own signals merged with extra ones (e.g. from a Digital I/O node)."""
    own = motion.signals if isinstance(motion, (Trajectory, Steps)) else Signal()
    return own if signals is None or len(signals) == 0 else own.merged(signals)


class _Found:
    """The earliest violation seen so far: row, then a message to build if it wins.

    ``names``: the program's segment names; ``ticks``: the program is an untimed step stream, whose
    times are tick indices.
    """

    def __init__(self, names: tuple[str, ...] = (), ticks: bool = False):
        self.row = None
        self.build = None
        self.names = names
        self.ticks = ticks

    def offer(self, row: int, build) -> None:
        if self.row is None or row < self.row:
            self.row, self.build = row, build


def _first(mask: np.ndarray) -> tuple[int, int] | None:
    """(row, column) of the first True in a 2-D mask, scanning rows first; None if none."""
    rows = np.flatnonzero(mask.any(axis=1))
    if not len(rows):
        return None
    r = int(rows[0])
    return r, int(np.flatnonzero(mask[r])[0])


def _fmt(x: float) -> str:
    return f"{x:,.6g}" if abs(x) >= 1e3 else f"{x:.6g}"


def _raise(segment: int, names: tuple[str, ...], t: float, message: str, ticks: bool = False, **details) -> None:
    """Raise LimitError for path segment index ``segment`` (0-based), named as the user counts it."""
    at = f"at tick {t:g}" if ticks else f"at t={t:.3f} s"
    err = LimitError(f"{message} {at}", where=describe_segment(segment, names))
    source = names[segment] if 0 <= segment < len(names) else ""
    err.details = {"segment": segment + 1, "source": source, "t": t, **details}
    raise err


def preflight(motion, machine: Machine, signals: Signal | None = None, *, ranges: CardRanges = CARD_6050,
              accel_slack: float = ACCEL_SLACK) -> PreflightReport:
    """Check ``motion`` (a Trajectory or Steps) and its signals; raise LimitError on the first violation.

    Returns a report of what the program needs when it passes. Times in messages are program
    time (row k of a trajectory is t = k T). ``LimitError.details`` holds segment (the 1-based number
    the message shows, not the 0-based ``motion.segment`` index), source (where that segment came
    from, "" when unknown), t, axis, value, limit.

    Example
    -------
    >>> import numpy as np
    >>> from flowmc.motion.machine import Machine
    >>> from flowmc.motion.trajectory import Trajectory
    >>> m = Machine(period=0.001)
    >>> tr = Trajectory(np.zeros((3, 3)), 0.001)
    >>> preflight(tr, m).duration
    0.002
    """
    if isinstance(motion, Trajectory):
        rows_t, seg, pos, period, cols = _trajectory_rows(motion, machine)
        found = _Found(motion.segment_names)
        _check_travel(found, pos, cols, machine, seg, rows_t, motion.axes)
        v, a, rate = _check_dynamics(found, pos, period, cols, machine, seg, rows_t, motion.axes, accel_slack)
    elif isinstance(motion, Steps):
        rows_t, seg, pos, period, cols = _steps_rows(motion, machine)
        found = _Found(motion.segment_names, ticks=motion.tick <= 0)
        _check_travel(found, pos, cols, machine, seg, rows_t, motion.axes)
        v, rate = _check_pulses(found, motion, cols, machine, seg, rows_t)
        a = np.zeros(len(cols))
    else:
        raise DeviceError(f"a device runs a Trajectory or Steps, not {type(motion).__name__}", where="pre-flight")
    sig = program_signals(motion, signals)
    _check_signals(found, sig, ranges, rows_t, seg)
    if found.row is not None:
        found.build()
    duration = float(rows_t[-1]) if len(rows_t) and not found.ticks else 0.0
    return PreflightReport(tuple(motion.axes), duration, pos.min(axis=0), pos.max(axis=0), v, a, rate, len(sig))


def _trajectory_rows(tr: Trajectory, machine: Machine):
    cols = axis_columns(tr.axes, machine)
    pos = np.asarray(tr.positions)
    if len(pos) == 0:
        raise DeviceError("the trajectory is empty", where="pre-flight")
    bad = _first(~np.isfinite(pos))
    if bad is not None:
        r, c = bad
        _raise(int(tr.segment[r]), tr.segment_names, r * tr.period, f"{tr.axes[c]} position is not a number",
               axis=tr.axes[c], value=float(pos[r, c]), limit=None)
    return tr.times, tr.segment, pos, tr.period, cols


def _steps_rows(st: Steps, machine: Machine):
    cols = axis_columns(st.axes, machine)
    step_mm = machine.column("step_mm")[cols]
    off = ~np.isclose(st.step_mm, step_mm, rtol=1e-9, atol=0.0)
    if off.any():
        c = int(np.flatnonzero(off)[0])
        raise DeviceError(f"the step stream's pulse equivalent for {st.axes[c]} is {st.step_mm[c]} mm but the "
                          f"machine's is {step_mm[c]} mm", where="pre-flight")
    pos = st.positions()
    seg = np.concatenate([st.segment[:1], st.segment]) if len(st) else np.zeros(1, dtype=int)
    rows_t = np.arange(len(pos)) * (st.tick if st.tick > 0 else 1.0)  # untimed: tick indices
    return rows_t, seg, pos, st.tick, cols


def _check_travel(found: _Found, pos, cols, machine: Machine, seg, rows_t, axes) -> None:
    lo, hi = machine.column("min")[cols], machine.column("max")[cols]
    span = hi - lo
    for mask, bound, word in ((pos > hi + _TOL * span, hi, "max"), (pos < lo - _TOL * span, lo, "min")):
        hit = _first(mask)
        if hit is not None:
            r, c = hit
            found.offer(r, lambda r=r, c=c, bound=bound, word=word: _raise(
                int(seg[r]), found.names, float(rows_t[r]),
                f"{axes[c]} = {_fmt(pos[r, c])} mm beyond soft limit {word} {_fmt(bound[c])} mm", found.ticks,
                axis=axes[c], value=float(pos[r, c]), limit=float(bound[c])))


def _check_dynamics(found: _Found, pos, period, cols, machine: Machine, seg, rows_t, axes, slack):
    n = pos.shape[1]
    lim = AxisLimits.of(machine, axes)
    vmax, amax = lim.vmax, lim.amax
    rmax, step = machine.column("max_step_rate")[cols], machine.column("step_mm")[cols]
    v = np.diff(pos, axis=0) / period
    a = np.diff(v, axis=0) / period
    rate = np.abs(np.diff(np.rint(pos / step), axis=0)) / period
    checks = (
        (np.abs(v), vmax * (1 + _TOL), 1, "velocity", "mm/s", vmax),
        (np.abs(a), amax * (1 + slack), 1, "acceleration", "mm/s^2", amax),
        (rate, rmax * (1 + _TOL), 1, "step rate", "Hz", rmax),
    )
    for values, bound, shift, name, unit, limit in checks:
        _offer_over_limit(found, values, bound, shift, axes, name, unit, limit, seg, rows_t)
    peak = lambda x: np.abs(x).max(axis=0) if len(x) else np.zeros(n)  # noqa: E731
    return peak(v), peak(a), peak(rate)


def _offer_over_limit(found: _Found, values, bound, shift: int, axes, name: str, unit: str, limit, seg, rows_t) -> None:
    """Offer the first value over ``bound`` (row ``r`` of ``values`` is program row ``r + shift``)."""
    hit = _first(values > bound)
    if hit is None:
        return
    r, c = hit
    row = r + shift
    found.offer(row, lambda: _raise(
        int(seg[row]), found.names, float(rows_t[row]),
        f"{axes[c]} {name} {_fmt(values[r, c])} {unit} over the limit {_fmt(limit[c])} {unit}",
        axis=axes[c], value=float(values[r, c]), limit=float(limit[c])))


def _check_pulses(found: _Found, st: Steps, cols, machine: Machine, seg, rows_t):
    n = len(cols)
    if st.tick <= 0 or len(st) == 0:
        return np.zeros(n), np.zeros(n)
    vmax, rmax = AxisLimits.of(machine, st.axes).vmax, machine.column("max_step_rate")[cols]
    window = max(machine.period, st.tick)
    k = max(int(round(window / st.tick)), 1)  # rows per window
    window = k * st.tick
    signed = np.vstack([np.zeros((1, n)), np.cumsum(st.steps, axis=0, dtype=np.int64)])
    absolute = np.vstack([np.zeros((1, n)), np.cumsum(np.abs(st.steps), axis=0, dtype=np.int64)])
    if len(signed) <= k:  # shorter than one window: the whole stream is the window
        k = len(signed) - 1
    rate = (absolute[k:] - absolute[:-k]) / window
    vel = np.abs(signed[k:] - signed[:-k]) * st.step_mm / window
    for values, limit, name, unit in ((rate, rmax, "step rate", "Hz"), (vel, vmax, "velocity", "mm/s")):
        _offer_over_limit(found, values, limit * (1 + _TOL), k, st.axes, name, unit, limit, seg, rows_t)
    return vel.max(axis=0), rate.max(axis=0)


_SINGLE = ("pwm_freq", "pwm_duty", "da", "spindle_rpm", "tool")


def _check_signals(found: _Found, sig: Signal, ranges: CardRanges, rows_t, seg) -> None:
    if len(sig) == 0:
        return
    t, kind, ch, val = sig.t, sig.kind, sig.channel, sig.value
    step = rows_t[1] - rows_t[0] if len(rows_t) > 1 else 0.0
    if step > 0:
        finite_t = np.where(np.isfinite(t), t, 0.0)
        row = np.clip(np.ceil(finite_t / step - 1e-9), 0, len(rows_t) - 1).astype(int)
    else:
        row = np.zeros(len(t), dtype=int)
    pwm_lo, pwm_hi = ranges.pwm_hz
    d_lo, d_hi = ranges.duty_pct
    v_lo, v_hi = ranges.da_volts
    is_ = lambda k: kind == k  # noqa: E731
    problems = [
        (~np.isfinite(t) | (t < 0) | ~np.isfinite(val), lambda i: f"signal {kind[i]} at t={t[i]} s = {val[i]}: "
                                                                  "time and value must be finite, time >= 0"),
        (is_("dout") & ((ch < 1) | (ch > ranges.outputs)),
         lambda i: f"digital output {ch[i]} does not exist (outputs 1-{ranges.outputs})"),
        (is_("dout") & ~np.isin(val, (0.0, 1.0)),
         lambda i: f"digital output {ch[i]} set to {_fmt(val[i])}, not 0 or 1"),
        (is_("tool") & ~np.isin(val, (0.0, 1.0)),
         lambda i: f"tool set to {_fmt(val[i])}, not 1 (down) or 0 (up)"),
        (np.isin(kind, _SINGLE) & ~np.isin(ch, (0, 1)),
         lambda i: f"{kind[i]} channel {ch[i]}: the card has one (channel 1)"),
        (is_("pwm_freq") & ((val < pwm_lo) | (val > pwm_hi)),
         lambda i: f"PWM frequency {_fmt(val[i])} Hz outside {_fmt(pwm_lo)}-{_fmt(pwm_hi)} Hz"),
        (is_("pwm_duty") & ((val < d_lo) | (val > d_hi)),
         lambda i: f"PWM duty {_fmt(val[i])} % outside {_fmt(d_lo)}-{_fmt(d_hi)} %"),
        (is_("da") & ((val < v_lo) | (val > v_hi)),
         lambda i: f"DA {_fmt(val[i])} V outside {_fmt(v_lo)}..{_fmt(v_hi)} V"),
        (is_("spindle_rpm") & (np.abs(val) > ranges.spindle_rpm_max),
         lambda i: f"spindle {_fmt(val[i])} rpm beyond {_fmt(ranges.spindle_rpm_max)} rpm"),
    ]
    if ranges.analog == "da":
        problems.append((np.isin(kind, ("pwm_freq", "pwm_duty")),
                         lambda i: f"{kind[i]}: the shared PWM/DA terminal is set to DA; set it to PWM"))
    elif ranges.analog == "pwm":
        problems.append((np.isin(kind, ("da", "spindle_rpm")),
                         lambda i: f"{kind[i]}: the shared PWM/DA terminal is set to PWM; set it to DA"))
    for mask, text in problems:
        idx = np.flatnonzero(mask)
        if len(idx):
            i = int(idx[0])
            r = int(row[i])
            found.offer(r, lambda i=i, r=r, text=text: _raise(
                int(seg[r]), found.names, float(t[i]) if np.isfinite(t[i]) else 0.0, text(i), found.ticks,
                axis="", value=float(val[i]), limit=None, signal=int(i)))
