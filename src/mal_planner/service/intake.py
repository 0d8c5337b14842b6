"""The radar intake: plausibility gates, the newest track per aircraft, the track filter and lost tracks.

Every radar track the service sees comes through :meth:`TrackIntake.take` (the node's subscriptions and the
closed loop's simulated radar alike): the gates of :func:`~mal_planner.service.tracks.check_track` (a refused jump
that repeats :data:`JUMP_CONFIRM` times in a row is taken as a re-initialised track), then the store (older and
duplicate stamps are dropped), then the track filter against the plan the aircraft flies. Decisions use
:meth:`TrackIntake.estimates`: the filtered tracks.

Two clocks: ``clock`` is the service's (a simulator's ``/clock`` or the monotonic clock), which runs at the radar's
pace; ``stamp_now`` is the ROS time that stamps would have now (for stamps in the future). The radar's clock is
estimated from both: the newest stamp plus the service clock's time since it arrived (:meth:`radar_now`).
"""

from __future__ import annotations

import logging
import math
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

from mal_planner.scenario import Scenario
from mal_planner.service.rules import ServiceRules
from mal_planner.service.track_filter import DeviationFilter
from mal_planner.service.tracks import AHEAD_TOLERANCE_S, Rejection, Track, TrackStore, check_track
from mal_planner.trajectory import Reference

log = logging.getLogger("mal_planner.service")

JUMP_CONFIRM = 3
"""Consistent jumps in a row after which a track is taken as re-initialised (else it would stay frozen)."""
BAD_INPUT_LOG_PERIOD_S = 5.0
"""Bad input is logged once per (source, callsign, reason) and this many seconds: a 10 Hz stream of bad data gives
one line, not a flood; every refusal is counted."""


@dataclass(frozen=True)
class Verdict:
    """What the intake did with one track: ``stored`` (accepted), ``rejected`` (``reason`` says why), or dropped as
    ``older``, ``duplicate`` or ``conflict``; ``new``: the first accepted track of this callsign."""

    outcome: str
    reason: Rejection | None = None
    new: bool = False

    @property
    def accepted(self) -> bool:
        return self.outcome == "stored"


class TrackIntake:
    """Gates, store, filter and lost tracks of one service (thread-safe through the store and its caller's lock)."""

    def __init__(self, scenario: Scenario, rules: ServiceRules,
                 plan_of: Callable[[str], Reference | None] = lambda callsign: None) -> None:
        """``plan_of``: the plan an aircraft flies now (the filter smooths the deviation from it)."""
        self.scenario = scenario
        self.rules = rules
        self.plan_of = plan_of
        self.store = TrackStore()
        self.filter = DeviationFilter(rules.filter_time_constant_s)
        self.counts: Counter[str] = Counter()
        self.first_seen: tuple[float, float] | None = None
        """(service clock, stamp) of the first accepted track."""
        self._estimates: dict[str, Track] = {}
        self._newest_rx: float | None = None
        self._jumps: dict[str, tuple[Track, int]] = {}
        self._logged: dict[str, float] = {}
        self._known: set[str] = set()

    # -- clocks -------------------------------------------------------------------------------------------------
    def radar_now(self, clock: float) -> float | None:
        """The radar's time now: the newest stamp plus the service clock's time since it arrived (None before)."""
        newest = self.store.latest_stamp()
        return None if newest is None or self._newest_rx is None else newest + (clock - self._newest_rx)

    # -- intake ---------------------------------------------------------------------------------------------------
    def take(self, track: Track, frame_id: str, source: str, clock: float, stamp_now: float | None = None
             ) -> Verdict:
        """Gate, store and filter one radar track from ``source`` (a topic); log a refusal (rate-limited)."""
        self.counts["received"] += 1
        reason = self._gate(track, frame_id, clock, stamp_now)
        if reason is not None and reason.key == "jump" and self._jump_confirmed(track):
            log.warning("track of %s re-initialised: %d jumps in a row agree (%s)", track.callsign, JUMP_CONFIRM,
                        reason)
            self.filter.forget(track.callsign)
            reason = None
        if reason is not None:
            self.reject(reason.key, f"{source}:{track.callsign}:{reason.key}", f"bad AircraftState on {source} for "
                        f"{track.callsign!r} at t={track.stamp:.3f}: {reason} (ignored)")
            return Verdict("rejected", reason)
        self._jumps.pop(track.callsign, None)
        previous = self.store.get(track.callsign)
        newest = self.store.latest_stamp()
        outcome = self.store.update(track)
        if outcome == "conflict":
            self.reject("conflict", f"{source}:{track.callsign}:conflict", f"bad AircraftState on {source} for "
                        f"{track.callsign!r} at t={track.stamp:.3f}: another state with the same stamp (ignored)")
        if outcome != "stored":
            self.counts[outcome] += 1  # older, duplicate (the same track on two topics) or conflict
            return Verdict(outcome)
        self.counts["accepted"] += 1
        if newest is None or track.stamp > newest:
            self._newest_rx = clock
        self._estimates[track.callsign] = self._filtered(track, previous)
        return Verdict("stored", new=self._first_track(track, source, clock))

    def reject(self, key: str, log_key: str, text: str) -> None:
        """Count a refused input under ``key`` and log ``text`` (once per ``log_key`` and period)."""
        self.counts["rejected"] += 1
        self.counts[f"rejected.{key}"] += 1
        self.log_bad(log_key, text)

    def log_bad(self, key: str, text: str) -> None:
        now = time.monotonic()
        if now - self._logged.get(key, -math.inf) >= BAD_INPUT_LOG_PERIOD_S:
            self._logged[key] = now
            log.error("%s", text)

    def check_alone(self, track: Track, frame_id: str) -> Rejection | None:
        """The gates a track passes on its own (not against the radar picture): explicit states of a what-if."""
        return check_track(track, frame_id, self.rules.frame_id, self.scenario.airspace,
                           expected_speed=self.scenario_speed(track.callsign))

    def _gate(self, track: Track, frame_id: str, clock: float, stamp_now: float | None) -> Rejection | None:
        newest = self.store.latest_stamp()
        ahead = None if newest is None or self._newest_rx is None else AHEAD_TOLERANCE_S + clock - self._newest_rx
        return check_track(track, frame_id, self.rules.frame_id, self.scenario.airspace,
                           expected_speed=self.scenario_speed(track.callsign), newest=newest,
                           timeout_s=self.rules.track_timeout_s, now=stamp_now, max_ahead_s=ahead,
                           previous=self.store.get(track.callsign), jump_tol_nm=self.scenario.separation_nm)

    def scenario_speed(self, callsign: str) -> float | None:
        """The scenario's speed of a known aircraft [nm/s] (None for one it does not know)."""
        try:
            return float(self.scenario.aircraft_by_callsign(callsign).speed)
        except KeyError:
            return None

    def _jump_confirmed(self, track: Track) -> bool:
        """A refused jump: True once ``JUMP_CONFIRM`` refused tracks in a row agree with each other (the track
        was re-initialised, not a glitch), so that a bad jump never freezes an aircraft for good."""
        pending = self._jumps.get(track.callsign)
        agree = pending is not None and check_track(
            track, self.rules.frame_id, self.rules.frame_id, previous=pending[0],
            jump_tol_nm=self.scenario.separation_nm) is None
        count = pending[1] + 1 if agree and pending is not None else 1
        self._jumps[track.callsign] = (track, count)
        return count >= JUMP_CONFIRM

    def _filtered(self, track: Track, previous: Track | None) -> Track:
        """The track with its position smoothed against the plan it flies (as measured where it flies none)."""
        plan = self.plan_of(track.callsign)
        if plan is None or not plan.start <= track.stamp <= plan.end:
            return track
        dt = 0.0 if previous is None else track.stamp - previous.stamp
        state = track.state.copy()
        state[:3] = self.filter.update(track.callsign, track.state, plan, track.stamp, dt)
        return Track(track.callsign, track.stamp, state, track.speed, track.wake)

    def _first_track(self, track: Track, source: str, clock: float) -> bool:
        if self.first_seen is None:
            self.first_seen = (clock, track.stamp)
            log.info("first radar message (%s, t=%.3f); first plan in %.1f s", track.callsign, track.stamp,
                     self.rules.settle_time_s)
        if track.callsign in self._known:
            return False
        self._known.add(track.callsign)
        log.info("new aircraft %s on %s (wake %s)", track.callsign, source, track.wake or "?")
        return True

    # -- what the service decides on ------------------------------------------------------------------------------
    def estimates(self) -> dict[str, Track]:
        """The newest track of every aircraft held, its position filtered against the plan it flies."""
        held = self.store.snapshot()
        return {cs: self._estimates.get(cs, tr) for cs, tr in held.items()}

    def lose_tracks(self) -> list[str]:
        """Forget the aircraft not seen for ``track_timeout_s`` before the newest track; their callsigns."""
        timeout = self.rules.track_timeout_s
        latest = self.store.latest_stamp()
        if timeout <= 0 or latest is None:
            return []
        gone = self.store.drop_older_than(latest - timeout)
        for cs in gone:
            self.counts["lost"] += 1
            self._estimates.pop(cs, None)
            self.filter.forget(cs)
            self._known.discard(cs)
        return gone

    def __len__(self) -> int:
        return len(self.store)
