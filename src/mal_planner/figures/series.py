"""States, controls and separations against time (thesis Figures 4-2 to 4-4 and 6-3 to 6-14), the
optimizer's phases shaded."""

from __future__ import annotations

import numpy as np

from mal_planner.dynamics import bank_angle
from mal_planner.figures import style
from mal_planner.figures.annotate import add_legend, aircraft_events, label_events, shade_phases, value_at
from mal_planner.figures.data import PairSeparation, PlanView

style.apply_style()
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

SERIES = {
    "x": ("x (nm)", 0, 1.0),
    "y": ("y (nm)", 1, 1.0),
    "z": ("z (nm)", 2, 1.0),
    "gamma": ("flight-path angle (deg)", 3, 180.0 / np.pi),
    "heading": ("heading (deg)", 4, 180.0 / np.pi),
    "airspeed": ("true airspeed (kt)", 5, 3600.0),
}
HIGHLIGHTED_PAIRS = 8
"""Separation figure: the pairs that come closest get a colour and a legend entry, the rest are grey."""


def _values(traj, key: str) -> np.ndarray:
    """The state ``key`` of :data:`SERIES` in its unit (heading unwrapped)."""
    _, col, scale = SERIES[key]
    if key == "heading":
        return np.degrees(np.unwrap(traj.states[:, col]))
    return traj.states[:, col] * scale


def draw_series(ax, view: PlanView, colors: dict[str, str], key: str, initial: bool = False) -> None:
    """One state against time for every aircraft, with phase bands and event markers."""
    if not initial:
        shade_phases(ax, view)
    for a in view.aircraft:
        tr = a.initial if initial else a.trajectory
        vals, c = _values(tr, key), colors[a.callsign]
        ax.plot(tr.t, vals, color=c)
        ax.plot(tr.t[0], vals[0], color=c, marker=style.MARKERS["start"], ms=3.5)
        events = [("land", float(tr.t[-1]))] if initial else aircraft_events(a)
        for kind, t in events:
            v = value_at(tr, t, vals)
            if v is not None:
                ax.plot(t, v, color=c, marker=style.MARKERS[kind], ms=5, mec="k", mew=0.4)
    ax.set_ylabel(SERIES[key][0])


def draw_separation(ax, view: PlanView, seps: list[PairSeparation], colors: dict[str, str]) -> None:
    """Distance of every pair against time (closest pairs coloured), the required separation and each minimum."""
    shade_phases(ax, view)
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


def figure_series(view: PlanView, colors: dict[str, str], key: str, initial: bool = False):
    """One state against time (thesis Figures 4-2 to 4-4)."""
    fig, ax = plt.subplots(figsize=(style.WIDTH_IN, 3.4))
    draw_series(ax, view, colors, key, initial=initial)
    ax.set_xlabel("time (s)")
    ax.set_title(f"{view.name}: {'initial ' if initial else ''}{SERIES[key][0].split(' (')[0]} against time")
    add_legend(fig, view, colors)
    return fig


def figure_states(view: PlanView, colors: dict[str, str]):
    """x, y, z, flight-path angle and heading against time (thesis Figures 6-3 to 6-7), phases shaded; and the
    airspeed of airspeed-model plans."""
    keys = ("x", "y", "z", "gamma", "heading")
    if view.aircraft and all(a.trajectory.states.shape[1] > SERIES["airspeed"][1] for a in view.aircraft):
        keys += ("airspeed",)
    fig, axs = plt.subplots(len(keys), 1, figsize=(style.WIDTH_IN, 1.9 * len(keys)), sharex=True)
    for ax, key in zip(axs, keys, strict=True):
        draw_series(ax, view, colors, key)
    axs[-1].set_xlabel("time (s)")
    axs[0].set_xlim(left=0.0)
    add_legend(fig, view, colors, top=0.97)
    rows = label_events(axs[0], view, colors)  # their x positions do not depend on the top margin
    fig.subplots_adjust(top=1.0 - (10 * rows + 26) / 72 / fig.get_figheight())
    fig.suptitle(f"{view.name}: states against time (shaded: every other optimizer phase)", y=0.995, va="top")
    return fig


def figure_controls(view: PlanView, colors: dict[str, str]):
    """Bank angle and load factors of every aircraft against their limits (thesis Figures 6-8 to 6-13); the
    longitudinal one of airspeed-model plans."""
    thrust = bool(view.aircraft) and all(a.trajectory.controls is not None and a.trajectory.controls.shape[1] > 2
                                         for a in view.aircraft)
    fig, axs = plt.subplots(3 + thrust, 1, figsize=(style.WIDTH_IN, 7.0 + 2.3 * thrust), sharex=True)
    same = len({a.limits for a in view.aircraft}) == 1
    for a in view.aircraft:
        tr, c = a.trajectory, colors[a.callsign]
        if tr.controls is None:
            continue
        n_h, n_v = tr.controls[:, 0], tr.controls[:, 1]
        series = (np.degrees(bank_angle(n_h, n_v)), n_h, n_v, *([tr.controls[:, 2]] if thrust else []))
        for ax, vals in zip(axs, series, strict=True):
            ax.plot(tr.t, vals, color=c, lw=1.1)
    limit_sets = [(None, view.aircraft[0].limits)] if same else [(a.callsign, a.limits) for a in view.aircraft]
    for cs, lim in limit_sets:
        c = style.REQUIRED_COLOR if cs is None else colors[cs]
        bank = np.degrees(lim.bank_angle_max)
        for ax, (lo, hi) in zip(axs, ((-bank, bank), lim.n_h, lim.n_v, *([lim.n_x] if thrust else [])), strict=True):
            for v in (lo, hi):
                ax.axhline(v, color=c, ls="--", lw=1.0, alpha=0.9)
    labels = ("bank angle (deg)", "n_h (horizontal load factor)", "n_v (vertical load factor)",
              "n_x ((thrust - drag) / weight)")
    for ax, label in zip(axs, labels[:len(axs)], strict=True):
        shade_phases(ax, view)
        ax.set_ylabel(label)
    axs[-1].set_xlabel("time (s)")
    axs[0].set_xlim(left=0.0)
    fig.suptitle(f"{view.name}: controls against their limits (dashed)", y=0.995, va="top")
    add_legend(fig, view, colors, [Line2D([], [], color=style.REQUIRED_COLOR if same else "0.3", ls="--",
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
