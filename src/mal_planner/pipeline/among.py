"""A replan of what changed: some aircraft replanned among the others, whose paths stay as they are.

The service replans an aircraft that strays from its plan together with those it can affect
(:mod:`mal_planner.service.subsets`); everyone else keeps flying what they fly. Each aircraft replanned starts from
its own current plan (the guess, moved to where the aircraft is) and keeps its landing time, so the others' landing
slots are kept; if that fails (e.g. an aircraft fell behind), each lands as early as the spacing after the landings
before its slot allows, and the verification checks the spacing to those after it. The sequential strategy plans
them in landing order against the fixed paths and those replanned before it; the verification checks them against
the fixed paths too (separation, landing spacing). Neither the initializer nor the fallbacks of
:meth:`~mal_planner.pipeline.planner.Planner.plan` run: a replan of what changed that fails is followed by a whole
one (the service's rule). Aircraft established on final (within ``landed_within_turn_times`` of their landing) are
not replanned: their plans join the fixed paths.
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace

from mal_planner.airspace_entry import inside_airspace
from mal_planner.deadline import Deadline
from mal_planner.errors import InvalidInput
from mal_planner.initializer.sequencer import InitialPlan, InitialTrajectory
from mal_planner.landing.guess import guess_along
from mal_planner.landing.sequential import SequentialOptimizer
from mal_planner.options import resolve_flown, scenario_for
from mal_planner.pipeline.planner import Planner, PlanResult
from mal_planner.pipeline.refine import verify_and_refine
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.scenario.traffic import FixedPath, Traffic
from mal_planner.sequencing.schedule import check_request

log = logging.getLogger("mal_planner")


def plan_among(planner: Planner, scenario: Scenario, traffic: Traffic, start_time: float = 0.0) -> PlanResult:
    """Plan ``scenario``'s aircraft (whose current plans are ``traffic.replanned``) among ``traffic.fixed``, with
    ``planner``'s options; initial states at ``start_time`` (any clock). See the module docstring."""
    if planner.options.tracking_margins:  # the margins of flown plans, sized to this scenario
        planner.options = resolve_flown(planner.options, scenario)
    opts = planner.options
    deadline = Deadline(opts.time_limit_s)
    scenario = scenario_for(opts, scenario)
    scales = Scales.of(scenario)
    margins = opts.landing.margins.in_nm(scales)
    scenario = inside_airspace(scenario, margin_nm=margins.airspace_nm)
    moving, settled = _split(scenario, traffic, scales.seconds(opts.landed_within_turn_times))
    fixed = (*traffic.fixed, *settled)
    scenario = replace(scenario, aircraft=tuple(scenario.aircraft_by_callsign(p.callsign) for p in moving))
    check_request(scenario, margins.hole_nm)
    log.info("replanning %s among %d aircraft whose paths stay", ", ".join(p.callsign for p in moving), len(fixed))
    gate = scenario.gates[0] if scenario.gates else None
    guesses = [guess_along(scenario.aircraft_by_callsign(p.callsign), p.t, p.states, gate, p.landing_time)
               for p in moving]  # type: ignore[arg-type]
    t0 = time.perf_counter()
    for fixed_times in (True, False):  # the slots kept; else (an aircraft fell behind) each as early as it can
        optimizer = SequentialOptimizer(scenario, guesses, replace(opts.landing, replanning=True,
                                                                   fixed_landing_times=fixed_times), fixed=fixed)
        landing = optimizer.solve(scenario, guesses=guesses, deadline=deadline)
        if landing.success or deadline.expired():
            break
        log.info("replan of what changed: %s; its landing times chosen by the optimizer instead", landing.status)
    timings = {"initializer_s": 0.0, "optimizer_s": time.perf_counter() - t0}
    report = None
    if landing.success and opts.verify:
        landing, report = verify_and_refine(scenario, landing, optimizer, opts, timings, deadline, fixed)
    return PlanResult(scenario, opts, _current_plans(moving), landing, report, timings, start_time,
                      timed_out=deadline.expired())


def _split(scenario: Scenario, traffic: Traffic, soon_s: float) -> tuple[list[FixedPath], list[FixedPath]]:
    """The current plans of ``scenario``'s aircraft in landing order: those to replan, and those about to land."""
    own = {p.callsign: p for p in traffic.replanned}
    missing = [a.callsign for a in scenario.aircraft if a.callsign not in own or own[a.callsign].landing_time is None]
    if missing:
        raise InvalidInput(f"replan of what changed: {', '.join(missing)} flies no plan to start from")
    paths = sorted((own[a.callsign] for a in scenario.aircraft), key=lambda p: p.landing_time)  # type: ignore
    settled = [p for p in paths if p.landing_time < soon_s]  # type: ignore[operator]
    moving = [p for p in paths if p.landing_time >= soon_s]  # type: ignore[operator]
    if settled:
        log.info("%s about to land: not replanned", ", ".join(p.callsign for p in settled))
    if not moving:
        raise InvalidInput("replan of what changed: every aircraft to replan is about to land")
    return moving, settled


def _current_plans(paths: list[FixedPath]) -> InitialPlan:
    """The replanned aircraft's current plans as the plan's initial paths (their landing order and times)."""
    out = []
    for k, p in enumerate(paths, start=1):
        pos = p.positions
        length = float(sum(((pos[1:] - pos[:-1]) ** 2).sum(axis=1) ** 0.5))
        out.append(InitialTrajectory(p.callsign, k, pos, p.t, p.aircraft.speed, length, float(p.landing_time),
                                     None, None, pos[[0, -1]], {}, float(p.landing_time)))  # type: ignore[arg-type]
    return InitialPlan(tuple(out), "current plans", None, {}, {})


def plan_or_replan(planner: Planner, scenario: Scenario, start_time: float, traffic: Traffic | None = None, *,
                   reuse: bool = True) -> PlanResult:
    """What the service asked for: a whole plan of ``scenario`` (``traffic`` None), else a replan of what changed."""
    if traffic is None:
        return planner.plan(scenario, reuse=reuse, start_time=start_time)
    return plan_among(planner, scenario, traffic, start_time)
