"""The closed-loop figure: the flown tracks over the plans they followed, and the separation flown."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from mal_planner.closedloop.simulator import FlightSimulator
from mal_planner.scenario import Scenario

FALLBACK_STYLE = {"hold": ("#111111", ":"), "vector": ("#d62728", "-")}
"""How the stretches flown on a service fallback are overdrawn: holds black dotted, the safety net's vectors red."""


def _fallback_stretches(instructions: list[tuple[float, str, str]], callsign: str, end: float
                        ) -> list[tuple[str, float, float]]:
    """(kind, from, to) of the stretches an aircraft flew on a hold or a vector."""
    told = sorted((t, kind) for t, cs, kind in instructions if cs == callsign) + [(end, "end")]
    return [(kind, t0, t1) for (t0, kind), (t1, _) in itertools.pairwise(told) if kind in FALLBACK_STYLE]


def _kind_at(instructions: list[tuple[float, str, str]], callsign: str, t: float) -> str:
    """What the aircraft was last told to fly at ``t`` ("plan" where nothing says otherwise)."""
    told = [(ti, kind) for ti, cs, kind in instructions if cs == callsign and ti <= t]
    return max(told)[1] if told else "plan"


def figure_closed_loop(sc: Scenario, sim: FlightSimulator, path: Path,
                       instructions: list[tuple[float, str, str]] | None = None) -> Path:
    """Left: plan view (flown tracks solid, every plan they were given dashed, a dot where a new plan began to be
    flown, the stretches flown on a hold or a vector overdrawn, the obstacles' footprints); right: the distance of
    each pair over time (over 8 aircraft: of each aircraft to its nearest), with the minimum."""
    from mal_planner.figures.style import WIDTH_IN, apply_style, color_map, save

    apply_style()
    import matplotlib.pyplot as plt

    colors = color_map([ac.callsign for ac in sim.aircraft])
    fig, (ax, ax_sep) = plt.subplots(1, 2, figsize=(WIDTH_IN * 1.6, WIDTH_IN * 0.7),
                                     gridspec_kw={"width_ratios": [1.2, 1.0]})
    _plan_view(ax, sc, sim, colors, instructions or [])
    _separations(ax_sep, sc, sim, colors)
    fig.tight_layout()
    return save(fig, path)


def _plan_view(ax, sc: Scenario, sim: FlightSimulator, colors: dict, told: list[tuple[float, str, str]]) -> None:
    from mal_planner.figures.style import OBSTACLE_COLOR, RUNWAY_COLOR

    for ob in sc.obstacles:
        box = ob.bounding_box()
        ax.add_patch(_rectangle(box, OBSTACLE_COLOR))
    for ac in sim.aircraft:
        x = np.asarray(ac.states)
        c = colors[ac.callsign]
        for ref, t_arr in zip(ac.plans, ac.plan_arrivals, strict=True):
            if _kind_at(told, ac.callsign, t_arr) not in FALLBACK_STYLE:  # a hold is drawn far ahead: flown part only
                ax.plot(ref.table[:, 0], ref.table[:, 1], "--", color=c, lw=0.7, alpha=0.6)
        t_flown = np.asarray(ac.t)
        for kind, t0, t1 in _fallback_stretches(told, ac.callsign, float(t_flown[-1])):
            keep = (t_flown >= t0) & (t_flown <= t1)
            color, style = FALLBACK_STYLE[kind]
            ax.plot(x[keep, 0], x[keep, 1], style, color=color, lw=2.2, alpha=0.8)
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
    for kind, (color, style) in FALLBACK_STYLE.items():
        if any(k == kind for _, _, k in told):
            ax.plot([], [], style, color=color, lw=2.2, label=kind)
    ax.set_title("flown (solid) and planned (dashed); dots: a new plan flown")
    ax.legend(fontsize=6 if len(sim.aircraft) > 8 else 7, loc="best", ncol=2 if len(sim.aircraft) > 8 else 1)


def _rectangle(box: np.ndarray, color: str):
    import matplotlib.pyplot as plt

    return plt.Rectangle((box[0, 0], box[1, 0]), box[0, 1] - box[0, 0], box[1, 1] - box[1, 0], color=color,
                         alpha=0.25, lw=0)


def _separations(ax_sep, sc: Scenario, sim: FlightSimulator, colors: dict) -> None:
    flown = sim.flown()
    nearest = len(flown) > 8
    closest: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for a, b in itertools.combinations(flown, 2):
        (ta, xa), (tb, xb) = flown[a], flown[b]
        t = ta[(ta >= max(ta[0], tb[0])) & (ta <= min(ta[-1], tb[-1]))]
        if len(t) < 2:
            continue
        other = np.column_stack([np.interp(t, tb, xb[:, k]) for k in range(3)])
        d = np.linalg.norm(np.column_stack([np.interp(t, ta, xa[:, k]) for k in range(3)]) - other, axis=1)
        if not nearest:
            ax_sep.plot(t, d, lw=1.0, label=f"{a}-{b}")
            continue
        for cs in (a, b):  # each aircraft's distance to its nearest, on its own samples
            own_t = flown[cs][0]
            dd = np.interp(own_t, t, d, left=np.inf, right=np.inf)
            prev = closest.get(cs)
            closest[cs] = (own_t, dd if prev is None else np.minimum(prev[1], dd))
    for cs, (t, d) in closest.items():
        finite = np.isfinite(d)
        ax_sep.plot(t[finite], d[finite], lw=0.8, color=colors[cs])
    ax_sep.axhline(sc.separation_nm, color="#d62728", lw=1.0, ls="--", label="minimum")
    for t_new in sorted({t for ac in sim.aircraft for t in ac.plan_arrivals[1:]}):
        ax_sep.axvline(t_new, color="k", lw=0.4, alpha=0.3)
    ax_sep.set_xlabel("t (s)")
    ax_sep.set_ylabel("distance (nm)")
    ax_sep.set_title(("distance of each aircraft to its nearest" if nearest else "distance of each pair")
                     + " (grey: a new plan flown)")
    if not nearest:
        ax_sep.legend(fontsize=7, loc="best")
