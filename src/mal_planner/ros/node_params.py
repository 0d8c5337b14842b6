"""Parameters of the planner node: defaults, validation (one log line per bad value) and PlanOptions."""

from __future__ import annotations

import logging
import math
import re
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from mal_planner.options import PLAN_OPTIONS, Option, PlanOptions, build_plan_options
from mal_planner.ros.transport import load_params_file
from mal_planner.sequencing import STRATEGIES
from mal_planner.wake import WAKE_TABLES

Check = Callable[[Any], Any]


def _bool(v: Any) -> bool:
    if isinstance(v, bool):
        return v
    raise ValueError("expected true or false")


INT64_MAX = 2**63 - 1
"""The largest ROS 2 integer parameter (int64): the upper end of an integer range with no upper bound."""


def _int(lo: int, hi: int | None = None) -> Check:
    def check(v: Any) -> int:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or int(v) != v:
            raise ValueError("expected an integer")
        if v < lo:
            raise ValueError(f"must be >= {lo}")
        if hi is not None and v > hi:
            raise ValueError(f"must be <= {hi}")
        return int(v)
    check.value_range = (lo, INT64_MAX if hi is None else hi)  # type: ignore[attr-defined]
    return check


def _float(positive: bool = False, lo: float | None = None, hi: float | None = None) -> Check:
    def check(v: Any) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError("expected a finite number")
        if v < 0 or (positive and v == 0):
            raise ValueError("must be > 0" if positive else "must be >= 0")
        if lo is not None and v < lo:
            raise ValueError(f"must be >= {lo:g}")
        if hi is not None and v > hi:
            raise ValueError(f"must be <= {hi:g}")
        return float(v)
    # the descriptor's inclusive range: "> 0" as the smallest positive double
    low = lo if lo is not None else (sys.float_info.min if positive else 0.0)
    check.value_range = (low, math.inf if hi is None else hi)  # type: ignore[attr-defined]
    return check


def value_range(name: str) -> tuple[float, float] | None:
    """The inclusive range of a numeric parameter (for its descriptor: ``ros2 param describe``), or None."""
    if name in ROS_OPTIONS:
        return ROS_OPTIONS[name].value_range
    return getattr(PARAMETERS[name][1], "value_range", None)


def _str(v: Any) -> str:
    if not isinstance(v, str):
        raise ValueError("expected a string")
    return v


FRAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_/]*$")


def _frame(v: Any) -> str:
    """A TF frame name: not empty, letters, digits, '_' and '/' (REP 103/105)."""
    if not isinstance(v, str) or not FRAME_RE.match(v):
        raise ValueError("expected a frame name (letters, digits, '_', '/'; not empty)")
    return v


def _choice(*options: str) -> Check:
    def check(v: Any) -> str:
        if v not in options:
            raise ValueError(f"expected one of {', '.join(options)}")
        return str(v)
    return check


def _figures(v: Any) -> str:
    """none, png, html or all; the former booleans true/false mean png/none."""
    if isinstance(v, bool):
        return "png" if v else "none"
    if isinstance(v, str) and v.strip().lower() in ("none", "png", "html", "all"):
        return v.strip().lower()
    raise ValueError("expected none, png, html or all")


MAX_SETTLE_TIME_S = 600.0
"""Waiting longer than ten minutes of radar for a first plan is a typo, not a setting."""

ROS_OPTIONS: dict[str, Option] = {o.ros: o for o in PLAN_OPTIONS if o.ros is not None}
"""The plan options the node offers, by parameter name (declared once in :mod:`mal_planner.options`)."""

#: name -> (default, check, description): the plan options, then the node's own
PARAMETERS: dict[str, tuple[Any, Check, str]] = {
    **{name: (o.ros_default(), o.check_ros, o.help + (f" [{o.unit}]" if o.unit else "")
              + ("; 0 = no limit" if o.none_as == 0.0 else "")) for name, o in ROS_OPTIONS.items()},
    "wake_table": ("scenario", _choice("scenario", *WAKE_TABLES), "wake-turbulence minima between landings: the "
                   "scenario's separation.wake, or icao, recat-eu, none; categories from the scenario, else the "
                   "radar's AircraftState.wake_category (unknown: the worst case)"),
    "sequencing": ("scenario", _choice("scenario", *STRATEGIES), "who lands when: the scenario's sequencing.strategy,"
                   " or fcfs (first come first served) or optimal (least total delay, MILP)"),
    "tracking_margins": (False, _bool, "plan with the closed loop's margins for flown plans: twice "
                         "deviation_threshold_m more separation, a tenth of the bank limit and half a path accuracy "
                         "from the airspace's bounds left to the aircraft's guidance"),
    "replan_period_s": (0.0, _float(), "periodic replanning [s], 0 = off"),
    "deviation_threshold_m": (926.0, _float(), "replan when radar deviates more from the plan [m], 0 = off"),
    "min_replan_interval_s": (5.0, _float(), "no deviation/periodic replan sooner after a plan [s]"),
    "min_aircraft": (1, _int(1), "plan only with at least this many tracked aircraft"),
    "settle_time_s": (2.0, _float(hi=MAX_SETTLE_TIME_S),
                      "wait after the first radar message before the first plan [s]"),
    "track_timeout_s": (30.0, _float(), "forget aircraft not seen for this long (radar time) [s], 0 = never"),
    "radar_qos": ("default", _choice("default", "sensor_data"), "QoS of the radar subscriptions"),
    "frame_id": ("runway", _frame, "frame of radar input and published paths"),
    "output_dir": ("", _str, "write plan.json, report.md and figures here after each plan ('' = off)"),
    "figures": ("png", _figures, "figures rendered into output_dir in a background process after each plan: "
                "none, png, html (interactive plan.html) or all (true/false: png/none)"),
    "kept_plan_expiry_s": (120.0, _float(), "withdraw a plan kept after failed replans this long after the first "
                           "failure (node clock) [s]; two minutes is 8 nm at 250 kt; 0 = never"),
    "service_timeout_s": (600.0, _float(positive=True), "longest a service call waits for its plan [s]"),
}


@dataclass(frozen=True)
class NodeParams:
    initializer: str
    seed: int
    optimize: bool
    verify: bool
    guess: str
    strategy: str
    fixed_landing_times: bool
    mesh_tol: float
    refine: bool
    segments: int
    degree: int
    nlp_tol: float
    max_nlp_iterations: int
    max_mesh_iterations: int
    wake_table: str
    sequencing: str
    output_dt: float
    tracking_margins: bool
    replan_period_s: float
    deviation_threshold_m: float
    min_replan_interval_s: float
    min_aircraft: int
    settle_time_s: float
    track_timeout_s: float
    radar_qos: str
    frame_id: str
    output_dir: str
    figures: str
    kept_plan_expiry_s: float
    service_timeout_s: float
    planning_time_limit_s: float

    def plan_options(self) -> PlanOptions:
        values = {o.name: getattr(self, name) for name, o in ROS_OPTIONS.items()}
        values["time_limit_s"] = values["time_limit_s"] or None  # 0: no limit
        return build_plan_options(values)


assert {f.name for f in fields(NodeParams)} == set(PARAMETERS)


ROS_STANDARD = frozenset({"use_sim_time"})
"""Parameters every ROS 2 node has (the node's clock follows /clock when use_sim_time is true)."""


def read_params_file(path: str | Path | None, node_name: str, namespace: str, log: logging.Logger) -> dict[str, Any]:
    """Overrides from a ROS 2 params YAML; a missing or malformed file is logged (one line) and ignored."""
    if not path:
        return {}
    try:
        values = load_params_file(path, node_name, namespace)
    except OSError as exc:
        log.error("params file %s: cannot read (%s); using defaults", path, exc.strerror or exc)
        return {}
    except Exception as exc:  # yaml errors and malformed structures
        log.error("params file %s: invalid (%s); using defaults", path, " ".join(str(exc).split()))
        return {}
    known = set(PARAMETERS) | ROS_STANDARD
    for name in sorted(set(values) - known):
        log.warning("params file %s: unknown parameter %r (ignored)", path, name)
    return {k: v for k, v in values.items() if k in known}


#: Parameters that only take effect at start-up (the radar subscriptions are created with this QoS).
READ_ONLY = frozenset({"radar_qos"})


def declare_parameters(node: Any, source: str, log: logging.Logger) -> NodeParams:
    """Declare every parameter on ``node`` and validate; a bad value is logged and replaced by its default."""
    values: dict[str, Any] = {}
    for name, (default, check, doc) in PARAMETERS.items():
        raw = node.declare_parameter(name, default, doc + (" (read-only at run time)" if name in READ_ONLY else ""),
                                     value_range=value_range(name)).value
        try:
            values[name] = check(raw)
        except ValueError as exc:
            log.error("parameter %r (%s): %s, got %r; using the default %r", name, source, exc, raw, default)
            values[name] = default
            node.set_parameter(name, default)
    return NodeParams(**values)


def update_params(current: NodeParams, changes: Mapping[str, Any]) -> NodeParams:
    """``current`` with ``changes`` (a parameter set at run time) applied, all checked like at start-up;
    ValueError with a one-line reason naming the parameter when one is unknown, read-only or invalid."""
    values = dict(current.__dict__)
    for name, raw in changes.items():
        if name not in PARAMETERS:
            raise ValueError(f"parameter {name!r}: unknown")
        if name in READ_ONLY and raw != values[name]:
            raise ValueError(f"parameter {name!r}: read-only at run time (restart the node to change it)")
        try:
            values[name] = PARAMETERS[name][1](raw)
        except ValueError as exc:
            raise ValueError(f"parameter {name!r}: {exc}, got {raw!r}") from None
    return NodeParams(**values)


def describe(params: Mapping[str, Any] | NodeParams) -> str:
    """``name=value`` list for the start-up log line."""
    items = params.__dict__ if isinstance(params, NodeParams) else params
    return ", ".join(f"{k}={v!r}" for k, v in items.items())
