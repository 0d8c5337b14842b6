"""The pipeline's options (:class:`PlanOptions`) and the one mapping from option values to them.

:func:`build_plan_options` turns option values (:mod:`mal_planner.options.table`) into PlanOptions for every
interface. Two options change what is planned rather than how: :func:`scenario_for` applies the wake table and the
sequencing strategy to a scenario, and :func:`resolve_flown` the margins of plans that are flown
(:func:`tracking_margins`); the pipeline applies both to every plan.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from mal_planner.landing.base import LandingOptions
from mal_planner.landing.margins import SafetyMargins
from mal_planner.options.option import Option
from mal_planner.options.table import PLAN_OPTIONS
from mal_planner.performance import performance_of
from mal_planner.scales import Scales
from mal_planner.scenario import Aircraft, Scenario
from mal_planner.verification import Tolerances

DEVIATION_ACCURACIES = 10.0
"""The closed loop replans when a track strays this many path accuracies (turn radius / 60) from its plan (thesis:
0.05 nm, 93 m; a terminal area at 150 kt and 30 deg: 0.09 nm): the deviation flown plans keep margins for, unless
a service gives its own (:attr:`PlanOptions.tracking_threshold_nm`). How far aircraft stray is set by their own
dynamics (turn radius and time: guidance, lag, gusts), not by the separation: sized to the separation (0.2 of it,
0.6 nm in a terminal area), the margins of flown plans made the first terminal-area plans infeasible."""
TRACKING_AIRSPACE_MARGIN = 0.5
"""The airspace margin of flown plans, in path accuracies (see :func:`tracking_margins`)."""
TRACKING_CEILING_MARGIN = 1.0
"""The ceiling's margin of flown plans, in path accuracies (a terminal area: 0.0072 nm, 44 ft): the floor's
(:data:`TRACKING_AIRSPACE_MARGIN`) is held down by the threshold's crossing height, the ceiling's is not. Twenty
aircraft in closed loop (traffic-0023, 30-m radar noise): a plan handed out at the ceiling's 0.5-accuracy margin to
an aircraft 0.3 accuracies below it, and the aircraft rose 0.5 accuracies past it, 0.6 m through the ceiling."""
TRACKING_AIRSPACE_BULGE = 0.1
"""How far, in path accuracies, a flown plan's path may enter its airspace margin between collocation points: the
other 0.4 are the aircraft's vertical stray (campaigns: up to 0.4). Without the check, a plan level at the ceiling
bulged 0.0021 nm into its 0.0021-nm margin, and its aircraft left the airspace by 2e-5 nm (ten aircraft,
traffic-0017)."""
BANK_RESERVE = 0.1
"""The share of the bank limit that flown plans leave to the guidance's feedback (thesis: 4.5 of 45 deg)."""


@dataclass(frozen=True)
class PlanOptions:
    initializer: str = "multi-rrt"
    """Path planner of the initializer: 'multi-rrt' or 'ompl:<planner>' (e.g. ompl:RRTConnect)."""
    seed: int | None = 0
    optimize: bool = True
    verify: bool = True
    landing: LandingOptions = field(default_factory=LandingOptions)
    tolerances: Tolerances | None = None
    """The verification's accuracy tolerances; None: the scenario's own (:meth:`Tolerances.for_scenario`)."""
    refinement_rounds: int = 3
    """Re-solves with a locally refined mesh where the verification finds a path constraint broken."""
    time_limit_s: float | None = None
    """Wall-clock limit of one whole plan, initializer included; when it runs out the best result so far is
    returned, or :class:`InitializerTimeout` raised when there is none yet (None: no limit)."""
    landed_within_turn_times: float = 0.4
    """On a replan, aircraft this close to their last planned landing leave the plan (in the scenario's turn
    times; thesis: 3 s)."""
    wake_table: str = "scenario"
    """The wake-turbulence table between landings: the scenario's (``separation.wake``), or icao, recat-eu, none."""
    sequencing: str = "scenario"
    """Who lands when: the scenario's ``sequencing.strategy``, or fcfs, optimal."""
    tracking_margins: bool = False
    """Plan with the margins of flown plans (:func:`tracking_margins`), sized to ``tracking_threshold_nm``."""
    tracking_threshold_nm: float | None = None
    """The deviation the margins of flown plans allow for (None: :data:`DEVIATION_ACCURACIES` path accuracies)."""
    partial: bool = False
    """When a sequential plan runs out of time or fails after its first aircraft, the plan of those first aircraft
    (verified on their own) is the result, the others unplanned (:attr:`PlanResult.unplanned`): the service hands it
    out and holds the others (:mod:`mal_planner.service.fallback`). False: such a plan is a failure."""


def build_plan_options(values: Mapping[str, Any], base: PlanOptions | None = None) -> PlanOptions:
    """PlanOptions from option values by name (the others: ``base``'s, else the defaults): the one mapping."""
    base = base or PlanOptions()
    v = {**{o.name: _current(o, base) for o in PLAN_OPTIONS}, **values}
    landing = replace(base.landing, guess=v["guess"], strategy=v["strategy"],
                      fixed_landing_times=v["fixed_landing_times"], mesh_tol=v["mesh_tol"], refine=v["refine"],
                      segments=v["segments"], degree=v["degree"], nlp_tol=v["nlp_tol"],
                      max_nlp_iterations=v["max_nlp_iterations"], max_mesh_iterations=v["max_mesh_iterations"],
                      output_dt=v["output_dt"])
    return replace(base, initializer=v["initializer"], seed=None if v["seed"] is None or v["seed"] < 0 else v["seed"],
                   optimize=v["optimize"], verify=v["verify"], landing=landing, time_limit_s=v["time_limit_s"],
                   refinement_rounds=base.refinement_rounds if v["refine"] else 0, wake_table=v["wake_table"],
                   sequencing=v["sequencing"],
                   tracking_margins=v["tracking_margins"] or v["tracking_threshold_nm"] is not None,
                   tracking_threshold_nm=v["tracking_threshold_nm"])


def _current(option: Option, base: PlanOptions) -> Any:
    """The value ``base`` has for ``option`` (e.g. ``output_dt`` None: the optimizer's own samples, as
    ``mal-plan`` and the campaigns publish them; the node sets it)."""
    holder = base.landing if hasattr(base.landing, option.name) else base
    return getattr(holder, option.name, option.default)


def scenario_for(options: PlanOptions, scenario: Scenario) -> Scenario:
    """``scenario`` with the options' wake table and sequencing strategy in place of its own (where set)."""
    if options.wake_table != "scenario" and options.wake_table != scenario.wake:
        scenario = replace(scenario, wake=options.wake_table)
    if options.sequencing != "scenario" and options.sequencing != scenario.sequencing.strategy:
        scenario = replace(scenario, sequencing=replace(scenario.sequencing, strategy=options.sequencing))
    reserve = options.landing.margins.spacing_s
    return scenario if reserve == scenario.spacing_reserve_s else replace(scenario, spacing_reserve_s=reserve)


def tracking_margins(margins: SafetyMargins, scales: Scales, threshold_nm: float, bank_limit_rad: float,
                     final_speed: float = float("inf")) -> SafetyMargins:
    """The optimizer's margins for plans that are flown: an aircraft may stray up to the replan threshold before
    the service replans, so the separation keeps twice that much more (two aircraft, each that far towards the other).
    No-fly zones (obstacles with volume) are inflated by the threshold too: with the open-loop margin only (0.02 nm
    in a 15-aircraft terminal area against a 0.1-nm threshold) a flown track grazed a zone's corner (traffic-0014). The
    thin pieces of walls keep the open-loop margins: inflated by the threshold, their holes would leave no room (a
    0.09-nm hole against 0.05 nm). The airspace keeps :data:`TRACKING_AIRSPACE_MARGIN` path accuracies: plans ride
    the floor and the ceiling, where the flown path strays vertically by the load-factor lag (campaigns: up to 0.4
    accuracies; the ceiling keeps :data:`TRACKING_CEILING_MARGIN`); the runway lies on the floor, so the threshold
    is crossed that high (thesis 4.6 m, a terminal area
    29 ft: inside the touchdown window's 0-100 ft). Plans keep :data:`BANK_RESERVE` of the bank limit for the guidance's
    feedback: a plan that turns at the limit onto the threshold leaves none to take out an error there.
    Landings keep the time the threshold takes at ``final_speed`` (nm/s, the slowest ground speed on final) beyond
    their spacing: an aircraft may be that far ahead of its plan, or behind it, before the service replans, and an
    along-track error left on final stays (a constant-speed aircraft keeps it; one of the airspeed model cannot slow
    down on a 3-deg path at idle). Without it a terminal area of airliners landed 88.4 s apart of 90 s (2.5 s early
    after a level deceleration at idle), and the thesis's aircraft 14.3 s of 15 s.
    ``bank_limit_rad``: the smallest bank limit of the scenario's aircraft."""
    return replace(margins, separation=max(margins.separation, 2.0 * threshold_nm / scales.accuracy_nm),
                   zone=max(margins.zone, threshold_nm / scales.accuracy_nm),
                   airspace=max(margins.airspace, TRACKING_AIRSPACE_MARGIN),
                   ceiling=max(margins.ceiling or margins.airspace, TRACKING_CEILING_MARGIN),
                   airspace_bulge=TRACKING_AIRSPACE_BULGE if margins.airspace_bulge is None else
                   min(margins.airspace_bulge, TRACKING_AIRSPACE_BULGE),
                   bank_rad=max(margins.bank_rad, BANK_RESERVE * bank_limit_rad),
                   spacing_s=max(margins.spacing_s, threshold_nm / final_speed))


def resolve_flown(options: PlanOptions, scenario: Scenario) -> PlanOptions:
    """With ``tracking_margins``, the options with the margins of flown plans applied (once: the flag is cleared);
    otherwise ``options`` itself."""
    if not options.tracking_margins:
        return options
    scales = Scales.of(scenario)
    threshold = options.tracking_threshold_nm
    if threshold is None:
        threshold = DEVIATION_ACCURACIES * scales.accuracy_nm
    bank = min((a.limits.bank_angle_max for a in scenario.aircraft),
               default=scenario.config.limits.to_limits().bank_angle_max)
    margins = tracking_margins(options.landing.margins, scales, threshold, bank, slowest_final_speed(scenario))
    return replace(options, landing=replace(options.landing, margins=margins), tracking_margins=False)


def slowest_final_speed(scenario: Scenario) -> float:
    """The slowest ground speed (nm/s) on final of ``scenario``'s aircraft: an airspeed-model aircraft's at its type's
    slowest final approach speed (CAS, as true airspeed at the runway), a constant-speed one's at its airspeed."""
    speeds = [scenario.final_ground_speed(a, _final_airspeed(scenario, a)) for a in scenario.aircraft]
    return min(speeds, default=float("inf"))


def _final_airspeed(scenario: Scenario, aircraft: Aircraft) -> float | None:
    kind = scenario.type_of(aircraft)
    if not aircraft.dynamics.variable_airspeed or kind is None:
        return None
    return min(aircraft.speed, performance_of(kind).final_approach_cas.low)
