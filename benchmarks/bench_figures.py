"""Benchmark of writing a plan's figures: PNGs and plan.html, each in a fresh process (imports included).

A fresh process per run is what the CLI and the node's background renderer pay. Give a plan.json, or a
scenario to plan once first.

Run: python benchmarks/bench_figures.py [scenarios/thesis.yaml | out/thesis/plan.json] [--runs 3]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _plan_json(source: Path, folder: Path) -> Path:
    if source.suffix == ".json":
        return source
    from mal_planner.pipeline import plan
    from mal_planner.report import write_outputs
    from mal_planner.scenario import load_scenario

    write_outputs(plan(load_scenario(source)), folder, figures="none")
    return folder / "plan.json"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("source", nargs="?", default="scenarios/thesis.yaml", type=Path)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        plan_json = _plan_json(args.source, Path(tmp))
        for kind in ("png", "html"):
            times = []
            for _ in range(args.runs):
                t0 = time.perf_counter()
                subprocess.run([sys.executable, "-m", "mal_planner.figures", str(plan_json), "--out", tmp,
                                "--figures", kind, "-q"], check=True)
                times.append(time.perf_counter() - t0)
            print(f"{args.source}: {kind}: median {statistics.median(times):.2f} s over {args.runs} runs "
                  f"(min {min(times):.2f} s)")


if __name__ == "__main__":
    main()
