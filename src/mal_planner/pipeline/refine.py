"""The verification of an optimized plan, and the mesh refined where it fails between collocation points."""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence

from mal_planner.deadline import Deadline
from mal_planner.landing import LandingResult
from mal_planner.landing.sequential import SequentialOptimizer
from mal_planner.landing.solve import LandingOptimizer
from mal_planner.options import PlanOptions
from mal_planner.scenario import Scenario
from mal_planner.scenario.traffic import FixedPath
from mal_planner.verification import VerificationReport, verify

log = logging.getLogger("mal_planner")


def verify_and_refine(scenario: Scenario, landing: LandingResult,
                      optimizer: LandingOptimizer | SequentialOptimizer | None, options: PlanOptions,
                      timings: dict[str, float], deadline: Deadline, fixed: Sequence[FixedPath] = ()
                      ) -> tuple[LandingResult, VerificationReport]:
    """Verify (against the ``fixed`` paths too); where separation or an obstacle fails between collocation points,
    add points there and re-solve with ``optimizer``, up to ``options.refinement_rounds`` times."""
    times_fixed = landing.required_landing_times if optimizer and optimizer.options.fixed_landing_times else None
    t2 = time.perf_counter()
    report = verify(scenario, landing.trajectories, options.tolerances, landing_times=times_fixed, fixed=fixed)
    for round_ in range(options.refinement_rounds):
        times = report.violation_times()
        if report.verified or not times or optimizer is None or deadline.expired():
            break
        log.info("verification round %d: %s; refining the mesh there", round_ + 1, "; ".join(report.reasons[:3]))
        refined = optimizer.refine_at(landing, times, scenario, deadline=deadline,
                                      callsigns=report.violating_callsigns())
        if not refined.success:
            break
        landing = refined
        report = verify(scenario, landing.trajectories, options.tolerances, landing_times=times_fixed, fixed=fixed)
    timings["verification_s"] = time.perf_counter() - t2
    log.info("verification: %s", "verified" if report.verified else "; ".join(report.reasons[:5]))
    return landing, report
