"""The plan options of a campaign: the same as ``mal-plan``'s, as a JSON-ready dict and as PlanOptions."""

from __future__ import annotations

import argparse
from dataclasses import replace
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from mal_planner.pipeline import PlanOptions

DEFAULTS: dict[str, Any] = {"initializer": "multi-rrt", "seed": 0, "guess": "initializer",
                            "free_landing_times": False, "mesh_tol": 1e-5, "refine": True, "time_limit_s": None,
                            "closed_loop": None}


def add_plan_arguments(parser: argparse.ArgumentParser) -> None:
    """mal-plan's planning options (figures and output options excepted)."""
    group = parser.add_argument_group("plan options (as in mal-plan)")
    group.add_argument("--initializer", default=DEFAULTS["initializer"],
                       help="path planner: multi-rrt, ompl:RRTConnect, ... (default: %(default)s)")
    group.add_argument("--seed", type=int, default=DEFAULTS["seed"],
                       help="random seed of the initializer, the same for every scenario (default: %(default)s)")
    group.add_argument("--guess", choices=["initializer", "straight"], default=DEFAULTS["guess"],
                       help="optimizer initial guess (default: %(default)s)")
    group.add_argument("--free-landing-times", action="store_true",
                       help="let the optimizer choose the landing times, also where a file fixes them")
    group.add_argument("--mesh-tol", type=float, default=DEFAULTS["mesh_tol"],
                       help="mesh error tolerance (default: %(default)s)")
    group.add_argument("--no-refine", action="store_true", help="solve on the initial mesh only")
    group.add_argument("--plan-time-limit-s", type=float, default=None,
                       help="the pipeline's own time limit per plan: it then returns its best result so far, "
                            "classed timeout (default: none; --timeout-s kills the process in any case)")


    loop = parser.add_argument_group("closed loop (mal_planner.closedloop): fly every scenario with the service")
    loop.add_argument("--closed-loop", action="store_true",
                      help="fly each scenario in closed loop instead of planning it once; a run succeeds when "
                           "everyone lands with every minimum kept on the flown tracks")
    loop.add_argument("--wind-kt-max", type=float, default=20.0,
                      help="mean wind per scenario: uniform in [0, this] kt from a uniform direction, drawn from "
                           "the seed and the file name (default: %(default)s)")
    loop.add_argument("--gust-kt", type=float, default=0.0, help="gusts, rms per axis, kt (default: 0)")
    loop.add_argument("--noise-m", type=float, default=30.0, help="radar noise sigma, m (default: %(default)s)")
    loop.add_argument("--delay-s", type=float, default=0.0, help="plan uptake delay, s (default: 0)")
    loop.add_argument("--unknown-wind", action="store_true", help="the planner plans in still air")
    loop.add_argument("--simulator", choices=("ours", "bluesky"), default="ours",
                      help="who flies the plans: our FlightSimulator or BlueSky (optional extra 'bluesky'; steady "
                           "wind only: --gust-kt must be 0) (default: %(default)s)")


def options_from_args(args: argparse.Namespace) -> dict[str, Any]:
    closed = None
    if args.closed_loop:
        closed = {"wind_kt_max": args.wind_kt_max, "gust_kt": args.gust_kt, "noise_m": args.noise_m,
                  "delay_s": args.delay_s, "knows_wind": not args.unknown_wind, "simulator": args.simulator}
    return {"initializer": args.initializer, "seed": args.seed, "guess": args.guess,
            "free_landing_times": bool(args.free_landing_times), "mesh_tol": args.mesh_tol,
            "refine": not args.no_refine, "time_limit_s": args.plan_time_limit_s, "closed_loop": closed}


def check_options(options: dict[str, Any]) -> str | None:
    """A one-line problem with the options (naming the option), or None. Imports the planners (~1 s)."""
    from mal_planner.initializer import known_specs

    if options["initializer"] not in known_specs():
        return f"--initializer: unknown planner {options['initializer']!r} (known: {', '.join(known_specs())})"
    if not 0.0 < options["mesh_tol"] < 1.0:
        return f"--mesh-tol: must lie in (0, 1), got {options['mesh_tol']}"
    limit = options.get("time_limit_s")
    if limit is not None and not limit > 0:
        return f"--plan-time-limit-s: must be > 0, got {limit}"
    closed = options.get("closed_loop") or {}
    for key, flag in (("wind_kt_max", "--wind-kt-max"), ("gust_kt", "--gust-kt"), ("noise_m", "--noise-m"),
                      ("delay_s", "--delay-s")):
        if key in closed and not closed[key] >= 0:
            return f"{flag}: must be >= 0, got {closed[key]}"
    if closed.get("simulator", "ours") != "ours":
        from mal_planner.closedloop.bluesky_sim import make_simulator

        try:
            make_simulator(closed["simulator"])
        except ValueError as exc:
            return str(exc)
        if closed.get("gust_kt", 0.0) > 0:
            return f"--gust-kt: BlueSky flies a steady wind only, got {closed['gust_kt']} with --simulator bluesky"
    return None


def to_plan_options(options: dict[str, Any]) -> PlanOptions:
    """The pipeline's PlanOptions, built exactly as mal-plan builds them (imported here: CasADi loads slowly)."""
    from mal_planner.landing import LandingOptions
    from mal_planner.pipeline import PlanOptions

    landing = replace(LandingOptions(), guess=options["guess"], fixed_landing_times=not options["free_landing_times"],
                      mesh_tol=options["mesh_tol"], refine=options["refine"])
    return PlanOptions(initializer=options["initializer"], seed=options["seed"], landing=landing,
                       time_limit_s=options.get("time_limit_s"))
