"""What the sequential decomposition costs in optimality, and what it saves in time, against the joint NLP.

Both strategies plan the same scenarios in this process (same initializer seed, same schedule), each plan is
checked by the independent verification; the objective is the same sum in both (-sum t_gate + the smoothness
integrals with fixed landing times, +sum t_land with free ones), so lower is better and the difference is the
loss of the decomposition (negative: the joint NLP ended in a worse local optimum).

    .venv/bin/python benchmarks/bench_decomposition.py --sizes 4,6,8,10 --out benchmarks/scaling

Scenarios: the thesis, ``scenarios/five_aircraft.yaml`` and scenario 0 of ``mal-traffic --aircraft N --seed 0
--layout wall`` per N (the scaling benchmark's streams). Writes ``decomposition.md`` and ``decomposition.json``.
"""

from __future__ import annotations

import argparse
import logging
import time
from dataclasses import replace
from pathlib import Path

from mal_planner import jsonio
from mal_planner.campaign.traffic import TrafficSpec, generate_one
from mal_planner.landing import LandingOptions
from mal_planner.options import PlanOptions
from mal_planner.pipeline import Planner
from mal_planner.scenario import Scenario, load_scenario, scenario_from_text

REPO = Path(__file__).resolve().parents[1]


def scenarios(sizes: list[int]) -> list[tuple[str, Scenario]]:
    out = [("thesis", load_scenario(REPO / "scenarios" / "thesis.yaml")),
           ("five_aircraft", load_scenario(REPO / "scenarios" / "five_aircraft.yaml"))]
    for n in sizes:
        text = generate_one(TrafficSpec(aircraft=(n, n), seed=0, layout="wall", landing_times="free"), 0).text
        out.append((f"stream N={n}", scenario_from_text(text)))
    return out


def run(name: str, scenario: Scenario, strategy: str, time_limit: float) -> dict:
    options = PlanOptions(seed=0, time_limit_s=time_limit, landing=replace(LandingOptions(), strategy=strategy))
    t0 = time.perf_counter()
    result = Planner(options).plan(scenario)
    wall = time.perf_counter() - t0
    landing = result.landing
    return {"scenario": name, "n": len(scenario.aircraft), "strategy": strategy, "wall_s": wall,
            "optimizer_s": result.timings.get("optimizer_s"), "verified": result.verified,
            "used": landing.strategy if landing else None,
            "objective": landing.objective if landing and landing.success else None,
            "failure": None if result.verified else str(result.failure)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", default="4,6,8,10", help="generated stream sizes (default 4,6,8,10)")
    parser.add_argument("--time-limit", type=float, default=300.0, help="per plan, s (default 300)")
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks" / "scaling")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    rows = []
    for name, sc in scenarios([int(s) for s in args.sizes.split(",") if s]):
        for strategy in ("joint", "sequential"):
            row = run(name, sc, strategy, args.time_limit)
            print(f"{name:>15} {strategy:>10}: {row['wall_s']:7.2f} s verified={row['verified']} "
                  f"objective={row['objective']}", flush=True)
            rows.append(row)
    args.out.mkdir(parents=True, exist_ok=True)
    jsonio.write(args.out / "decomposition.json", rows, indent=1)
    lines = ["# Sequential decomposition against the joint NLP", "",
             "`python benchmarks/bench_decomposition.py` (one run each, in process, 2-core development machine). "
             "Objective: lower is better; loss = sequential - joint (relative to |joint|).", "",
             "| scenario | N | joint s | joint objective | sequential s | sequential objective | loss | speed-up | "
             "verified (joint / sequential) |", "|---|---|---|---|---|---|---|---|---|"]
    for name, _ in scenarios([]) + [(f"stream N={s}", None) for s in args.sizes.split(",") if s]:
        pair = {r["strategy"]: r for r in rows if r["scenario"] == name}
        if len(pair) < 2:
            continue
        j, q = pair["joint"], pair["sequential"]
        loss = "-" if j["objective"] is None or q["objective"] is None else (
            f"{q['objective'] - j['objective']:+.3f} ({(q['objective'] - j['objective']) / abs(j['objective']):+.2%})")
        lines.append(f"| {name} | {j['n']} | {j['wall_s']:.2f} | {_num(j['objective'])} | {q['wall_s']:.2f} | "
                     f"{_num(q['objective'])} | {loss} | {j['wall_s'] / q['wall_s']:.1f}x | "
                     f"{j['verified']} / {q['verified']} |")
    (args.out / "decomposition.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    print("\n".join(lines))


def _num(value: float | None) -> str:
    return "-" if value is None else f"{value:.3f}"


if __name__ == "__main__":
    main()
