"""The planner node's files in its output folder: ``planner_status.json`` (for ``mal-launch``) and each plan's
``plan.json``, ``report.md`` and figures (rendered in a background process, so that the node never waits for them).
"""

from __future__ import annotations

import logging
import subprocess
from pathlib import Path
from typing import Any

from mal_planner import jsonio
from mal_planner.pipeline import PlanResult
from mal_planner.ros.plan_messages import aircraft_verified

STATUS_FILE = "planner_status.json"
log = logging.getLogger("mal_planner.ros.planner")


class NodeOutputs:
    """Writes into ``out_dir`` (None: nothing)."""

    def __init__(self, out_dir: str | Path | None, figures: str) -> None:
        self._renderer: subprocess.Popen | None = None
        self.set_folder(out_dir, figures)

    def set_folder(self, out_dir: str | Path | None, figures: str) -> None:
        """Write into ``out_dir`` from now on (a parameter set at run time); the figure renderer carries on."""
        self.out_dir = Path(out_dir) if out_dir else None
        self.figures = figures

    def write_status(self, counts: dict[str, Any], plan_start: float | None, result: PlanResult | None,
                     flying: set[str]) -> None:
        """``planner_status.json``: plan counts, busy flags, the plan being flown (strict JSON, atomically)."""
        if self.out_dir is None:
            return
        status: dict[str, Any] = {**counts, "plan_start": plan_start, "aircraft": []}
        if result is not None:
            land = result.landing_times()
            status["aircraft"] = [{"order": k, "callsign": cs, "landing_time_s": land[cs],
                                   "verified": aircraft_verified(result, cs)}
                                  for k, cs in enumerate(result.order, 1) if cs in flying]
        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            jsonio.write(self.out_dir / STATUS_FILE, status)
        except OSError as exc:
            log.error("cannot write %s: %s", self.out_dir / STATUS_FILE, exc)

    def write_plan(self, result: PlanResult) -> bool:
        """plan.json and report.md now, the figures in the background; False when nothing was written."""
        if self.out_dir is None:
            return False
        from mal_planner.report import start_figures, write_outputs

        try:
            write_outputs(result, self.out_dir, figures="none")
            if self.figures != "none":
                self._renderer = start_figures(self.out_dir, self.figures, self._renderer)
        except Exception as exc:
            log.error("writing outputs to %s failed: %s", self.out_dir, exc)
            return False
        return True
