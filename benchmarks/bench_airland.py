"""OR-Library airland1-13 with the optimal strategy: cost, reference value, proven gap and solve time.

airland1-8 are bundled; airland9-13 (100-500 aircraft) are read from ``--data`` (default ../shared/airland
relative to the project, not bundled: they are large). Each instance runs ``--repeat`` times (the machine is
shared: the table gives the median time and every run's time). Writes benchmarks/airland/results.md.

    .venv/bin/python benchmarks/bench_airland.py --time-limit 60 --repeat 5 --repeat-large 1
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

from mal_planner.sequencing import SequencingOptions, sequence
from mal_planner.sequencing.orlib import BUNDLED, PUBLISHED_OPTIMA, ORLibraryError, read_airland

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "airland"
OUT = ROOT / "benchmarks" / "airland" / "results.md"
LARGE: tuple[str, ...] = tuple(f"airland{k}" for k in range(9, 14))


def run(name: str, data: Path, time_limit_s: float, repeat: int) -> dict[str, object]:
    problem = read_airland(name if name in BUNDLED else data / f"{name}.txt")
    results = [sequence(problem, SequencingOptions(strategy="optimal", time_limit_s=time_limit_s))
               for _ in range(repeat)]
    times = [r.solve_time_s for r in results]
    best = min(results, key=lambda r: r.cost)
    worst_gap = max((r.gap for r in results if r.gap is not None), default=None)
    return {"name": name, "n": problem.n, "cost": best.cost, "costs": sorted({round(r.cost, 2) for r in results}),
            "status": sorted({r.status for r in results}), "gap": worst_gap, "median_s": statistics.median(times),
            "times": times}


def table(rows: list[dict[str, object]], time_limit_s: float, runs: str) -> str:
    lines = ["# OR-Library aircraft landing, one runway (`benchmarks/bench_airland.py`)", "",
             f"Strategy optimal, time limit {time_limit_s:g} s, {runs}, on the shared 2-core machine. "
             "Reference: the published optimum (Beasley et al., Transportation Science 34(2), 2000) for "
             "airland1-8; for airland9-13 the best-known values of Pinol and Beasley (EJOR 171, 2006) and later "
             "work could not be retrieved here, so none is given. Gap: the proven relative gap "
             "(cost - lower bound) / cost, the worst of the runs. Cost: the best of the runs (all listed if "
             "they differ).", "",
             "| instance | aircraft | cost | reference | status | gap | time (s), median | every run (s) |",
             "|---|---|---|---|---|---|---|---|"]
    for row in rows:
        ref = PUBLISHED_OPTIMA.get(str(row["name"]))
        costs = row["costs"]
        cost = f"{row['cost']:.2f}" if len(costs) == 1 else " / ".join(f"{c:.2f}" for c in costs)  # type: ignore[union-attr]
        gap = "-" if row["gap"] is None else f"{100 * float(row['gap']):.2f} %"  # type: ignore[arg-type]
        every = ", ".join(f"{t:.2f}" for t in row["times"])  # type: ignore[union-attr]
        lines.append(f"| {row['name']} | {row['n']} | {cost} | {'not found' if ref is None else f'{ref:g}'} | "
                     f"{'/'.join(row['status'])} | {gap} | {float(row['median_s']):.2f} | {every} |")  # type: ignore[arg-type]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="folder of airland9.txt ... airland13.txt")
    parser.add_argument("--time-limit", type=float, default=60.0, help="seconds per run (default: %(default)s)")
    parser.add_argument("--repeat", type=int, default=5, help="runs per bundled instance (default: %(default)s)")
    parser.add_argument("--repeat-large", type=int, default=1,
                        help="runs per instance of airland9-13, each up to the time limit (default: %(default)s)")
    parser.add_argument("--only", nargs="*", default=None, help="instance names (default: airland1-13)")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    rows = []
    for name in args.only or [*BUNDLED, *LARGE]:
        try:
            row = run(name, args.data, args.time_limit, args.repeat if name in BUNDLED else args.repeat_large)
        except ORLibraryError as exc:
            print(f"bench_airland: {exc}", file=sys.stderr)
            return 2
        print(f"{name}: {row['n']} aircraft  cost {row['cost']:.2f}  gap {row['gap']}  median {row['median_s']:.2f} s",
              flush=True)
        rows.append(row)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(table(rows, args.time_limit, f"{args.repeat} run(s) per bundled instance, "
                                                      f"{args.repeat_large} per large one"))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
