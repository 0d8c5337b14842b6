"""What the plan figures share: event marks, the aircraft legend, phase bands and labels that do not overlap.

Colour encodes the aircraft (legend), the optimizer's phases are shaded bands, events carry markers
(start o, gate passage D, landing v) and labels placed so that they do not overlap.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.lines import Line2D

from mal_planner.figures import style
from mal_planner.figures.data import AircraftView, PlanView


def value_at(traj, t: float | None, values: np.ndarray) -> float | None:
    """``values`` (sampled at ``traj.t``) at time ``t``; None outside the trajectory."""
    if t is None or not traj.t[0] - 1e-9 <= t <= traj.t[-1] + 1e-9:
        return None
    return float(np.interp(t, traj.t, values))


def aircraft_events(a: AircraftView) -> list[tuple[str, float]]:
    """(kind, time) of the aircraft's gate passage and landing, those it has."""
    return [(k, t) for k, t in (("gate", a.gate_time), ("land", a.landing_time)) if t is not None]


def legend_handles(view: PlanView, colors: dict[str, str], extra: Sequence[Line2D] = ()) -> list[Line2D]:
    """One entry per aircraft, then the event markers and the gate hole drawn, then ``extra``."""
    handles = [Line2D([], [], color=colors[cs], lw=2, label=cs) for cs in view.callsigns]
    kinds = [("start", "start"), ("gate", "gate passage"), ("land", "landing")]
    if all(a.gate_time is None for a in view.aircraft):
        kinds.pop(1)
    handles += [Line2D([], [], color="0.3", ls="", marker=style.MARKERS[k], label=lbl) for k, lbl in kinds]
    if view.gates:
        handles.append(Line2D([], [], color=style.GATE_COLOR, lw=3, label="gate hole"))
    return handles + list(extra)


def legend_margin(fig, handles: Sequence) -> tuple[float, int]:
    """Fraction of the figure's width a legend beside the axes needs, and its columns."""
    ncol = style.legend_columns(len(handles), 16)
    return style.legend_width([h.get_label() for h in handles], ncol) / fig.get_figwidth(), ncol


def add_legend(fig, view: PlanView, colors: dict[str, str], extra: Sequence[Line2D] = (), loc: str = "right",
               layout: bool = True, top: float = 1.0) -> None:
    """Aircraft legend (columns for many aircraft) plus the marker key, beside the axes or at the top.

    ``layout``: fit the axes into the rest of the figure (tight layout below ``top``).
    """
    handles = legend_handles(view, colors, extra)
    if loc == "top":
        fig.legend(handles=handles, loc="upper center", ncol=min(len(handles), 12), bbox_to_anchor=(0.5, 0.975))
        return
    width, ncol = legend_margin(fig, handles)
    if layout:
        fig.tight_layout(rect=(0.0, 0.0, 1.0 - width, top))
    fig.legend(handles=handles, loc="center right", bbox_to_anchor=(1.0, 0.5), ncol=ncol)


def shade_phases(ax, view: PlanView) -> None:
    """Every other optimizer phase shaded (the phases end at the gate passages and landings)."""
    if not view.optimized:
        return
    bounds = [0.0, *view.event_times()]
    for k in range(1, len(bounds) - 1, 2):
        ax.axvspan(bounds[k], bounds[k + 1], color=style.PHASE_BAND_COLOR, alpha=style.PHASE_BAND_ALPHA, lw=0)


def stagger_rows(positions: Sequence[float], widths: Sequence[float]) -> list[int]:
    """Row of each label so that labels in one row do not overlap (greedy, from left to right).

    ``positions`` are the labels' centres and ``widths`` their widths, in the same units.
    """
    ends: list[float] = []
    out = [0] * len(positions)
    for i in np.argsort(positions, kind="stable"):
        lo = positions[i] - widths[i] / 2
        row = next((r for r, end in enumerate(ends) if lo > end), len(ends))
        if row == len(ends):
            ends.append(0.0)
        ends[row] = positions[i] + widths[i] / 2
        out[i] = row
    return out


def label_events(ax, view: PlanView, colors: dict[str, str]) -> int:
    """Labels 'A1 gate', 'A1 land' above the top axis at their times, staggered into rows."""
    items = [(t, f"{a.callsign} {kind}", colors[a.callsign]) for a in view.aircraft for kind, t in aircraft_events(a)]
    if not items:
        return 0
    fig = ax.figure
    ax.apply_aspect()  # fixes the axes' position, so text widths convert to data units
    bbox = ax.get_window_extent()
    x0, x1 = ax.get_xlim()
    per_px = (x1 - x0) / bbox.width
    font_px = (style.FONT_SIZE - 2) * fig.dpi / 72.0
    widths = [(len(text) * 0.6 * font_px + 6) * per_px for _, text, _ in items]
    rows = stagger_rows([t for t, _, _ in items], widths)
    for (t, text, color), row in zip(items, rows, strict=True):
        ax.axvline(t, color=color, lw=0.6, ls=":", alpha=0.8)
        ax.annotate(text, (t, 1.0), xycoords=("data", "axes fraction"), xytext=(0, 3 + 10 * row),
                    textcoords="offset points", ha="center", va="bottom", fontsize=style.FONT_SIZE - 2, color=color)
    return max(rows) + 1


def place_labels(ax, points: np.ndarray, texts: Sequence[str], colors: Sequence[str]) -> None:
    """Label 2-D data points with the first of 8 directions x 3 radii whose box overlaps no other label."""
    fig = ax.figure
    ax.apply_aspect()
    disp = ax.transData.transform(points)
    font_px = (style.FONT_SIZE - 1) * fig.dpi / 72.0
    placed: list[tuple[float, float, float, float]] = []
    frame = ax.get_window_extent()
    directions = [(1, 1), (1, -1), (-1, 1), (-1, -1), (1, 0), (-1, 0), (0, 1), (0, -1)]
    for (px, py), point, text, color in zip(disp, points, texts, colors, strict=True):
        w, h = len(text) * 0.62 * font_px + 2, font_px * 1.2
        choice = None
        for radius in (6, 16, 28):
            for dx, dy in directions:
                cx, cy = px + dx * (radius + w / 2), py + dy * (radius + h / 2)
                box = (cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)
                inside = frame.x0 <= box[0] and box[2] <= frame.x1 and frame.y0 <= box[1] and box[3] <= frame.y1
                if inside and all(box[2] < b[0] or box[0] > b[2] or box[3] < b[1] or box[1] > b[3] for b in placed):
                    choice = (cx - px, cy - py, box)
                    break
            if choice:
                break
        if choice is None:
            choice = (6 + w / 2, 6 + h / 2, (px, py, px + w, py + h))
        placed.append(choice[2])
        ax.annotate(text, xy=tuple(point), xytext=choice[:2],
                    textcoords="offset pixels", ha="center", va="center", fontsize=style.FONT_SIZE - 1, color=color,
                    fontweight="bold")

