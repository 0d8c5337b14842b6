"""What the sequential strategy tries when an aircraft finds no plan against the plans of those before it (see
:data:`RECOVERIES`)."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from mal_planner.landing.aircraft_plans import earliest_after, guess_from, landed, retimed, spaced
from mal_planner.landing.base import LandingOptions, LandingResult
from mal_planner.landing.guess import AircraftGuess
from mal_planner.landing.pairs import PairScreen
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.sequencing.schedule import planned_spacing
from mal_planner.trajectory import closest_approach

log = logging.getLogger("mal_planner.optimizer")

Flown = list[tuple[str, np.ndarray, np.ndarray]]
"""Callsign, times and positions of each aircraft planned so far."""

RECOVERIES = ("another guess", "later landing", "give way", "swap with the previous")
"""What the sequential strategy tries, in this order, when an aircraft finds no plan against the plans of those
before it (the joint NLP of everyone is the pipeline's last resort):

* *another guess*: the initializer stretches the aircraft's path anew, clear of the plans made so far (the
  first guess only kept clear of the others' guesses);
* *later landing*: where the schedule (not the scenario) set its landing time, it lands as soon as it can after
  it (a free landing time), else later by half a landing spacing, then one, then two (the aircraft after it move
  back as far as their spacing needs);
* *give way*: its plan alone (no intruders) shows which earlier aircraft block it; the last of them is planned
  again with that plan as an intruder, then the aircraft again against everyone;
* *swap with the previous*: it takes the previous aircraft's landing slot, and that one is planned after it.

On a replan (``LandingOptions.replanning``) 'later landing' comes first: there the aircraft that find no plan are
those that fell behind the plan they fly (gusts, the guidance's lag); in the campaigns 'later landing' served 305 of
346 aircraft that tried it, 'another guess' 14 of 389. Such an aircraft's warm solve that IPOPT finds infeasible goes
straight to the recovery: its cold retries never found a plan (ten-aircraft closed loop, seed 0: the cold NLP on the
same mesh 0 of 24 times in the first 12 runs, the solve from the guess 0 of 30 in the first 17) and cost twice the
first solve."""


LATER_BY_SPACINGS = (0.5, 1.0, 2.0)
"""The delays the recovery 'later landing' tries, in landing spacings."""


@dataclass
class Recovery:
    callsign: str
    name: str
    success: bool
    seconds: float


class Planner(Protocol):
    """What the recoveries need of the sequential optimizer."""

    reguess: Any
    scales: Scales
    fixed: Flown
    """Paths that stay as they are (a plan among the others'): no recovery may move them."""

    @property
    def screen(self) -> PairScreen: ...

    def solve_one(self, scenario: Scenario, guess: AircraftGuess, flown: Flown, before: LandingResult | None, mesh,
                  deadline, earliest: float | None, options: LandingOptions) -> LandingResult: ...

    def inaccurate(self, part: LandingResult) -> bool: ...


@dataclass
class Stuck:
    """An aircraft that found no plan: its place ``i`` in the landing ``order`` and what was planned before it (the
    recoveries may change all of these)."""

    scenario: Scenario
    order: list[AircraftGuess]
    i: int
    parts: list[LandingResult]
    flown: Flown
    recoveries: list[Recovery]
    """Every recovery tried so far (this one's are appended)."""
    deadline: Any
    options: LandingOptions


def recover(planner: Planner, stuck: Stuck) -> LandingResult | str | None:
    """Try :data:`RECOVERIES` for the aircraft at ``order[i]``: a plan (``order`` updated), ``"swap"`` (the
    aircraft and the previous one exchanged in ``order``: plan the previous index again) or None."""
    return _Recoveries(planner, stuck).run()


class _Recoveries:
    """The recoveries of one stuck aircraft, each a method, tried in turn by :meth:`run`."""

    def __init__(self, planner: Planner, stuck: Stuck) -> None:
        self.planner, self.stuck = planner, stuck
        self.guess = stuck.order[stuck.i]
        """Its guess when it got stuck."""
        self.cs = self.guess.callsign
        scenario = stuck.scenario
        self.schedule_made = scenario.aircraft_by_callsign(self.cs).landing_time is None
        self.traffic = [(t, pos) for _, t, pos in stuck.flown]
        self.earliest = earliest_after(scenario, stuck.parts[-1], self.cs) if stuck.parts else None
        self.free_earliest = None if stuck.options.fixed_landing_times else self.earliest

    def run(self) -> LandingResult | str | None:
        stuck, cs = self.stuck, self.cs
        options = stuck.options
        steps: list[tuple[str, Callable[[], LandingResult | str | None]]] = [("another guess", self.another_guess)]
        if self.schedule_made and options.fixed_landing_times:
            steps.insert(0 if options.replanning else 1, ("later landing", self.later_landing))
        if self.planner.fixed:  # among paths that stay: those before it cannot give way or swap (they may be fixed)
            return self._first_that_works(steps)
        steps.append(("give way", self.give_way))
        if self.schedule_made and stuck.i > 0 and not any(r.callsign == cs and r.name == "swap with the previous"
                                                          for r in stuck.recoveries):
            steps.append(("swap with the previous", self.swap))
        return self._first_that_works(steps)

    def _first_that_works(self, steps: list[tuple[str, Callable[[], LandingResult | str | None]]]
                          ) -> LandingResult | str | None:
        for name, run in steps:
            outcome = self.attempt(name, run)
            if outcome is not None:
                return outcome
        return None

    def attempt(self, name: str, run: Callable[[], LandingResult | str | None]) -> LandingResult | str | None:
        """``run``'s outcome if it worked (recorded and logged either way), else None."""
        deadline = self.stuck.deadline
        if deadline is not None and deadline.expired():
            return None
        t0 = time.perf_counter()
        outcome = run()
        ok = outcome == "swap" or (isinstance(outcome, LandingResult) and outcome.success
                                   and not self.planner.inaccurate(outcome))
        self.stuck.recoveries.append(Recovery(self.cs, name, ok, time.perf_counter() - t0))
        log.info("sequential: %s: recovery '%s' %s (%.1f s)", self.cs, name, "worked" if ok else "failed",
                 time.perf_counter() - t0)
        return outcome if ok else None

    def another_guess(self) -> LandingResult | None:
        planner, stuck = self.planner, self.stuck
        scenario = stuck.scenario
        new = (planner.reguess(scenario, self.cs, self.guess.landing_time, self.traffic, len(stuck.recoveries))
               if planner.reguess else None)
        if new is None:
            return None
        part = planner.solve_one(scenario, new, stuck.flown, None, None, stuck.deadline, self.free_earliest,
                                 stuck.options)
        if part.success:
            stuck.order[stuck.i] = new
        return part

    def later_landing(self) -> LandingResult | None:
        planner, stuck, guess = self.planner, self.stuck, self.guess
        scenario, order, i, deadline = stuck.scenario, stuck.order, stuck.i, stuck.deadline
        # As little later as it can: its landing time free, no earlier than its slot (nor the spacing behind
        # the previous one). A replan's aircraft that fell behind its plan (gusts) is seconds late, not half a
        # spacing: the fixed delays below pushed everyone behind it back, each re-solved far from its guess.
        soonest = guess.landing_time if self.earliest is None else max(guess.landing_time, self.earliest)
        part = planner.solve_one(scenario, retimed(order[i], soonest), stuck.flown, None, None, deadline, soonest,
                                 replace(stuck.options, fixed_landing_times=False))
        if part.success:  # the time it found is its fixed time from now on (the verification checks it)
            part.required_landing_times = {self.cs: landed(part)}
        if not part.success or planner.inaccurate(part):
            for delay in LATER_BY_SPACINGS:  # fixed times a little later: surer than a free-time NLP
                later = retimed(order[i], guess.landing_time + delay * scenario.landing_spacing_s)
                part = planner.solve_one(scenario, later, stuck.flown, None, None, deadline, None, stuck.options)
                if part.success or (deadline is not None and deadline.expired()):
                    break
        if part is not None and part.success:
            at = landed(part)
            order[i] = retimed(order[i], at)
            _move_back_after(scenario, order, i, at)
        return part

    def give_way(self) -> LandingResult | None:
        planner, stuck, cs = self.planner, self.stuck, self.cs
        scenario, order, i, deadline, options = stuck.scenario, stuck.order, stuck.i, stuck.deadline, stuck.options
        parts, flown = stuck.parts, stuck.flown
        alone = planner.solve_one(scenario, order[i], [], None, None, deadline, self.free_earliest, options)
        if not alone.success:
            return None
        mine = alone.trajectories[0]
        recheck = scenario.separation_nm + planner.screen.recheck_nm(planner.scales)
        blockers = [k for k, (_, t, pos) in enumerate(flown)
                    if closest_approach(mine.t, mine.positions, t, pos) < recheck]
        if not blockers:  # its own plan keeps clear of everyone: the failure was the solver's
            return alone
        log.info("sequential: %s: its own plan comes close to %s; they give way (latest first)", cs,
                 ", ".join(flown[b][0] for b in blockers))
        for k in reversed(blockers):
            others = flown[:k] + flown[k + 1:] + [(cs, mine.t, mine.positions)]
            earlier = (earliest_after(scenario, parts[k - 1], flown[k][0])
                       if k > 0 and not options.fixed_landing_times else None)
            moved = planner.solve_one(scenario, guess_from(parts[k]), others, parts[k], None, deadline, earlier,
                                      options)
            if not moved.success:
                return None
            parts[k] = moved
            tr = moved.trajectories[0]
            flown[k] = (tr.callsign, tr.t, tr.positions)
        # from its own plan, which the others now keep clear of
        return planner.solve_one(scenario, guess_from(alone), flown, alone, None, deadline, self.free_earliest,
                                 options)

    def swap(self) -> str | None:
        stuck, guess = self.stuck, self.guess
        scenario, order, i = stuck.scenario, stuck.order, stuck.i
        previous = order[i - 1]
        if scenario.aircraft_by_callsign(previous.callsign).landing_time is not None:
            return None
        slot_early, slot_late = previous.landing_time, guess.landing_time
        swapped = [*order[:i - 1], retimed(guess, slot_early), retimed(previous, slot_late), *order[i + 1:]]
        if not spaced(scenario, swapped[max(i - 2, 0):i + 2]):
            return None  # the exchanged slots would break a pair's spacing (e.g. its wake minimum)
        order[i - 1], order[i] = swapped[i - 1], swapped[i]
        return "swap"


def _move_back_after(scenario: Scenario, order: list[AircraftGuess], i: int, landing: float) -> None:
    """Those after ``order[i]`` (landing at ``landing``) move back by as much as their spacing needs, where the
    schedule set their times."""
    follows = landing
    for j in range(i + 1, len(order)):
        follows += planned_spacing(scenario, scenario.aircraft_by_callsign(order[j - 1].callsign),
                                   scenario.aircraft_by_callsign(order[j].callsign))
        if order[j].landing_time < follows and \
                scenario.aircraft_by_callsign(order[j].callsign).landing_time is None:
            order[j] = retimed(order[j], follows)
        follows = max(follows, order[j].landing_time)
