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

Aircraft that fly no plan (new, holding, vectored) join the same way (:func:`plan_joining`): slotted after the last
fixed landing, each with a new initial path stretched to its slot clear of the paths before it, then optimized and
verified as above.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import replace
from functools import partial

from mal_planner.airspace_entry import inside_airspace
from mal_planner.deadline import Deadline
from mal_planner.errors import InvalidInput
from mal_planner.initializer.sequencer import InitialPlan, InitialTrajectory, Sequencer
from mal_planner.initializer.timed_paths import timed_guess
from mal_planner.landing.guess import AircraftGuess, guess_along, guess_from_initial_plan
from mal_planner.landing.sequential import Reguess, SequentialOptimizer
from mal_planner.options import PlanOptions, resolve_flown, scenario_for
from mal_planner.pipeline.planner import Planner, PlanResult
from mal_planner.pipeline.refine import verify_and_refine
from mal_planner.pipeline.reguess import another_guess
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.scenario.traffic import FixedPath, Traffic
from mal_planner.sequencing.schedule import DEFAULT_MARGIN_TURN_TIMES, check_request, slot_in_order
from mal_planner.sequencing.timing import earliest_landing_time

log = logging.getLogger("mal_planner")


def plan_among(planner: Planner, scenario: Scenario, traffic: Traffic, start_time: float = 0.0) -> PlanResult:
    """Plan ``scenario``'s aircraft (whose current plans are ``traffic.replanned``) among ``traffic.fixed``, with
    ``planner``'s options; initial states at ``start_time`` (any clock). See the module docstring."""
    opts, deadline, scenario, scales = _prepared(planner, scenario)
    margins = opts.landing.margins.in_nm(scales)
    moving, settled = _split(scenario, traffic, scales.seconds(opts.landed_within_turn_times))
    fixed = (*traffic.fixed, *settled)
    scenario = replace(scenario, aircraft=tuple(scenario.aircraft_by_callsign(p.callsign) for p in moving))
    check_request(scenario, margins.hole_nm)
    log.info("replanning %s among %d aircraft whose paths stay", ", ".join(p.callsign for p in moving), len(fixed))
    gate = scenario.gates[0] if scenario.gates else None
    guesses = [guess_along(scenario.aircraft_by_callsign(p.callsign), p.t, p.states, gate, p.landing_time)
               for p in moving]  # type: ignore[arg-type]
    return _solve_among(opts, scenario, guesses, fixed, deadline, _current_plans(moving), start_time)


def plan_joining(planner: Planner, scenario: Scenario, traffic: Traffic, start_time: float = 0.0) -> PlanResult:
    """Plan ``scenario``'s aircraft, which fly no plan (``traffic.joining``), to land after everyone in
    ``traffic.fixed``, clear of their paths, which stay as they are; initial states at ``start_time``.

    Their landing slots follow the last fixed landing in order of their turn-aware earliest landing times, each its
    pair's spacing behind the one before (as the sequencer spaces them); each gets a new initial path stretched to
    its slot clear of the paths before it (the initializer's), then the optimization and verification of
    :func:`plan_among`."""
    opts, deadline, scenario, scales = _prepared(planner, scenario)
    check_request(scenario, opts.landing.margins.in_nm(scales).hole_nm)
    slots = _slots_after(scenario, traffic.fixed, scales.seconds(DEFAULT_MARGIN_TURN_TIMES))
    log.info("planning %s after %d aircraft whose paths stay (slots %s)", ", ".join(slots), len(traffic.fixed),
             ", ".join(f"{t:.1f} s" for t in slots.values()))
    sequencer = Sequencer(opts.initializer)
    seen = [(p.t, p.positions) for p in traffic.fixed]
    paths = []
    for k, (cs, slot) in enumerate(slots.items(), start=1):
        path = sequencer.replan_one(scenario, cs, slot, seen, opts.seed, order=k, deadline=deadline)
        paths.append(path)
        seen.append(timed_guess(path.waypoints, scenario.aircraft_by_callsign(cs).dynamics, slot))
    initial = InitialPlan(tuple(paths), str(opts.initializer), opts.seed, {}, {})
    guesses = guess_from_initial_plan(scenario, paths, list(slots.values()))

    return _solve_among(opts, scenario, guesses, tuple(traffic.fixed), deadline, initial, start_time,
                        partial(another_guess, opts.initializer, opts.seed, deadline))


def _prepared(planner: Planner, scenario: Scenario) -> tuple[PlanOptions, Deadline, Scenario, Scales]:
    """The planner's options (the margins of flown plans sized to ``scenario``), the plan's deadline, ``scenario``
    as planned (the options' wake table and sequencing, initial states inside the airspace) and its scales."""
    if planner.options.tracking_margins:
        planner.options = resolve_flown(planner.options, scenario)
    opts = planner.options
    deadline = Deadline(opts.time_limit_s)
    scenario = scenario_for(opts, scenario)
    scales = Scales.of(scenario)
    margins = opts.landing.margins.in_nm(scales)
    scenario = inside_airspace(scenario, margin_nm=margins.airspace_nm, ceiling_margin_nm=margins.top_nm)
    return opts, deadline, scenario, scales


def _slots_after(scenario: Scenario, fixed: Sequence[FixedPath], margin_s: float) -> dict[str, float]:
    """Landing times of ``scenario``'s aircraft after the last landing in ``fixed`` (see :func:`plan_joining`)."""
    landings = [p for p in fixed if p.landing_time is not None]
    leader = max(landings, key=lambda p: p.landing_time, default=None)  # type: ignore[arg-type, return-value]
    earliest = {ac.callsign: earliest_landing_time(scenario, ac) + margin_s for ac in scenario.aircraft}
    order = sorted(scenario.aircraft, key=lambda ac: (earliest[ac.callsign], ac.callsign))
    after = None if leader is None else (leader.aircraft, float(leader.landing_time))  # type: ignore[arg-type]
    return slot_in_order(scenario, order, lambda ac: earliest[ac.callsign], after=after)


def _solve_among(opts: PlanOptions, scenario: Scenario, guesses: list[AircraftGuess], fixed: Sequence[FixedPath],
                 deadline: Deadline, initial: InitialPlan, start_time: float, reguess: Reguess | None = None
                 ) -> PlanResult:
    """Solve ``scenario``'s aircraft from ``guesses`` among the ``fixed`` paths at the guesses' landing times, else
    (an aircraft fell behind) at times the optimizer chooses; verified against the fixed paths. With ``reguess``
    (aircraft joining) the sequential strategy tries its recoveries that leave the fixed paths as they are."""
    t0 = time.perf_counter()
    for fixed_times in (True, False):  # the slots kept; else (an aircraft fell behind) each as early as it can
        optimizer = SequentialOptimizer(scenario, guesses, replace(opts.landing, replanning=True,
                                                                   fixed_landing_times=fixed_times), reguess,
                                        fixed=fixed, recover_among_fixed=reguess is not None)
        landing = optimizer.solve(scenario, guesses=guesses, deadline=deadline)
        if landing.success or deadline.expired():
            break
        log.info("plan among fixed paths: %s; its landing times chosen by the optimizer instead", landing.status)
    timings = {"initializer_s": 0.0, "optimizer_s": time.perf_counter() - t0}
    report = None
    if landing.success and opts.verify:
        landing, report = verify_and_refine(scenario, landing, optimizer, opts, timings, deadline, list(fixed))
    return PlanResult(scenario, opts, initial, landing, report, timings, start_time, timed_out=deadline.expired())


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
    if traffic.joining:
        return plan_joining(planner, scenario, traffic, start_time)
    return plan_among(planner, scenario, traffic, start_time)
