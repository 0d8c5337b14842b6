"""Every option, once: the plan options (:data:`PLAN_OPTIONS`) and the planner node's own (:data:`NODE_OPTIONS`).

``mal-plan``'s flags, the campaigns' options, ``mal-closed-loop``'s plan flags and the node's parameters are
derived from these rows (:mod:`mal_planner.options.arguments`, :mod:`mal_planner.ros.node_params`).
"""

from __future__ import annotations

import re
from typing import Any

from mal_planner.options.option import Option
from mal_planner.scenario import STRATEGIES
from mal_planner.wake import WAKE_TABLES

SERVICE_TIME_LIMIT_S = 60.0
"""Wall-clock limit of one plan of the service (the node's ``planning_time_limit_s`` default, the closed loop's):
the best result so far then; ``mal-plan`` has no limit by default."""


def _known_planner(value: str) -> str | None:
    """A path planner that exists in this installation (imports the planners: ~1 s)."""
    from mal_planner.initializer.planners import known_specs

    known = known_specs()
    return None if value in known else f"no such planner (known: {', '.join(known)})"


PLAN_OPTIONS: tuple[Option, ...] = (
    Option("initializer", str, "multi-rrt", "path planner of the initializer: multi-rrt (the thesis's), "
           "ompl:RRTConnect, ompl:RRT, ompl:RRTstar, ...", validate=_known_planner, flag="--initializer",
           campaign="initializer", ros="initializer"),
    Option("seed", int, 0, "random seed of the initializer; -1 draws one", lo=-1, flag="--seed", campaign="seed",
           ros="seed"),
    Option("optimize", bool, True, "run the pseudospectral optimizer (false: the initializer's paths only)",
           flag="--initial-only", flag_sets=False, flag_help="run the initializer only, no optimization",
           ros="optimize"),
    Option("verify", bool, True, "verify the optimized trajectories independently (flown controls, every minimum)",
           ros="verify"),
    Option("guess", str, "initializer", "optimizer initial guess: the initializer's paths or naive straight lines",
           choices=("initializer", "straight"), flag="--guess", campaign="guess", ros="guess"),
    Option("strategy", str, "auto", "one NLP for all aircraft (joint) or one per aircraft in landing order against "
           "the plans of those before it (sequential); auto: sequential from 4 aircraft on",
           choices=("auto", "joint", "sequential"), flag="--strategy", campaign="strategy", ros="strategy"),
    Option("fixed_landing_times", bool, True, "keep the scenario's landing times (else the optimizer chooses them, "
           "the minimum spacing from the scenario)", flag="--free-landing-times", flag_sets=False,
           flag_help="let the optimizer choose the landing times (minimum spacing from the scenario), also where "
                     "a file fixes them",
           campaign="free_landing_times", campaign_inverted=True, ros="fixed_landing_times"),
    Option("mesh_tol", float, 1e-5, "mesh error tolerance of the hp refinement", above=0.0, below=1.0,
           flag="--mesh-tol", campaign="mesh_tol", ros="mesh_tol"),
    Option("refine", bool, True, "hp mesh refinement and the verification-driven refinement (false: the initial "
           "mesh only)", flag="--no-refine", flag_sets=False,
           flag_help="solve on the initial mesh only (no hp refinement, no verification-driven refinement)",
           campaign="refine", ros="refine"),
    Option("segments", int, 4, "initial mesh segments per phase (refinement adds more where needed)", lo=1, hi=64,
           ros="segments"),
    Option("degree", int, 6, "collocation degree per segment (refinement splits dense segments instead)", lo=2,
           hi=16, ros="degree"),
    Option("nlp_tol", float, 1e-8, "IPOPT tolerance", above=0.0, below=1.0, ros="nlp_tol"),
    Option("max_nlp_iterations", int, 3000, "IPOPT iteration limit", lo=1, ros="max_nlp_iterations"),
    Option("max_mesh_iterations", int, 8, "mesh refinement iteration limit", lo=1, ros="max_mesh_iterations"),
    Option("output_dt", float, 0.25, "sample step of the published paths: no controller follows a path finer than "
           "100 Hz, a minute between samples is no path", lo=0.01, hi=60.0, unit="s", ros="output_dt"),
    Option("time_limit_s", float, None, "wall-clock limit of one whole plan, initializer included; when it runs "
           "out the best result so far is kept (a failure is reported)", above=0.0, none_as=0.0, unit="s",
           flag="--time-limit", campaign="time_limit_s", ros="planning_time_limit_s",
           node_default=SERVICE_TIME_LIMIT_S, metavar="S"),
    Option("wake_table", str, "scenario", "wake-turbulence minima between landings: the scenario's separation.wake, "
           "or icao, recat-eu, none; categories from the scenario, else the radar's AircraftState.wake_category "
           "(unknown: the worst case)", choices=("scenario", *WAKE_TABLES), flag="--wake-table", campaign="wake_table",
           ros="wake_table"),
    Option("sequencing", str, "scenario", "who lands when: the scenario's sequencing.strategy, or fcfs (first come "
           "first served) or optimal (least total delay, MILP)", choices=("scenario", *STRATEGIES),
           flag="--sequencing", campaign="sequencing", ros="sequencing"),
    Option("tracking_margins", bool, False, "plan with the closed loop's margins for flown plans: twice the "
           "deviation threshold more separation, a tenth of the bank limit and half a path accuracy from the "
           "airspace's bounds left to the aircraft's guidance", flag="--tracking-margins", flag_sets=True,
           flag_help="plan with the closed loop's margins for flown plans (deviation threshold: ten path "
                     "accuracies)", ros="tracking_margins"),
    Option("tracking_threshold_nm", float, None, "how far the aircraft that fly the plans may stray from them: the "
           "margins of flown plans are sized to it (implies tracking_margins); none: the closed loop's replan "
           "threshold, ten path accuracies (a service replans at its own deviation threshold; BlueSky's A320 flying "
           "an export, with nothing replanning it, strays up to 0.3 nm)", above=0.0, none_as=0.0, unit="nm",
           flag="--tracking-error", metavar="NM"),
)
"""Every plan option, once."""


def _figures(value: Any) -> Any:
    """The node's former boolean ``figures`` (true/false) as png/none; other values as given."""
    if isinstance(value, bool):
        return "png" if value else "none"
    return value.strip().lower() if isinstance(value, str) else value


def _frame(value: str) -> str | None:
    return None if FRAME_RE.match(value) else "expected a frame name (letters, digits, '_', '/'; not empty)"


FRAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_/]*$")
"""A TF frame name: not empty, letters, digits, '_' and '/' (REP 103/105)."""
MAX_SETTLE_TIME_S = 600.0
"""Waiting longer than ten minutes of radar for a first plan is a typo, not a setting."""

NODE_OPTIONS: tuple[Option, ...] = (
    Option("replan_period_s", float, 0.0, "periodic replanning, 0 = off", lo=0.0, unit="s", ros="replan_period_s"),
    Option("deviation_threshold_m", float, 926.0, "replan when a (filtered) track strays more from its plan; a plan "
           "that finds an aircraft this far from it when it starts is stale (not handed out); 0 = neither", lo=0.0,
           unit="m", ros="deviation_threshold_m"),
    Option("min_replan_interval_s", float, 5.0, "no deviation, new-aircraft or periodic replan sooner after the last "
           "plan arrived (a failed one too)", lo=0.0, unit="s", ros="min_replan_interval_s"),
    Option("track_filter_turn_times", float, 0.5, "time constant of the track filter (the deviation from the plan "
           "flown, smoothed), in the scenario's turn times; 0 = raw radar tracks", lo=0.0,
           ros="track_filter_turn_times"),
    Option("min_aircraft", int, 1, "plan only with at least this many tracked aircraft", lo=1, ros="min_aircraft"),
    Option("settle_time_s", float, 2.0, "wait after the first radar message before the first plan (radar time)",
           lo=0.0, hi=MAX_SETTLE_TIME_S, unit="s", ros="settle_time_s"),
    Option("track_timeout_s", float, 30.0, "forget aircraft not seen for this long (radar time), 0 = never", lo=0.0,
           unit="s", ros="track_timeout_s"),
    Option("radar_qos", str, "default", "QoS of the radar subscriptions", choices=("default", "sensor_data"),
           ros="radar_qos", read_only=True),
    Option("frame_id", str, "runway", "frame of radar input and published paths", validate=_frame, ros="frame_id"),
    Option("output_dir", str, "", "write plan.json, report.md and figures here after each plan ('' = off)",
           ros="output_dir"),
    Option("figures", str, "png", "figures rendered into output_dir in a background process after each plan: none, "
           "png, html (interactive plan.html) or all (true/false: png/none)", choices=("none", "png", "html", "all"),
           coerce=_figures, ros="figures"),
    Option("kept_plan_expiry_s", float, 120.0, "withdraw a plan kept after failed replans this long after the first "
           "failure (radar time); two minutes is 8 nm at 250 kt; 0 = never", lo=0.0, unit="s",
           ros="kept_plan_expiry_s"),
    Option("replan_what_changed", bool, False, "replan an aircraft that strays with those it can affect (within two "
           "separations), and plan aircraft without a plan to land after the others, the others keeping their "
           "instructions; false: every replan is whole",
           ros="replan_what_changed"),
    Option("service_timeout_s", float, 600.0, "longest a service call waits for its plan", above=0.0, unit="s",
           ros="service_timeout_s"),
)
"""The planner node's own parameters (the service's rules and the node's plumbing)."""


BY_NAME: dict[str, Option] = {o.name: o for o in PLAN_OPTIONS}
DEFAULTS: dict[str, Any] = {o.name: o.default for o in PLAN_OPTIONS}
NODE_BY_NAME: dict[str, Option] = {o.name: o for o in NODE_OPTIONS}
