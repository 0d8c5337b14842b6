"""Where the aircraft fly: 3-D paths with the obstacles (thesis Figures 4-1 and 6-1), the plan view and the Y-Z
view (thesis Figure 6-2). Each ``draw_*`` draws into a given axis, so the overview reuses them."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mal_planner.figures import style
from mal_planner.figures.annotate import (
    add_legend,
    aircraft_events,
    legend_handles,
    legend_margin,
    place_labels,
    value_at,
)
from mal_planner.figures.data import PlanView
from mal_planner.figures.geometry import gate_outline, obstacle_mesh, projection, section

style.apply_style()
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402


def _hole_centre(view: PlanView) -> np.ndarray | None:
    return view.gates[0].center() if view.gates else None


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
            for kind, t in aircraft_events(a):
                q = [value_at(tr, t, p[:, k]) for k in range(3)]
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
        for kind, t in aircraft_events(a):
            u, v = value_at(tr, t, p[:, axes[0]]), value_at(tr, t, p[:, axes[1]])
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


def figure_paths_3d(view: PlanView, colors: dict[str, str], initial: bool = False):
    """3-D paths with the obstacles (thesis Figures 4-1 and 6-1)."""
    fig = plt.figure(figsize=(style.WIDTH_IN, 5.6))
    ax = fig.add_subplot(projection="3d", computed_zorder=False)
    draw_3d(ax, view, colors, initial=initial, direct=initial)
    what = "initial paths (RRT + sequencer)" if initial else "optimal trajectories"
    ax.set_title(f"{view.name}: {what}")
    extra = [Line2D([], [], color="0.3", ls="--", label="shortest path")] if initial else []
    width, _ = legend_margin(fig, legend_handles(view, colors, extra))
    fig.subplots_adjust(left=0.0, right=1.0 - width, bottom=0.02, top=0.95)
    add_legend(fig, view, colors, extra, layout=False)
    return fig


def _figure_2d(view: PlanView, colors: dict[str, str], size: tuple[float, float], draw: Callable) -> object:
    """A 2-D view with the legend at its right; the axes are placed before drawing (labels need them)."""
    fig, ax = plt.subplots(figsize=size)
    extra: list[Line2D] = []
    width, _ = legend_margin(fig, legend_handles(view, colors, extra))
    em_w, em_h = style.FONT_SIZE / 72 / size[0], style.FONT_SIZE / 72 / size[1]
    fig.subplots_adjust(left=6 * em_w, right=1.0 - width - em_w, bottom=4 * em_h, top=1.0 - 2.5 * em_h)
    draw(ax, view, colors)
    add_legend(fig, view, colors, extra, layout=False)
    return fig


def figure_plan(view: PlanView, colors: dict[str, str]):
    return _figure_2d(view, colors, (style.WIDTH_IN, style.WIDTH_IN * 0.85), draw_plan)


def figure_yz(view: PlanView, colors: dict[str, str]):
    return _figure_2d(view, colors, (style.WIDTH_IN, 3.2), draw_yz)

