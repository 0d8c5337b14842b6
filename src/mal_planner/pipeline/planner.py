"""The planning pipeline shared by the CLI and the ROS node: initializer -> optimizer -> verification."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace

from mal_planner.airspace_entry import inside_airspace
from mal_planner.deadline import Deadline
from mal_planner.errors import Failure, InvalidInput, Outcome, PlanningError, TimeLimitReached
from mal_planner.initializer.planners import known_specs
from mal_planner.initializer.sequencer import InitialPlan, plan_initial
from mal_planner.landing import LandingOptions, LandingResult
from mal_planner.landing.guess import AircraftGuess
from mal_planner.landing.sequential import SequentialOptimizer
from mal_planner.landing.solve import LandingOptimizer, make_guesses, shift_guesses, uses_sequential
from mal_planner.landing.strategy import make_optimizer
from mal_planner.options import PlanOptions, resolve_flown, scenario_for
from mal_planner.pipeline.partial import better, others_planned, partial_plan
from mal_planner.pipeline.refine import verify_and_refine
from mal_planner.pipeline.reguess import another_guess
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.sequencing.schedule import check_request
from mal_planner.trajectory import Trajectory
from mal_planner.verification import VerificationReport

log = logging.getLogger("mal_planner")




@dataclass
class PlanResult:
    scenario: Scenario
    options: PlanOptions
    initial: InitialPlan
    landing: LandingResult | None
    verification: VerificationReport | None
    timings: dict[str, float]
    start_time: float = 0.0
    """Clock time of the initial states; every time in the result is relative to it."""
    timed_out: bool = False
    """The time limit ran out (the result is the best found until then)."""
    stopped: str | None = None
    """Where the time limit stopped a stage that had no result yet (one line), e.g. a fallback's initializer."""
    unplanned: tuple[str, ...] = ()
    """A partial plan (:attr:`PlanOptions.partial`): the aircraft left without a plan (``scenario`` holds only the
    planned ones)."""

    @property
    def optimized(self) -> bool:
        return self.landing is not None and self.landing.success

    @property
    def verified(self) -> bool:
        return self.verification is not None and self.verification.verified

    @property
    def failure(self) -> Failure | None:
        """Why this result is not a verified plan (its failure class and one line); None if it is.

        A run without the optimizer (``optimize=False``) or without verification is not a failure.
        """
        if not self.options.optimize:
            return None
        if self.landing is None or not self.landing.success:
            reasons = [self.stopped] if self.stopped else []
            if self.landing is not None or not reasons:
                reasons.append(f"optimizer: {self.landing.status if self.landing is not None else 'not run'}")
            return Failure(Outcome.TIMEOUT if self.timed_out else Outcome.OPTIMIZER_FAILED, "; ".join(reasons))
        if self.verification is None:
            return None if not self.options.verify else Failure(Outcome.TIMEOUT,
                                                                "time limit reached before the verification")
        if not self.verification.verified:
            reason = "; ".join(self.verification.reasons[:3])
            return Failure(Outcome.TIMEOUT if self.timed_out else Outcome.VERIFICATION_FAILED, reason)
        return None

    @property
    def order(self) -> list[str]:
        return [t.callsign for t in self.initial.trajectories]

    def trajectories(self) -> list[Trajectory]:
        """The optimizer's trajectories when it succeeded, else the initializer's paths (no controls)."""
        if self.optimized:
            assert self.landing is not None
            return self.landing.trajectories
        out = []
        for tr in self.initial.trajectories:
            t, states = tr.sample(1.0, self.scenario.aircraft_by_callsign(tr.callsign).dynamics)
            out.append(Trajectory(tr.callsign, t, states))
        return out

    def landing_times(self) -> dict[str, float]:
        if self.optimized:
            assert self.landing is not None
            return dict(self.landing.landing_times)
        return {t.callsign: t.landing_time for t in self.initial.trajectories}

    def gate_times(self) -> dict[str, float | None]:
        if self.optimized:
            assert self.landing is not None
            return dict(self.landing.gate_times)
        return {t.callsign: next(iter(t.gate_times.values()), None) for t in self.initial.trajectories}


class Planner:
    """Keeps the optimizer between calls so that replans reuse the NLP and warm-start.

    A replan (the aircraft of the last successful plan or some of them, the same obstacles and gates) skips the
    initializer: the previous optimal trajectories, shifted to the new start time (their meshes without the
    segments flown since), are the initial guess and keep their absolute landing times; the cached NLP is reused
    unless the order of the events or the aircraft changed (e.g. an aircraft has passed the gate or landed since).
    When a step fails, the next is tried, so a plan never gets stuck on a stale state: the warm replan, then (its
    radar states may no longer reach the times: an aircraft fell behind its plan) a solve in which the optimizer
    chooses the landing times, then, when the replan before failed as well, a cold solve of the same order, then a
    fresh initializer. A first plan whose solve fails is tried once more from the initializer with another seed,
    then, where the schedule fixed the landing times, with times the optimizer chooses. A failed sequential solve
    is followed by the joint NLP of the same order, except for partial plans (:attr:`PlanOptions.partial`), which
    keep the attempt that planned the most aircraft before it failed. Aircraft within
    ``landed_within_turn_times`` of their last planned landing leave the plan quietly.
    """

    def __init__(self, options: PlanOptions | None = None) -> None:
        self.options = options or PlanOptions()
        known = known_specs()
        if self.options.initializer not in known:  # at start-up, not at the first plan
            raise InvalidInput(f"initializer: unknown planner {self.options.initializer!r} (known: {', '.join(known)})")
        self._optimizer: LandingOptimizer | SequentialOptimizer | None = None
        self._initial: InitialPlan | None = None
        """The initial plan the latest attempt started from (a fallback may have made a new one)."""
        self._deadline = Deadline(None)
        """The deadline of the plan under way (for the sequential optimizer's new initial paths)."""
        self._stopped: str | None = None
        self._replanning = False
        """The plan under way started from the last plan (no new initial plan yet)."""
        self._replan_failed = False
        """The latest replan failed: the next one may start over (see :meth:`_optimize`)."""
        self.last: PlanResult | None = None

    def plan(self, scenario: Scenario, reuse: bool = True, start_time: float = 0.0,
             initial: InitialPlan | None = None) -> PlanResult:
        """Plan ``scenario`` whose initial states hold at ``start_time`` (any clock, in seconds).

        ``initial`` supplies the initializer's result instead of running it (e.g. one computed before).
        Raises :class:`InfeasibleRequest` for requests no plan can meet (before any expensive work) and
        :class:`PlanningFailed` when the initializer finds no path: :class:`InitializerTimeout` (failure class
        ``timeout``, its message names the stage) when the time limit runs out in it.
        """
        if self.options.tracking_margins:  # the margins of flown plans, sized to this scenario (once)
            self.options = resolve_flown(self.options, scenario)
        opts = self.options
        scenario = scenario_for(opts, scenario)
        self._deadline = deadline = Deadline(opts.time_limit_s)
        self._stopped = None
        margins = opts.landing.margins.in_nm(Scales.of(scenario))
        scenario = self._without_landed(inside_airspace(scenario, margin_nm=margins.airspace_nm,
                                                        ceiling_margin_nm=margins.top_nm), start_time)
        check_request(scenario, opts.landing.margins.in_nm(Scales.of(scenario)).hole_nm)
        timings: dict[str, float] = {}
        last = self.last
        t0 = time.perf_counter()
        warm = initial is None and reuse and opts.optimize and self._can_warm_start(scenario, start_time)
        self._replanning = warm
        if warm:
            assert last is not None
            initial = last.initial.only(set(_key(scenario)))
            if initial.schedule is not None:  # its times in this plan's clock (the node reports targets and delays)
                initial = replace(initial, schedule=initial.schedule.shifted(start_time - last.start_time))
            log.info("replanning %.1f s after the previous plan (warm start)", start_time - last.start_time)
        elif initial is None:
            log.info("initializer %s (seed %s) on %d aircraft", opts.initializer, opts.seed, len(scenario.aircraft))
            initial = plan_initial(scenario, opts.initializer, seed=opts.seed, deadline=deadline)
        timings["initializer_s"] = time.perf_counter() - t0
        landing = None
        unplanned: tuple[str, ...] = ()
        if opts.optimize:
            t1 = time.perf_counter()
            landing = self._optimize(scenario, initial, warm, start_time, deadline)
            initial = self._initial or initial
            if opts.partial and landing is not None and not landing.success:
                scenario, landing, initial, unplanned = partial_plan(scenario, landing, initial)
            timings["optimizer_s"] = time.perf_counter() - t1
        report = None
        if landing is not None and landing.success and opts.verify:
            # A partial plan's mesh is refined by a sequential optimizer, which re-solves the parts it is given.
            refiner = self._optimizer if not unplanned or isinstance(self._optimizer, SequentialOptimizer) else None
            landing, report = verify_and_refine(scenario, landing, refiner, opts, timings, deadline)
        result = PlanResult(scenario, opts, initial, landing, report, timings, start_time,
                            timed_out=deadline.expired() or self._stopped is not None, stopped=self._stopped,
                            unplanned=unplanned)
        if result.optimized and (report is None or report.verified) and not unplanned:
            self.last = result
        if warm:
            self._replan_failed = result.failure is not None
        return result

    def _can_warm_start(self, scenario: Scenario, start_time: float) -> bool:
        last = self.last
        if last is None or last.landing is None or self._optimizer is None or start_time < last.start_time:
            return False
        # The same aircraft, or some fewer (those that landed since leave; the others keep their previous plans
        # as guesses): in closed loop an aircraft lands every landing spacing, so nearly every replan has fewer.
        callsigns = set(_key(scenario))
        return (bool(callsigns) and callsigns <= set(_key(last.scenario))
                and last.scenario.obstacles == scenario.obstacles and last.scenario.gates == scenario.gates)

    def _without_landed(self, scenario: Scenario, start_time: float) -> Scenario:
        """Drop the aircraft whose last planned landing is (nearly) over: they leave the plan quietly."""
        last = self.last
        if last is None or not last.optimized:
            return scenario
        soon = Scales.of(last.scenario).seconds(self.options.landed_within_turn_times)
        landed = [cs for cs, t in last.landing_times().items() if last.start_time + t - start_time < soon]
        keep = tuple(a for a in scenario.aircraft if a.callsign not in landed)
        if landed and keep and len(keep) < len(scenario.aircraft):
            log.info("%s landed (or about to): left out of the plan", ", ".join(sorted(landed)))
            return replace(scenario, aircraft=keep)
        return scenario

    def _optimize(self, scenario: Scenario, initial: InitialPlan, warm: bool, start_time: float,
                  deadline: Deadline) -> LandingResult | None:
        """Solve, falling back step by step (see the class docstring); None if nothing was tried."""
        attempts = self._attempts(scenario, warm)
        landing = None
        self._initial = initial
        for name, attempt in attempts:
            if deadline.expired():
                log.warning("time limit reached before the %s", name)
                break
            try:
                candidate = attempt(scenario, start_time, deadline)  # type: ignore[operator]
            except TimeLimitReached as exc:  # a fallback's initializer: nothing more can be tried
                self._stopped = f"{exc}, in the {name}"
                log.warning("%s", self._stopped)
                break
            except (PlanningError, ValueError, RuntimeError) as exc:  # PlanningFailed, infeasible, solver errors
                log.warning("%s failed: %s", name, " ".join(str(exc).split()) or type(exc).__name__)
                continue
            if candidate is None:
                continue
            landing = better(landing, candidate, self.options.partial)
            if candidate.success or others_planned(candidate):
                break
            log.warning("%s: %s; trying the next fallback", name, candidate.status)
        return landing

    def _attempts(self, scenario: Scenario, warm: bool) -> list[tuple[str, object]]:
        """The solves to try in turn, with their names (see the class docstring)."""
        opts = self.options
        attempts: list[tuple[str, object]] = []
        # Planned one aircraft at a time, a failure falls back to the joint NLP of the same order first.
        # Not where a partial plan is wanted (the service): there the joint NLP of many aircraft runs out of the
        # replan's time (15-aircraft closed-loop campaigns: 0 of 13 served, 34 times no time was left for it) and the
        # aircraft planned before the sequential solve failed are handed out instead.
        joint_fallback = uses_sequential(opts.landing, len(scenario.aircraft)) and not opts.partial
        # Optimizer-chosen landing times: when the planner made the schedule, or on a replan, where the aircraft
        # may have drifted (radar) so that the scenario's times can no longer be met: a safe plan at other
        # times beats none (the plan reports its times; a warning says the fixed ones were given up).
        free_fallback = opts.landing.fixed_landing_times and (warm or any(a.landing_time is None
                                                                          for a in scenario.aircraft))
        if warm:
            attempts.append(("warm replan", self._warm_attempt))
            if free_fallback:  # a warm replan fails mostly for an aircraft that fell behind: times, not paths
                attempts.append(("optimizer-chosen landing times", self._free_times_attempt))
            # Starting over only when the replan before failed too: in the closed-loop campaigns (about 1,000
            # replans) these never served one that the landing times could not (0 of 21) and took the failing
            # replans to the time limit; a replan that fails leaves the aircraft on the plans they fly.
            if self._replan_failed or not free_fallback:
                attempts.append(("cold solve of the same order", self._cold_same_order))
                if joint_fallback:
                    attempts.append(("joint solve of the same order", self._joint_same_order))
                attempts.append(("fresh initializer", self._fresh_initializer))
        else:
            attempts.append(("solve", self._cold_attempt))
            if joint_fallback:
                attempts.append(("joint solve", self._joint_attempt))
            attempts.append(("solve from another initializer seed", self._reseeded_attempt))
        if free_fallback and not warm:
            attempts.append(("optimizer-chosen landing times", self._free_times_attempt))
        return attempts

    def _new_optimizer(self, scenario: Scenario, guesses, landing_options: LandingOptions | None = None
                       ) -> LandingOptimizer | SequentialOptimizer:
        options = landing_options or self.options.landing
        options = replace(options, replanning=self._replanning, leave_out_failed=self.options.partial)
        self._optimizer = make_optimizer(scenario, guesses, options, self._reguess)
        return self._optimizer

    def _reguess(self, scenario: Scenario, callsign: str, landing_time: float, traffic, attempt: int
                 ) -> AircraftGuess | None:
        """A new initial guess of one aircraft, clear of ``traffic`` (the sequential strategy's first recovery)."""
        return another_guess(self.options.initializer, self.options.seed, self._deadline, scenario, callsign,
                             landing_time, traffic, attempt)

    def _joint_attempt(self, scenario: Scenario, start_time: float, deadline: Deadline) -> LandingResult:
        joint = replace(self.options.landing, strategy="joint")
        guesses = make_guesses(scenario, self._initial, joint)
        return self._new_optimizer(scenario, guesses, joint).solve(scenario, deadline=deadline)

    def _joint_same_order(self, scenario: Scenario, start_time: float, deadline: Deadline) -> LandingResult:
        guesses = self._previous_guesses(scenario, start_time)
        joint = replace(self.options.landing, strategy="joint")
        return self._new_optimizer(scenario, guesses, joint).solve(scenario, deadline=deadline)

    def _cold_attempt(self, scenario: Scenario, start_time: float, deadline: Deadline) -> LandingResult:
        guesses = make_guesses(scenario, self._initial, self.options.landing)
        return self._new_optimizer(scenario, guesses).solve(scenario, deadline=deadline)

    def _previous_guesses(self, scenario: Scenario, start_time: float) -> list[AircraftGuess]:
        """The last plan seen from ``start_time``, of ``scenario``'s aircraft (in the last plan's landing order)."""
        last = self.last
        assert last is not None and last.landing is not None
        keep = set(_key(scenario))
        return [g for g in shift_guesses(last.landing, start_time - last.start_time) if g.callsign in keep]

    def _warm_attempt(self, scenario: Scenario, start_time: float, deadline: Deadline) -> LandingResult:
        last = self.last
        assert last is not None and last.landing is not None and self._optimizer is not None
        guesses = self._previous_guesses(scenario, start_time)
        if self._optimizer.accepts(scenario, guesses):
            self._optimizer.options = replace(self._optimizer.options, replanning=True)
            return self._optimizer.solve(scenario, warm=last.landing, guesses=guesses, deadline=deadline)
        log.info("%s: new NLP", "the order of gate passages and landings changed"
                 if len(guesses) == len(last.landing.trajectories) else "fewer aircraft")
        optimizer = self._new_optimizer(scenario, guesses)
        # Per-aircraft subproblems still warm-start from each one's previous plan; a joint NLP has a new layout.
        warm = last.landing if optimizer.warm_by_aircraft else None
        return optimizer.solve(scenario, warm=warm, guesses=guesses, deadline=deadline)

    def _cold_same_order(self, scenario: Scenario, start_time: float, deadline: Deadline) -> LandingResult:
        guesses = self._previous_guesses(scenario, start_time)
        return self._new_optimizer(scenario, guesses).solve(scenario, deadline=deadline)

    def _fresh_initializer(self, scenario: Scenario, start_time: float, deadline: Deadline) -> LandingResult:
        opts = self.options
        self._initial = plan_initial(scenario, opts.initializer, seed=opts.seed, deadline=deadline)
        self._replanning = False
        return self._cold_attempt(scenario, start_time, deadline)

    def _reseeded_attempt(self, scenario: Scenario, start_time: float, deadline: Deadline) -> LandingResult:
        """Another initial guess (IPOPT's infeasibility verdicts are local): the initializer with a new seed."""
        opts = self.options
        seed = None if opts.seed is None else opts.seed + 1000
        self._initial = plan_initial(scenario, opts.initializer, seed=seed, deadline=deadline)
        return self._cold_attempt(scenario, start_time, deadline)

    def _free_times_attempt(self, scenario: Scenario, start_time: float, deadline: Deadline) -> LandingResult:
        if all(a.landing_time is not None for a in scenario.aircraft):
            log.warning("the scenario's landing times cannot be met from these states: the optimizer chooses them")
        free = replace(self.options.landing, fixed_landing_times=False)
        # On a replan with no new initial plan, the last plan is the guess (the initial plan's times are old).
        guesses = (self._previous_guesses(scenario, start_time) if self._replanning
                   else make_guesses(scenario, self._initial, free))
        return self._new_optimizer(scenario, guesses, free).solve(scenario, deadline=deadline)

def _key(scenario: Scenario) -> tuple[str, ...]:
    return tuple(sorted(a.callsign for a in scenario.aircraft))


def plan(scenario: Scenario, options: PlanOptions | None = None, initial: InitialPlan | None = None) -> PlanResult:
    """One-shot planning (see :class:`Planner` for replanning)."""
    return Planner(options).plan(scenario, reuse=False, initial=initial)
