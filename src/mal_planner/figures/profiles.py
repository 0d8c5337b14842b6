"""Speed and altitude profiles against the track miles to the threshold, with the limits they keep: what a controller
checks of an arrival (the airspeed model's plans; :mod:`mal_planner.scenario.procedures`)."""

from __future__ import annotations

import numpy as np

from mal_planner.figures import style
from mal_planner.figures.annotate import add_legend
from mal_planner.figures.data import AircraftView, PlanView
from mal_planner.units import nm_per_s_to_kt, nm_to_ft

style.apply_style()
import matplotlib.pyplot as plt  # noqa: E402

LIMIT_STYLE = {"color": style.REQUIRED_COLOR, "lw": 1.1, "ls": "--", "zorder": 5}
TYPE_STYLE = {"color": "0.35", "lw": 1.0, "ls": ":", "zorder": 5}


def has_profiles(view: PlanView) -> bool:
    """Whether the plan has calibrated airspeeds to draw (aircraft of the airspeed model)."""
    return view.optimized and any(a.cas is not None for a in view.aircraft)


def distance_to_threshold(view: PlanView, a: AircraftView) -> np.ndarray:
    """Track miles to go (nm) at each of ``a``'s samples: the ground distance it still flies to its path's end on
    the threshold (as controllers count; on the straight final the distance to the threshold itself)."""
    steps = np.hypot(*np.diff(a.trajectory.positions[:, :2], axis=0).T)
    return np.concatenate([np.cumsum(steps[::-1])[::-1], [0.0]])


def _speed_panel(ax, view: PlanView, colors: dict[str, str]) -> None:
    for a in view.aircraft:
        if a.cas is not None:
            ax.plot(distance_to_threshold(view, a), nm_per_s_to_kt(a.cas), color=colors[a.callsign], lw=1.3)
    pr = view.procedures
    if pr:
        reach = max(float(distance_to_threshold(view, a).max()) for a in view.aircraft)
        final = pr["final_distance_nm"]
        ax.plot([0.0, final], [nm_per_s_to_kt(pr["final_speed"])] * 2, **LIMIT_STYLE,
                label=f"{nm_per_s_to_kt(pr['final_speed']):.0f} kt inside {final:g} nm")
        below_ft = nm_to_ft(pr["speed_limit_below_nm"])
        ax.plot([0.0, reach], [nm_per_s_to_kt(pr["speed_limit"])] * 2, **{**LIMIT_STYLE, "ls": "-."},
                label=f"{nm_per_s_to_kt(pr['speed_limit']):.0f} kt below {below_ft:,.0f} ft")
    envelopes = {a.envelope["type"]: a.envelope for a in view.aircraft if a.envelope}
    for kind, env in envelopes.items():
        low, high = (nm_per_s_to_kt(v) for v in env["final_approach_cas"])
        ax.plot([0.0, 0.0], [low, high], color="0.2", lw=5, alpha=0.35, solid_capstyle="butt", zorder=4,
                label=f"{kind} final approach {low:.0f}-{high:.0f} kt")
        ax.axhline(nm_per_s_to_kt(env["vmo"]), **TYPE_STYLE, label=f"{kind} VMO {nm_per_s_to_kt(env['vmo']):.0f} kt")
    ax.set_ylabel("calibrated airspeed (kt)")
    ax.legend(loc="upper left", fontsize=style.FONT_SIZE - 1.5, frameon=False)


def _altitude_panel(ax, view: PlanView, colors: dict[str, str]) -> None:
    for a in view.aircraft:
        ax.plot(distance_to_threshold(view, a), nm_to_ft(view.elevation_nm + a.trajectory.positions[:, 2]),
                color=colors[a.callsign], lw=1.3)
    reach = max(float(distance_to_threshold(view, a).max()) for a in view.aircraft)
    threshold_ft = nm_to_ft(view.elevation_nm + float(view.runway[2]))
    slope = -float(np.tan(view.runway[3]))
    if slope > 0.0:
        d = np.array([0.0, reach])
        ax.plot(d, threshold_ft + nm_to_ft(slope * d), color="0.35", lw=0.9, ls=":", zorder=4,
                label=f"glide path {np.degrees(np.arctan(slope)):.1f} deg")
    pr = view.procedures
    if pr:
        floor_ft = threshold_ft + nm_to_ft(pr["min_height_nm"])
        ax.fill_between([pr["final_distance_nm"], reach], threshold_ft, floor_ft, color=style.REQUIRED_COLOR,
                        alpha=0.12, lw=0, zorder=1, label=f"below {nm_to_ft(pr['min_height_nm']):,.0f} ft above the "
                                                          f"threshold beyond {pr['final_distance_nm']:g} nm")
        ax.axhline(nm_to_ft(pr["speed_limit_below_nm"]), **{**LIMIT_STYLE, "ls": "-."})
    ax.set(xlabel="track miles to the threshold (nm)", ylabel="altitude (ft)")
    ax.set_ylim(bottom=threshold_ft)
    ax.legend(loc="upper left", fontsize=style.FONT_SIZE - 1.5, frameon=False)


def figure_profiles(view: PlanView, colors: dict[str, str]):
    """Calibrated airspeed and altitude against the track miles to the threshold (the runway on the left), with the
    procedures' limits (the speed limit, the final speed, the minimum height) and each type's VMO and final approach
    speeds."""
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(style.WIDTH_IN, 6.2), sharex=True)
    _speed_panel(top, view, colors)
    _altitude_panel(bottom, view, colors)
    bottom.set_xlim(left=0.0)
    top.set_title(f"{view.name}: speed and altitude profiles")
    add_legend(fig, view, colors)
    return fig
