"""The sweep report: chosen outputs against chosen settings, and the Pareto front of two objectives,
as plotly figures (the editor shows them) and one self-contained HTML page (plotly.js inside, so it
opens offline).
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from flowmc.settings import UsageError
from flowmc.sweep.results import write_atomic

__all__ = ["Choice", "choose", "pareto_front", "figures", "write_report"]

_MAX_DEFAULT_OUTPUTS = 6
_MAX_COLOR_GROUPS = 12


@dataclass(frozen=True)
class Choice:
    """What to plot: ``outputs`` (columns) against ``params`` (swept settings); ``pareto``: two objectives,
    each minimised unless its ``maximize`` flag is set."""

    outputs: tuple[str, ...]
    params: tuple[str, ...]
    pareto: tuple[str, str] | None = None
    maximize: tuple[bool, bool] = (False, False)


def _numeric(rows: list[dict[str, Any]], column: str) -> bool:
    values = [r.get(column) for r in rows if r.get("status") == "done" and r.get(column) is not None]
    return bool(values) and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def _column(name: str, columns: list[str], what: str) -> str:
    name = name.strip()
    for candidate in (name, f"out.{name}"):
        if candidate in columns:
            return candidate
    outs = [c.removeprefix("out.") for c in columns if c.startswith("out.")]
    raise UsageError(f"{what}: no output {name!r} (outputs: {', '.join(outs) or 'none yet'})")


def choose(columns: list[str], rows: list[dict[str, Any]], params: list[str], *, outputs: list[str] | None = None,
           against: list[str] | None = None, pareto: list[str] | None = None) -> Choice:
    """Resolve names the user gave (``lookahead_s`` or ``out.lookahead_s``); defaults: the numeric outputs
    (the graph's own Number outputs first, at most six) against every swept setting."""
    if outputs:
        chosen = tuple(_column(o, columns, "--plot") for o in outputs)
    else:
        numeric = [c for c in columns if c.startswith("out.") and _numeric(rows, c)]
        numeric.sort(key=lambda c: c.count("."))  # out.<output> before out.<table>.<name>
        chosen = tuple(numeric[:_MAX_DEFAULT_OUTPUTS])
    if against:
        unknown = [a for a in against if a not in params]
        if unknown:
            raise UsageError(f"--against {unknown[0]}: not a swept setting (swept: {', '.join(params) or 'none'})")
        xs = tuple(against)
    else:
        xs = tuple(params)
    front, maximize = None, (False, False)
    if pareto:
        if len(pareto) != 2:
            raise UsageError(f"--pareto takes two objectives, got {len(pareto)}")
        flags = tuple(p.strip().startswith("max:") for p in pareto)
        names = tuple(_column(p.strip().removeprefix("max:"), columns, "--pareto") for p in pareto)
        front, maximize = (names[0], names[1]), (flags[0], flags[1])
    return Choice(chosen, xs, front, maximize)


def pareto_front(a: np.ndarray, b: np.ndarray, maximize: tuple[bool, bool] = (False, False)) -> np.ndarray:
    """Mask of the points no other point beats on both objectives (ties: the first one).

    >>> pareto_front(np.array([1.0, 2.0, 3.0, 2.5]), np.array([3.0, 1.0, 0.5, 2.0])).tolist()
    [True, True, True, False]
    """
    x = -np.asarray(a, float) if maximize[0] else np.asarray(a, float)
    y = -np.asarray(b, float) if maximize[1] else np.asarray(b, float)
    order = np.lexsort((y, x))
    ys = y[order]
    best_before = np.concatenate(([np.inf], np.minimum.accumulate(ys)[:-1]))
    mask = np.zeros(len(x), bool)
    mask[order] = ys < best_before
    return mask


def _hover(row: dict[str, Any], params: list[str]) -> str:
    status = "" if row.get("status") == "done" else f" ({row.get('status')})"
    return "<br>".join([f"variant {row['variant']}{status}"] + [f"{html.escape(p)} = {html.escape(str(row.get(p)))}"
                                                        for p in params])


def _finite(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _against(x: str, outputs: tuple[str, ...], shown: list[dict[str, Any]], params: list[str]) -> Any:
    """One figure: each output (a row of subplots) against the setting ``x``, coloured by another setting.
    Failed variants that still produced the output are drawn as crosses."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    others = [p for p in params if p != x and 1 < len({str(r.get(p)) for r in shown}) <= _MAX_COLOR_GROUPS]
    by = others[0] if others else None
    groups: dict[str, list[dict[str, Any]]] = {}
    for row in shown:
        groups.setdefault(f"{by} = {row.get(by)}" if by else "variants", []).append(row)
    numeric_x = all(_finite(r.get(x)) for r in shown)
    names = [o.removeprefix("out.") for o in outputs]
    fig = make_subplots(rows=len(outputs), cols=1, shared_xaxes=True, vertical_spacing=0.06,
                        subplot_titles=names if len(names) > 1 else None)
    for k, output in enumerate(outputs, start=1):
        for g, (label, members) in enumerate(groups.items()):
            points = [r for r in members if _finite(r.get(output))]
            if numeric_x:
                points.sort(key=lambda r: r[x])
            fig.add_trace(go.Scatter(
                x=[r.get(x) if numeric_x else str(r.get(x)) for r in points], y=[r[output] for r in points],
                mode="lines+markers" if numeric_x else "markers", name=label, legendgroup=label, showlegend=k == 1,
                line={"color": _palette(g)},
                marker={"color": _palette(g), "size": 8,
                        "symbol": ["circle" if r["status"] == "done" else "x" for r in points]},
                text=[_hover(r, params) for r in points], hoverinfo="text+y"), row=k, col=1)
    fig.update_xaxes(title_text=x, row=len(outputs), col=1)
    failed = any(r["status"] != "done" for r in shown)
    if len(names) == 1:
        fig.update_yaxes(title_text=names[0], row=1, col=1)
    what = names[0] if len(names) == 1 else "Outputs"
    fig.update_layout(title=f"{what} against {x}" + (" (crosses: variants that failed)" if failed else ""),
                      height=max(340, 240 * len(outputs)), template="plotly_white",
                      margin={"l": 60, "r": 20, "t": 70, "b": 50})
    return fig


def _palette(k: int) -> str:
    colours = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
               "#17becf", "#393b79", "#637939")
    return colours[k % len(colours)]


def _pareto(choice: Choice, done: list[dict[str, Any]], params: list[str]) -> tuple[Any, list[dict[str, Any]]]:
    import plotly.graph_objects as go

    a_name, b_name = choice.pareto  # type: ignore[misc]
    points = [r for r in done if _finite(r.get(a_name)) and _finite(r.get(b_name))]
    mask = pareto_front(np.array([r[a_name] for r in points]), np.array([r[b_name] for r in points]), choice.maximize)
    front = sorted((r for r, m in zip(points, mask) if m), key=lambda r: r[a_name])
    fig = go.Figure()
    fig.add_trace(go.Scatter(x=[r[a_name] for r in points], y=[r[b_name] for r in points], mode="markers",
                             name="variants", marker={"color": "#9aa5b1", "size": 7},
                             text=[_hover(r, params) for r in points], hoverinfo="text+x+y"))
    fig.add_trace(go.Scatter(x=[r[a_name] for r in front], y=[r[b_name] for r in front], mode="lines+markers",
                             name="Pareto front", line={"shape": "hv", "color": "#d62728"},
                             marker={"color": "#d62728", "size": 10},
                             text=[_hover(r, params) for r in front], hoverinfo="text+x+y"))
    sense = ["higher" if m else "lower" for m in choice.maximize]
    fig.update_layout(title="Pareto front of the variants done",
                      xaxis_title=f"{a_name.removeprefix('out.')} ({sense[0]} is better)",
                      yaxis_title=f"{b_name.removeprefix('out.')} ({sense[1]} is better)",
                      template="plotly_white", height=520, margin={"l": 60, "r": 20, "t": 60, "b": 50})
    return fig, front


def figures(choice: Choice, rows: list[dict[str, Any]], params: list[str]) -> tuple[list[Any], list[dict[str, Any]]]:
    """The plotly figures for ``choice`` (outputs against each setting, then the Pareto front of the variants
    that are done), and the rows on the front."""
    done = [r for r in rows if r.get("status") == "done"]
    shown = [r for r in rows if r.get("status") != "lost"]
    figs, front = [], []
    if choice.outputs and any(_finite(r.get(o)) for r in shown for o in choice.outputs):
        figs += [_against(x, choice.outputs, shown, params) for x in choice.params]
    if choice.pareto and done:
        fig, front = _pareto(choice, done, params)
        figs.append(fig)
    return figs, front


def _html_table(columns: list[str], rows: list[dict[str, Any]], row_class: str = "") -> str:
    head = "".join(f"<th>{html.escape(c.removeprefix('out.'))}</th>" for c in columns)
    opening = f"<tr class='{row_class}'>" if row_class else "<tr>"
    body = "".join(opening + "".join(f"<td>{html.escape(_fmt(r.get(c)))}</td>" for c in columns) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _fmt(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


_STYLE = """body{font-family:system-ui,sans-serif;margin:24px;color:#222}h1{font-size:22px}h2{font-size:18px;margin-top:28px}
table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left}
th{background:#f3f4f6}.failed td{color:#a40000}.meta{color:#555}"""


def write_report(path: Path, *, title: str, summary: list[str], choice: Choice, rows: list[dict[str, Any]],
                 params: list[str]) -> Path:
    """One HTML page: the summary lines, the figures, the Pareto-front variants and the failed ones."""
    import plotly.io as pio

    figs, front = figures(choice, rows, params)
    parts = [f"<h1>{html.escape(title)}</h1>", "".join(f"<p class='meta'>{html.escape(s)}</p>" for s in summary)]
    for k, fig in enumerate(figs):
        parts.append(pio.to_html(fig, include_plotlyjs=k == 0, full_html=False, default_width="100%"))
    if not figs:
        parts.append("<p>No finished variant with a numeric output to plot.</p>")
    if front:
        a, b = choice.pareto  # type: ignore[misc]
        parts.append(f"<h2>On the Pareto front ({len(front)})</h2>")
        parts.append(_html_table(["variant", *params, a, b], front))
    failed = [r for r in rows if r.get("status") != "done"]
    if failed:
        parts.append(f"<h2>Not done ({len(failed)})</h2>")
        parts.append(_html_table(["variant", *params, "status", "error"], failed, "failed"))
    page = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_STYLE}</style></head><body>{''.join(parts)}</body></html>")
    write_atomic(path, page.encode("utf-8"))
    return path
