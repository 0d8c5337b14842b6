"""The plan options of a campaign: the same as ``mal-plan``'s, as a JSON-ready dict and as PlanOptions."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

from mal_planner.options import (
    PLAN_OPTIONS,
    add_arguments,
    build_plan_options,
    campaign_defaults,
    check_values,
    from_campaign,
    to_campaign,
    values_from_args,
)

if TYPE_CHECKING:
    from mal_planner.options import PlanOptions

CAMPAIGN_OPTIONS = tuple(o.name for o in PLAN_OPTIONS if o.campaign is not None)
"""The plan options a campaign offers (those with a campaign key)."""
CAMPAIGN_FLAGS = {"time_limit_s": "--plan-time-limit-s"}
"""Campaign spellings of mal-plan's flags (--timeout-s is the campaign's own hard limit per run)."""

DEFAULTS: dict[str, Any] = {**campaign_defaults(), "closed_loop": None}


def add_plan_arguments(parser: argparse.ArgumentParser) -> None:
    """mal-plan's planning options (figures and output options excepted), from the one option table."""
    group = parser.add_argument_group("plan options (as in mal-plan)")
    add_arguments(group, names=CAMPAIGN_OPTIONS, flags=CAMPAIGN_FLAGS)

    loop = parser.add_argument_group("closed loop (mal_planner.closedloop): fly every scenario with the service")
    loop.add_argument("--closed-loop", action="store_true",
                      help="fly each scenario in closed loop instead of planning it once; a run succeeds when "
                           "everyone lands with every minimum kept on the flown tracks")
    loop.add_argument("--wind-kt-max", type=float, default=20.0,
                      help="mean wind per scenario: uniform in [0, this] kt from a uniform direction, drawn from "
                           "the seed and the file name (default: %(default)s)")
    loop.add_argument("--gust-kt", type=float, default=0.0, help="gusts, rms per axis, kt (default: 0)")
    loop.add_argument("--noise-m", type=float, default=30.0, help="radar noise sigma, m (default: %(default)s)")
    loop.add_argument("--delay-s", type=float, default=0.0, help="plan uptake delay, s (default: 0)")
    loop.add_argument("--unknown-wind", action="store_true", help="the planner plans in still air")
    loop.add_argument("--extra-plan-delay-s", type=float, default=0.0,
                      help="a slow planner: every replan reaches the aircraft this much later, s (default: 0)")
    loop.add_argument("--fail-every", type=int, default=0, metavar="K",
                      help="a failing planner: every K-th replan fails (2: every other one; default: 0, none)")
    loop.add_argument("--replan-what-changed", action="store_true",
                      help="replan an aircraft that strays with those it can affect; the others keep their "
                           "instructions (default: every replan is whole)")
    loop.add_argument("--simulator", choices=("ours", "bluesky"), default="ours",
                      help="who flies the plans: our FlightSimulator or BlueSky (optional extra 'bluesky'; steady "
                           "wind only: --gust-kt must be 0) (default: %(default)s)")


def options_from_args(args: argparse.Namespace) -> dict[str, Any]:
    closed = None
    if args.closed_loop:
        closed = {"wind_kt_max": args.wind_kt_max, "gust_kt": args.gust_kt, "noise_m": args.noise_m,
                  "delay_s": args.delay_s, "knows_wind": not args.unknown_wind, "simulator": args.simulator,
                  "extra_plan_delay_s": args.extra_plan_delay_s, "fail_every": args.fail_every,
                  "replan_what_changed": args.replan_what_changed}
    return {**to_campaign(values_from_args(args, CAMPAIGN_OPTIONS)), "closed_loop": closed}


def check_options(options: dict[str, Any]) -> str | None:
    """A one-line problem with the options (naming the option by its flag), or None. Imports the planners (~1 s)."""
    problem = check_values(from_campaign(options), lambda o: CAMPAIGN_FLAGS.get(o.name, o.flag))
    if problem:
        return problem
    closed = options.get("closed_loop") or {}
    for key, flag in (("wind_kt_max", "--wind-kt-max"), ("gust_kt", "--gust-kt"), ("noise_m", "--noise-m"),
                      ("delay_s", "--delay-s"), ("extra_plan_delay_s", "--extra-plan-delay-s"),
                      ("fail_every", "--fail-every")):
        if key in closed and not closed[key] >= 0:
            return f"{flag}: must be >= 0, got {closed[key]}"
    if closed.get("simulator", "ours") != "ours":
        from mal_planner.closedloop.bluesky_sim import make_simulator

        try:
            make_simulator(closed["simulator"])
        except ValueError as exc:
            return str(exc)
        if closed.get("gust_kt", 0.0) > 0:
            return f"--gust-kt: BlueSky flies a steady wind only, got {closed['gust_kt']} with --simulator bluesky"
    return None


def to_plan_options(options: dict[str, Any]) -> PlanOptions:
    """The pipeline's PlanOptions, built exactly as mal-plan builds them (``mal_planner.options``); a campaign
    recorded before an option existed gets its default."""
    return build_plan_options(from_campaign({**DEFAULTS, **options}))
