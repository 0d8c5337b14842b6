"""The plan book: which plan each aircraft flies, the plans waiting for their start, kept plans and withdrawals.

A plan arrives (:meth:`PlanBook.arrive`) when its planning ends. It is handed out when it starts
(:meth:`PlanBook.due`; at once if it started already), re-anchored to where its aircraft are then, unless that is
unsafe (:mod:`mal_planner.service.reanchor`): then it is stale. An aircraft established on final by then keeps the
plan it flies (:func:`~mal_planner.service.rules.established_window_s`). Handed out, each of its aircraft flies it; an
aircraft that a later plan leaves out (established on final, or left out) flies on along the plan it has. A failed
replan keeps the plans being flown; after ``kept_plan_expiry_s`` of failures they are withdrawn. An aircraft
without a plan flies the service's fallback (a hold or the safety net's vector, :meth:`PlanBook.give`). Every time
is on the radar's clock.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from mal_planner.scales import Scales, level_turn_radius
from mal_planner.scenario import Scenario
from mal_planner.sequencing.schedule import landing_spacing
from mal_planner.service.conflicts import Minima
from mal_planner.service.fallback import Fallback
from mal_planner.service.reanchor import fade_time, reanchored, turn_stray, unsafe_offsets
from mal_planner.service.request import PlanRequest
from mal_planner.service.rules import ServiceRules, established
from mal_planner.service.tracks import Track
from mal_planner.trajectory import Reference, Trajectory

if TYPE_CHECKING:
    from mal_planner.pipeline import PlanResult


@dataclass(frozen=True)
class Handout:
    """A plan handed out at ``at``: its aircraft fly ``trajectories`` (those still tracked) from now on."""

    request: PlanRequest
    result: PlanResult
    trajectories: dict[str, Trajectory]
    at: float
    lost: tuple[str, ...] = ()
    """Aircraft of the plan lost while it was planned (not handed out)."""
    established: tuple[str, ...] = ()
    """Aircraft of the plan established on final by then: they keep the plans they fly (not handed out)."""


@dataclass(frozen=True)
class Stale:
    """A plan not handed out: the aircraft strayed too far from it by its start."""

    request: PlanRequest
    reason: str


@dataclass(frozen=True)
class Kept:
    """A replan failed: the aircraft keep the plans they fly (``since``: the first failure since the last plan)."""

    reason: str
    since: float
    plan_start: float | None
    """The start of the plan kept (None: none was handed out yet)."""
    age_s: float
    """How old the plan kept is (s since its start)."""
    callsigns: tuple[str, ...]


@dataclass(frozen=True)
class Withdrawn:
    """The plans of ``callsigns`` are withdrawn (lost tracks, or a kept plan expired)."""

    callsigns: tuple[str, ...]
    why: str


@dataclass(frozen=True)
class Instructed:
    """The service's own instructions (holds, the safety net's vectors) given to aircraft without a valid plan."""

    fallbacks: tuple[Fallback, ...]


Event = Handout | Stale | Kept | Withdrawn | Instructed


@dataclass
class PlanBook:
    rules: ServiceRules
    estimate: Callable[[str, Reference, float], np.ndarray | None]
    """The filtered position of an aircraft at a time, against the plan it flies (None before its first track)."""
    flying: dict[str, Reference] = field(default_factory=dict)
    """The plan each aircraft flies now."""
    upcoming: list[tuple[PlanResult, PlanRequest]] = field(default_factory=list)
    current: Handout | None = None
    """The latest plan handed out."""
    last_arrival: float = -math.inf
    """When the latest plan arrived or was handed out (-inf: the policy may ask at once)."""
    kept_since: float | None = None
    search_s: float = math.inf
    """How far from the clock the closest point of an instruction is searched (the guidance's: a turn time)."""
    follow_nm: float = math.inf
    """An aircraft further than this from its instruction is not flying it: predicted straight on."""
    fallbacks: dict[str, Fallback] = field(default_factory=dict)
    """The hold or vector of each aircraft that flies no plan."""
    on_handout: Callable[[str, Reference | None, Reference, float], None] | None = None
    """Called per aircraft as it gets a new plan (old plan, new plan, time): the track filter re-anchors on it."""
    established_s: float = 0.0
    """An aircraft this close to the end of the plan it flies keeps it (:func:`~mal_planner.service.rules.established`;
    0: none does)."""
    progress: dict[str, tuple[Reference, tuple[float, float]]] = field(default_factory=dict)
    """Per aircraft, where it was on its instruction at the last scan: (instruction, (track time, the instruction's
    time there))."""

    def plan_times(self, tracks: Mapping[str, Track]) -> dict[str, float]:
        """Where each tracked aircraft is on its instruction: the time of the instruction's point closest to it,
        searched within :attr:`search_s` of where it was at the last scan moved on by the time since (of the track's
        time for a new instruction): :meth:`~mal_planner.trajectory.Reference.follow`, as the guidance follows a plan.
        Searched around the clock, an aircraft more than a turn time late was predicted from a point ahead of it."""
        out = {}
        for gone in set(self.progress) - set(tracks):
            del self.progress[gone]
        for cs, tr in tracks.items():
            ref = self.instruction(cs)
            if ref is None:
                self.progress.pop(cs, None)
                continue
            last = self.progress.get(cs)
            out[cs] = ref.follow(tr.state[:3], tr.stamp, self.search_s, None if last is None or last[0] is not ref
                                 else last[1])
            self.progress[cs] = (ref, (tr.stamp, out[cs]))
        return out

    def instruction(self, callsign: str) -> Reference | None:
        """What an aircraft flies now: its plan, else its fallback, else nothing."""
        plan = self.flying.get(callsign)
        if plan is not None:
            return plan
        fallback = self.fallbacks.get(callsign)
        return None if fallback is None else fallback.reference

    def instructions(self) -> dict[str, Reference]:
        return {**{cs: f.reference for cs, f in self.fallbacks.items()}, **self.flying}

    def give(self, fallback: Fallback, now: float) -> None:
        """The aircraft flies ``fallback`` from ``now`` (its plan, if any, is dropped: it is no longer valid)."""
        cs = fallback.callsign
        old = self.instruction(cs)
        if self.on_handout is not None:
            self.on_handout(cs, old, fallback.reference, now)
        if self.flying.pop(cs, None) is not None and self.current is not None:
            kept = {k: tr for k, tr in self.current.trajectories.items() if k != cs}
            self.current = replace(self.current, trajectories=kept)
        self.fallbacks[cs] = fallback

    def arrive(self, request: PlanRequest, result: PlanResult, now: float, tracked: set[str]) -> list[Event]:
        """A verified plan arrived at ``now``: handed out when it starts (now, if it started already)."""
        self.last_arrival = now
        self.upcoming.append((result, request))
        return self.due(now, tracked)

    def failed(self, reason: str, now: float) -> Kept | None:
        """A replan failed at ``now``: the aircraft keep their plans (a Kept event), if they fly any."""
        self.last_arrival = now
        if not self.flying:
            return None
        if self.kept_since is None:
            self.kept_since = now
        start = self.current.result.start_time if self.current is not None else None
        return Kept(reason, self.kept_since, start, 0.0 if start is None else now - start, tuple(sorted(self.flying)))

    def due(self, now: float, tracked: set[str]) -> list[Event]:
        """Hand out the plans that start by ``now``, re-anchored (unless that is unsafe: stale); withdraw a kept plan
        past its expiry."""
        events: list[Event] = []
        for entry in [u for u in self.upcoming if u[0].start_time <= now]:
            self.upcoming = [u for u in self.upcoming if u is not entry]  # by identity: results hold arrays
            result, request = entry
            trajectories, lost = self._planned(result, request, tracked)
            settled = tuple(sorted(cs for cs in trajectories if established(self.flying.get(cs), now,
                                                                            self.established_s)))
            trajectories = {cs: tr for cs, tr in trajectories.items() if cs not in settled}
            if not trajectories:  # every aircraft of the plan is established on final by now: nothing changes
                continue
            offsets = self._offsets(trajectories, result.start_time, now)
            scales, minima = Scales.of(result.scenario), Minima.of(result.scenario)
            refs = {cs: Reference(tr.t + result.start_time, tr.states) for cs, tr in trajectories.items()}
            others = {cs: self.flying[cs] for cs in settled} if request.traffic is None else {  # clear of the others
                cs: ref for cs, ref in self.instructions().items() if cs in tracked and cs not in refs}
            strays = {cs: turn_stray(ref, self.instruction(cs), now, level_turn_radius(
                result.scenario.aircraft_by_callsign(cs))) for cs, ref in refs.items() if cs in offsets}
            why = None if self.rules.deviation_nm <= 0 else unsafe_offsets(  # 0: the tracks do not follow plans
                refs, offsets, now, scales, minima, result.scenario.airspace, self.rules.deviation_nm, others, strays,
                result.scenario.obstacles)
            if why is not None:  # the aircraft keep what they fly; the policy asks again at once
                self.last_arrival = -math.inf
                events.append(Stale(request, f"stale: {why}, {now - request.plan_start:.1f} s after the tracks it "
                                             "was made from; not handed out"))
                continue
            moved = {cs: reanchored(tr, offsets[cs], now - result.start_time,
                                    fade_time(scales, now, refs[cs].end)) if cs in offsets else tr
                     for cs, tr in trajectories.items()}
            events.append(self._hand_out(result, request, now, moved, lost, settled))
            unplanned = self._clashing([cs for cs in result.unplanned if cs in self.flying], set(moved), now,
                                       result.scenario)
            if unplanned:  # their plans are not clear of the new ones: they hold instead (the guard)
                events.append(self.withdraw(unplanned, "not in the partial plan handed out, and its plan is not "
                                                       "clear of it"))
        expiry = self.rules.kept_plan_expiry_s
        if self.kept_since is not None and expiry > 0 and now - self.kept_since >= expiry and self.flying:
            self.kept_since = None
            events.append(self.withdraw(sorted(self.flying), f"kept plan expired: replans have failed for {expiry:g} s"
                                                             " (kept_plan_expiry_s)"))
        return events

    def _clashing(self, unplanned: list[str], new: set[str], now: float, scenario: Scenario) -> list[str]:
        """The aircraft of ``unplanned`` (left out of a partial plan, each still flying its old plan) whose plans are
        not clear of the instructions flown now: closer to one than the minima plus twice the deviation threshold (the
        margin of flown plans), or landing closer to one of the ``new`` plans than their landing spacing. The others
        keep their plans. Withdrawing them all sent twelve of twenty aircraft to holds when a replan planned six
        (traffic-0048), and the holds' replans ran out of time in turn."""
        base = Minima.of(scenario)
        grow = 2.0 * max(self.rules.deviation_nm, 0.0)
        minima = Minima(base.horizontal_nm + grow, None if base.vertical_nm is None else base.vertical_nm + grow)
        step = Scales.of(scenario).seconds(0.25)
        out: list[str] = []
        for cs in unplanned:
            mine = self.flying[cs]
            times = np.arange(now, mine.end, step)
            for other, ref in self.instructions().items():
                if other == cs or other in out:
                    continue
                live = times <= ref.end
                close = live.any() and float(minima.ratio(mine.positions(times[live]),
                                                          ref.positions(times[live])).min()) < 1.0
                if close or (other in new and abs(ref.end - mine.end) < _spacing(scenario, cs, other, mine, ref)):
                    out.append(cs)
                    break
        return out

    @staticmethod
    def _planned(result: PlanResult, request: PlanRequest, tracked: set[str]
                 ) -> tuple[dict[str, Trajectory], tuple[str, ...]]:
        """The plan's trajectories of the aircraft still tracked, and those lost while it was planned."""
        trajectories = {tr.callsign: tr for tr in (result.landing.trajectories if result.landing else [])}
        if not trajectories:  # the initializer's paths (optimizer off)
            trajectories = {tr.callsign: tr for tr in result.trajectories()}
        lost = tuple(sorted(cs for cs in trajectories if cs not in tracked)) if not request.given_tracks else ()
        return {cs: tr for cs, tr in trajectories.items() if cs not in lost}, lost

    def _offsets(self, trajectories: Mapping[str, Trajectory], start: float, now: float) -> dict[str, np.ndarray]:
        """Where each aircraft is at ``now`` (its filtered estimate) less where the plan has it."""
        out = {}
        for cs, traj in trajectories.items():
            flying = self.instruction(cs)
            here = None if flying is None else self.estimate(cs, flying, now)
            if here is not None and 0.0 <= now - start <= float(traj.t[-1]):
                out[cs] = here - traj.state_at(np.array([now - start]))[0, :3]
        return out

    def _hand_out(self, result: PlanResult, request: PlanRequest, now: float, trajectories: dict[str, Trajectory],
                  lost: tuple[str, ...], established: tuple[str, ...] = ()) -> Handout:
        for cs, traj in trajectories.items():
            ref = Reference(traj.t + result.start_time, traj.states)
            if self.on_handout is not None:
                self.on_handout(cs, self.instruction(cs), ref, now)
            self.flying[cs] = ref
            self.fallbacks.pop(cs, None)
        self.kept_since = None
        self.last_arrival = now
        self.current = Handout(request, result, trajectories, now, lost, established)
        return self.current

    def withdraw(self, callsigns: list[str], why: str) -> Withdrawn:
        """Withdraw the plans of ``callsigns``: they fly none any more."""
        gone = tuple(cs for cs in callsigns if self.flying.pop(cs, None) is not None)
        for cs in callsigns:
            self.fallbacks.pop(cs, None)
        if self.current is not None and gone:
            kept = {cs: tr for cs, tr in self.current.trajectories.items() if cs not in gone}
            self.current = replace(self.current, trajectories=kept)
        return Withdrawn(gone, why)

    def predicted(self, tracks: Mapping[str, Track], at: float) -> dict[str, Track]:
        """The tracks at time ``at``, along the instructions being flown: a plan's state then, moved by the deviation
        measured at the track's time (as model predictive control does with a known delay); a fallback (a hold's
        circles) as the guidance follows it, from its point closest to the track (the along-track error kept), if
        the aircraft flies it; straight on where an aircraft flies none. A track already stamped ``at`` is kept as
        it is."""
        out = {}
        for cs, tr in tracks.items():
            ref = self.instruction(cs)
            if at == tr.stamp:
                out[cs] = tr
                continue
            if ref is None or not ref.start <= tr.stamp or at > ref.end:
                out[cs] = Track(cs, at, tr.at(at), tr.speed, tr.wake)
                continue
            s0 = tr.stamp
            if cs not in self.flying:
                s0 = ref.closest_time(tr.state[:3], tr.stamp, self.search_s)
            now, then = ref.sample(s0), ref.sample(s0 + at - tr.stamp)
            if cs not in self.flying and np.linalg.norm(tr.state[:3] - now[:3]) > self.follow_nm:
                out[cs] = Track(cs, at, tr.at(at), tr.speed, tr.wake)  # not flying it
                continue
            state = then[:5].copy()
            state[:3] += tr.state[:3] - now[:3]
            state[3:5] += tr.state[3:5] - now[3:5]
            out[cs] = Track(cs, at, state, _speed_then(ref, tr.speed, s0, s0 + at - tr.stamp), tr.wake)
        return out


def _speed_then(ref: Reference, speed: float, now: float, then: float) -> float:
    """A track's airspeed ``speed`` at the instruction's time ``now``, carried to its time ``then``: changed as the
    instruction's airspeed changes (an airspeed-model plan slows down), the same where it carries none."""
    planned_now, planned_then = ref.airspeed(now), ref.airspeed(then)
    return speed if planned_now is None or planned_then is None else speed + planned_then - planned_now


def _spacing(scenario: Scenario, a: str, b: str, ref_a: Reference, ref_b: Reference) -> float:
    """The landing spacing of ``a`` and ``b`` in the order their plans land (the scenario's, where one is unknown)."""
    (lead, _), (follow, _) = sorted(((a, ref_a.end), (b, ref_b.end)), key=lambda p: p[1])
    known = {ac.callsign: ac for ac in scenario.aircraft}
    if lead not in known or follow not in known:
        return scenario.landing_spacing_s
    return landing_spacing(scenario, known[lead], known[follow])
