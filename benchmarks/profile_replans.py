"""Profile the closed loop's replans (not the first plan, not the simulation) with cProfile.

Each scenario is flown as a closed-loop campaign flies it (mean wind drawn from the campaign seed and the file's
name, up to 20 kt, 2 kt gusts, 30 m radar noise); every plan request after the first runs under the profiler.

    .venv/bin/python benchmarks/profile_replans.py SCENARIO.yaml [...] [--top 40] [--out replans.prof]

Prints each replan (time, CPU seconds, outcome) and the functions by cumulative time; ``--out`` keeps the raw
profile for ``python -m pstats`` or snakeviz.
"""

from __future__ import annotations

import argparse
import cProfile
import logging
import math
import pstats
from pathlib import Path

from mal_planner.campaign.closed_loop import drawn_wind
from mal_planner.closedloop.disturbances import WindSpec
from mal_planner.closedloop.loop import ClosedLoop, ClosedLoopOptions
from mal_planner.closedloop.simulator import SimOptions
from mal_planner.scenario import load_scenario


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="+", type=Path)
    parser.add_argument("--seed", type=int, default=0, help="campaign seed (wind draw, disturbances)")
    parser.add_argument("--wind-kt-max", type=float, default=20.0)
    parser.add_argument("--gust-kt", type=float, default=2.0)
    parser.add_argument("--noise-m", type=float, default=30.0)
    parser.add_argument("--top", type=int, default=40, help="functions to print")
    parser.add_argument("--out", type=Path, help="write the raw profile here")
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)

    profile = cProfile.Profile()
    plan = ClosedLoop._plan

    def profiled(self: ClosedLoop, tracks, reason: str):
        if reason == "initial plan":
            return plan(self, tracks, reason)
        profile.enable()
        try:
            return plan(self, tracks, reason)
        finally:
            profile.disable()

    ClosedLoop._plan = profiled  # type: ignore[method-assign]
    cpu = []
    for path in args.scenarios:
        speed_kt, from_deg = drawn_wind(str(path), args.seed, {"wind_kt_max": args.wind_kt_max})
        options = ClosedLoopOptions(sim=SimOptions(wind=WindSpec.from_knots(speed_kt, math.radians(from_deg),
                                                                            args.gust_kt), seed=args.seed),
                                    radar_noise_m=args.noise_m)
        run = ClosedLoop(load_scenario(path), options).run()
        for r in run.replans:
            cpu.append(r.cpu_s)
            print(f"{path.name}: t={r.t:.0f} s, CPU {r.cpu_s:.2f} s, {'verified' if r.ok else r.message[:100]}")
    cpu.sort()
    if cpu:
        print(f"{len(cpu)} replans, CPU {sum(cpu):.2f} s, median {cpu[len(cpu) // 2]:.2f} s")
    if args.out:
        profile.dump_stats(args.out)
    pstats.Stats(profile).sort_stats("cumulative").print_stats(args.top)


if __name__ == "__main__":
    main()
