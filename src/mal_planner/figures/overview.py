"""The one-page overview of a plan: 3-D and plan views, altitude and separation against time, the Table 6-1
analog and the landing sequence."""

from __future__ import annotations

import numpy as np

from mal_planner.figures import style
from mal_planner.figures.annotate import add_legend
from mal_planner.figures.data import PairSeparation, PlanView
from mal_planner.figures.sequence import draw_sequence_panel
from mal_planner.figures.series import draw_separation, draw_series
from mal_planner.figures.spatial import draw_3d, draw_plan

style.apply_style()
import matplotlib.pyplot as plt  # noqa: E402


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
    draw_sequence_panel(fig, gs[2, 1], view, colors)
    verdict = ("optimal, verified" if view.verified else "optimal, NOT verified") if view.optimized else (
        view.status.replace("_", " "))
    order = view.callsigns if n <= 8 else [*view.callsigns[:3], "…", view.callsigns[-1]]
    fig.suptitle(f"{view.name}: {n} aircraft, landing order {' → '.join(order)} ({verdict})",
                 fontsize=style.FONT_SIZE + 3, fontweight="bold", y=0.995)
    add_legend(fig, view, colors, loc="top")
    return fig
