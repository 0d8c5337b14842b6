"""The service's rules in planner units (nm, s): one set of numbers for the node and the closed-loop simulation.

The planner node fills :class:`ServiceRules` from its parameters (:mod:`mal_planner.ros.node_params`), the
closed loop from its options and the scenario's scales (:meth:`ServiceRules.closed_loop`), and ``mal-launch
--closed-loop`` gives the node the closed loop's numbers. Every time here is on the radar's clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from mal_planner.options import PlanOptions, resolve_flown
from mal_planner.options.plan import DEVIATION_ACCURACIES
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.service.track_filter import noise_factor
from mal_planner.trajectory import Reference

DEVIATION_PER_NOISE = 6.0
"""... or this many radar-noise sigmas (after the track filter), if more: a deviation the radar can tell from its
noise."""
DEVIATION_PER_SEPARATION = 0.05
"""... or this share of the separation, if more (a terminal area 0.15 nm of 3; the thesis 0.0125 nm, below its 0.05 nm
of path accuracies): plans keep twice it as a margin (10 % of the minimum), and a real-size aircraft is not replanned
for a tenth of a mile."""
LEAD_PER_LATENCY = 1.5
"""A replan the policy asks for starts this many times the latest planning time ahead of the tracks it is made
from (predicted along the plans being flown), so that it reaches the aircraft before it starts."""
REPLAN_INTERVAL_TURN_TIMES = 1.0
"""No deviation or periodic replan sooner than this after a plan arrived (thesis: 7.6 s; terminal area 14 s)."""
REPLAN_LIMIT_TURN_TIMES = 2.0
"""Wall-clock limit of a replan in turn times (thesis 15 s, a terminal area 28 s; the first plan has the plan
options' limit): the aircraft fly on meanwhile, and a plan much later than that finds them elsewhere."""
TRACK_FILTER_TURN_TIMES = 0.5
"""Time constant of the track filter (:mod:`mal_planner.service.track_filter`) in turn times (thesis 3.8 s: 30 m
of radar noise at 1 Hz leave 11 m)."""
ESTABLISHED_TURN_TIMES = 2.0
"""The planner leaves an aircraft within this many turn times of its planned landing (thesis 15 s, a terminal area
28 s) out of replans: replanned from a drifted state seconds before the threshold, it got plans that loop back along
the airspace's edge (campaign: crossings 260-420 m off the centreline, 400-600 ft high). The service's own, longer
rule: :func:`established_window_s`."""


@dataclass(frozen=True)
class ServiceRules:
    """When the service plans, from what, and what it does with the result (nm, s on the radar's clock)."""

    deviation_nm: float = 0.0
    """Replan when an aircraft's track strays this far from the plan it flies; a plan is stale (not handed out) when
    re-anchoring it to where the aircraft are is unsafe (:mod:`mal_planner.service.reanchor`). 0: neither (tracks
    that do not follow the plans, e.g. a recording replayed)."""
    min_interval_s: float = 0.0
    """No replan for a deviation, a new aircraft or the period sooner than this after the last plan arrived (a
    failed one too); nor a deviation check within this of an aircraft's plan's end (a new plan would come too
    late to help)."""
    period_s: float = 0.0
    """Replan this often regardless of deviations (0: only when something changed)."""
    filter_time_constant_s: float = 0.0
    """The track filter's time constant (0: raw radar tracks)."""
    track_timeout_s: float = 30.0
    """Forget an aircraft not seen for this long (its plan is withdrawn); 0: never."""
    kept_plan_expiry_s: float = 0.0
    """Withdraw the plans kept after a failed replan this long after the first failure; 0: never."""
    settle_time_s: float = 0.0
    """The first plan waits this long after the first radar track (so that every aircraft has been seen)."""
    min_aircraft: int = 1
    """Plan only with at least this many aircraft tracked."""
    replan_time_limit_s: float | None = None
    """Wall-clock limit of a replan (the first plan has the plan options' limit); None: the options' limit."""
    frame_id: str = "runway"
    """The frame radar tracks must be given in."""
    replan_what_changed: bool = False
    """An aircraft that strays is replanned with those it can affect, among the others' current instructions
    (:mod:`mal_planner.service.subsets`); False: every replan is whole."""

    @classmethod
    def closed_loop(cls, scenario: Scenario, *, noise_sigma_nm: float = 0.0, radar_period_s: float = 1.0,
                    deviation_nm: float | None = None, period_s: float = 0.0,
                    filter_turn_times: float = TRACK_FILTER_TURN_TIMES,
                    replan_limit_turn_times: float = REPLAN_LIMIT_TURN_TIMES,
                    replan_what_changed: bool = False) -> ServiceRules:
        """The closed loop's rules, sized by the scenario's scales: the deviation threshold the larger of
        :data:`DEVIATION_ACCURACIES` path accuracies, :data:`DEVIATION_PER_SEPARATION` separations and
        :data:`DEVIATION_PER_NOISE` filtered noise sigmas (unless given), a turn time between replans. A simulated
        radar never misses a scan: an aircraft missing from the latest one has landed (the track timeout is half a
        period)."""
        scales = Scales.of(scenario)
        tau = scales.seconds(filter_turn_times)
        if deviation_nm is None:
            deviation_nm = max(DEVIATION_ACCURACIES * scales.accuracy_nm,
                               DEVIATION_PER_SEPARATION * scales.separation_nm,
                               DEVIATION_PER_NOISE * noise_sigma_nm * noise_factor(radar_period_s, tau))
        return cls(deviation_nm=deviation_nm, min_interval_s=scales.seconds(REPLAN_INTERVAL_TURN_TIMES),
                   period_s=period_s, filter_time_constant_s=tau, track_timeout_s=0.5 * radar_period_s,
                   replan_time_limit_s=scales.seconds(replan_limit_turn_times), replan_what_changed=replan_what_changed)


def established_window_s(scenario: Scenario) -> float:
    """How close to the end of the plan it flies (the threshold) an aircraft is established on final: one landing
    spacing (the thesis 15 s; a terminal area 90 s, 3.5-4 nm at 140-160 kt: inside the final approach fix, where
    a controller no longer vectors an aircraft). Nobody ahead of it is nearer than a spacing, so it lands on the plan it
    flies: the service hands it no new plan, the policy does not replan it for a deviation and the safety net moves
    the other aircraft of a conflict. Twenty aircraft in closed loop (31 runs): new plans reached aircraft 3-38 s
    before the threshold, the net held one 54 s before it, and 4 crossed it 26-600 m off the centreline or
    155-885 ft high (missed approaches)."""
    return scenario.landing_spacing_s


def established(plan: Reference | None, now: float, window_s: float) -> bool:
    """Whether an aircraft flying ``plan`` (a plan lands at its end) is established on final at ``now``."""
    return plan is not None and plan.end - now < window_s


def service_plan_options(options: PlanOptions, scenario: Scenario, rules: ServiceRules, *,
                         flown: bool) -> PlanOptions:
    """The plan options the service plans with: partial plans handed out (the others hold); aircraft established on
    final (:data:`ESTABLISHED_TURN_TIMES`) are
    left out of replans; with ``flown`` (the plans are flown by aircraft that the service watches) or the options'
    ``tracking_margins``, the margins of flown plans (:func:`~mal_planner.options.tracking_margins`) sized to the
    deviation threshold (or to the options' tracking error, if larger)."""
    threshold = max(rules.deviation_nm, options.tracking_threshold_nm or 0.0)
    options = replace(options, landed_within_turn_times=max(options.landed_within_turn_times, ESTABLISHED_TURN_TIMES),
                      tracking_margins=flown or options.tracking_margins, tracking_threshold_nm=threshold,
                      partial=True)
    return resolve_flown(options, scenario)


def replan_time_limit(options: PlanOptions, rules: ServiceRules) -> float | None:
    """A replan's wall-clock limit: the smaller of the options' and the rules' (None: no limit)."""
    limits = [v for v in (options.time_limit_s, rules.replan_time_limit_s) if v is not None and math.isfinite(v)]
    return min(limits) if limits else None
