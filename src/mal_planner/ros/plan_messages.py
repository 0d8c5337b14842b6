"""The planner node's outgoing messages, built from plans (no DDS): LandingPlan, Paths and diagnostics.

``types`` is a node's ``node.types``, so the same code serves the rclpy and the built-in backend.
"""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

import numpy as np

from mal_planner.dynamics import bank_angle
from mal_planner.errors import outcome_code
from mal_planner.geodesy import GeoFrame
from mal_planner.pipeline import PlanResult
from mal_planner.ros.convert import byte_field, frame_origin_fields, geodetic_path_fields, path_msg, time_to_msg
from mal_planner.service.request import PlanRequest
from mal_planner.trajectory import Trajectory

# mal_msgs/AircraftPlan status constants and diagnostic_msgs/DiagnosticStatus levels
OPTIMAL, INITIAL_GUESS, FAILED, HOLD = 0, 1, 2, 3
DIAG_OK, DIAG_WARN, DIAG_ERROR = 0, 1, 2


def deduplicated(traj: Trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Samples with strictly increasing times (a phase boundary appears twice in optimizer output), and the bank."""
    keep = np.concatenate([[True], np.diff(traj.t) > 1e-9])
    bank = None if traj.controls is None else bank_angle(traj.controls[keep, 0], traj.controls[keep, 1])
    return traj.t[keep], traj.states[keep], bank


def aircraft_verified(result: PlanResult, callsign: str) -> bool:
    rep = result.verification
    return rep is not None and rep.aircraft_verified(callsign)


def status_text(result: PlanResult) -> str:
    """``optimal, verified``, ``optimizer <status>`` or ``initializer only``."""
    if result.landing is None:
        return "initializer only"
    verdict = "n/a" if result.verification is None else (
        "verified" if result.verification.verified else "NOT verified")
    return f"{result.landing.status}, {verdict}" if result.optimized else f"optimizer {result.landing.status}"


def summary_text(result: PlanResult) -> str:
    land = result.landing_times()
    return "order " + ", ".join(f"{cs} lands at {land[cs]:.1f} s" for cs in result.order)


def path_messages(types: Any, trajectories: list[Trajectory], plan_start: float, frame_id: str) -> dict[str, Any]:
    """A ``nav_msgs/Path`` per trajectory, stamped from ``plan_start``."""
    out = {}
    for traj in trajectories:
        t, states, bank = deduplicated(traj)
        out[traj.callsign] = path_msg(types, traj.callsign, plan_start, t, states, bank, frame_id)
    return out


def empty_path(types: Any, stamp: float, frame_id: str) -> Any:
    """An empty ``nav_msgs/Path``: the aircraft's plan is withdrawn."""
    header = types.msg("std_msgs/msg/Header")(stamp=time_to_msg(types, stamp), frame_id=frame_id)
    return types.msg("nav_msgs/msg/Path")(header=header, poses=[])


def _failed_entry(types: Any, k: int, callsign: str, reason: str) -> Any:
    return types.msg("mal_msgs/msg/AircraftPlan")(
        callsign=callsign, order=k, gate_time=math.nan, landing_time=math.nan, status=FAILED, verified=False,
        reason=reason, target_time=math.nan, delay=math.nan, **geodetic_path_fields(None, np.zeros((0, 5))))


def _planned_entries(types: Any, result: PlanResult, frame: GeoFrame | None) -> list[Any]:
    land, gates = result.landing_times(), result.gate_times()
    status = OPTIMAL if result.optimized else INITIAL_GUESS
    schedule = getattr(result.initial, "schedule", None)
    targets = {} if schedule is None else schedule.target
    samples = {tr.callsign: deduplicated(tr)[1] for tr in result.trajectories()}
    entries = []
    for k, cs in enumerate(result.order, 1):
        gate, target = gates.get(cs), targets.get(cs)
        target_time = math.nan if target is None else float(target)
        entries.append(types.msg("mal_msgs/msg/AircraftPlan")(
            callsign=cs, order=k, gate_time=math.nan if gate is None else float(gate), landing_time=float(land[cs]),
            status=status, verified=result.optimized and aircraft_verified(result, cs),
            wake_category=result.scenario.aircraft_by_callsign(cs).wake_category or "", target_time=target_time,
            delay=float(land[cs]) - target_time, **geodetic_path_fields(frame, samples.get(cs, np.zeros((0, 5))))))
    return entries


def landing_plan_message(types: Any, result: PlanResult | None, plan_start: float, callsigns: list[str],
                         frame_id: str, frame: GeoFrame | None, left_out: dict[str, str] | None = None,
                         failure: str = "") -> Any:
    """The LandingPlan of ``result`` (None: a failed plan of ``callsigns``, each FAILED with ``failure``),
    followed by a FAILED entry with its reason for each aircraft left out of it."""
    if result is None:
        entries = [_failed_entry(types, k, cs, failure) for k, cs in enumerate(callsigns, 1)]
    else:
        entries = _planned_entries(types, result, frame)
    first = len(entries) + 1
    entries += [_failed_entry(types, k, cs, why) for k, (cs, why) in enumerate(sorted((left_out or {}).items()), first)]
    header = types.msg("std_msgs/msg/Header")(stamp=time_to_msg(types, plan_start), frame_id=frame_id)
    return types.msg("mal_msgs/msg/LandingPlan")(header=header, aircraft=entries, **frame_origin_fields(frame))


def diagnostic_status(types: Any, node_name: str, level: int | None, message: str, values: dict[str, Any],
                      name: str = "landing plan") -> Any:
    kvs = [types.msg("diagnostic_msgs/msg/KeyValue")(key=k, value=str(v)) for k, v in values.items()]
    return types.msg("diagnostic_msgs/msg/DiagnosticStatus")(
        level=byte_field(types, DIAG_OK if level is None else level), name=f"{node_name}: {name}", message=message,
        hardware_id="mal_planner", values=kvs)


def plan_diagnostic_values(result: PlanResult | None, plans: int, failed: bool) -> tuple[int, dict[str, Any]]:
    """The plan's diagnostic level and key values (the plan count, its status, solver and verification)."""
    values: dict[str, Any] = {"plans": plans, "status": "FAILED" if failed else "OK"}
    if result is None:
        return DIAG_ERROR, values
    lr, rep = result.landing, result.verification
    level = DIAG_ERROR if failed else (DIAG_OK if result.optimized and rep is not None and rep.verified else DIAG_WARN)
    failure = result.failure
    values |= {"failure_class": failure.outcome if failure else "",
               "error_code": outcome_code(failure.outcome if failure else None).error_code}
    values |= {"order": ",".join(result.order), "solver_status": lr.status if lr else "not run",
               "solve_time_s": f"{lr.solve_time:.3f}" if lr else "nan",
               "nlp_iterations": lr.nlp_iterations if lr else 0, "verified": bool(rep and rep.verified),
               "reasons": "; ".join(rep.reasons) if rep else ""}
    values |= {k: f"{v:.3f}" for k, v in result.timings.items()}
    return level, values


def radar_diagnostic_values(counts: Counter[str], tracked: int) -> tuple[dict[str, Any], str]:
    """The radar intake's key values (tracked, received, accepted, rejected by reason, dropped, duplicates, lost)
    and its message."""
    rejected = {k.removeprefix("rejected."): n for k, n in sorted(counts.items()) if k.startswith("rejected.")}
    values = {"tracked": tracked, "received": counts["received"], "accepted": counts["accepted"],
              "rejected": counts["rejected"], "dropped": counts["older"], "duplicates": counts["duplicate"],
              "lost": counts["lost"]}
    values |= {f"rejected.{k}": n for k, n in rejected.items()}
    message = f"{tracked} aircraft tracked"
    if rejected:
        message += "; rejected: " + ", ".join(f"{k} {n}" for k, n in rejected.items())
    return values, message


def plan_answer(types: Any, request: PlanRequest, result: PlanResult, frame_id: str, frame: GeoFrame | None
                ) -> tuple[Any, list[Any]]:
    """The LandingPlan and paths (in landing order) of a plan, for a service's response."""
    plan_msg = landing_plan_message(types, result, request.plan_start, result.order, frame_id, frame,
                                    request.inputs.left_out)
    paths = path_messages(types, result.trajectories(), request.plan_start, frame_id)
    return plan_msg, [paths[cs] for cs in result.order]


def failed_answer(types: Any, request: PlanRequest, reason: str, result: PlanResult | None, frame_id: str,
                  frame: GeoFrame | None) -> tuple[Any, list[Any]]:
    """The LandingPlan of a failed plan (every aircraft FAILED with ``reason``) and the paths it got to, if any."""
    callsigns = [a.callsign for a in request.scenario.aircraft]
    plan = landing_plan_message(types, None, request.plan_start, callsigns, frame_id, frame, request.inputs.left_out,
                                reason)
    paths = path_messages(types, result.trajectories(), request.plan_start, frame_id) if result is not None else {}
    return plan, list(paths.values())
