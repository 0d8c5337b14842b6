"""Benchmark of the landing optimizer on a scenario: medians of several runs and ratios in one run.

Compares, on the same machine in the same run:
  * the initial guess: the initializer's paths (thesis) vs naive straight lines (baseline);
  * a cold solve with hp refinement to 1e-6 vs a warm replan 10 s later (real-time replanning);
  * the fixed initial mesh only (no refinement).
The initializer itself is timed separately (its result is shared by the optimizer runs).

Run: python benchmarks/bench_landing.py [scenarios/thesis.yaml] [--runs 5]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from mal_planner.initializer import plan_initial
from mal_planner.landing import LandingOptions
from mal_planner.options import PlanOptions
from mal_planner.pipeline import Planner
from mal_planner.scenario import load_scenario


def _median(values: list[float]) -> float:
    return statistics.median(values)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("scenario", nargs="?", default="scenarios/thesis.yaml")
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    sc = load_scenario(args.scenario)

    t_init = []
    for seed in range(args.runs):
        t0 = time.perf_counter()
        initial = plan_initial(sc, "multi-rrt", seed=seed)
        t_init.append(time.perf_counter() - t0)
    initial = plan_initial(sc, "multi-rrt", seed=0)

    cases = {
        "initializer guess, hp to 1e-6": LandingOptions(),
        "straight-line guess, hp to 1e-6": LandingOptions(guess="straight"),
        "initializer guess, initial mesh only": LandingOptions(refine=False),
        "straight-line guess, initial mesh only": LandingOptions(guess="straight", refine=False),
    }
    rows = {}
    for name, landing in cases.items():
        wall, iters, verified = [], [], []
        for _ in range(args.runs):
            planner = Planner(PlanOptions(seed=0, landing=landing, verify=False))
            t0 = time.perf_counter()
            res = planner.plan(sc, initial=initial)
            wall.append(time.perf_counter() - t0)
            iters.append(res.landing.nlp_iterations)
            verified.append(res.landing.success)
        rows[name] = (_median(wall), _median(iters), all(verified))

    replan_wall, replan_iters = [], []
    for _ in range(args.runs):
        planner = Planner(PlanOptions(seed=0, verify=False))
        first = planner.plan(sc, initial=initial, start_time=0.0)
        states = {}
        for tr in first.trajectories():
            state = tr.state_at(10.0)
            state[:3] += np.array([0.005, -0.005, -0.001])
            states[tr.callsign] = state
        t0 = time.perf_counter()
        res = planner.plan(sc.with_initial_states(states), start_time=10.0)
        replan_wall.append(time.perf_counter() - t0)
        replan_iters.append(res.landing.nlp_iterations)
    rows["warm replan 10 s later (same NLP)"] = (_median(replan_wall), _median(replan_iters), True)

    base = rows["straight-line guess, hp to 1e-6"][0]
    print(f"scenario {sc.name}: {len(sc.aircraft)} aircraft, median of {args.runs} runs")
    print(f"initializer (multi-rrt, seeds 0..{args.runs - 1}): {_median(t_init):.2f} s")
    print(f"{'optimizer case':<40} {'median s':>9} {'IPOPT it':>9} {'vs straight hp':>15} {'all ok':>7}")
    for name, (wall, iters, ok) in rows.items():
        print(f"{name:<40} {wall:>9.2f} {iters:>9.0f} {wall / base:>14.2f}x {str(ok):>7}")


if __name__ == "__main__":
    main()
