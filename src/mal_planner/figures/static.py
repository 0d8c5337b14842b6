"""PNG figures of a plan (matplotlib, Agg): the thesis's Figures 4-1 to 4-4 and 6-1 to 6-14, restyled.

The figure families are modules of their own: :mod:`.spatial` (3-D, plan and Y-Z views), :mod:`.series` (states,
controls and separations against time), :mod:`.sequence` (the landing time line) and :mod:`.overview`; what they
share (legend, event marks, labels) is :mod:`.annotate`; :mod:`.profiles` draws the airspeed model's speed and
altitude against the distance to the threshold. This module writes the set.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from mal_planner.figures import style
from mal_planner.figures.annotate import stagger_rows
from mal_planner.figures.data import PlanView
from mal_planner.figures.overview import figure_overview
from mal_planner.figures.profiles import figure_profiles, has_profiles
from mal_planner.figures.sequence import figure_sequence, gap_label
from mal_planner.figures.series import figure_controls, figure_separation, figure_series, figure_states
from mal_planner.figures.spatial import figure_paths_3d, figure_plan, figure_yz

__all__ = [
    "figure_controls", "figure_overview", "figure_paths_3d", "figure_profiles", "figure_plan", "figure_separation",
    "figure_sequence", "figure_series", "figure_states", "figure_yz", "gap_label", "stagger_rows", "write_pngs",
]
"""The figures of the set, and the label rules (:func:`gap_label`, :func:`stagger_rows`) callers use with them."""


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
    if has_profiles(view):
        jobs.append(("profiles", lambda: figure_profiles(view, colors)))
    return [style.save(make(), out_dir / f"{name}.png") for name, make in jobs]
