"""What a closed-loop run achieved, measured on the tracks that were actually flown.

The minima are checked as the verification checks plans, with no tolerance on the unsafe side: every pair
on the union of both aircraft's samples with the chords' error taken off (a protected sphere or cylinder, as
the scenario says), airspace and obstacles with the chord error added. Landings are the threshold crossings
inside the touchdown window (:mod:`mal_planner.closedloop.simulator`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass, field

import numpy as np

from mal_planner.closedloop.loop import ClosedLoopRun, Replan, percentile
from mal_planner.closedloop.simulator import LANDED, FlightSimulator
from mal_planner.scenario import Scenario
from mal_planner.units import nm_to_m
from mal_planner.verification import flown_path_infringements, separation_checks


@dataclass
class ClosedLoopMetrics:
    """One run's outcome: a success only when everyone landed with every minimum kept (``failures`` empty)."""

    scenario: str
    aircraft: int
    all_landed: bool
    landed: int
    failures: list[str]
    """Why the run is not a success, one line each (empty: success)."""
    min_separation_nm: float
    """Smallest distance of any pair while both flew (sphere), or the horizontal distance of the pair closest to
    its protected cylinder; a lower bound (chord errors taken off)."""
    closest_pair: str
    separation_ratio: float
    """Smallest distance in minima (< 1: a loss of separation)."""
    losses_of_separation: int
    infringements: int
    """Airspace exits and obstacle entries on the flown tracks."""
    landing_times_s: dict[str, float]
    landing_spacings_s: list[float]
    """Between successive threshold crossings. Constant-speed aircraft cannot take out along-track errors, so
    these differ from the planned spacings by the timing errors; recorded, not a failure (a note)."""
    min_landing_spacing_s: float
    landing_errors_m: dict[str, float]
    """Distance of each threshold crossing from the runway point."""
    max_deviation_nm: float
    """Largest distance of an aircraft from the plan it was flying."""
    replans: int
    replan_reasons: dict[str, int]
    failed_replans: int
    replan_latency_s: dict[str, float]
    """Planning time of the replans as charged in simulated time (CPU time by default): median, p95, max."""
    first_plan_s: float | None
    """Planning time of the first plan (wall clock) [s]; None where the service's requests are not seen and the
    caller did not measure it (the simulator node)."""
    order_changes: int
    """Replans whose landing order differs from the previous plan's (for the aircraft in both)."""
    wall_s: float
    notes: list[str] = field(default_factory=list)
    fallback_share: float = 0.0
    """Share of the aircraft's flight time flown on a service fallback (a hold or a vector) or on nothing."""
    holds: int = 0
    """Holds the service gave (:mod:`mal_planner.service.fallback`)."""
    net_alerts: int = 0
    """Pairs the safety net predicted in conflict (:mod:`mal_planner.service.safety_net`)."""
    net_uses: int = 0
    """Scans at which the safety net vectored aircraft (the planner had no plan in time)."""
    vectors: int = 0
    replans_what_changed: int = 0
    """Replans of what changed (some aircraft among the others' instructions; :mod:`mal_planner.service.subsets`)."""
    external_losses_of_separation: list[str] | None = None
    """The losses of separation the simulator's own detection counted (pairs "A-B"), when it has one (BlueSky's
    ``external_los_pairs``); None: ours only."""

    @property
    def success(self) -> bool:
        return not self.failures

    def to_dict(self) -> dict:
        return {**asdict(self), "success": self.success}


def _reason_key(reason: str) -> str:
    if "deviates" in reason:
        return "deviation"
    if "has no plan" in reason:
        return "no plan"
    if "plan has ended" in reason:
        return "plan ended"
    return reason


def measure(run: ClosedLoopRun) -> ClosedLoopMetrics:
    """The metrics of one closed-loop run."""
    m = measure_flight(run.scenario, run.sim, run.replans, run.first, run.wall_s)
    m.fallback_share = fallback_share(run.sim, run.instructions)
    m.holds, m.vectors = run.guard.get("holds", 0), run.guard.get("vectors", 0)
    m.net_alerts, m.net_uses = run.guard.get("alerts", 0), run.guard.get("uses", 0)
    return m


def fallback_share(sim: FlightSimulator, instructions: list[tuple[float, str, str]]) -> float:
    """Share of the flight time (all aircraft) flown on anything but a plan, from the service's instructions."""
    total = fallback = 0.0
    for ac in sim.aircraft:
        if len(ac.t) < 2:
            continue
        start, end = ac.t[0], ac.t[-1]
        told = sorted((t, kind) for t, cs, kind in instructions if cs == ac.callsign)
        kind, since = "none", start
        for t, new in told + [(end, "end")]:
            t = min(max(t, start), end)
            if kind != "plan":
                fallback += t - since
            kind, since = new, t
        total += end - start
    return fallback / total if total > 0 else 0.0


def _infringements(sc: Scenario, sim: FlightSimulator, flown: dict[str, tuple[np.ndarray, np.ndarray]]
                   ) -> list[str]:
    """Airspace and obstacle infringements of the flown paths (the touchdown is judged by the touchdown window)."""
    found: list[str] = []
    landed_here = {ac.callsign for ac in sim.aircraft if ac.status == LANDED}
    step_s = float(getattr(sim, "step_s", 0.0))
    for cs, (t, x) in flown.items():
        if cs in landed_here:  # the runway lies on the airspace's boundary: the touchdown, and the step that reaches
            keep = t < t[-1] - step_s  # it (within a chord error of the threshold), are judged by the touchdown window
            t, x = t[keep], x[keep]
        if len(t) >= 2:
            found += flown_path_infringements(sc, sc.aircraft_by_callsign(cs), t, x)
    return found


def _order_changes(first: Replan | None, replans: list[Replan]) -> int:
    """How often a verified replan changed the landing order of the aircraft it shared with the plan before."""
    changes, previous = 0, first.landing_order if first else []
    for r in replans:
        if not r.ok:
            continue
        common = [cs for cs in r.landing_order if cs in previous]
        if common != [cs for cs in previous if cs in r.landing_order]:
            changes += 1
        previous = r.landing_order
    return changes


def measure_flight(sc: Scenario, sim: FlightSimulator, replans: list[Replan] | None = None,
                   first: Replan | None = None, wall_s: float = math.nan,
                   first_plan_s: float | None = None) -> ClosedLoopMetrics:
    """The metrics of a flight (the service's plan requests, when known: in the simulator node they are not, and
    it may give the first plan's time it measured as ``first_plan_s``)."""
    replans = replans or []
    failures: list[str] = []
    flown = {cs: (t, x) for cs, (t, x) in sim.flown().items() if len(t) > 1}
    for ac in sim.aircraft:
        if ac.status != LANDED:
            what = ac.status if ac.end_time is None else f"{ac.status} at t={ac.end_time:.1f} s"
            failures.append(f"{ac.callsign}: not landed ({what}{': ' + ac.end_note if ac.end_note else ''})")
    pair_failures: list[str] = []
    pairs = separation_checks(flown, sc, lambda _cs, text: pair_failures.append(text))
    failures += [f"loss of separation: {text}" for text in pair_failures]
    found = _infringements(sc, sim, flown)
    infringements = len(found)
    failures += found
    closest = min(pairs, key=lambda p: p.min_distance_nm, default=None)
    radius = sc.separation_nm
    landed = {ac.callsign: float(ac.end_time) for ac in sim.aircraft if ac.status == LANDED and ac.end_time}
    order = sorted(landed, key=landed.__getitem__)
    spacings = [landed[b] - landed[a] for a, b in itertools.pairwise(order)]
    notes = [f"{a}->{b}: landed {gap:.2f} s apart (planned at least {sc.landing_spacing_s:g} s)"
             for (a, b), gap in zip(itertools.pairwise(order), spacings, strict=True) if gap < sc.landing_spacing_s]
    errors = {ac.callsign: float(nm_to_m(np.linalg.norm(ac.states[-1][:3] - sc.runway_state[:3])))
              for ac in sim.aircraft if ac.status == LANDED}
    latencies = [r.charged_s if math.isfinite(r.charged_s) else r.wall_s for r in replans]
    reasons: dict[str, int] = {}
    for r in replans:
        reasons[_reason_key(r.reason)] = reasons.get(_reason_key(r.reason), 0) + 1
    changes = _order_changes(first, replans)
    ratio = math.inf
    if closest is not None:
        ratio = closest.min_distance_nm / radius
    return ClosedLoopMetrics(
        scenario=sc.name, aircraft=len(sim.aircraft), all_landed=len(landed) == len(sim.aircraft),
        landed=len(landed), failures=failures,
        min_separation_nm=closest.min_distance_nm if closest else math.inf,
        closest_pair=closest.pair if closest else "", separation_ratio=ratio,
        losses_of_separation=len(pair_failures), infringements=infringements,
        landing_times_s=landed, landing_spacings_s=spacings, min_landing_spacing_s=min(spacings, default=math.inf),
        landing_errors_m=errors, max_deviation_nm=max((ac.deviation_nm for ac in sim.aircraft), default=0.0),
        replans=len(replans), replan_reasons=reasons, failed_replans=sum(not r.ok for r in replans),
        replan_latency_s={"median": percentile(latencies, 50), "p95": percentile(latencies, 95),
                          "max": max(latencies, default=math.nan)},
        first_plan_s=first.wall_s if first else first_plan_s, order_changes=changes, wall_s=wall_s,
        notes=notes + ([] if first is None or first.ok else [f"first plan failed: {first.message}"]),
        external_losses_of_separation=_external_losses(sim), replans_what_changed=sum(r.kept > 0 for r in replans))


def _external_losses(sim: FlightSimulator) -> list[str] | None:
    pairs = getattr(sim, "external_los_pairs", None)
    return None if pairs is None else ["-".join(pair) for pair in pairs]
