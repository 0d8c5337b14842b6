"""The planner node's files in its output folder: ``planner_status.json`` (for ``mal-launch``) and each plan's
``plan.json``, ``report.md`` and figures (rendered in a background process, so that the node never waits for them).
"""

from __future__ import annotations

import json
import logging
import subprocess
from pathlib import Path
from typing import Any

import yaml

from mal_planner import jsonio
from mal_planner.pipeline import PlanResult
from mal_planner.ros.node_params import closed_loop_values
from mal_planner.ros.plan_messages import aircraft_verified
from mal_planner.scenario import load_scenario

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


def read_status(out: Path) -> dict[str, Any] | None:
    """The node's ``planner_status.json`` in ``out`` (None: none yet, or half written)."""
    try:
        return json.loads((out / STATUS_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def summary_table(status: dict[str, Any]) -> str:
    """The plan of a status file as a table: order, callsign, landing time, verified."""
    rows = [f"{'order':>5}  {'callsign':<8} {'landing (s)':>11}  verified"]
    for ac in status.get("aircraft", []):
        rows.append(f"{ac['order']:>5}  {ac['callsign']:<8} {ac['landing_time_s']:>11.2f}  "
                    f"{'yes' if ac['verified'] else 'no'}")
    return "\n".join(rows)


def write_closed_loop_params(params: str, scenario: str, out: Path, noise_m: float = 0.0,
                             radar_rate_hz: float = 1.0) -> str:
    """The planner's params file for a closed loop: the given one, on simulated time, planning once every aircraft
    is tracked, with the closed loop's rules (:meth:`~mal_planner.service.rules.ServiceRules.closed_loop`: the
    deviation threshold from the path accuracy and the radar noise, a turn time between replans) and the margins
    of flown plans."""
    data = yaml.safe_load(Path(params).read_text(encoding="utf-8")) or {}
    data.setdefault("planner", {}).setdefault("ros__parameters", {}).update(
        closed_loop_values(load_scenario(scenario), noise_m, 1.0 / radar_rate_hz))
    path = out / "planner.closed_loop.params.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return str(path)
