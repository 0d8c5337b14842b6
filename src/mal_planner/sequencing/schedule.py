"""The landing schedule: who lands when, decided before any path is stretched or any NLP is built.

The order and the free times come from :mod:`mal_planner.sequencing`, the one place where they are decided
(:func:`make_schedule`): fixed landing times (the scenario's) are kept; free aircraft may land from their
turn-aware earliest time (:mod:`mal_planner.sequencing.timing`) plus a margin on, each pair at least
:func:`landing_spacing` apart (wake turbulence included). Strategy ``fcfs`` (the default): in order of the
earliest times, each at the earliest slot that keeps the spacing to every time taken; ``optimal``: the MILP's
order and times of least total delay (scenario ``sequencing:``).

:func:`check_request` finds the requests no plan can meet (exit 2 / a FAILED status with the reason), so
that they never reach the optimizer as solver noise.
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from mal_planner.errors import InfeasibleRequest
from mal_planner.scales import Scales
from mal_planner.scenario import Aircraft, Scenario
from mal_planner.sequencing import SequencingInfeasible, SequencingProblem, sequence
from mal_planner.sequencing.timing import fastest_dynamics, reachable_lower_bound
from mal_planner.wake import wake_spacing_s

log = logging.getLogger("mal_planner.sequencing")

FINAL_RADII = 3.0
"""Length of the straight final approach every aircraft flies in file, in turn radii (thesis: 0.9 nm): the
initializer's approach route ends with it, and the schedule spaces landings over it."""

DEFAULT_MARGIN_TURN_TIMES = 2.0 / 3.0
"""Scheduled landing times sit this many turn times after the turn-aware earliest estimate (room for the
optimizer; thesis: 5 s)."""
SPACING_MARGIN_TURN_TIMES = 1.0 / 7500.0
"""The schedule and the optimizer keep each pair's landing spacing plus this many turn times (thesis: 1 ms, the
verification's landing-time resolution), so round-off never leaves a pair on the unsafe side of its minimum."""


@dataclass(frozen=True)
class LandingSchedule:
    order: tuple[str, ...]
    """Callsigns, first to land first."""
    times: dict[str, float]
    """Scheduled landing time per callsign (s from the initial states)."""
    earliest: dict[str, float]
    """Turn-aware earliest landing estimates the schedule was made from."""
    fixed: frozenset[str]
    """Aircraft whose landing time the scenario fixes."""
    target: dict[str, float] = field(default_factory=dict)
    """The time each aircraft aims at: the scenario's fixed time, else its earliest plus the schedule's margin."""
    strategy: str = "fcfs"
    """The sequencing strategy that chose the order (``sequencing.strategy``)."""
    status: str = "heuristic"
    """optimal, feasible (time limit; see ``gap``) or heuristic (first come, first served)."""
    gap: float | None = None

    def delay(self, callsign: str) -> float:
        """Seconds after its target that ``callsign`` lands."""
        return self.times[callsign] - self.target.get(callsign, self.times[callsign])

    def time_list(self) -> list[float]:
        return [self.times[cs] for cs in self.order]

    def shifted(self, dt: float) -> LandingSchedule:
        """This schedule seen ``dt`` seconds later (its times are from the initial states)."""
        return replace(self, times={cs: t - dt for cs, t in self.times.items()},
                       earliest={cs: t - dt for cs, t in self.earliest.items()},
                       target={cs: t - dt for cs, t in self.target.items()})

    def only(self, callsigns: set[str]) -> LandingSchedule:
        """This schedule of ``callsigns`` alone (the others' slots left empty)."""
        return replace(self, order=tuple(cs for cs in self.order if cs in callsigns),
                       times={cs: t for cs, t in self.times.items() if cs in callsigns},
                       earliest={cs: t for cs, t in self.earliest.items() if cs in callsigns},
                       fixed=frozenset(self.fixed & callsigns),
                       target={cs: t for cs, t in self.target.items() if cs in callsigns})


def start_conflicts(scenario: Scenario, aircraft) -> list[tuple[Aircraft, Aircraft, float]]:
    """The pairs of ``aircraft`` closer than the scenario's separation at their initial states, with their
    distance (nm): no plan can separate them from the first instant."""
    sep = scenario.separation_nm
    out = []
    for a, b in itertools.combinations(aircraft, 2):
        d = float(np.linalg.norm(a.position - b.position))
        if d < sep:
            out.append((a, b, d))
    return out


def check_request(scenario: Scenario, gate_margin_nm: float = 0.0) -> None:
    """Raise :class:`InfeasibleRequest` (one line, naming the aircraft and the numbers) for impossible requests.

    Checked: separation broken at the start, an aircraft that leaves the airspace through its floor or ceiling
    whatever it does, fixed landing times closer than the minimum spacing or their wake-turbulence minimum,
    fixed landing times earlier than any trajectory can reach the runway, a gate hole no aircraft can pass.
    """
    for a, b, d in start_conflicts(scenario, scenario.aircraft):
        raise InfeasibleRequest(f"{a.callsign} and {b.callsign} are {d:.3f} nm apart at the start "
                                f"(minimum separation {scenario.separation_nm:g} nm)")
    for ac in scenario.aircraft:
        reason = vertical_escape_problem(scenario, ac)
        if reason is not None:
            raise InfeasibleRequest(reason)
    for gate in scenario.gates:
        axes = [a for a in range(3) if a != gate.axis]
        for (lo, hi), ax in zip(gate.bounds, axes, strict=True):
            lo_ok, hi_ok = max(lo + gate_margin_nm, scenario.airspace[ax, 0]), min(hi - gate_margin_nm,
                                                                                  scenario.airspace[ax, 1])
            if lo_ok >= hi_ok:
                raise InfeasibleRequest(f"gate {gate.name!r}: its hole {'xyz'[ax]} [{lo:g}, {hi:g}] nm leaves no "
                                        f"room to pass inside the airspace {scenario.airspace[ax].tolist()}")
        if not scenario.airspace[gate.axis, 0] <= gate.position <= scenario.airspace[gate.axis, 1]:
            raise InfeasibleRequest(f"gate {gate.name!r} lies outside the airspace")
    fixed = [(ac.landing_time, ac) for ac in scenario.aircraft if ac.landing_time is not None]
    for ac in scenario.aircraft:
        if ac.landing_time is None:
            continue
        bound = reachable_lower_bound(scenario, ac)
        if ac.landing_time < bound:
            raise InfeasibleRequest(f"{ac.callsign}: landing time {ac.landing_time:g} s is earlier than it can "
                                    f"reach the runway ({bound:.1f} s at full speed on straight lines"
                                    f"{' in the wind' if ac.dynamics.has_wind else ''})")
    fixed.sort(key=lambda item: item[0])
    for (ta, a), (tb, b) in itertools.pairwise(fixed):
        if tb - ta < scenario.landing_spacing_s - 1e-9:
            raise InfeasibleRequest(f"{a.callsign} and {b.callsign} land {tb - ta:g} s apart ({ta:g} s, {tb:g} s); "
                                    f"the minimum spacing is {scenario.landing_spacing_s:g} s")
        wake = wake_spacing_s(scenario.wake, a.wake_category, b.wake_category, scenario.final_ground_speed(b),
                              scenario.separation_nm, 0.0)
        if tb - ta < wake:
            raise InfeasibleRequest(f"{a.callsign} and {b.callsign} land {tb - ta:g} s apart ({ta:g} s, {tb:g} s); "
                                    f"the {scenario.wake} wake minimum {a.wake_category}->{b.wake_category} needs "
                                    f"{wake:.1f} s")


def vertical_escape_problem(scenario: Scenario, ac) -> str | None:
    """Why ``ac`` crosses the airspace's ceiling (floor) even when it pulls its vertical load factor to the
    limit at once (e.g. a radar track at the ceiling, still climbing), or None. The flight-path angle rate
    (g / V)(n_v - cos gamma) does not depend on n_h, so the extreme n_v is the best escape (RK4 on the model,
    steps of T / 150 for at most 16 T, thesis: 0.05 s and 120 s)."""
    scales = Scales.of(scenario)
    step_s, horizon_s = scales.seconds(1.0 / 150.0), scales.seconds(16.0)
    lo, hi = scenario.airspace[2]
    gamma = float(ac.state0[3])
    if gamma == 0.0:
        return None
    n_v = ac.limits.n_v[0] if gamma > 0 else ac.limits.n_v[1]
    control = ac.dynamics.level_flight_control(0.0)
    control[1] = n_v
    x = ac.state0.astype(float).copy()
    extreme = x[2]
    for _ in range(int(horizon_s / step_s)):
        x = ac.dynamics.rk4_step(x, control, step_s)
        extreme = max(extreme, x[2]) if gamma > 0 else min(extreme, x[2])
        if np.sign(x[3]) != np.sign(gamma):
            break
    deg = float(np.degrees(gamma))
    if gamma > 0 and extreme > hi:
        return (f"{ac.callsign}: at {ac.state0[2]:.4f} nm climbing at {deg:.1f} deg it rises to {extreme:.4f} nm "
                f"before it can level off (n_v = {n_v:g}): above the airspace ceiling {hi:g} nm")
    if gamma < 0 and extreme < lo:
        return (f"{ac.callsign}: at {ac.state0[2]:.4f} nm descending at {-deg:.1f} deg it sinks to {extreme:.4f} nm "
                f"before it can level off (n_v = {n_v:g}): below the airspace floor {lo:g} nm")
    return None


def common_approach_nm(scenario: Scenario) -> float:
    """Length (nm) of the path every aircraft flies in file to the runway: from the gate's hole (the thesis's
    wall), else the straight final approach of the initializer (:data:`FINAL_RADII` turn radii)."""
    runway = scenario.runway_state[:3]
    if scenario.gates:
        return float(np.linalg.norm(scenario.gates[0].center() - runway))
    return FINAL_RADII * Scales.of(scenario).length_nm


def landing_spacing(scenario: Scenario, leader: Aircraft, follower: Aircraft) -> float:
    """Time (s) between the landings of ``leader`` and ``follower`` (who lands next) that keeps them separated
    on the common approach of length D (:func:`common_approach_nm`), at least the scenario's spacing.

    A faster follower is closest when the leader lands: it must then be a separation S out, S / V_f. A slower
    follower is closest when it joins the common approach: the leader must then be S ahead, which takes
    S / V_l + D (1 / V_f - 1 / V_l) between the landings. With one spacing for every pair, a slow aircraft
    behind a fast one through a gate 8.5 nm out needed 103 s, not the 90 s it was given, and no plan existed.
    With ``separation.wake``, also the wake-turbulence minimum of the pair at the follower's speed
    (:func:`mal_planner.wake.wake_spacing_s`). The speeds are ground speeds on final
    (:meth:`~mal_planner.scenario.Scenario.final_ground_speed`: the airspeeds in still air).
    """
    sep = scenario.separation_nm
    v_l, v_f = scenario.final_ground_speed(leader), scenario.final_ground_speed(follower)
    gap = sep / v_f if v_f >= v_l else sep / v_l + common_approach_nm(scenario) * (1.0 / v_f - 1.0 / v_l)
    wake = wake_spacing_s(scenario.wake, leader.wake_category, follower.wake_category, v_f, sep,
                          scenario.landing_spacing_s)
    return max(scenario.landing_spacing_s, gap, wake)


def planned_spacing(scenario: Scenario, leader: Aircraft, follower: Aircraft) -> float:
    """:func:`landing_spacing`, with a wake table plus :data:`SPACING_MARGIN_TURN_TIMES`: what the schedule and
    the optimizer keep, so that the verification's wake check (no tolerance) never finds a pair a round-off short
    of its minimum. Without one, today's times exactly (the verification's spacing check has a tolerance). Plus the
    scenario's :attr:`~mal_planner.scenario.Scenario.spacing_reserve_s` (plans that are flown)."""
    spacing = landing_spacing(scenario, leader, follower) + scenario.spacing_reserve_s
    return spacing if scenario.wake == "none" else spacing + Scales.of(scenario).seconds(SPACING_MARGIN_TURN_TIMES)


def sequencing_problem(scenario: Scenario, earliest: Mapping[str, float], margin_s: float | Mapping[str, float]
                       ) -> SequencingProblem:
    """The scenario's landings as an aircraft landing problem (:mod:`mal_planner.sequencing`).

    A free aircraft may land from its turn-aware earliest time plus ``margin_s`` (one for all, or per callsign) on;
    its target is the scenario's ``target_time``, else that earliest time; its latest time the scenario's
    ``latest_time``, else none; each second early or late costs its ``cost_early`` / ``cost_late`` (defaults 0 and
    1: the total delay). A fixed landing time is a window of one instant (the scenario's times win;
    :func:`check_request` checks them against each other). Each pair keeps :func:`planned_spacing`; two fixed
    aircraft need none from the sequencer. A window that no landing can meet is refused by the sequencer, naming the
    aircraft."""
    aircraft = scenario.aircraft
    n = len(aircraft)
    margins = margin_s if isinstance(margin_s, Mapping) else {ac.callsign: margin_s for ac in aircraft}
    start = np.array([float(ac.landing_time) if ac.landing_time is not None
                      else earliest[ac.callsign] + margins[ac.callsign] for ac in aircraft])
    target = np.array([s if ac.landing_time is not None or ac.target_time is None else float(ac.target_time)
                       for s, ac in zip(start, aircraft, strict=True)])
    latest = np.array([float(ac.landing_time) if ac.landing_time is not None else
                       (np.inf if ac.latest_time is None else float(ac.latest_time)) for ac in aircraft])
    separation = np.zeros((n, n))
    for i, j in itertools.permutations(range(n), 2):
        if aircraft[i].landing_time is None or aircraft[j].landing_time is None:
            separation[i, j] = planned_spacing(scenario, aircraft[i], aircraft[j])
    return SequencingProblem(tuple(ac.callsign for ac in aircraft), start, target, latest,
                             np.array([ac.cost_early for ac in aircraft], float),
                             np.array([ac.cost_late for ac in aircraft], float), separation)


def make_schedule(scenario: Scenario, earliest: Mapping[str, float], margin_s: float | Mapping[str, float] | None = None
                  ) -> LandingSchedule:
    """Order and landing times from :mod:`mal_planner.sequencing` with the scenario's ``sequencing`` strategy
    (see :func:`sequencing_problem`); ``margin_s`` default: :data:`DEFAULT_MARGIN_TURN_TIMES`.

    Each pair keeps the spacing :func:`landing_spacing` asks for (the scenario's, more behind a faster aircraft,
    the wake-turbulence minimum) plus a round-off margin."""
    if margin_s is None:
        margin_s = Scales.of(scenario).seconds(DEFAULT_MARGIN_TURN_TIMES)
    for ac in scenario.aircraft:
        if ac.landing_time is not None and ac.landing_time < earliest[ac.callsign]:
            log.warning("%s: fixed landing time %.1f s is before the estimated earliest landing %.1f s; "
                        "trying anyway", ac.callsign, ac.landing_time, earliest[ac.callsign])
    try:
        problem = sequencing_problem(scenario, earliest, margin_s)
        result = sequence(problem, scenario.sequencing)
    except (SequencingInfeasible, TimeoutError) as exc:
        raise InfeasibleRequest(f"sequencing ({scenario.sequencing.strategy}): {exc}") from None
    if result.status != "heuristic":
        log.info("sequencing: %s, total delay %.1f s (%s%s, %.2f s)", result.strategy, result.cost, result.status,
                 "" if result.gap is None else f", gap {result.gap:.2%}", result.solve_time_s)
    times = {cs: float(t) for cs, t in zip(problem.names, result.times, strict=True)}
    order = tuple(sorted(times, key=lambda cs: (times[cs], earliest[cs], cs)))
    fixed = frozenset(ac.callsign for ac in scenario.aircraft if ac.landing_time is not None)
    target = {cs: float(t) for cs, t in zip(problem.names, problem.target, strict=True)}
    return LandingSchedule(order, times, dict(earliest), fixed, target, result.strategy, result.status, result.gap)


def slot_in_order(scenario: Scenario, order: Sequence[Aircraft], ready: Callable[[Aircraft], float], *,
                  after: tuple[Aircraft, float] | None = None, extra: Callable[[], float] = lambda: 0.0,
                  rounding: Callable[[float], float] = float) -> dict[str, float]:
    """Landing times for aircraft in a given ``order``: each at its ``ready`` time, or its pair's
    :func:`landing_spacing` (plus ``extra()``) after the landing before it, whichever is later, then ``rounding``;
    ``after``: the aircraft (and its time) that lands before the first (None: the first is spaced by the scenario's
    spacing from no one). ``ready`` is called before ``extra`` for each aircraft (a traffic generator's random draws
    keep their order)."""
    times: dict[str, float] = {}
    leader, last = after if after is not None else (None, -math.inf)
    for ac in order:
        spacing = scenario.landing_spacing_s if leader is None else landing_spacing(scenario, leader, ac)
        last = rounding(max(ready(ac), last + spacing + extra()))
        times[ac.callsign] = last
        leader = ac
    return times


MIN_TIME_FACTOR = 1.0
"""Fixed landing times shorter than this factor x (straight distance / speed) cannot be met: given up."""
UNKNOWN_MARGIN_S = 5.0
"""An aircraft the scenario does not know lands this long after its straight-line time at the earliest."""


def straight_in_time(aircraft: Aircraft, runway: np.ndarray) -> float:
    """Seconds straight to the runway at the best crab (in the wind its model carries), times MIN_TIME_FACTOR."""
    return MIN_TIME_FACTOR * float(aircraft.dynamics.air_distance(runway - aircraft.position)) / aircraft.speed


def _straight_in_bound(scenario: Scenario, aircraft: Aircraft) -> float:
    """:func:`straight_in_time` at the fastest airspeed ``aircraft`` may fly (a bound that proves)."""
    return straight_in_time(replace(aircraft, dynamics=fastest_dynamics(scenario, aircraft)), scenario.runway_state[:3])


def slot_after_fixed(scenario: Scenario, aircraft: list[Aircraft]) -> list[Aircraft]:
    """Keep the fixed landing times; aircraft without one (e.g. radar tracks the scenario does not know) land after
    them in order of their straight-in times, each its pair's landing spacing (wake included) behind the one before
    (:func:`slot_in_order`). Only if that fails (a gap wider than the scenario's largest spacing), or a fixed time
    cannot be met, the sequencer decides all: the times are all given up."""
    runway = scenario.runway_state[:3]
    fixed = [a for a in aircraft if a.landing_time is not None]
    if not fixed:
        return aircraft
    free_all = [replace(a, landing_time=None) for a in aircraft]
    if not all(a.landing_time is None or a.landing_time >= _straight_in_bound(scenario, a) for a in aircraft):
        return free_all
    leader = max(fixed, key=lambda a: a.landing_time)  # type: ignore[arg-type, return-value]
    order = sorted((a for a in aircraft if a.landing_time is None), key=lambda a: straight_in_time(a, runway))
    times = slot_in_order(scenario, order, lambda a: straight_in_time(a, runway) + UNKNOWN_MARGIN_S,
                          after=(leader, float(leader.landing_time)))  # type: ignore[arg-type]
    previous = [leader, *order]
    for before, ac in zip(previous, order, strict=False):
        gap = times[ac.callsign] - (float(before.landing_time) if before is leader else times[before.callsign])
        if gap > max(scenario.max_landing_spacing_s, landing_spacing(scenario, before, ac)):
            return free_all  # cannot be slotted in
    return [replace(a, landing_time=times[a.callsign]) if a.callsign in times else a for a in aircraft]
