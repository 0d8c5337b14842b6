"""Figures of a plan: PNGs (matplotlib, :mod:`.static`) and the interactive ``plan.html`` (plotly,
:mod:`.interactive`), both drawn from a plan.json document with the one style of :mod:`.style`.

matplotlib and plotly are imported only when something is rendered, so ``import mal_planner`` stays lean.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

FIGURE_CHOICES = ("none", "png", "html", "all")
"""Values of ``mal-plan --figures`` and of the node parameter ``figures``."""

log = logging.getLogger("mal_planner.figures")


def want(figures: str | bool) -> frozenset[str]:
    """The kinds to write ({'png', 'html'}) for a --figures value; True means png, False none."""
    if isinstance(figures, bool):
        return frozenset({"png"} if figures else ())
    value = str(figures).strip().lower()
    if value not in FIGURE_CHOICES:
        raise ValueError(f"figures must be one of {', '.join(FIGURE_CHOICES)}, got {figures!r}")
    return frozenset({"png", "html"} if value == "all" else () if value == "none" else {value})


def render(doc: dict, out_dir: Path, kinds: frozenset[str] | set[str]) -> list[Path]:
    """Write the PNGs and/or plan.html of a plan.json document into ``out_dir``; return the paths."""
    from mal_planner.figures.data import plan_view

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    view = plan_view(doc)
    written: list[Path] = []
    t0 = time.perf_counter()
    if "png" in kinds:
        from mal_planner.figures.static import write_pngs

        written += write_pngs(view, out_dir)
    t1 = time.perf_counter()
    if "html" in kinds:
        from mal_planner.figures.interactive import write_html

        written.append(write_html(view, out_dir / "plan.html"))
    log.info("figures: %d files in %.2f s (png %.2f s, html %.2f s)", len(written), time.perf_counter() - t0,
             t1 - t0, time.perf_counter() - t1)
    return written
