"""The replan policy: when the service asks for a plan, and why (one line for the log).

In this order, on the radar's clock:

1. nothing while a plan is under way or waits for its start (a request made meanwhile would plan from the same
   picture);
2. the first plan, once ``settle_time_s`` has passed since the first track and ``min_aircraft`` are tracked;
3. nothing sooner than ``min_interval_s`` after the last plan arrived, a failed one too (the back-off);
4. an aircraft tracked that flies no plan (new, or left out of the last one);
5. the aircraft whose filtered track strays farthest from its plan, beyond ``deviation_nm``; an aircraft within
   ``min_interval_s`` of its plan's end, or established on final (``established_s``), is not checked (a new plan
   would come too late to help, or is not handed to it: it lands on the plan it flies);
6. the period, ``period_s``.

Changes that come from outside the radar (a no-fly zone, the wind) ask for a plan at once:
:func:`wind_change_reason` says when a new wind matters.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from mal_planner.service.rules import ServiceRules
from mal_planner.service.tracks import Track
from mal_planner.trajectory import Reference

STRAYING_SHARE = 0.5
"""When an aircraft strays beyond the deviation threshold, those beyond this share of it stray too (a replan of what
changed replans them with it): they would ask for a replan of their own within the replan interval or so."""


class ReplanPolicy:
    """Decides from the rules, the filtered tracks and the plans being flown (it remembers only who strayed)."""

    def __init__(self, rules: ServiceRules, established_s: float = 0.0) -> None:
        """``established_s``: an aircraft this close to its plan's end is established on final
        (:func:`~mal_planner.service.rules.established_window_s`)."""
        self.rules = rules
        self.established_s = established_s
        self.straying: tuple[str, set[str]] | None = None
        """(the reason, the aircraft) when the latest decision was a deviation: the one beyond the threshold and
        those beyond :data:`STRAYING_SHARE` of it; a replan of what changed may serve them."""
        self.joining: tuple[str, set[str]] | None = None
        """(the reason, the aircraft) when the latest decision was an aircraft without a plan: every aircraft tracked
        that flies none; a plan of them among the others' plans may serve them."""

    def decide(self, now: float, tracks: Mapping[str, Track], flying: Mapping[str, Reference], *, busy: bool,
               planned: bool, last_arrival: float, first_track_at: float | None) -> str | None:
        """Why the service should plan now (None: it should not). ``planned``: a plan was asked for before;
        ``last_arrival``: when the last plan arrived (-inf: ask at the next chance); ``first_track_at``: the first
        radar track's time (None: none yet)."""
        if busy or not tracks:
            return None
        self.straying = self.joining = None
        if not planned:
            return self._first_plan(now, tracks, first_track_at)
        if now - last_arrival < self.rules.min_interval_s:
            return None
        unplanned = [cs for cs in tracks if cs not in flying]
        if unplanned:
            reason = f"{unplanned[0]} has no plan" + (f" (and {len(unplanned) - 1} more)" if len(unplanned) > 1 else "")
            self.joining = (reason, set(unplanned))
            return reason
        deviations = self.deviations(tracks, flying)
        who = max(deviations, key=deviations.__getitem__, default="")
        if self.rules.deviation_nm > 0 and deviations.get(who, 0.0) > self.rules.deviation_nm:
            reason = f"{who} deviates {deviations[who]:.3f} nm from its plan"
            self.straying = (reason, {cs for cs, d in deviations.items()
                                      if d > STRAYING_SHARE * self.rules.deviation_nm})
            return reason
        if self.rules.period_s > 0 and now - last_arrival >= self.rules.period_s:
            return "periodic replan"
        return None

    def _first_plan(self, now: float, tracks: Mapping[str, Track], first_track_at: float | None) -> str | None:
        if first_track_at is None or now - first_track_at < self.rules.settle_time_s:
            return None
        if len(tracks) < self.rules.min_aircraft:
            return None
        return f"initial plan ({len(tracks)} aircraft tracked)"

    def deviations(self, tracks: Mapping[str, Track], flying: Mapping[str, Reference]) -> dict[str, float]:
        """The distance (nm) of each track from its plan at the track's time; aircraft near their plan's end (within
        ``min_interval_s``, or established on final) or without a plan are not counted."""
        out = {}
        near_end = max(self.rules.min_interval_s, self.established_s)
        for cs, tr in tracks.items():
            ref = flying.get(cs)
            if ref is not None and ref.start <= tr.stamp <= ref.end - near_end:
                out[cs] = float(np.linalg.norm(ref.position(tr.stamp) - tr.state[:3]))
        return out


def wind_change_reason(old: tuple[float, float], new: tuple[float, float], rules: ServiceRules,
                       described: str) -> str | None:
    """A new wind that would move an aircraft by the deviation threshold within the replan interval asks for a
    plan now (``described``: the wind in words, the reason's text); None: it can wait for the next plan."""
    change = math.hypot(new[0] - old[0], new[1] - old[1])
    if change == 0.0 or rules.deviation_nm <= 0:
        return None
    return described if change * rules.min_interval_s > rules.deviation_nm else None
