"""PNG figures of a plan (matplotlib, Agg): the thesis's Figures 4-1 to 4-4 and 6-1 to 6-14, restyled.

Colour encodes the aircraft (legend), the optimizer's phases are shaded bands, events carry markers
(start o, gate passage D, landing v) and labels placed so that they do not overlap.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from mal_planner.figures import style
from mal_planner.figures.data import AircraftView, GapView, LandingTimeline, PairSeparation, PlanView, SlotView
from mal_planner.figures.geometry import gate_outline, obstacle_mesh, projection, section

style.apply_style()
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from mal_planner.dynamics import bank_angle  # noqa: E402

SERIES = {
    "x": ("x (nm)", 0, 1.0),
    "y": ("y (nm)", 1, 1.0),
    "z": ("z (nm)", 2, 1.0),
    "gamma": ("flight-path angle (deg)", 3, 180.0 / np.pi),
    "heading": ("heading (deg)", 4, 180.0 / np.pi),
}
HIGHLIGHTED_PAIRS = 8
"""Separation figure: the pairs that come closest get a colour and a legend entry, the rest are grey."""
NEEDED_COLOR = "#c8c8c8"
"""Sequence figure: the spacing a pair needs, a light band under the bracket of what it got."""
GAP_COLOR = "#404040"


# -- helpers ---------------------------------------------------------------------------------------------
def _values(traj, key: str) -> np.ndarray:
    _, col, scale = SERIES[key]
    if key == "heading":
        return np.degrees(np.unwrap(traj.states[:, col]))
    return traj.states[:, col] * scale


def _at(traj, t: float | None, values: np.ndarray) -> float | None:
    if t is None or not traj.t[0] - 1e-9 <= t <= traj.t[-1] + 1e-9:
        return None
    return float(np.interp(t, traj.t, values))


def _events(a: AircraftView) -> list[tuple[str, float]]:
    return [(k, t) for k, t in (("gate", a.gate_time), ("land", a.landing_time)) if t is not None]


def _handles(view: PlanView, colors: dict[str, str], extra: Sequence[Line2D] = ()) -> list[Line2D]:
    handles = [Line2D([], [], color=colors[cs], lw=2, label=cs) for cs in view.callsigns]
    kinds = [("start", "start"), ("gate", "gate passage"), ("land", "landing")]
    if all(a.gate_time is None for a in view.aircraft):
        kinds.pop(1)
    handles += [Line2D([], [], color="0.3", ls="", marker=style.MARKERS[k], label=lbl) for k, lbl in kinds]
    if view.gates:
        handles.append(Line2D([], [], color=style.GATE_COLOR, lw=3, label="gate hole"))
    return handles + list(extra)


def _right_margin(fig, handles: Sequence) -> tuple[float, int]:
    """Fraction of the figure's width a legend beside the axes needs, and its columns."""
    ncol = style.legend_columns(len(handles), 16)
    return style.legend_width([h.get_label() for h in handles], ncol) / fig.get_figwidth(), ncol


def _legend(fig, view: PlanView, colors: dict[str, str], extra: Sequence[Line2D] = (), loc: str = "right",
            layout: bool = True, top: float = 1.0) -> None:
    """Aircraft legend (columns for many aircraft) plus the marker key, beside the axes or at the top.

    ``layout``: fit the axes into the rest of the figure (tight layout below ``top``).
    """
    handles = _handles(view, colors, extra)
    if loc == "top":
        fig.legend(handles=handles, loc="upper center", ncol=min(len(handles), 12), bbox_to_anchor=(0.5, 0.975))
        return
    width, ncol = _right_margin(fig, handles)
    if layout:
        fig.tight_layout(rect=(0.0, 0.0, 1.0 - width, top))
    fig.legend(handles=handles, loc="center right", bbox_to_anchor=(1.0, 0.5), ncol=ncol)


def _phase_bands(ax, view: PlanView) -> None:
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


def _event_labels(ax, view: PlanView, colors: dict[str, str]) -> int:
    """Labels 'A1 gate', 'A1 land' above the top axis at their times, staggered into rows."""
    items = [(t, f"{a.callsign} {kind}", colors[a.callsign]) for a in view.aircraft for kind, t in _events(a)]
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


def _hole_centre(view: PlanView) -> np.ndarray | None:
    return view.gates[0].center() if view.gates else None


# -- views (each draws into a given axis, so the overview reuses them) -----------------------------------
def draw_3d(ax, view: PlanView, colors: dict[str, str], initial: bool = False, direct: bool = False) -> None:
    """Obstacles (translucent, to scale), gate holes, runway and one path per aircraft with its events."""
    for ob in view.obstacles:
        verts, tris = obstacle_mesh(ob)
        ax.add_collection3d(Poly3DCollection(verts[tris], facecolor=style.OBSTACLE_COLOR, alpha=0.18,
                                             edgecolor=style.OBSTACLE_COLOR, linewidth=0.1))
    for gate in view.gates:
        p = gate_outline(gate)
        ax.plot(p[:, 0], p[:, 1], p[:, 2], color=style.GATE_COLOR, lw=2)
    rw = view.runway
    ax.scatter([rw[0]], [rw[1]], [rw[2]], marker="s", color=style.RUNWAY_COLOR, s=25)
    for a in view.aircraft:
        tr = a.initial if initial else a.trajectory
        p, c = tr.positions, colors[a.callsign]
        ax.plot(p[:, 0], p[:, 1], p[:, 2], color=c, lw=1.5)
        ax.scatter(*p[0], color=c, marker=style.MARKERS["start"], s=18)
        if direct and len(a.direct_path):
            ax.plot(*a.direct_path.T, color=c, lw=0.9, ls="--", alpha=0.8)
        if not initial:
            for kind, t in _events(a):
                q = [_at(tr, t, p[:, k]) for k in range(3)]
                if q[0] is not None:
                    ax.scatter(*q, color=c, marker=style.MARKERS[kind], s=22, edgecolor="k", linewidth=0.4)
    (x0, x1), (y0, y1), (z0, z1) = view.airspace
    ax.set(xlim=(x0, x1), ylim=(y0, y1), zlim=(z0, z1), xlabel="x (nm)", ylabel="y (nm)", zlabel="z (nm)")
    ax.set_box_aspect((x1 - x0, y1 - y0, max((x1 - x0) * 0.3, z1 - z0)))
    ax.view_init(elev=24, azim=-60)
    ax.tick_params(labelsize=style.FONT_SIZE - 2, pad=0)


def _draw_section_view(ax, view: PlanView, axes: tuple[int, int], cut: float | None) -> None:
    """Obstacles on a 2-D view: their shadows (light) and the cut through the gate hole (dark)."""
    for ob in view.obstacles:
        shadow = projection(ob, axes)
        ax.fill(shadow[:, 0], shadow[:, 1], color=style.OBSTACLE_COLOR, alpha=0.12 if cut is not None else 0.4,
                lw=0)
        cut_outline = section(ob, axes, cut) if cut is not None else None
        if cut_outline is not None:
            ax.fill(cut_outline[:, 0], cut_outline[:, 1], facecolor=style.OBSTACLE_COLOR, alpha=0.55,
                    edgecolor=style.OBSTACLE_COLOR, lw=1.5)
    for gate in view.gates:
        if gate.axis in axes:
            # The gate plane is a line on this view; the hole spans the bounds along the other drawn axis.
            other = axes[1] if gate.axis == axes[0] else axes[0]
            lo, hi = gate.bounds[gate.other_axes.index(other)]
            seg = np.array([[gate.position, lo], [gate.position, hi]])
            if gate.axis != axes[0]:
                seg = seg[:, ::-1]
            ax.plot(seg[:, 0], seg[:, 1], color=style.GATE_COLOR, lw=3, solid_capstyle="butt", zorder=3)


def _draw_paths_2d(ax, view: PlanView, colors: dict[str, str], axes: tuple[int, int], labels: bool) -> None:
    starts, names = [], []
    for a in view.aircraft:
        tr, c = a.trajectory, colors[a.callsign]
        p = tr.positions
        ax.plot(p[:, axes[0]], p[:, axes[1]], color=c, lw=1.4, zorder=4)
        ax.plot(p[0, axes[0]], p[0, axes[1]], color=c, marker=style.MARKERS["start"], ms=4, zorder=5)
        for kind, t in _events(a):
            u, v = _at(tr, t, p[:, axes[0]]), _at(tr, t, p[:, axes[1]])
            if u is not None:
                ax.plot(u, v, color=c, marker=style.MARKERS[kind], ms=5, mec="k", mew=0.4, ls="", zorder=6)
        starts.append(p[0, list(axes)])
        names.append(a.callsign)
    rw = view.runway
    ax.plot(rw[axes[0]], rw[axes[1]], marker="s", color=style.RUNWAY_COLOR, ms=5, zorder=6)
    if labels and starts:
        place_labels(ax, np.array(starts), names, [colors[n] for n in names])


def draw_plan(ax, view: PlanView, colors: dict[str, str], labels: bool = True) -> None:
    """Plan (x-y) view to scale; obstacles cut at the height of the gate hole's centre."""
    hole = _hole_centre(view)
    _draw_section_view(ax, view, (0, 1), None if hole is None else float(hole[2]))
    ax.set(xlim=tuple(view.airspace[0]), ylim=tuple(view.airspace[1]), xlabel="x (nm)", ylabel="y (nm)")
    ax.set_aspect("equal")
    _draw_paths_2d(ax, view, colors, (0, 1), labels)
    cut = "" if hole is None else f" (dark: obstacles at z = {hole[2]:.3g} nm)"
    ax.set_title(f"Plan view{cut}", fontsize=style.FONT_SIZE)


def draw_yz(ax, view: PlanView, colors: dict[str, str], labels: bool = True) -> None:
    """Y-Z view (thesis Figure 6-2); obstacles cut at the x of the gate hole's centre, so the hole shows."""
    hole = _hole_centre(view)
    _draw_section_view(ax, view, (1, 2), None if hole is None else float(hole[0]))
    ax.set(xlim=tuple(view.airspace[1][::-1]), ylim=tuple(view.airspace[2]), xlabel="y (nm)", ylabel="z (nm)")
    _draw_paths_2d(ax, view, colors, (1, 2), labels)
    cut = "" if hole is None else f" (dark: obstacles at x = {hole[0]:.3g} nm)"
    ax.set_title(f"Y-Z view, vertical scale exaggerated{cut}", fontsize=style.FONT_SIZE)


def draw_series(ax, view: PlanView, colors: dict[str, str], key: str, initial: bool = False) -> None:
    """One state against time for every aircraft, with phase bands and event markers."""
    if not initial:
        _phase_bands(ax, view)
    for a in view.aircraft:
        tr = a.initial if initial else a.trajectory
        vals, c = _values(tr, key), colors[a.callsign]
        ax.plot(tr.t, vals, color=c)
        ax.plot(tr.t[0], vals[0], color=c, marker=style.MARKERS["start"], ms=3.5)
        events = [("land", float(tr.t[-1]))] if initial else _events(a)
        for kind, t in events:
            v = _at(tr, t, vals)
            if v is not None:
                ax.plot(t, v, color=c, marker=style.MARKERS[kind], ms=5, mec="k", mew=0.4)
    ax.set_ylabel(SERIES[key][0])


def draw_separation(ax, view: PlanView, seps: list[PairSeparation], colors: dict[str, str]) -> None:
    """Distance of every pair against time (closest pairs coloured), the required separation and each minimum."""
    _phase_bands(ax, view)
    ranked = sorted(seps, key=lambda s: float(np.min(s.distance)))
    highlighted = {s.pair for s in ranked[:HIGHLIGHTED_PAIRS]}
    pair_colors = style.pair_colors(min(len(ranked), HIGHLIGHTED_PAIRS))
    for s in reversed(ranked):
        if s.pair in highlighted:
            c = pair_colors[ranked.index(s)]
            k = int(np.argmin(s.distance))
            lbl = f"{s.pair}: min {s.distance[k]:.3f} nm at {s.t[k]:.0f} s"
            ax.plot(s.t, s.distance, color=c, lw=1.3, label=lbl, zorder=3)
            ax.plot(s.t[k], s.distance[k], marker="o", color=c, ms=4, zorder=4)
        else:
            ax.plot(s.t, s.distance, color="0.65", lw=0.7, zorder=2)
    if view.separation_nm:
        ax.axhline(view.separation_nm, color=style.REQUIRED_COLOR, ls="--", lw=1.2,
                   label=f"required {view.separation_nm:g} nm", zorder=5)
    ax.set_ylim(bottom=0.0)
    ax.set(xlabel="time (s)", ylabel="distance (nm)")
    if len(ranked) > HIGHLIGHTED_PAIRS:
        ax.plot([], [], color="0.65", lw=0.7, label=f"{len(ranked) - HIGHLIGHTED_PAIRS} other pairs")


def gap_label(g: GapView, pair: bool = True) -> str:
    """'B1→B3  100.0 ≥ 100.0 s  H→H 4 nm': the gap got against the spacing needed (and the wake pair)."""
    digits = 3 if g.short and g.needed is not None and f"{g.gap:.1f}" == f"{g.needed:.1f}" else 1
    text = f"{g.gap:.{digits}f} s" if g.needed is None else (
        f"{g.gap:.{digits}f} {'<' if g.short else '≥'} {g.needed:.{digits}f} s")
    if g.wake:
        text += f"  {g.wake.replace('->', '→')}" + ("" if g.wake_nm is None else f" {g.wake_nm:g} nm")
    if g.short:
        text += "  SHORT"
    return f"{g.leader}→{g.follower}  {text}" if pair else text


def _slot_label(s: SlotView) -> str:
    """'B1 (H)', 'A1 (M, fixed)': callsign, wake category and whether the landing time was fixed."""
    notes = [n for n in (s.wake_category, "fixed" if s.fixed else None) if n]
    return f"{s.callsign} ({', '.join(notes)})" if notes else s.callsign


def draw_sequence(ax, tl: LandingTimeline, colors: dict[str, str], pair_labels: bool = True) -> None:
    """Landing time line: a row per aircraft in landing order (earliest-to-landing bar, delay shaded, target |,
    landing v) and, between consecutive rows, a bracket of the gap got over a band of the spacing needed (red
    where short); the gap labels go in a column right of the axes."""
    row = {s.callsign: k for k, s in enumerate(tl.slots)}
    small = style.FONT_SIZE - 1.5
    for k, s in enumerate(tl.slots):
        c = colors.get(s.callsign, "0.3")
        if s.earliest is not None:
            ax.plot([min(s.earliest, s.landing_time), s.landing_time], [k, k], color=c, lw=1.2, alpha=0.7,
                    solid_capstyle="butt", zorder=2)
        if s.target is not None and s.landing_time > s.target:
            ax.barh(k, s.landing_time - s.target, left=s.target, height=0.36, color=c, alpha=0.28, lw=0, zorder=1)
        if s.target is not None:
            ax.plot(s.target, k, marker="|", ms=9, mew=1.6, color="0.15", ls="", zorder=4)
        ax.plot(s.landing_time, k, marker=style.MARKERS["land"], ms=7, color=c, mec="k", mew=0.5, ls="", zorder=5)
        if s.delay is not None and abs(s.delay) >= 0.05:
            ax.annotate(f"{s.delay:+.1f} s", (s.landing_time, k), xytext=(6, 0), textcoords="offset points",
                        va="center", ha="left", fontsize=small, color="0.35")
    for g in tl.gaps:
        if g.leader not in row or g.follower not in row:
            continue
        (t0, y0), (t1, y1) = ((tl.slots[row[cs]].landing_time, row[cs]) for cs in (g.leader, g.follower))
        y = (y0 + y1) / 2
        color = style.REQUIRED_COLOR if g.short else GAP_COLOR
        if g.needed is not None:
            ax.plot([t0, t0 + g.needed], [y + 0.14, y + 0.14], color=style.REQUIRED_COLOR if g.short else NEEDED_COLOR,
                    lw=4, alpha=0.35 if g.short else 1.0, solid_capstyle="butt", zorder=1)
        ax.plot([t0, t0], [y0, y], [t1, t1], [y, y1], color=color, lw=0.6, ls=":", zorder=2)
        ax.annotate("", xy=(t1, y), xytext=(t0, y), zorder=3,
                    arrowprops={"arrowstyle": "|-|, widthA=0.25, widthB=0.25", "color": color, "lw": 1.0,
                                "shrinkA": 0, "shrinkB": 0})
        ax.annotate(gap_label(g, pair_labels), (1.0, y), xycoords=("axes fraction", "data"), xytext=(6, 0),
                    textcoords="offset points", va="center", ha="left", fontsize=small, color=color,
                    fontweight="bold" if g.short else "normal", annotation_clip=False)
    n = len(tl.slots)
    ax.set_yticks(range(n), [_slot_label(s) for s in tl.slots])
    for label, s in zip(ax.get_yticklabels(), tl.slots, strict=True):
        label.set_color(colors.get(s.callsign, "0.3"))
        label.set_fontweight("bold")
    ax.set_ylim(max(n, 1) - 0.5, -0.5)
    ax.grid(False, axis="y")
    times = [t for s in tl.slots for t in (s.earliest, s.target, s.landing_time) if t is not None]
    times += [tl.slots[row[g.leader]].landing_time + g.needed for g in tl.gaps
              if g.needed is not None and g.leader in row]
    if times:
        lo, hi = min(times), max(times)
        span = max(hi - lo, 10.0)
        ax.set_xlim(lo - 0.04 * span, hi + 0.12 * span)  # room right for the delay labels
    ax.set_xlabel("time (s)")


def sequence_handles(tl: LandingTimeline) -> list:
    """Legend entries of the sequence figure (only what it draws)."""
    from matplotlib.patches import Patch

    slots = tl.slots
    handles = [Line2D([], [], color="0.3", marker=style.MARKERS["land"], mec="k", ls="", label="landing")]
    if any(s.earliest is not None for s in slots):
        handles.append(Line2D([], [], color="0.3", lw=1.2, label="earliest to landing"))
    if any(s.target is not None for s in slots):
        handles += [Line2D([], [], color="0.15", marker="|", ms=9, mew=1.6, ls="", label="target"),
                    Patch(color="0.3", alpha=0.28, lw=0, label="delay")]
    if any(g.needed is not None for g in tl.gaps):
        handles.append(Line2D([], [], color=NEEDED_COLOR, lw=4, label="spacing needed"))
    handles.append(Line2D([], [], color=GAP_COLOR, lw=1.0, marker="|", label="gap got"))
    if any(g.short for g in tl.gaps):
        handles.append(Line2D([], [], color=style.REQUIRED_COLOR, lw=1.0, marker="|", label="gap short"))
    return handles


def _label_column(tl: LandingTimeline, pair: bool, fontsize: float) -> float:
    """Width (inches) of the gap labels right of the sequence axes."""
    longest = max((len(gap_label(g, pair)) for g in tl.gaps), default=0)
    return (longest * 0.58 + 1.5) * fontsize / 72.0


# -- figures -----------------------------------------------------------------------------------------------
def figure_paths_3d(view: PlanView, colors: dict[str, str], initial: bool = False):
    """3-D paths with the obstacles (thesis Figures 4-1 and 6-1)."""
    fig = plt.figure(figsize=(style.WIDTH_IN, 5.6))
    ax = fig.add_subplot(projection="3d", computed_zorder=False)
    draw_3d(ax, view, colors, initial=initial, direct=initial)
    what = "initial paths (RRT + sequencer)" if initial else "optimal trajectories"
    ax.set_title(f"{view.name}: {what}")
    extra = [Line2D([], [], color="0.3", ls="--", label="shortest path")] if initial else []
    width, _ = _right_margin(fig, _handles(view, colors, extra))
    fig.subplots_adjust(left=0.0, right=1.0 - width, bottom=0.02, top=0.95)
    _legend(fig, view, colors, extra, layout=False)
    return fig


def figure_series(view: PlanView, colors: dict[str, str], key: str, initial: bool = False):
    """One state against time (thesis Figures 4-2 to 4-4)."""
    fig, ax = plt.subplots(figsize=(style.WIDTH_IN, 3.4))
    draw_series(ax, view, colors, key, initial=initial)
    ax.set_xlabel("time (s)")
    ax.set_title(f"{view.name}: {'initial ' if initial else ''}{SERIES[key][0].split(' (')[0]} against time")
    _legend(fig, view, colors)
    return fig


def figure_states(view: PlanView, colors: dict[str, str]):
    """x, y, z, flight-path angle and heading against time (thesis Figures 6-3 to 6-7), phases shaded."""
    keys = ("x", "y", "z", "gamma", "heading")
    fig, axs = plt.subplots(len(keys), 1, figsize=(style.WIDTH_IN, 9.5), sharex=True)
    for ax, key in zip(axs, keys, strict=True):
        draw_series(ax, view, colors, key)
    axs[-1].set_xlabel("time (s)")
    axs[0].set_xlim(left=0.0)
    _legend(fig, view, colors, top=0.97)
    rows = _event_labels(axs[0], view, colors)  # their x positions do not depend on the top margin
    fig.subplots_adjust(top=1.0 - (10 * rows + 26) / 72 / fig.get_figheight())
    fig.suptitle(f"{view.name}: states against time (shaded: every other optimizer phase)", y=0.995, va="top")
    return fig


def figure_controls(view: PlanView, colors: dict[str, str]):
    """Bank angle and load factors of every aircraft against their limits (thesis Figures 6-8 to 6-13)."""
    fig, axs = plt.subplots(3, 1, figsize=(style.WIDTH_IN, 7.0), sharex=True)
    same = len({a.limits for a in view.aircraft}) == 1
    for a in view.aircraft:
        tr, c = a.trajectory, colors[a.callsign]
        if tr.controls is None:
            continue
        n_h, n_v = tr.controls[:, 0], tr.controls[:, 1]
        for ax, vals in zip(axs, (np.degrees(bank_angle(n_h, n_v)), n_h, n_v), strict=True):
            ax.plot(tr.t, vals, color=c, lw=1.1)
    limit_sets = [(None, view.aircraft[0].limits)] if same else [(a.callsign, a.limits) for a in view.aircraft]
    for cs, lim in limit_sets:
        c = style.REQUIRED_COLOR if cs is None else colors[cs]
        bank = np.degrees(lim.bank_angle_max)
        for ax, (lo, hi) in zip(axs, ((-bank, bank), lim.n_h, lim.n_v), strict=True):
            for v in (lo, hi):
                ax.axhline(v, color=c, ls="--", lw=1.0, alpha=0.9)
    for ax, label in zip(axs, ("bank angle (deg)", "n_h (horizontal load factor)", "n_v (vertical load factor)"),
                         strict=True):
        _phase_bands(ax, view)
        ax.set_ylabel(label)
    axs[-1].set_xlabel("time (s)")
    axs[0].set_xlim(left=0.0)
    fig.suptitle(f"{view.name}: controls against their limits (dashed)", y=0.995, va="top")
    _legend(fig, view, colors, [Line2D([], [], color=style.REQUIRED_COLOR if same else "0.3", ls="--",
                                       label="limit")], top=0.97)
    return fig


def figure_separation(view: PlanView, colors: dict[str, str], seps: list[PairSeparation]):
    """Pairwise separation against time (replaces the bar chart of thesis Figure 6-14)."""
    fig, ax = plt.subplots(figsize=(style.WIDTH_IN, 3.8))
    draw_separation(ax, view, seps, colors)
    ax.set_xlim(left=0.0)
    ax.set_title(f"{view.name}: distance between every pair of airborne aircraft")
    handles, labels = ax.get_legend_handles_labels()
    width = style.legend_width(labels) / fig.get_figwidth()
    fig.tight_layout(rect=(0.0, 0.0, 1.0 - width, 1.0))
    fig.legend(handles, labels, loc="center right", bbox_to_anchor=(1.0, 0.5))
    return fig


def figure_sequence(view: PlanView, colors: dict[str, str]):
    """The landing sequence as a time line: who lands when, each consecutive gap against what it needs."""
    tl = view.timeline
    n = max(len(tl.slots), 1)
    column = _label_column(tl, True, style.FONT_SIZE - 1.5)
    width = max(style.WIDTH_IN, 4.8 + column)
    fig, ax = plt.subplots(figsize=(width, 1.7 + 0.45 * n))
    h = fig.get_figheight()
    left = (0.25 + max((len(_slot_label(s)) for s in tl.slots), default=4) * 0.08) / width
    fig.subplots_adjust(left=left, right=1.0 - (column + 0.15) / width, bottom=0.55 / h, top=1.0 - 0.85 / h)
    draw_sequence(ax, tl, colors)
    how = [tl.strategy] if tl.strategy else []
    how += [f"wake table {tl.wake_table}"] if tl.wake_table else []
    how += [f"total delay {tl.total_delay:.1f} s"] if tl.total_delay is not None else []
    short = sum(g.short for g in tl.gaps)
    how += [f"{short} gap{'s' if short > 1 else ''} short"] if short else []
    fig.suptitle(f"{view.name}: landing sequence" + (f" ({', '.join(how)})" if how else ""), y=1.0 - 0.08 / h,
                 va="top")
    handles = sequence_handles(tl)
    fig.legend(handles=handles, loc="upper center", ncol=len(handles), bbox_to_anchor=(0.5, 1.0 - 0.32 / h),
               handlelength=1.6, columnspacing=1.2)
    return fig


def _figure_2d(view: PlanView, colors: dict[str, str], size: tuple[float, float], draw: Callable) -> object:
    """A 2-D view with the legend at its right; the axes are placed before drawing (labels need them)."""
    fig, ax = plt.subplots(figsize=size)
    extra: list[Line2D] = []
    width, _ = _right_margin(fig, _handles(view, colors, extra))
    em_w, em_h = style.FONT_SIZE / 72 / size[0], style.FONT_SIZE / 72 / size[1]
    fig.subplots_adjust(left=6 * em_w, right=1.0 - width - em_w, bottom=4 * em_h, top=1.0 - 2.5 * em_h)
    draw(ax, view, colors)
    _legend(fig, view, colors, extra, layout=False)
    return fig


def figure_plan(view: PlanView, colors: dict[str, str]):
    return _figure_2d(view, colors, (style.WIDTH_IN, style.WIDTH_IN * 0.85), draw_plan)


def figure_yz(view: PlanView, colors: dict[str, str]):
    return _figure_2d(view, colors, (style.WIDTH_IN, 3.2), draw_yz)


def summary_rows(view: PlanView, seps: list[PairSeparation]) -> list[list[str]]:
    """Table 6-1 analog: order, callsign, gate and landing time, closest other aircraft and distance."""
    closest: dict[str, tuple[float, str]] = {}
    for s in seps:
        a, b = s.pair.split("-", 1)
        d = s.verified_min if s.verified_min is not None else float(np.min(s.distance))
        for me, other in ((a, b), (b, a)):
            if me not in closest or d < closest[me][0]:
                closest[me] = (d, other)
    rows = []
    for a in view.aircraft:
        d, other = closest.get(a.callsign, (None, "-"))
        rows.append([str(a.order), a.callsign, "-" if a.gate_time is None else f"{a.gate_time:.2f}",
                     "-" if a.landing_time is None else f"{a.landing_time:.2f}",
                     "-" if d is None else f"{d:.3f} ({other})"])
    return rows


def figure_overview(view: PlanView, colors: dict[str, str], seps: list[PairSeparation]):
    """One page: 3-D and plan views, altitude and separation against time, the Table 6-1 analog and, beside it,
    the landing sequence as a time line."""
    n = len(view.aircraft)
    table_h = 1.0 + 0.26 * n
    fig = plt.figure(figsize=(12.0, 9.0 + table_h))
    legend_rows = -(-(n + 4) // 12)
    top = 1.0 - (0.75 + 0.22 * legend_rows) / fig.get_figheight()
    gs = fig.add_gridspec(3, 2, height_ratios=[4.4, 3.2, table_h], hspace=0.35, wspace=0.18,
                          left=0.05, right=0.98, top=top, bottom=0.45 / fig.get_figheight())
    ax3 = fig.add_subplot(gs[0, 0], projection="3d", computed_zorder=False)
    draw_3d(ax3, view, colors)
    ax3.set_title("3-D view")
    draw_plan(fig.add_subplot(gs[0, 1]), view, colors, labels=True)
    axz = fig.add_subplot(gs[1, 0])
    draw_series(axz, view, colors, "z")
    shaded = " (shaded: every other optimizer phase)" if view.optimized else ""
    axz.set(xlabel="time (s)", title=f"Altitude against time{shaded}")
    axs = fig.add_subplot(gs[1, 1])
    draw_separation(axs, view, seps, colors)
    axs.set_title("Separation of every pair")
    axs.legend(loc="upper right", fontsize=style.FONT_SIZE - 2, ncol=2)
    axt = fig.add_subplot(gs[2, 0])
    axt.axis("off")
    rows = summary_rows(view, seps)
    table = axt.table(cellText=rows, colLabels=["order", "aircraft", "gate passage (s)", "landing (s)",
                                                "closest approach (nm, to)"], loc="upper center", cellLoc="center",
                      colWidths=[0.1, 0.13, 0.23, 0.18, 0.36])
    table.auto_set_font_size(False)
    table.set_fontsize(style.FONT_SIZE - 0.5)
    for i, a in enumerate(view.aircraft, start=1):
        table[i, 1].get_text().set_color(colors[a.callsign])
        table[i, 1].get_text().set_fontweight("bold")
    _overview_sequence(fig, gs[2, 1], view, colors)
    verdict = ("optimal, verified" if view.verified else "optimal, NOT verified") if view.optimized else (
        view.status.replace("_", " "))
    order = view.callsigns if n <= 8 else [*view.callsigns[:3], "…", view.callsigns[-1]]
    fig.suptitle(f"{view.name}: {n} aircraft, landing order {' → '.join(order)} ({verdict})",
                 fontsize=style.FONT_SIZE + 3, fontweight="bold", y=0.995)
    _legend(fig, view, colors, loc="top")
    return fig


def _overview_sequence(fig, cell, view: PlanView, colors: dict[str, str]) -> None:
    """The overview's time-line panel: the landing sequence in ``cell``, its gap labels in a column at its right."""
    tl = view.timeline
    column = _label_column(tl, False, style.FONT_SIZE - 1.5)
    cell_w = cell.get_position(fig).width * fig.get_figwidth()
    sub = cell.subgridspec(1, 2, width_ratios=[max(cell_w - column - 0.1, 1.0), column + 0.1], wspace=0.0)
    ax = fig.add_subplot(sub[0, 0])
    draw_sequence(ax, tl, colors, pair_labels=False)
    ax.set_xlabel("time (s)", labelpad=1)
    key = ["| target, shaded: delay"] if any(s.target is not None for s in tl.slots) else []
    key += [f"total {tl.total_delay:.1f} s"] if tl.total_delay is not None else []
    ax.set_title("Landing sequence" + (f" ({'; '.join(key)})" if key else ""))

def write_pngs(view: PlanView, out_dir: Path) -> list[Path]:
    """Every PNG of a plan into ``out_dir``; return the paths."""
    out_dir = Path(out_dir)
    colors = style.color_map(view.callsigns)
    seps = view.separations()
    jobs: list[tuple[str, Callable[[], object]]] = [
        ("initial_paths_3d", lambda: figure_paths_3d(view, colors, initial=True)),
        *[(f"initial_{k}", lambda k=k: figure_series(view, colors, k, initial=True)) for k in "xyz"],
        ("overview", lambda: figure_overview(view, colors, seps)),
        ("plan_view", lambda: figure_plan(view, colors)),
        ("yz_view", lambda: figure_yz(view, colors)),
        ("separation", lambda: figure_separation(view, colors, seps)),
        ("sequence", lambda: figure_sequence(view, colors)),
    ]
    if view.optimized:
        jobs += [
            ("paths_3d", lambda: figure_paths_3d(view, colors)),
            ("states", lambda: figure_states(view, colors)),
            ("controls", lambda: figure_controls(view, colors)),
        ]
    return [style.save(make(), out_dir / f"{name}.png") for name, make in jobs]
