"""The plan book: which plan each aircraft flies, the plans waiting for their start, kept plans and withdrawals.

A plan arrives (:meth:`PlanBook.arrive`) when its planning ends. It is handed out when it starts
(:meth:`PlanBook.due`; at once if it started already), unless it is stale: the aircraft then stray more than the
deviation threshold from it (they flew on elsewhere while it was planned). Handed out, each of its aircraft flies
it; an aircraft that a later plan leaves out (established on final, or left out) flies on along the plan it has. A
failed replan keeps the plans being flown; after ``kept_plan_expiry_s`` of failures they are withdrawn. Every time
is on the radar's clock.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from mal_planner.service.request import PlanRequest
from mal_planner.service.rules import ServiceRules
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


Event = Handout | Stale | Kept | Withdrawn


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
    on_handout: Callable[[str, Reference | None, Reference, float], None] | None = None
    """Called per aircraft as it gets a new plan (old plan, new plan, time): the track filter re-anchors on it."""

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
        """Hand out the plans that start by ``now`` (unless stale); withdraw a kept plan past its expiry."""
        events: list[Event] = []
        for result, request in [u for u in self.upcoming if u[0].start_time <= now]:
            self.upcoming.remove((result, request))
            stale = self.stale(result, request, now)
            if stale is not None:  # the aircraft keep the plans they fly; the policy asks again at once
                self.last_arrival = -math.inf
                events.append(Stale(request, stale))
                continue
            events.append(self._hand_out(result, request, now, tracked))
        expiry = self.rules.kept_plan_expiry_s
        if self.kept_since is not None and expiry > 0 and now - self.kept_since >= expiry and self.flying:
            self.kept_since = None
            events.append(self.withdraw(sorted(self.flying), f"kept plan expired: replans have failed for {expiry:g} s"
                                                             " (kept_plan_expiry_s)"))
        return events

    def _hand_out(self, result: PlanResult, request: PlanRequest, now: float, tracked: set[str]) -> Handout:
        trajectories = {tr.callsign: tr for tr in (result.landing.trajectories if result.landing else [])}
        if not trajectories:  # the initializer's paths (optimizer off)
            trajectories = {tr.callsign: tr for tr in result.trajectories()}
        lost = tuple(sorted(cs for cs in trajectories if cs not in tracked)) if not request.given_tracks else ()
        for cs in lost:
            del trajectories[cs]
        for cs, traj in trajectories.items():
            ref = Reference(traj.t + result.start_time, traj.states)
            if self.on_handout is not None:
                self.on_handout(cs, self.flying.get(cs), ref, now)
            self.flying[cs] = ref
        self.kept_since = None
        self.last_arrival = now
        self.current = Handout(request, result, trajectories, now, lost)
        return self.current

    def stale(self, result: PlanResult, request: PlanRequest, now: float) -> str | None:
        """Why a plan is not handed out at ``now`` (None: it is): an aircraft then strays more than the deviation
        threshold from it (its planning took longer than the lead it was made with, or the prediction along the old
        plans was off). Handed out, it would ask for the next replan at once, from aircraft turning to join it."""
        if self.rules.deviation_nm <= 0:
            return None
        worst, who = 0.0, ""
        for traj in result.landing.trajectories if result.landing else []:
            flying = self.flying.get(traj.callsign)
            here = None if flying is None else self.estimate(traj.callsign, flying, now)
            if here is None or not 0.0 <= now - result.start_time <= float(traj.t[-1]):
                continue
            dev = float(np.linalg.norm(traj.state_at(np.array([now - result.start_time]))[0, :3] - here))
            if dev > worst:
                worst, who = dev, traj.callsign
        if worst <= self.rules.deviation_nm:
            return None
        return (f"stale: {who} {worst:.3f} nm from it when it starts, {now - request.plan_start:.1f} s after the "
                f"tracks it was made from (threshold {self.rules.deviation_nm:.3f} nm); not handed out")

    def withdraw(self, callsigns: list[str], why: str) -> Withdrawn:
        """Withdraw the plans of ``callsigns``: they fly none any more."""
        gone = tuple(cs for cs in callsigns if self.flying.pop(cs, None) is not None)
        if self.current is not None and gone:
            kept = {cs: tr for cs, tr in self.current.trajectories.items() if cs not in gone}
            self.current = Handout(self.current.request, self.current.result, kept, self.current.at,
                                   self.current.lost)
        return Withdrawn(gone, why)

    def predicted(self, tracks: Mapping[str, Track], at: float) -> dict[str, Track]:
        """The tracks at time ``at``, along the plans being flown (the plan's state then, moved by the deviation
        measured at the track's time, as model predictive control does with a known delay); straight on where an
        aircraft flies none. A track already stamped ``at`` is kept as it is."""
        out = {}
        for cs, tr in tracks.items():
            ref = self.flying.get(cs)
            if at == tr.stamp:
                out[cs] = tr
            elif ref is None or not ref.start <= tr.stamp or at > ref.end:
                out[cs] = Track(cs, at, tr.at(at), tr.speed, tr.wake)
            else:
                now, then = ref.sample(tr.stamp), ref.sample(at)
                state = then[:5].copy()
                state[:3] += tr.state[:3] - now[:3]
                state[3:5] += tr.state[3:5] - now[3:5]
                out[cs] = Track(cs, at, state, tr.speed, tr.wake)
        return out
