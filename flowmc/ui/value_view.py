"""How a value looks in the editor's probes and front-panel indicators: a few lines of text (escaped
markdown) and, for a path, a trajectory or a numeric table, a small SVG chart. No viser here."""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from flowmc.motion.path import Path
from flowmc.motion.table import Table
from flowmc.motion.trajectory import Trajectory
from flowmc.runtime.executor import summarize
from flowmc.ui.text import escape_html, escape_md, md

__all__ = ["describe", "short", "chart", "unit_of", "TABLE_ROWS"]

TABLE_ROWS = 5  # rows of a table shown
_PLOT_POINTS = 400
_UNIT_AT_END = re.compile(r"\(([^()]{1,12})\)\s*$")
_SUFFIX_UNITS = (("_mm_s", "mm/s"), ("_pct", "%"), ("_percent", "%"), ("_mm", "mm"), ("_s", "s"), ("_rpm", "rpm"),
                 ("_deg", "°"), ("_hz", "Hz"))


def unit_of(name: str, description: str = "") -> str:
    """A number's unit from its description's last parentheses ("... (s)"), else its name ("cycle_time_s")."""
    found = _UNIT_AT_END.search(description or "")
    if found:
        return found.group(1)
    return next((unit for suffix, unit in _SUFFIX_UNITS if name.lower().endswith(suffix)), "")


def _number(value: float) -> str:
    return f"{value:.6g}"


def _cell(value: Any) -> str:
    return _number(float(value)) if isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(
        value, bool) else escape_md(value, 40)


def _table(table: Table) -> str:
    rows = table.to_rows()[:TABLE_ROWS]
    head = "| " + " | ".join(escape_md(n, 30) for n in table.names) + " |\n|" + "---|" * len(table.names) + "\n"
    body = "".join("| " + " | ".join(_cell(r[n]) for n in table.names) + " |\n" for r in rows)
    more = md("\n{} rows in all", len(table)) if len(table) > TABLE_ROWS else ""
    return head + body + more


def _speeds(traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    pos = np.asarray(traj.positions, dtype=float)
    if len(pos) < 2:
        return np.zeros(0), np.zeros(0)
    v = np.linalg.norm(np.diff(pos, axis=0), axis=1) / traj.period
    return np.arange(1, len(pos)) * traj.period, v


def _log_summary(value: Any) -> dict | None:
    """A device log's summary (the editor imports no device module: a log is known by its summary)."""
    summary = summarize(value)
    return summary if isinstance(summary, dict) and summary.get("type") == "Log" else None


def short(value: Any, unit: str = "") -> str:
    """One line of plain text for the canvas: ``5 mm``, ``Path · 71 seg · 814.35 mm``."""
    if value is None:
        return "(not run)"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float, np.floating, np.integer)):
        return _number(float(value)) + (f" {unit}" if unit else "")
    if isinstance(value, str):
        return value if len(value) <= 30 else value[:29] + "…"
    if isinstance(value, Table):
        return f"Table · {len(value)} rows · {', '.join(value.names[:4])}"
    if isinstance(value, Path):
        return f"Path · {len(value)} seg · {_number(value.length)} mm"
    if isinstance(value, Trajectory):
        _t, v = _speeds(value)
        return f"Trajectory · {_number(value.duration)} s · peak {_number(float(v.max()) if len(v) else 0.0)} mm/s"
    log = _log_summary(value)
    if log is not None:
        return f"Log · {log['outcome']} · {_number(log['duration_s'])} s"
    return type(value).__name__


def describe(value: Any, unit: str = "") -> str:
    """A value as escaped markdown: a number (with its unit) or text, a table's first rows, a path's
    segments, length and box, a trajectory's cycle time and peak speed, a log's summary."""
    if value is None:
        return "no value (not run yet)"
    if isinstance(value, bool):
        return md("**{}**", "true" if value else "false")
    if isinstance(value, (int, float, np.floating, np.integer)):
        return md("**{}**{}", _number(float(value)), f" {unit}" if unit else "")
    if isinstance(value, str):
        return md("“{}”", value)
    if isinstance(value, Table):
        return _table(value)
    if isinstance(value, Path):
        lo, hi = value.bbox() if len(value) else (np.zeros(3), np.zeros(3))
        return md("Path: {} segments · length {} mm · box [{}] to [{}]", len(value), _number(value.length),
                  ", ".join(_number(v) for v in lo), ", ".join(_number(v) for v in hi))
    if isinstance(value, Trajectory):
        _t, v = _speeds(value)
        return md("Trajectory: cycle time {} s · peak speed {} mm/s · {} setpoints at T = {} s",
                  _number(value.duration), _number(float(v.max()) if len(v) else 0.0), len(value.positions),
                  _number(value.period))
    s = _log_summary(value)
    if s is not None:
        lines = [md("Log: {} on {} · {} s · ends at [{}] · {} I/O changes", s["outcome"], s["device"],
                    _number(s["duration_s"]), ", ".join(_number(v) for v in s["end_position"]), s["changes"])]
        lines += [md("- {}", e) for e in s["events"][:4]]
        return "\n".join(lines)
    summary = summarize(value)
    if isinstance(summary, dict):
        return md("{}", ", ".join(f"{k}: {v}" for k, v in summary.items()))
    return md("{}", summary)


def _thin(*columns: np.ndarray) -> tuple[np.ndarray, ...]:
    n = len(columns[0])
    if n <= _PLOT_POINTS:
        return columns
    keep = np.linspace(0, n - 1, _PLOT_POINTS).astype(int)
    return tuple(c[keep] for c in columns)


_SERIES = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e")
_W, _H, _PAD_L, _PAD_B, _PAD = 300, 170, 46, 30, 8


def _series(value: Any) -> tuple[list[tuple[str, np.ndarray, np.ndarray]], str, str, bool] | None:
    """(named x/y series, x title, y title, equal axes) for a path (XY), a trajectory (speed over time) or a
    table with two numeric columns or more (the others over the first); None for anything else."""
    if isinstance(value, Path) and len(value):
        pts, _seg = value.sample(0.05)
        x, y = _thin(pts[:, 0], pts[:, 1])
        return [("XY", x, y)], "X (mm)", "Y (mm)", True
    if isinstance(value, Trajectory):
        t, v = _thin(*_speeds(value))
        return ([("speed", t, v)], "t (s)", "speed (mm/s)", False) if len(t) else None
    if isinstance(value, Table) and len(value) > 1:
        numeric = [n for n in value.names if np.issubdtype(np.asarray(value[n]).dtype, np.number)]
        if len(numeric) < 2:
            return None
        x = np.asarray(value[numeric[0]], dtype=float)
        lines = []
        for name in numeric[1:5]:
            xs, ys = _thin(x, np.asarray(value[name], dtype=float))
            lines.append((name, xs, ys))
        return lines, numeric[0], "", False
    return None


def chart(value: Any) -> str | None:
    """A small line chart as inline SVG (html): a path's XY, a trajectory's speed over time, a table's numeric
    columns over its first; None for anything else. Drawn here rather than with plotly: the first plotly chart
    makes the browser evaluate 4.8 MB of plotly.js, which froze the editor's page for about 2 s after a Run."""
    found = _series(value)
    if found is None:
        return None
    lines, x_title, y_title, equal = found
    xs = np.concatenate([x for _n, x, _y in lines])
    ys = np.concatenate([y for _n, _x, y in lines])
    ok = np.isfinite(xs) & np.isfinite(ys)
    if not ok.any():
        return None
    x0, x1, y0, y1 = float(xs[ok].min()), float(xs[ok].max()), float(ys[ok].min()), float(ys[ok].max())
    w, h = _W - _PAD_L - _PAD, _H - _PAD_B - _PAD
    sx, sy = w / max(x1 - x0, 1e-12), h / max(y1 - y0, 1e-12)
    if equal:
        sx = sy = min(sx, sy)
    ox = _PAD_L + (w - (x1 - x0) * sx) / 2
    oy = _PAD + h - (h - (y1 - y0) * sy) / 2
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {_W} {_H}" width="100%" '
             f'style="display:block;font:10px sans-serif;color:inherit" role="img">',
             f'<rect x="{_PAD_L}" y="{_PAD}" width="{w}" height="{h}" fill="none" stroke="currentColor" '
             f'stroke-opacity=".3"/>']
    for k, (_name, x, y) in enumerate(lines):
        keep = np.isfinite(x) & np.isfinite(y)
        pts = " ".join(f"{ox + (a - x0) * sx:.1f},{oy - (b - y0) * sy:.1f}" for a, b in zip(x[keep], y[keep]))
        parts.append(f'<polyline points="{pts}" fill="none" stroke="{_SERIES[k % len(_SERIES)]}" stroke-width="1.5"/>')
    bottom, right = _PAD + h, _PAD_L + w
    ticks = ((_PAD_L, bottom + 12, "start", _number(x0)), (right, bottom + 12, "end", _number(x1)),
             (_PAD_L - 3, bottom, "end", _number(y0)), (_PAD_L - 3, _PAD + 8, "end", _number(y1)),
             ((_PAD_L + right) / 2, bottom + 24, "middle", x_title))
    parts += [f'<text x="{x:.1f}" y="{y:.1f}" text-anchor="{a}" fill="currentColor">{escape_html(t, 40)}</text>'
              for x, y, a, t in ticks]
    if y_title:
        parts.append(f'<text transform="translate(10 {_PAD + h / 2:.1f}) rotate(-90)" text-anchor="middle" '
                     f'fill="currentColor">{escape_html(y_title, 40)}</text>')
    if len(lines) > 1:
        parts += [f'<text x="{right - 4}" y="{_PAD + 12 + 12 * k}" text-anchor="end" fill="{_SERIES[k % len(_SERIES)]}">'
                  f'{escape_html(name, 30)}</text>' for k, (name, _x, _y) in enumerate(lines)]
    return "".join(parts) + "</svg>"
