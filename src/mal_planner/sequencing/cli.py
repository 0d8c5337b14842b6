"""``mal-schedule FILE``: the optimal landing sequence of an OR-Library aircraft landing instance."""

from __future__ import annotations

import argparse
import sys

from mal_planner.sequencing import OBJECTIVES, STRATEGIES, SequencingInfeasible, SequencingOptions, sequence
from mal_planner.sequencing.orlib import BUNDLED, PUBLISHED_OPTIMA, ORLibraryError, instance_name, read_airland

PROG = "mal-schedule"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG, description="Sequence the landings of an OR-Library aircraft landing file (Beasley's airland1-13): "
                               "print the cost, the order, the landing times, the proven gap and the solve time. "
                               f"Bundled instances by name: {', '.join(BUNDLED)}.")
    parser.add_argument("files", nargs="+", metavar="FILE", help="OR-Library airland file(s) or bundled names")
    parser.add_argument("--strategy", choices=STRATEGIES, default="optimal",
                        help="optimal (MILP on HiGHS) or fcfs (first come, first served) (default: %(default)s)")
    parser.add_argument("--objective", choices=OBJECTIVES, default="cost",
                        help="cost: weighted earliness and tardiness; makespan: last landing (default: %(default)s)")
    parser.add_argument("--max-shift", type=int, default=None, metavar="K",
                        help="constrained position shifting: no aircraft more than K places from first come")
    parser.add_argument("--time-limit", type=float, default=60.0, metavar="S",
                        help="MILP time limit in seconds; the best order found is printed with its gap "
                             "(default: %(default)s)")
    parser.add_argument("--brief", action="store_true", help="one line per file: no order and times")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.max_shift is not None and args.max_shift < 0:
        print(f"{PROG}: error: --max-shift: must be >= 0, got {args.max_shift}", file=sys.stderr)
        return 2
    if not args.time_limit > 0:
        print(f"{PROG}: error: --time-limit: must be > 0, got {args.time_limit}", file=sys.stderr)
        return 2
    try:
        problems = [(path, read_airland(path)) for path in args.files]
    except ORLibraryError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    options = SequencingOptions(strategy=args.strategy, objective=args.objective, max_shift=args.max_shift,
                                time_limit_s=args.time_limit)
    status = 0
    for path, problem in problems:
        name = instance_name(path)
        try:
            result = sequence(problem, options)
        except (SequencingInfeasible, TimeoutError) as exc:
            print(f"{PROG}: {path}: {exc}", file=sys.stderr)
            status = 1
            continue
        gap = "-" if result.gap is None else f"{100 * result.gap:.2f} %"
        published = PUBLISHED_OPTIMA.get(name)
        reference = f"  published optimum {published:g}" if published is not None and args.objective == "cost" else ""
        print(f"{name}: {problem.n} aircraft  {args.objective} {result.value:.2f}  {result.status}  gap {gap}  "
              f"{result.solve_time_s:.2f} s{reference}")
        if not args.brief:
            print("  order: " + " ".join(result.order_names(problem)))
            print("  times: " + " ".join(f"{problem.names[i]}@{result.times[i]:g}" for i in result.order))
    return status


if __name__ == "__main__":
    sys.exit(main())
