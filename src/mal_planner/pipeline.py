"""The planning pipeline shared by the CLI and the ROS node: initializer -> optimizer -> verification."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from mal_planner.initializer.sequencer import InitialPlan, plan_initial
from mal_planner.landing import LandingOptions, LandingResult
from mal_planner.landing.solve import LandingOptimizer, make_guesses, shift_guesses
from mal_planner.scenario import Scenario
from mal_planner.trajectory import Trajectory
from mal_planner.verification import Tolerances, VerificationReport, verify

log = logging.getLogger("mal_planner")


@dataclass(frozen=True)
class PlanOptions:
    initializer: str = "multi-rrt"
    """Path planner of the initializer: 'multi-rrt' or 'ompl:<planner>' (e.g. ompl:RRTConnect)."""
    seed: int | None = 0
    optimize: bool = True
    verify: bool = True
    landing: LandingOptions = field(default_factory=LandingOptions)
    tolerances: Tolerances = field(default_factory=Tolerances)
    refinement_rounds: int = 3
    """Re-solves with a locally refined mesh where the verification finds a path constraint broken."""


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

    @property
    def optimized(self) -> bool:
        return self.landing is not None and self.landing.success

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
            t, states = tr.sample(1.0)
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


def inside_airspace(scenario: Scenario, tolerance_nm: float = 0.01) -> Scenario:
    """Move initial positions that lie just outside the airspace (radar noise) onto its boundary.

    Raises ValueError naming the aircraft when one is further out than ``tolerance_nm``.
    """
    moved = {}
    for ac in scenario.aircraft:
        clipped = np.clip(ac.position, scenario.airspace[:, 0], scenario.airspace[:, 1])
        offset = float(np.max(np.abs(clipped - ac.position)))
        if offset > tolerance_nm:
            raise ValueError(f"{ac.callsign}: initial position {np.round(ac.position, 4).tolist()} nm is "
                             f"{offset:.3f} nm outside the airspace")
        if offset > 0.0:
            log.warning("%s: initial position moved %.4f nm onto the airspace boundary", ac.callsign, offset)
            moved[ac.callsign] = np.concatenate([clipped, ac.state0[3:]])
    return scenario.with_initial_states(moved) if moved else scenario


class Planner:
    """Keeps the optimizer between calls so that replans reuse the NLP and warm-start.

    A replan (same aircraft, obstacles and gates as the last successful plan) skips the initializer: the
    previous optimal trajectories, shifted to the new start time, are the initial guess and keep their
    absolute landing times; the cached NLP is reused unless the order of the events changed (e.g. an
    aircraft has passed the gate since).
    """

    def __init__(self, options: PlanOptions | None = None) -> None:
        self.options = options or PlanOptions()
        self._optimizer: LandingOptimizer | None = None
        self._key: tuple | None = None
        self.last: PlanResult | None = None

    def plan(self, scenario: Scenario, reuse: bool = True, start_time: float = 0.0,
             initial: InitialPlan | None = None) -> PlanResult:
        """Plan ``scenario`` whose initial states hold at ``start_time`` (any clock, in seconds).

        ``initial`` supplies the initializer's result instead of running it (e.g. one computed before).
        """
        opts = self.options
        scenario = inside_airspace(scenario)
        timings: dict[str, float] = {}
        last = self.last
        key = tuple(sorted(a.callsign for a in scenario.aircraft)), scenario.obstacles, scenario.gates
        replan = (reuse and opts.optimize and last is not None and last.landing is not None and self._key == key
                  and self._optimizer is not None and start_time >= last.start_time)
        t0 = time.perf_counter()
        if initial is not None:
            replan = False
        elif replan:
            assert last is not None
            initial = last.initial
            log.info("replanning %.1f s after the previous plan (warm start)", start_time - last.start_time)
        else:
            log.info("initializer %s (seed %s) on %d aircraft", opts.initializer, opts.seed, len(scenario.aircraft))
            initial = plan_initial(scenario, opts.initializer, seed=opts.seed)
        timings["initializer_s"] = time.perf_counter() - t0
        landing = None
        if opts.optimize:
            t1 = time.perf_counter()
            if replan:
                assert last is not None and last.landing is not None and self._optimizer is not None
                guesses = shift_guesses(last.landing, start_time - last.start_time)
                if self._optimizer.accepts(scenario, guesses):
                    landing = self._optimizer.solve(scenario, warm=last.landing, guesses=guesses)
                else:
                    log.info("the order of gate passages and landings changed: new NLP")
                    self._optimizer = LandingOptimizer(scenario, guesses, opts.landing)
                    landing = self._optimizer.solve(scenario)
            else:
                self._optimizer = LandingOptimizer(scenario, make_guesses(scenario, initial, opts.landing),
                                                   opts.landing)
                self._key = key
                landing = self._optimizer.solve(scenario)
            timings["optimizer_s"] = time.perf_counter() - t1
        report = None
        if landing is not None and landing.success and opts.verify:
            landing, report = self._verify_and_refine(scenario, landing, timings)
        result = PlanResult(scenario, opts, initial, landing, report, timings, start_time)
        if result.optimized:
            self.last = result
        return result


    def _verify_and_refine(self, scenario: Scenario, landing: LandingResult, timings: dict[str, float]
                           ) -> tuple[LandingResult, VerificationReport]:
        """Verify; where separation or an obstacle fails between collocation points, add points and re-solve."""
        opts = self.options
        fixed = landing.required_landing_times if opts.landing.fixed_landing_times else None
        t2 = time.perf_counter()
        report = verify(scenario, landing.trajectories, opts.tolerances, landing_times=fixed)
        for round_ in range(opts.refinement_rounds):
            times = report.violation_times()
            if report.verified or not times or self._optimizer is None:
                break
            log.info("verification round %d: %s; refining the mesh there", round_ + 1, "; ".join(report.reasons[:3]))
            refined = self._optimizer.refine_at(landing, times, scenario)
            if not refined.success:
                break
            landing = refined
            report = verify(scenario, landing.trajectories, opts.tolerances, landing_times=fixed)
        timings["verification_s"] = time.perf_counter() - t2
        log.info("verification: %s", "verified" if report.verified else "; ".join(report.reasons[:5]))
        return landing, report


def plan(scenario: Scenario, options: PlanOptions | None = None, initial: InitialPlan | None = None) -> PlanResult:
    """One-shot planning (see :class:`Planner` for replanning)."""
    return Planner(options).plan(scenario, reuse=False, initial=initial)
