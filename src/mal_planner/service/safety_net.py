"""The safety net under the planner: short-term conflict detection and a tactical resolution (an STCA with MVP).

Every radar scan the service predicts every aircraft along its instruction over the look-ahead
(:mod:`mal_planner.service.conflicts`). A pair predicted below the minimum is an alert. The net resolves it only
when the planner has no plan in time (none under way or waiting whose start comes the net's time to act before the
conflict): then the pair gets vectors, by the Modified Voltage Potential of Eby (1994) as BlueSky's
``asas/MVP.py`` computes it, on the predicted paths instead of straight lines: the displacement that would put the
pair ``resolve`` minima apart at their closest point, over the time to it, shared by both aircraft (all of it by
the one that is not established on final), summed over an aircraft's conflicts. Constant-speed aircraft take it
as a heading: that of their velocity plus the displacement. The vectored aircraft hold their level and lose their
plans, so the policy replans them at once; after the vector they hold (:mod:`mal_planner.service.fallback`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from mal_planner.scenario import Scenario
from mal_planner.service.conflicts import Conflict, Picture
from mal_planner.service.fallback import Fallback, FallbackRules, fits_airspace
from mal_planner.service.manoeuvres import vector
from mal_planner.service.tracks import Track

VECTOR_TURN_TIMES = 4.0
"""A vector lasts this long past the predicted closest point (a terminal area 55 s), then the aircraft holds."""


def displacements(conflicts: list[Conflict], pic: Picture, rules: FallbackRules, now: float,
                  fixed: Mapping[str, float]) -> dict[str, np.ndarray]:
    """Per aircraft, the horizontal velocity change (nm/s) that resolves its conflicts (see the module docstring);
    aircraft in ``fixed`` (established on final, with their plan's end) do not move unless both of a pair are: then
    the later one gives way."""
    resolve = 1.0 + rules.margin
    out: dict[str, np.ndarray] = {}
    for c in conflicts:
        d = _miss(pic, c, rules.minima.horizontal_nm)
        dist = float(np.linalg.norm(d))
        t_go = max(c.t_closest - now, rules.scales.seconds(1.0))
        dv = (resolve * rules.minima.horizontal_nm - dist) * (d / dist) / t_go
        share_a = 0.5 if (c.a in fixed) == (c.b in fixed) else (0.0 if c.a in fixed else 1.0)
        if c.a in fixed and c.b in fixed:  # both on final: the follower gives way
            share_a = 1.0 if fixed[c.a] > fixed[c.b] else 0.0
        out[c.a] = out.get(c.a, np.zeros(2)) + share_a * dv
        out[c.b] = out.get(c.b, np.zeros(2)) - (1.0 - share_a) * dv
    return {cs: dv for cs, dv in out.items() if np.any(dv)}


def _miss(pic: Picture, c: Conflict, separation_nm: float) -> np.ndarray:
    """The horizontal miss vector of ``c``'s pair (a less b) at their closest point, across their relative motion
    there (the along-track part a constant-speed aircraft cannot change is left out); head on, a's right."""
    k = min(int(np.searchsorted(pic.times, c.t_closest)), len(pic.times) - 1)
    lo, hi = max(k - 1, 0), min(k + 1, len(pic.times) - 1)
    rel = pic.paths[c.a][:, :2] - pic.paths[c.b][:, :2]
    v = rel[hi] - rel[lo]
    if not np.any(v):
        v = np.array([1.0, 0.0])
    v = v / np.linalg.norm(v)
    d = rel[k] - np.dot(rel[k], v) * v
    if np.linalg.norm(d) < 1e-6 * separation_nm:
        d = 1e-6 * separation_nm * np.array([v[1], -v[0]])
    return d


def resolution_vectors(tracks: Mapping[str, Track], dv: Mapping[str, np.ndarray], conflicts: list[Conflict],
                       scenario: Scenario, rules: FallbackRules, now: float, vectored: Mapping[str, float]
                       ) -> list[Fallback]:
    """The vectors of the aircraft that move: heading of velocity + displacement, at their level (inside the
    airspace), until :data:`VECTOR_TURN_TIMES` past their last conflict's closest point. An aircraft already on a
    vector (``vectored``: its heading) adds the displacement to it, as MVP adds it to the commanded velocity."""
    out = []
    lo, hi = scenario.airspace[2, 0] + rules.edge_nm, scenario.airspace[2, 1] - rules.edge_nm
    for cs, change in dv.items():
        tr = tracks[cs]
        h = float(vectored.get(cs, tr.state[4]))
        v = tr.speed * np.array([math.cos(h), math.sin(h)]) + change
        until = max(c.t_closest for c in conflicts if cs in (c.a, c.b))
        ref = vector(tr.state, tr.speed, rules.turn_radius(tr.speed), math.atan2(v[1], v[0]),
                     level=min(max(float(tr.state[2]), lo), hi), t0=now,
                     duration_s=until - now + rules.scales.seconds(VECTOR_TURN_TIMES), step_s=rules.step_s,
                     wind=rules.wind)
        others = [c.b if c.a == cs else c.a for c in conflicts if cs in (c.a, c.b)]
        inside = fits_airspace(scenario, ref.positions(np.arange(now, ref.end, rules.step_s)), 0.0)
        note = f"clear of {', '.join(sorted(set(others)))}" + ("" if inside else LEAVES)
        out.append(Fallback(cs, "vector", ref, now, f"safety net: {note}", math.nan))
    return out


LEAVES = " (leaves the airspace)"
"""Said of an MVP heading that leaves the airspace (a turned heading that does not is tried next)."""
TRY_TURNS_DEG = (0.0, 30.0, -30.0, 60.0, -60.0, 90.0, -90.0, 135.0, -135.0)
"""Headings tried from the MVP heading when it leaves the airspace, enters a no-fly zone or stays in conflict."""


def turned(fb: Fallback, track: Track, rules: FallbackRules, turn_deg: float, now: float) -> Fallback:
    """``fb``'s vector with its heading turned by ``turn_deg`` (the same level and length)."""
    ref = fb.reference
    heading = float(ref.table[-1, 4]) + math.radians(turn_deg)
    out = vector(track.state, track.speed, rules.turn_radius(track.speed), heading, level=float(ref.table[-1, 2]),
                 t0=now, duration_s=ref.end - now, step_s=rules.step_s, wind=rules.wind)
    base = fb.reason.replace(LEAVES, "")
    return Fallback(fb.callsign, "vector", out, now, fb.reason if turn_deg == 0.0 else
                    f"{base}, turned {turn_deg:+.0f} deg from the MVP heading", fb.clearance)
