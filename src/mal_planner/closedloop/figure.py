"""The closed-loop figure: the flown tracks over the plans they followed, and the separation flown."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from mal_planner.closedloop.simulator import FlightSimulator
from mal_planner.scenario import Scenario


def figure_closed_loop(sc: Scenario, sim: FlightSimulator, path: Path) -> Path:
    """Left: plan view (flown tracks solid, every plan they were given dashed, a dot where a new plan began to be
    flown, the obstacles' footprints); right: the distance of each pair over time, with the minimum."""
    from mal_planner.figures.style import OBSTACLE_COLOR, RUNWAY_COLOR, WIDTH_IN, apply_style, color_map, save

    apply_style()
    import matplotlib.pyplot as plt

    colors = color_map([ac.callsign for ac in sim.aircraft])
    fig, (ax, ax_sep) = plt.subplots(1, 2, figsize=(WIDTH_IN * 1.6, WIDTH_IN * 0.7),
                                     gridspec_kw={"width_ratios": [1.2, 1.0]})
    for ob in sc.obstacles:
        box = ob.bounding_box()
        ax.add_patch(plt.Rectangle((box[0, 0], box[1, 0]), box[0, 1] - box[0, 0], box[1, 1] - box[1, 0],
                                   color=OBSTACLE_COLOR, alpha=0.25, lw=0))
    for ac in sim.aircraft:
        x = np.asarray(ac.states)
        c = colors[ac.callsign]
        for ref in ac.plans:
            ax.plot(ref.table[:, 0], ref.table[:, 1], "--", color=c, lw=0.7, alpha=0.6)
        ax.plot(x[:, 0], x[:, 1], "-", color=c, lw=1.6, label=f"{ac.callsign} ({ac.status})")
        ax.plot(x[0, 0], x[0, 1], "o", color=c, ms=4)
        for t_arr in ac.plan_arrivals[1:]:
            k = min(np.searchsorted(ac.t, t_arr), len(x) - 1)
            ax.plot(x[k, 0], x[k, 1], ".", color="k", ms=4)
    rw = sc.runway_state
    ax.plot(rw[0], rw[1], "v", color=RUNWAY_COLOR, ms=7, label="runway")
    ax.set_aspect("equal")
    ax.set_xlabel("x (nm)")
    ax.set_ylabel("y (nm)")
    ax.set_title("flown (solid) and planned (dashed); dots: a new plan flown")
    ax.legend(fontsize=7, loc="best")
    flown = sim.flown()
    for a, b in itertools.combinations(flown, 2):
        (ta, xa), (tb, xb) = flown[a], flown[b]
        t = ta[(ta >= max(ta[0], tb[0])) & (ta <= min(ta[-1], tb[-1]))]
        if len(t) < 2:
            continue
        other = np.column_stack([np.interp(t, tb, xb[:, k]) for k in range(3)])
        mine = np.column_stack([np.interp(t, ta, xa[:, k]) for k in range(3)])
        ax_sep.plot(t, np.linalg.norm(mine - other, axis=1), lw=1.0, label=f"{a}-{b}")
    ax_sep.axhline(sc.separation_nm, color="#d62728", lw=1.0, ls="--", label="minimum")
    for t_new in sorted({t for ac in sim.aircraft for t in ac.plan_arrivals[1:]}):
        ax_sep.axvline(t_new, color="k", lw=0.4, alpha=0.3)
    ax_sep.set_xlabel("t (s)")
    ax_sep.set_ylabel("distance (nm)")
    ax_sep.set_title("distance of each pair (grey: a new plan flown)")
    if len(flown) <= 8:
        ax_sep.legend(fontsize=7, loc="best")
    fig.tight_layout()
    return save(fig, path)
