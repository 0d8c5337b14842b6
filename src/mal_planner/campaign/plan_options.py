"""The plan options of a campaign: the same as ``mal-plan``'s, as a JSON-ready dict and as PlanOptions."""

from __future__ import annotations

import argparse
from dataclasses import replace
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from mal_planner.pipeline import PlanOptions

DEFAULTS: dict[str, Any] = {"initializer": "multi-rrt", "seed": 0, "guess": "initializer",
                            "free_landing_times": False, "mesh_tol": 1e-5, "refine": True, "time_limit_s": None}


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


def options_from_args(args: argparse.Namespace) -> dict[str, Any]:
    return {"initializer": args.initializer, "seed": args.seed, "guess": args.guess,
            "free_landing_times": bool(args.free_landing_times), "mesh_tol": args.mesh_tol,
            "refine": not args.no_refine, "time_limit_s": args.plan_time_limit_s}


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
    return None


def to_plan_options(options: dict[str, Any]) -> PlanOptions:
    """The pipeline's PlanOptions, built exactly as mal-plan builds them (imported here: CasADi loads slowly)."""
    from mal_planner.landing import LandingOptions
    from mal_planner.pipeline import PlanOptions

    landing = replace(LandingOptions(), guess=options["guess"], fixed_landing_times=not options["free_landing_times"],
                      mesh_tol=options["mesh_tol"], refine=options["refine"])
    return PlanOptions(initializer=options["initializer"], seed=options["seed"], landing=landing,
                       time_limit_s=options.get("time_limit_s"))
