"""``mal-plan``: plan a multiple-aircraft landing scenario from the command line."""

from __future__ import annotations

import argparse
import logging
import sys
import time
from dataclasses import replace
from pathlib import Path

from mal_planner.landing import LandingOptions
from mal_planner.scenario import ScenarioError, load_scenario


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mal-plan",
        description="Plan conflict-free landing trajectories for several aircraft: RRT initializer and landing "
                    "sequencer (thesis chapters 3-4), then the multi-phase Radau pseudospectral optimizer with "
                    "hp-adaptive mesh refinement (chapter 5) and an independent verification.",
    )
    parser.add_argument("scenario", type=Path, help="scenario YAML file (see README: Scenario files)")
    parser.add_argument("--initializer", default="multi-rrt",
                        help="path planner: multi-rrt (thesis), ompl:RRTConnect, ompl:RRT, ompl:RRTstar, ... "
                             "(default: %(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default: out/<scenario name>)")
    parser.add_argument("--initial-only", action="store_true", help="run the initializer only, no optimization")
    parser.add_argument("--guess", choices=["initializer", "straight"], default="initializer",
                        help="optimizer initial guess: the initializer's paths or naive straight lines")
    parser.add_argument("--free-landing-times", action="store_true",
                        help="let the optimizer choose landing times (minimum spacing from the scenario)")
    parser.add_argument("--mesh-tol", type=float, default=1e-6, help="mesh error tolerance (default: %(default)s)")
    parser.add_argument("--no-refine", action="store_true", help="solve on the initial mesh only")
    parser.add_argument("--figures", choices=["none", "png", "html", "all"], default="all",
                        help="figures written after the result: PNGs, the interactive plan.html, both or none "
                             "(default: %(default)s)")
    parser.add_argument("--no-figures", dest="figures", action="store_const", const="none", help=argparse.SUPPRESS)
    parser.add_argument("-q", "--quiet", action="store_true", help="only print the summary")
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    level = logging.WARNING if args.quiet else (logging.DEBUG if args.verbose else logging.INFO)
    logging.basicConfig(level=level, format="%(asctime)s %(levelname).1s %(name)s: %(message)s", datefmt="%H:%M:%S")
    try:
        scenario = load_scenario(args.scenario)
    except ScenarioError as exc:
        print(f"mal-plan: error: {exc}", file=sys.stderr)
        return 2
    # Imported after argument parsing: CasADi and OMPL take a moment to load.
    from mal_planner.initializer import PlanningFailed, known_specs
    from mal_planner.pipeline import Planner, PlanOptions
    from mal_planner.report import summary_table, write_figures, write_outputs

    if args.initializer not in known_specs():
        print(f"mal-plan: error: --initializer: unknown planner {args.initializer!r} "
              f"(known: {', '.join(known_specs())})", file=sys.stderr)
        return 2
    landing = replace(LandingOptions(), guess=args.guess, fixed_landing_times=not args.free_landing_times,
                      mesh_tol=args.mesh_tol, refine=not args.no_refine)
    options = PlanOptions(initializer=args.initializer, seed=args.seed, optimize=not args.initial_only,
                          landing=landing)
    t0 = time.perf_counter()
    try:
        result = Planner(options).plan(scenario, reuse=False)
    except PlanningFailed as exc:
        print(f"mal-plan: error: {args.scenario}: initializer failed: {exc}", file=sys.stderr)
        return 1
    out_dir = args.out or Path("out") / scenario.name
    written = write_outputs(result, out_dir, figures="none")
    print(f"{scenario.name}: {len(scenario.aircraft)} aircraft, landing order {' -> '.join(result.order)} "
          f"({time.perf_counter() - t0:.1f} s)")
    print(summary_table(result), flush=True)
    written += write_figures(out_dir / "plan.json", out_dir, args.figures)
    print(f"wrote {len(written)} files to {out_dir}/ (plan.json, report.md"
          f"{'' if args.figures == 'none' else ', figures: ' + args.figures})")
    if result.landing is not None and not result.optimized:
        return 1
    if result.verification is not None and not result.verification.verified:
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main())
