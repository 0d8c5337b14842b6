"""Every aircraft has a safe instruction at every scan: holds for those without a plan, the safety net for all.

:class:`Guard` runs after each radar scan (:meth:`~mal_planner.service.core.PlanningService.instruct`): it
predicts the traffic along what each aircraft flies, gives a hold to each aircraft without a plan (or whose
fallback runs out; :mod:`mal_planner.service.fallback`), then looks for conflicts in the picture with the holds in
it and resolves those the planner cannot resolve in time (:mod:`mal_planner.service.safety_net`). Every hold, alert
and resolution is counted.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from mal_planner.scenario import Scenario
from mal_planner.service.book import Instructed, PlanBook
from mal_planner.service.conflicts import (
    POSITION_TIME_PER_TURN_TIME,
    Conflict,
    Picture,
    closest_to_others,
    conflicts,
    picture,
)
from mal_planner.service.fallback import Fallback, FallbackRules, choose_hold, fits_airspace
from mal_planner.service.rules import established, established_window_s
from mal_planner.service.safety_net import TRY_TURNS_DEG, displacements, resolution_vectors, turned
from mal_planner.service.tracks import Track

log = logging.getLogger("mal_planner.service")

ALERT_MARGIN_SHARE = 0.5
"""The net alerts below 1 + this share of the fallback margin, in minima: the minimum plus one aircraft's tracking
deviation (a terminal area 3.15 nm of 3)."""
ACT_TURN_TIMES = 4.0
"""The net's time to act: a conflict predicted this soon is resolved now (a terminal area 55 s, the thesis 30 s: a
turn of 30 deg then still opens the separation and its margin); a later one waits only for a plan due this long
before it, so a plan that fails or comes stale still leaves the net all of its time."""
KEEP_VECTOR_SHARE = 0.5
"""When no heading clears a conflict, an aircraft already on a vector keeps it unless another heading keeps more than
this share of the fallback margin (in minima) more separation (a terminal area 0.15 nm, one aircraft's tracking
deviation): re-choosing the clearest heading every scan flipped between headings 30-150 deg apart, so the aircraft
never turned away (a 20-aircraft run: 31 vectors to T06 in 31 s, and a loss of separation at 0.79 minima where 1.04
had been predicted before the net acted)."""


@dataclass
class Guard:
    """Holds and the safety net over one scenario (see the module docstring)."""

    scenario: Scenario
    rules: FallbackRules
    counts: Counter = field(default_factory=Counter)
    """holds, vectors, alerts (pairs newly in conflict), uses (scans at which the net gave vectors), waited (alerts
    left to a plan on its way, per scan)."""
    _active: set[tuple[str, str]] = field(default_factory=set)

    @classmethod
    def of(cls, scenario: Scenario, deviation_nm: float) -> Guard:
        """The guard of ``scenario`` (its no-fly zones and the wind the service knows)."""
        return cls(scenario, FallbackRules.of(scenario, deviation_nm))

    def update(self, scenario: Scenario) -> None:
        """New no-fly zones or a new wind (``scenario``'s): the next holds and vectors are drawn in them."""
        self.scenario = scenario
        self.rules = FallbackRules.of(scenario, self.rules.edge_nm)

    def _picture(self, tracks: Mapping[str, Track], book: PlanBook, now: float) -> Picture:
        scales = self.rules.scales
        return picture(tracks, book.instructions(), self.rules.look_ahead(now), search_s=scales.time_s,
                       settle_s=scales.seconds(POSITION_TIME_PER_TURN_TIME), plan_times=book.plan_times(tracks))

    def instruct(self, tracks: Mapping[str, Track], book: PlanBook, now: float, deliver_at: float | None,
                 coming: frozenset[str] | set[str] = frozenset()) -> list[Instructed]:
        """Holds and resolutions at ``now``; ``deliver_at``: when the next plan is expected (None: none coming);
        ``coming``: the aircraft of the plan under way or waiting (one without a hold yet flies on as the plan
        was made for it, straight; the net still watches it)."""
        pic = self._picture(tracks, book, now)
        given = self._holds(tracks, book, pic, now, coming)
        given += self._net(tracks, book, pic, now, deliver_at)
        return [Instructed(tuple(given))] if given else []

    def _holds(self, tracks: Mapping[str, Track], book: PlanBook, pic: Picture, now: float,
               coming: frozenset[str] | set[str]) -> list[Fallback]:
        renew_by = now + self.rules.scales.time_s
        given = []
        for cs in sorted(tracks):
            fb = book.fallbacks.get(cs)
            if cs in book.flying or (fb is not None and fb.reference.end > renew_by) or (fb is None and cs in coming):
                continue
            given.append(self._hold(tracks[cs], book, pic, now, "no plan" if fb is None else f"its {fb.kind} ends"))
        return given

    def _feasible_vector(self, fb: Fallback, track: Track, pic: Picture, now: float,
                         current: Fallback | None = None) -> Fallback | None:
        """The MVP vector, or the first heading turned from it (:data:`TRY_TURNS_DEG`) that stays inside the airspace
        and clear of the no-fly zones and keeps the minimum from the others' predicted paths; else the one that fits
        with the most separation, unless the aircraft's ``current`` vector keeps nearly as much
        (:data:`KEEP_VECTOR_SHARE`); None when none fits."""
        others = Picture(pic.times, {k: v for k, v in pic.paths.items() if k != fb.callsign})
        chosen = self._clearest_vector(fb, track, pic, others, now)
        if current is None or chosen is None or fb.callsign not in pic.paths or \
                chosen.clearance >= 1.0 + ALERT_MARGIN_SHARE * self.rules.margin:
            return chosen
        kept, _ = closest_to_others(pic.paths[fb.callsign], others, self.rules.minima, fb.callsign)
        return current if kept >= chosen.clearance - KEEP_VECTOR_SHARE * self.rules.margin else chosen

    def _clearest_vector(self, fb: Fallback, track: Track, pic: Picture, others: Picture,
                         now: float) -> Fallback | None:
        best: tuple[float, Fallback] | None = None
        for turn in TRY_TURNS_DEG:
            cand = turned(fb, track, self.rules, turn, now)
            ref = cand.reference
            if not fits_airspace(self.scenario, ref.positions(np.arange(now, ref.end + self.rules.step_s,
                                                                        self.rules.step_s)), self.rules.edge_nm):
                continue
            clearance, _ = closest_to_others(ref.positions(pic.times), others, self.rules.minima, fb.callsign)
            cand = Fallback(cand.callsign, cand.kind, ref, now, cand.reason, clearance)
            if clearance >= 1.0 + ALERT_MARGIN_SHARE * self.rules.margin:
                return cand
            if best is None or clearance > best[0]:
                best = (clearance, cand)
        return None if best is None else best[1]

    def _hold(self, track: Track, book: PlanBook, pic: Picture, now: float, why: str) -> Fallback:
        """The hold of ``track``'s aircraft against everyone else in ``pic`` (which it then joins), given."""
        cs = track.callsign
        others = Picture(pic.times, {k: v for k, v in pic.paths.items() if k != cs})
        hold = choose_hold(track, others, self.scenario, self.rules, now, why)
        before = book.fallbacks.get(cs)
        book.give(hold, now)
        pic.paths[cs] = hold.reference.positions(pic.times)
        self.counts["holds"] += 1
        again = before is not None and before.kind == "hold" and before.reason == why  # the net, scan after scan
        log.log(logging.DEBUG if again else logging.INFO, "t=%.1f s: %s holds (%s; %.2f minima from the others)",
                now, cs, why, hold.clearance)
        return hold

    def _net(self, tracks: Mapping[str, Track], book: PlanBook, pic: Picture, now: float,
             deliver_at: float | None) -> list[Fallback]:
        alerts = conflicts(pic, self.rules.minima, 1.0 + ALERT_MARGIN_SHARE * self.rules.margin)
        pairs = {(c.a, c.b) for c in alerts}
        for c in alerts:
            if (c.a, c.b) not in self._active:
                log.info("t=%.1f s: alert %s-%s: %.2f minima predicted at t=%.1f s (below %.2f from t=%.1f s)", now,
                         c.a, c.b, c.ratio, c.t_closest, 1.0 + ALERT_MARGIN_SHARE * self.rules.margin, c.t)
        self.counts["alerts"] += len(pairs - self._active)
        self._active = pairs
        if not alerts:
            return []
        act = self.rules.scales.seconds(ACT_TURN_TIMES)
        urgent: list[Conflict] = []
        due = None if deliver_at is None else max(deliver_at, now)  # an overdue plan may come any time from now
        for c in alerts:
            if due is not None and due <= c.t - act:
                self.counts["waited"] += 1
            else:
                urgent.append(c)
        if not urgent:
            return []
        window = established_window_s(self.scenario)  # on final: the net moves the other aircraft of a conflict
        final = {cs: ref.end for cs, ref in book.flying.items() if established(ref, now, window)}
        headings = {cs: fb.reference.table[-1, 4] for cs, fb in book.fallbacks.items() if fb.kind == "vector"}
        vectors = resolution_vectors(tracks, displacements(urgent, pic, self.rules, now, final), urgent,
                                     self.scenario, self.rules, now, headings)
        stuck = {fb.callsign for fb in vectors if self._feasible_vector(fb, tracks[fb.callsign], pic, now) is None}
        given = [self._hold(tracks[cs], book, pic, now, "safety net: no vector inside the airspace and clear of the "
                            "no-fly zones") for cs in sorted(stuck)]
        if stuck:  # their partners take the whole resolution, clear of their holds
            dv = displacements(urgent, pic, self.rules, now, {**final, **{cs: math.inf for cs in stuck}})
            vectors = [fb for fb in resolution_vectors(tracks, dv, urgent, self.scenario, self.rules, now, headings)
                       if fb.callsign not in stuck]
        for fb in vectors:
            current = book.fallbacks.get(fb.callsign)
            current = current if current is not None and current.kind == "vector" and current.reference.end > now \
                else None
            chosen = self._feasible_vector(fb, tracks[fb.callsign], pic, now, current)
            if chosen is None:  # every heading leaves the airspace or enters a no-fly zone: it holds
                given.append(self._hold(tracks[fb.callsign], book, pic, now, "safety net: no vector inside the "
                                        "airspace and clear of the no-fly zones"))
                continue
            if chosen is current:  # no heading clears it: it keeps turning the way it was sent
                self.counts["kept"] += 1
                continue
            book.give(chosen, now)
            pic.paths[chosen.callsign] = chosen.reference.positions(pic.times)
            self.counts["vectors"] += 1
            log.info("t=%.1f s: %s vectored by the safety net (%s)", now, chosen.callsign, chosen.reason)
            given.append(chosen)
        self.counts["uses"] += 1
        return given
