"""A late plan re-anchored to where its aircraft are, and the test of whether that is still safe.

A plan is made from tracks predicted to its start; when it arrives the aircraft are somewhat off it (the planning
took longer than its lead, the prediction was off). Dropping it for that left aircraft without a new plan for a
deviation far below the separation ("stale: 0.169 nm ... threshold 0.097 nm" at 3 nm). Instead each aircraft's
plan is moved by its offset at the hand-out, the offset fading out linearly over :data:`REANCHOR_TURN_TIMES`: the
aircraft starts on its plan and joins the planned path by the end of the fade (the guidance does the same with
any offset, and so keeps the planned times). A plan is stale only when that is unsafe: an offset of more than half
the separation or the deviation threshold (it was made for another picture), a re-anchored path closer than a
path accuracy to the airspace's edge or to a no-fly zone (unless the aircraft is already), or two closer than the
minimum during the fade.

Re-anchoring moves positions, not headings: an aircraft whose ground track at the hand-out is far from its plan's
turns onto it and strays sideways by about R (1 - cos d), R its turn radius and d the angle (2R turning round; 20
aircraft, traffic-0002: a plan reached T20 half way round its hold 1.5 nm from the airspace's edge, and it left the
airspace by 0.46 nm turning onto it). Where that stray is more than the deviation threshold (which the margins of
flown plans cover), the re-anchored path must keep it from the airspace's horizontal edges during the fade, and two
re-anchored paths (or one and what another aircraft flies) must keep the horizontal minimum plus the strays apart
(20 aircraft, traffic-0031: a plan made before the safety net vectored T07 and T11 turned them back onto it, and they
lost separation, 2.80 nm of 3, where the moved paths kept 3).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from mal_planner.obstacles import Superquadric
from mal_planner.scales import Scales
from mal_planner.service.conflicts import Minima
from mal_planner.trajectory import Reference, Trajectory

REANCHOR_TURN_TIMES = 4.0
"""The offset fades out over this (a terminal area 55 s, the thesis 30 s): gently, near the floor and the ceiling."""
MAX_OFFSET_SEPARATIONS = 0.5
"""An aircraft further than this share of the separation from its plan's start makes the plan stale."""


def fade_time(scales: Scales, now: float, end: float) -> float:
    """How long an offset fades: :data:`REANCHOR_TURN_TIMES`, at most half the time left to the plan's end (the
    runway: an aircraft is on the centreline and the glide path well before it), at least a second."""
    return max(min(scales.seconds(REANCHOR_TURN_TIMES), 0.5 * (end - now)), 1.0)


def reanchored(traj: Trajectory, offset: np.ndarray, at: float, fade_s: float) -> Trajectory:
    """``traj`` moved by ``offset`` (nm) at its time ``at``, fading out linearly over ``fade_s`` (its controls kept:
    the guidance flies the positions)."""
    states = traj.states.copy()
    w = np.clip(1.0 - (traj.t - at) / fade_s, 0.0, 1.0)
    states[:, :3] += w[:, None] * np.asarray(offset, float)[None, :3]
    meta = {**traj.meta, "reanchored_nm": float(np.linalg.norm(offset))}
    return replace(traj, states=states, meta=meta)


def turn_stray(plan: Reference, flying: Reference | None, now: float, radius_nm: float) -> float:
    """How far (nm) an aircraft flying ``flying`` strays sideways turning onto ``plan`` at ``now``: R (1 - cos d) for
    the angle d between their ground tracks there, with R = ``radius_nm``; 0 without an instruction."""
    if flying is None:
        return 0.0
    a, b = flying.sample(now)[5:7], plan.sample(now)[5:7]
    norms = float(np.linalg.norm(a) * np.linalg.norm(b))
    return 0.0 if norms == 0.0 else radius_nm * (1.0 - float(np.dot(a, b)) / norms)


def unsafe_offsets(refs: Mapping[str, Reference], offsets: Mapping[str, np.ndarray], now: float, scales: Scales,
                   minima: Minima, airspace: np.ndarray, deviation_nm: float = 0.0,
                   others: Mapping[str, Reference] | None = None, strays: Mapping[str, float] | None = None,
                   obstacles: Sequence[Superquadric] = ()) -> str | None:
    """Why re-anchoring ``refs`` by ``offsets`` at ``now`` is unsafe (one line), or None (see the module
    docstring); ``deviation_nm``: the service's deviation threshold, the largest offset where it is larger than half
    the separation (the margins of flown plans are sized to it); ``others``: what the aircraft outside the plan fly
    (a replan of what changed), which the moved paths must keep the minimum from too; ``strays``: how far each
    aircraft strays turning onto its plan (:func:`turn_stray`); ``obstacles``: the no-fly zones."""
    limit = max(MAX_OFFSET_SEPARATIONS * minima.horizontal_nm, deviation_nm)
    for cs, off in offsets.items():
        d = float(np.linalg.norm(off))
        if d > limit:
            return f"{cs} {d:.3f} nm from it when it starts (more than {limit:.3f} nm)"
    times = now + np.linspace(0.0, scales.seconds(REANCHOR_TURN_TIMES), 33)
    moved, live = {}, {}
    for cs, ref in refs.items():
        w = np.clip(1.0 - (times - now) / fade_time(scales, now, ref.end), 0.0, 1.0)
        planned = ref.positions(times)
        moved[cs] = planned + w[:, None] * np.asarray(offsets.get(cs, np.zeros(3)))[None, :3]
        live[cs] = times <= ref.end  # past its end an aircraft has landed
        stray = _wide(strays, cs, deviation_nm)
        why = _leaves_airspace(cs, moved[cs], planned, live[cs], airspace, scales.accuracy_nm, stray) or \
            _enters_no_fly_zone(cs, moved[cs], planned, live[cs], obstacles, max(scales.accuracy_nm, stray))
        if why is not None:
            return why
    fixed = {cs: ref.positions(times) for cs, ref in (others or {}).items() if cs not in moved}
    live |= {cs: times <= (others or {})[cs].end for cs in fixed}
    return _too_close(moved, fixed, live, minima, strays, deviation_nm)


def _outside(airspace: np.ndarray, path: np.ndarray) -> np.ndarray:
    """How far each point of ``path`` ((x, y) or (x, y, z) columns) is outside ``airspace`` (negative: inside)."""
    box = airspace[: path.shape[1]]
    return np.max(np.maximum(box[:, 0] - path, path - box[:, 1]), axis=1)


def _leaves_airspace(cs: str, moved: np.ndarray, planned: np.ndarray, live: np.ndarray, airspace: np.ndarray,
                     accuracy_nm: float, stray: float) -> str | None:
    """Nearer the edge than a path accuracy (a flown path strays about that far from its plan) only where the plan
    or the aircraft is; and the stray turning onto the plan kept from the horizontal edges."""
    out = _outside(airspace, moved)
    bound = np.maximum(np.maximum(_outside(airspace, planned), out[0]), -accuracy_nm)
    if np.any((out > bound + 1e-12)[1:] & live[1:]):
        return f"{cs} would leave the airspace on the plan moved to where it is"
    if stray > 0.0 and np.any((_outside(airspace, moved[:, :2]) + stray > 0.0) & live):
        return f"{cs} would stray {stray:.2f} nm out of the airspace turning onto its plan"
    return None


def _enters_no_fly_zone(cs: str, moved: np.ndarray, planned: np.ndarray, live: np.ndarray,
                        obstacles: Sequence[Superquadric], margin_nm: float) -> str | None:
    """The moved path kept ``margin_nm`` (a path accuracy, or the stray turning onto the plan) out of every no-fly
    zone the plan itself keeps it from; an aircraft already inside that margin must only not enter the zone (20
    aircraft, traffic-0003 with a failing planner: a plan re-anchored to a holding aircraft took it through a wall
    beside the wall's hole, 0.4 s after the hand-out)."""
    starts, ends, on = moved[:-1], moved[1:], live[1:]
    for ob in obstacles:
        zone = ob.inflated(margin_nm)
        if bool(zone.contains(moved[:1])[0]):
            zone = ob
        hits = zone.segment_hits(starts, ends) & on & ~zone.segment_hits(planned[:-1], planned[1:])
        if np.any(hits):
            return f"{cs} would enter the no-fly zone '{ob.name}' on the plan moved to where it is"
    return None


def _too_close(moved: Mapping[str, np.ndarray], fixed: Mapping[str, np.ndarray], live: Mapping[str, np.ndarray],
               minima: Minima, strays: Mapping[str, float] | None, deviation_nm: float) -> str | None:
    """Two moved paths, or a moved path and what another aircraft flies, closer than the minimum plus the strays
    of the aircraft turning onto their plans."""
    pairs = [*itertools.combinations(sorted(moved), 2), *itertools.product(sorted(moved), sorted(fixed))]
    paths = {**moved, **fixed}
    for a, b in pairs:
        both = live[a] & live[b]
        if not both.any():
            continue
        grow = _wide(strays, a, deviation_nm) + _wide(strays, b, deviation_nm)
        wider = Minima(minima.horizontal_nm + grow, minima.vertical_nm)
        if float(wider.ratio(paths[a][both], paths[b][both]).min()) < 1.0:
            r = float(minima.ratio(paths[a][both], paths[b][both]).min())
            turning = f" ({grow:.2f} nm more: turning onto it they stray)" if grow > 0.0 else ""
            return f"{a} and {b} {r:.2f} minima apart on the plan moved to where they are{turning}"
    return None


def _wide(strays: Mapping[str, float] | None, callsign: str, deviation_nm: float) -> float:
    """How much wider (nm) ``callsign``'s protected zone is while it turns onto its plan: its stray where that is
    more than the deviation threshold (the margins of flown plans cover less), else 0."""
    stray = (strays or {}).get(callsign, 0.0)
    return stray if stray > deviation_nm else 0.0
