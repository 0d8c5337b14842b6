"""``mal-closed-loop``: fly a scenario in closed loop (planner + simulated aircraft) and report what was flown.

    mal-closed-loop scenarios/thesis.yaml --wind-kt 15 --wind-from-heading-deg 60 --gust-kt 3 --noise-m 30

Writes OUT/closed_loop.json (the metrics, every plan request and the flown tracks) and OUT/closed_loop.png.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import time
from pathlib import Path

from mal_planner import jsonio
from mal_planner.closedloop.bluesky_sim import make_simulator
from mal_planner.closedloop.disturbances import DEFAULT_GUST_TAU_S, WindSpec
from mal_planner.closedloop.loop import ClosedLoopOptions, run_closed_loop
from mal_planner.closedloop.metrics import ClosedLoopMetrics, measure
from mal_planner.closedloop.record import run_record
from mal_planner.closedloop.simulator import LOAD_FACTOR_LAG_S, SimOptions
from mal_planner.options import SERVICE_TIME_LIMIT_S, add_arguments, build_plan_options, check_values, values_from_args
from mal_planner.scenario import Scenario, ScenarioError, load_scenario
from mal_planner.units import kt_to_nm_per_s, nm_per_s_to_kt

PLAN_FLAGS = ("initializer", "seed", "strategy", "mesh_tol", "time_limit_s", "wake_table", "sequencing")
"""The plan options mal-closed-loop offers (from the one option table; the time limit's default is the node's)."""
EXIT_CODES = """exit codes:
  0  everyone landed with every minimum kept on the flown tracks
  1  someone did not land, or a minimum was broken (the reasons are printed)
  2  bad input (one line on stderr)
"""


def _nonnegative(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value) or value < 0.0:
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text!r}")
    return value


def _positive(text: str) -> float:
    value = _nonnegative(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return value


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="mal-closed-loop", description=__doc__.split("\n")[0], epilog=EXIT_CODES,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scenario", type=Path, help="scenario YAML file")
    p.add_argument("--out", type=Path, default=None, help="output folder (default: out/closed_loop/<scenario name>)")
    p.add_argument("--wind-kt", type=_nonnegative, default=None,
                   help="mean wind speed, kt (default: the scenario's wind, else none)")
    p.add_argument("--wind-from-heading-deg", type=float, default=0.0,
                   help="local heading the wind blows from, deg, as the aircraft's heading_deg (default: 0)")
    p.add_argument("--gust-kt", type=_nonnegative, default=0.0, help="gusts, rms per horizontal axis, kt (default: 0)")
    p.add_argument("--gust-tau-s", type=_positive, default=DEFAULT_GUST_TAU_S,
                   help="correlation time of the gusts, s (default: %(default)s)")
    p.add_argument("--unknown-wind", action="store_true", help="the planner plans in still air (default: it knows "
                   "the mean wind)")
    p.add_argument("--noise-m", type=_nonnegative, default=0.0, help="radar noise, sigma per axis, m (default: 0)")
    p.add_argument("--radar-period-s", type=_positive, default=1.0, help="track update period, s (default: 1)")
    p.add_argument("--delay-s", type=_nonnegative, default=0.0,
                   help="delay before a received plan is flown, s (default: 0)")
    p.add_argument("--lag-s", type=_nonnegative, default=LOAD_FACTOR_LAG_S,
                   help="load-factor lag of the aircraft, s (default: %(default)s)")
    p.add_argument("--replan-period-s", type=_nonnegative, default=0.0,
                   help="replan this often as well as on deviations, s (default: 0, only on deviations)")
    p.add_argument("--planning-time-factor", type=_nonnegative, default=1.0,
                   help="simulated seconds charged per second of planning (default: 1, honest)")
    p.add_argument("--extra-plan-delay-s", type=_nonnegative, default=0.0,
                   help="a slow planner: every replan reaches the aircraft this much later, s (default: 0)")
    p.add_argument("--fail-every", type=int, default=0, metavar="K",
                   help="a failing planner: every K-th replan fails (2: every other one; default: 0, none)")
    p.add_argument("--replan-what-changed", action="store_true",
                   help="replan an aircraft that strays with those it can affect; the others keep their instructions "
                        "(default: every replan is whole)")
    p.add_argument("--simulator", choices=("ours", "bluesky"), default="ours",
                   help="who flies the plans: our FlightSimulator, or BlueSky's aircraft and autopilot (steady wind "
                        "only; needs the bluesky extra) (default: %(default)s)")
    plan = p.add_argument_group("plan options (as in mal-plan; the seed seeds the disturbances too)")
    add_arguments(plan, names=PLAN_FLAGS, defaults={"time_limit_s": SERVICE_TIME_LIMIT_S})
    p.add_argument("--no-figure", action="store_true", help="no PNG")
    p.add_argument("-q", "--quiet", action="store_true", help="warnings and the summary only")
    return p


def _seconds(value: float | None) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.2f} s"


def summary_lines(m: ClosedLoopMetrics, planner_side: bool = True) -> list[str]:
    lat = m.replan_latency_s
    verdict = "everyone landed, every minimum kept" if m.success else f"FAILED ({len(m.failures)} reasons)"
    lines = [
        f"closed loop {m.scenario}: {verdict}",
        f"  landed               {m.landed}/{m.aircraft}"
        + (f", spacing >= {m.min_landing_spacing_s:.1f} s" if m.landed > 1 else ""),
        f"  closest pair flown   {m.closest_pair or '-'} {m.min_separation_nm:.4f} nm ({m.separation_ratio:.3f} of the "
        f"minimum)",
        f"  largest deviation    {m.max_deviation_nm:.4f} nm from the plan being flown",
        f"  replans              {m.replans} ({', '.join(f'{k} {v}' for k, v in m.replan_reasons.items()) or 'none'}"
        f"{f'; {m.failed_replans} failed' if m.failed_replans else ''}"
        f"{f'; {m.replans_what_changed} of what changed' if m.replans_what_changed else ''}), order changes "
        f"{m.order_changes}",
        f"  planning time        first {_seconds(m.first_plan_s)}; replans median {_seconds(lat['median'])}, p95 "
        f"{_seconds(lat['p95'])}, max {_seconds(lat['max'])}",
        f"  fallback             {100.0 * m.fallback_share:.1f} % of the flight time; {m.holds} holds, safety net "
        f"{m.net_alerts} alerts, {m.net_uses} uses ({m.vectors} vectors)",
        f"  whole run            {m.wall_s:.1f} s wall clock",
    ]
    if not planner_side:  # the simulator does not see the service's requests
        del lines[4:7]
    if m.external_losses_of_separation is not None:
        found = m.external_losses_of_separation
        lines.insert(3, f"  simulator's LoS      {len(found)}{' (' + ', '.join(found) + ')' if found else ''} "
                        "(its own detection)")
    lines += [f"  ! {text}" for text in m.failures[:10]]
    lines += [f"  note: {text}" for text in m.notes]
    return lines


def _wind(args: argparse.Namespace, scenario: Scenario) -> WindSpec | str:
    """The wind flown (the scenario's mean, or the flags'), or why it cannot be flown (one line)."""
    if args.wind_kt is None:
        if args.gust_kt >= nm_per_s_to_kt(min(a.speed for a in scenario.aircraft)):
            return "--gust-kt: not below the airspeed"
        wind = WindSpec(tuple(scenario.wind), kt_to_nm_per_s(args.gust_kt), args.gust_tau_s)  # type: ignore[arg-type]
    else:
        wind = WindSpec.from_knots(args.wind_kt, math.radians(args.wind_from_heading_deg), args.gust_kt,
                                   args.gust_tau_s)
    slowest = min(a.speed * math.cos(a.state0[3]) for a in scenario.aircraft)
    if wind.speed + 3.0 * wind.gust_sigma >= slowest:
        return (f"--wind-kt/--gust-kt: {nm_per_s_to_kt(wind.speed):.0f} kt plus 3 x "
                f"{nm_per_s_to_kt(wind.gust_sigma):.0f} kt of gusts is not below the slowest airspeed "
                f"{nm_per_s_to_kt(slowest):.0f} kt")
    return wind


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    values = values_from_args(args, PLAN_FLAGS)
    if (problem := check_values(values, lambda o: o.flag)) is not None:
        print(f"mal-closed-loop: {problem}", file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.WARNING if args.quiet else logging.INFO,
                        format="%(asctime)s %(levelname).1s %(name)s: %(message)s", datefmt="%H:%M:%S")
    for noisy in ("mal_planner.ocp", "mal_planner.landing", "mal_planner.initializer"):
        logging.getLogger(noisy).setLevel(logging.WARNING)
    try:
        scenario = load_scenario(args.scenario)
    except ScenarioError as exc:
        print(f"mal-closed-loop: {exc}", file=sys.stderr)
        return 2
    wind = _wind(args, scenario)
    if isinstance(wind, str):
        print(f"mal-closed-loop: {wind}", file=sys.stderr)
        return 2
    try:
        simulator = make_simulator(args.simulator)
        if args.simulator == "bluesky" and wind.gust_sigma > 0.0:
            raise ValueError("--gust-kt: BlueSky flies a steady wind (no gusts)")
    except ValueError as exc:
        print(f"mal-closed-loop: {exc}", file=sys.stderr)
        return 2
    options = ClosedLoopOptions(
        sim=SimOptions(wind=wind, plan_delay_s=args.delay_s, load_factor_lag_s=args.lag_s,
                       seed=None if args.seed < 0 else args.seed),
        plan=build_plan_options(values),
        planner_knows_wind=not args.unknown_wind, radar_noise_m=args.noise_m, radar_period_s=args.radar_period_s,
        replan_period_s=args.replan_period_s, planning_time_factor=args.planning_time_factor, progress=not args.quiet,
        extra_plan_delay_s=args.extra_plan_delay_s, fail_every=max(args.fail_every, 0),
        replan_what_changed=args.replan_what_changed)
    out = args.out or Path("out") / "closed_loop" / scenario.name
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    run = run_closed_loop(scenario, options, simulator)
    metrics = measure(run)
    record = run_record(run, metrics, {k: v for k, v in vars(args).items() if k not in ("scenario", "out")})
    record["wind_mean_kt"] = [nm_per_s_to_kt(w) for w in wind.mean]
    jsonio.write(out / "closed_loop.json", record, default=float)
    if not args.no_figure:
        from mal_planner.closedloop.figure import figure_closed_loop

        figure_closed_loop(scenario, run.sim, out / "closed_loop.png", run.instructions)
    print("\n".join(summary_lines(metrics)))
    print(f"  outputs              {out} ({time.perf_counter() - t0:.1f} s)")
    return 0 if metrics.success else 1


if __name__ == "__main__":
    sys.exit(main())
