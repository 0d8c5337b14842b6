"""``mal-plan``: plan a multiple-aircraft landing scenario from the command line."""

from __future__ import annotations

import argparse
import logging
import os
import secrets
import sys
import time
from pathlib import Path

from mal_planner.errors import Outcome, PlanningError, exit_codes_help
from mal_planner.options import add_arguments, build_plan_options, check_values, values_from_args
from mal_planner.scenario import ScenarioError, load_scenario

EXIT_CODES = exit_codes_help()
REFUSALS: dict[Outcome, tuple[str, str]] = {
    Outcome.INFEASIBLE_REQUEST: ("error", "impossible request"),
    Outcome.INVALID_INPUT: ("error", ""),
    Outcome.TIMEOUT: ("timeout", ""),
    Outcome.INITIALIZER_FAILED: ("error", "initializer failed"),
}
"""How mal-plan words a request refused before there is anything to write: the label and what it was."""


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
    parser.add_argument("--out", type=Path, default=None, help="output folder (default: out/<scenario name>)")
    add_arguments(parser)
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
        return exc.outcome.code.exit_code
    problem = check_values(values_from_args(args), lambda o: o.flag)
    if problem:
        print(f"mal-plan: error: {problem}", file=sys.stderr)
        return Outcome.INVALID_INPUT.code.exit_code
    out_dir = args.out or Path("out") / scenario.name
    problem = _unwritable(out_dir)
    if problem:
        print(f"mal-plan: error: --out {out_dir}: {problem}", file=sys.stderr)
        return Outcome.INVALID_INPUT.code.exit_code
    if args.seed == -1:
        args.seed = secrets.randbelow(2**31)
        print(f"mal-plan: random seed {args.seed}", file=sys.stderr)
    # Imported after argument parsing: CasADi and OMPL take a moment to load.
    from mal_planner.pipeline import Planner
    from mal_planner.report import summary_table, write_figures, write_outputs

    options = build_plan_options(values_from_args(args))
    t0 = time.perf_counter()
    try:
        result = Planner(options).plan(scenario, reuse=False)
    except PlanningError as exc:  # refused before planning, or the initializer found nothing: nothing to write
        label, what = REFUSALS.get(exc.outcome, ("error", exc.outcome.replace("_", " ")))
        print(f"mal-plan: {label}: {args.scenario}: {what + ': ' if what else ''}{exc}", file=sys.stderr)
        return exc.outcome.code.exit_code
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
    print(f"mal-plan: {failure.outcome.replace('_', ' ')}: {failure.reason}", file=sys.stderr)
    return failure.outcome.code.exit_code


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
