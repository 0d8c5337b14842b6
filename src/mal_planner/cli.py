"""``mal-plan``: plan a multiple-aircraft landing scenario from the command line."""

from __future__ import annotations

import argparse
import logging
import math
import os
import secrets
import sys
import time
from dataclasses import replace
from pathlib import Path

from mal_planner.errors import exit_codes_help, outcome_code
from mal_planner.landing import LandingOptions
from mal_planner.scenario import ScenarioError, load_scenario

EXIT_CODES = exit_codes_help()


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value) or value <= 0.0:
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return value


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < -1:
        raise argparse.ArgumentTypeError(f"must be >= 0, or -1 for a random seed; got {value}")
    return value


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit 2 (argparse prints the usage too)
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="mal-plan",
        description="Plan conflict-free landing trajectories for several aircraft: RRT initializer and landing "
                    "sequencer (thesis chapters 3-4), then the multi-phase Radau pseudospectral optimizer with "
                    "hp-adaptive mesh refinement (chapter 5) and an independent verification.",
        epilog=EXIT_CODES, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("scenario", type=Path, help="scenario YAML file (see README: Scenario files)")
    parser.add_argument("--initializer", default="multi-rrt",
                        help="path planner: multi-rrt (thesis), ompl:RRTConnect, ompl:RRT, ompl:RRTstar, ... "
                             "(default: %(default)s)")
    parser.add_argument("--seed", type=_seed, default=0,
                        help="random seed; -1 draws one (it is printed and saved) (default: %(default)s)")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default: out/<scenario name>)")
    parser.add_argument("--initial-only", action="store_true", help="run the initializer only, no optimization")
    parser.add_argument("--guess", choices=["initializer", "straight"], default="initializer",
                        help="optimizer initial guess: the initializer's paths or naive straight lines")
    parser.add_argument("--free-landing-times", action="store_true",
                        help="let the optimizer choose landing times (minimum spacing from the scenario)")
    parser.add_argument("--strategy", choices=["auto", "joint", "sequential"], default="auto",
                        help="one NLP for all aircraft (joint) or one per aircraft in landing order against the "
                             "plans of those before it (sequential); auto: sequential from 4 aircraft on "
                             "(default: auto)")
    parser.add_argument("--mesh-tol", type=_positive_float, default=1e-5,
                        help="mesh error tolerance (default: %(default)s)")
    parser.add_argument("--no-refine", action="store_true",
                        help="solve on the initial mesh only (no hp refinement, no verification-driven refinement)")
    parser.add_argument("--time-limit", type=_positive_float, default=None, metavar="S",
                        help="wall-clock limit of the planning in seconds; the best result so far is kept "
                             "(default: none)")
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
        return outcome_code("invalid_input").exit_code
    out_dir = args.out or Path("out") / scenario.name
    problem = _unwritable(out_dir)
    if problem:
        print(f"mal-plan: error: --out {out_dir}: {problem}", file=sys.stderr)
        return outcome_code("invalid_input").exit_code
    if args.seed == -1:
        args.seed = secrets.randbelow(2**31)
        print(f"mal-plan: random seed {args.seed}", file=sys.stderr)
    # Imported after argument parsing: CasADi and OMPL take a moment to load.
    from mal_planner.errors import InfeasibleRequest, TimeLimitReached
    from mal_planner.initializer import PlanningFailed, known_specs
    from mal_planner.pipeline import Planner, PlanOptions
    from mal_planner.report import summary_table, write_figures, write_outputs

    if args.initializer not in known_specs():
        print(f"mal-plan: error: --initializer: unknown planner {args.initializer!r} "
              f"(known: {', '.join(known_specs())})", file=sys.stderr)
        return outcome_code("invalid_input").exit_code
    landing = replace(LandingOptions(), guess=args.guess, fixed_landing_times=not args.free_landing_times,
                      mesh_tol=args.mesh_tol, refine=not args.no_refine, strategy=args.strategy)
    options = PlanOptions(initializer=args.initializer, seed=args.seed, optimize=not args.initial_only,
                          landing=landing, time_limit_s=args.time_limit,
                          refinement_rounds=0 if args.no_refine else PlanOptions.refinement_rounds)
    t0 = time.perf_counter()
    try:
        result = Planner(options).plan(scenario, reuse=False)
    except InfeasibleRequest as exc:
        print(f"mal-plan: error: {args.scenario}: impossible request: {exc}", file=sys.stderr)
        return outcome_code(exc.failure_class).exit_code
    except TimeLimitReached as exc:  # in the initializer: nothing to write yet
        print(f"mal-plan: timeout: {args.scenario}: {exc}", file=sys.stderr)
        return outcome_code(exc.failure_class).exit_code
    except PlanningFailed as exc:
        print(f"mal-plan: error: {args.scenario}: initializer failed: {exc}", file=sys.stderr)
        return outcome_code("initializer_failed").exit_code
    written = write_outputs(result, out_dir, figures="none")
    print(f"{scenario.name}: {len(scenario.aircraft)} aircraft, landing order {' -> '.join(result.order)} "
          f"({time.perf_counter() - t0:.1f} s)")
    print(summary_table(result), flush=True)
    written += write_figures(out_dir / "plan.json", out_dir, args.figures)
    print(f"wrote {len(written)} files to {out_dir}/ (plan.json, report.md"
          f"{'' if args.figures == 'none' else ', figures: ' + args.figures})")
    failure = result.failure
    if failure is None:
        return 0
    print(f"mal-plan: {failure[0].replace('_', ' ')}: {failure[1]}", file=sys.stderr)
    return outcome_code(failure[0]).exit_code


def _unwritable(folder: Path) -> str | None:
    """Why ``folder`` cannot take the outputs (checked before planning), or None."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return f"cannot create the folder ({exc.strerror or exc})"
    if not os.access(folder, os.W_OK | os.X_OK):
        return "the folder is not writable"
    return None


if __name__ == "__main__":
    sys.exit(main())
