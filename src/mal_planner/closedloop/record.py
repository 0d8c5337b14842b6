"""The record of one closed-loop run as written to ``closed_loop.json`` (by ``mal-closed-loop``, and by
``mal-campaign --closed-loop`` for each run that failed): its metrics, options, every plan request, what each
aircraft was told to fly and when, and the flown tracks."""

from __future__ import annotations

from typing import Any

from mal_planner.closedloop.loop import ClosedLoopRun
from mal_planner.closedloop.metrics import ClosedLoopMetrics


def run_record(run: ClosedLoopRun, metrics: ClosedLoopMetrics, options: dict[str, Any]) -> dict[str, Any]:
    """``closed_loop.json``'s content; ``options``: how the run was asked for (the CLI's or the campaign's)."""
    return {"metrics": metrics.to_dict(), "options": options,
            "plans": [vars(r) for r in [run.first, *run.replans]],
            "instructions": [{"t": t, "callsign": cs, "kind": kind} for t, cs, kind in run.instructions],
            "flown": {ac.callsign: {"t": ac.t, "x": [s[0] for s in ac.states], "y": [s[1] for s in ac.states],
                                    "z": [s[2] for s in ac.states], "status": ac.status, "note": ac.end_note}
                      for ac in run.sim.aircraft}}
