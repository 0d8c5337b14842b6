"""What the figures show, read from a ``plan.json`` document alone (schema in the README).

The node renders its figures in another process from the saved file, and ``mal-figures`` re-renders
any saved plan, so nothing here needs the planner's live objects.
"""

from __future__ import annotations

import itertools
import json
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from mal_planner.dynamics import ControlLimits
from mal_planner.obstacles import Gate, Superquadric
from mal_planner.trajectory import Trajectory


@dataclass(frozen=True)
class AircraftView:
    callsign: str
    order: int
    gate_time: float | None
    landing_time: float | None
    trajectory: Trajectory
    """The optimal trajectory, or the initializer's path sampled every second when not optimized."""
    initial: Trajectory
    """The initializer's path (states x, y, z; flight-path angle and heading zero) through its waypoints."""
    direct_path: np.ndarray
    """(k, 3) shortest path before sequencing."""
    limits: ControlLimits
    cas: np.ndarray | None = None
    """The calibrated airspeed (nm/s) at each trajectory sample: the airspeed model's (None: constant speed)."""
    envelope: dict | None = None
    """The type's speeds (nm/s CAS): ``type``, ``vmo``, ``final_approach_cas`` [low, high] (plan.json ``limits``)."""


@dataclass(frozen=True)
class PairSeparation:
    pair: str
    t: np.ndarray
    distance: np.ndarray
    """Distance (nm) while both aircraft are airborne."""
    verified_min: float | None = None
    """Minimum of the re-integrated trajectories (the verification), if verified."""
    verified_at: float | None = None


@dataclass(frozen=True)
class SlotView:
    """One landing of the time line (times in s; None where the plan does not say)."""

    callsign: str
    slot: int
    landing_time: float
    wake_category: str | None = None
    earliest: float | None = None
    target: float | None = None
    delay: float | None = None
    """Landing minus target."""
    fixed: bool = False


@dataclass(frozen=True)
class GapView:
    """Two consecutive landings: the time between them against the time they need."""

    leader: str
    follower: str
    gap: float
    needed: float | None = None
    """The scenario's spacing or the wake minimum; None when the plan carries no verification."""
    wake: str | None = None
    """leader->follower wake categories when a wake table applies."""
    wake_nm: float | None = None
    short: bool = False
    """Less than needed: the verification failed this pair's spacing."""

    @property
    def pair(self) -> str:
        return f"{self.leader}->{self.follower}"


@dataclass(frozen=True)
class LandingTimeline:
    """Who lands when and the spacing of each consecutive pair (plan.json ``sequence`` and
    ``verification.landings``, or the landing times alone)."""

    slots: list[SlotView] = field(default_factory=list)
    """In landing order."""
    gaps: list[GapView] = field(default_factory=list)
    strategy: str | None = None
    wake_table: str | None = None
    total_delay: float | None = None


@dataclass(frozen=True)
class PlanView:
    name: str
    status: str
    verified: bool
    aircraft: list[AircraftView]
    """In landing order."""
    airspace: np.ndarray
    runway: np.ndarray
    obstacles: tuple[Superquadric, ...]
    gates: tuple[Gate, ...]
    separation_nm: float | None
    phase_names: list[str] = field(default_factory=list)
    verification_pairs: dict[str, tuple[float, float]] = field(default_factory=dict)
    """pair -> (minimum distance nm, at time s) from the verification."""
    timeline: LandingTimeline = field(default_factory=LandingTimeline)
    procedures: dict | None = None
    """plan.json ``scenario.procedures`` (nm, nm/s CAS); None: none."""
    elevation_nm: float = 0.0
    """The threshold's elevation: a height plus this is an altitude."""

    @property
    def optimized(self) -> bool:
        return self.status == "optimal"

    @property
    def callsigns(self) -> list[str]:
        return [a.callsign for a in self.aircraft]

    def event_times(self) -> list[float]:
        """Sorted gate and landing times of all aircraft: the boundaries of the optimizer's phases."""
        times = {round(t, 9) for a in self.aircraft for t in (a.gate_time, a.landing_time) if t is not None}
        return sorted(times)

    def separations(self, dt: float = 0.25) -> list[PairSeparation]:
        """Distance against time of every pair of aircraft while both fly, on a ``dt`` grid plus the ends."""
        out = []
        for a, b in itertools.combinations(self.aircraft, 2):
            ta, tb = a.trajectory.t, b.trajectory.t
            lo, hi = max(ta[0], tb[0]), min(ta[-1], tb[-1])
            if hi <= lo:
                continue
            t = np.union1d(np.arange(lo, hi, dt), [lo, hi])
            pa = np.stack([np.interp(t, ta, a.trajectory.positions[:, k]) for k in range(3)], axis=1)
            pb = np.stack([np.interp(t, tb, b.trajectory.positions[:, k]) for k in range(3)], axis=1)
            name = f"{a.callsign}-{b.callsign}"
            ver = self.verification_pairs.get(name) or self.verification_pairs.get(f"{b.callsign}-{a.callsign}")
            out.append(PairSeparation(name, t, np.linalg.norm(pa - pb, axis=1), *(ver or (None, None))))
        return out


def _limits(doc: dict | None) -> ControlLimits:
    if not doc:
        return ControlLimits()
    return ControlLimits(tuple(doc["n_h"]), tuple(doc["n_v"]), float(doc["bank_angle_max"]),
                         tuple(doc.get("n_x", (0.0, 0.0))))


def _initial(callsign: str, doc: dict) -> Trajectory:
    wp = doc["waypoints"]
    states = np.zeros((len(wp["t"]), 5))
    states[:, :3] = np.column_stack([wp["x"], wp["y"], wp["z"]])
    return Trajectory(callsign, np.asarray(wp["t"], float), states)


_SPACING_REASON = re.compile(r"^(\S+->\S+): landings ")


def _float(value: float | str | None) -> float | None:
    return None if value is None else float(value)


def _landing_slots(doc: dict) -> list[SlotView]:
    """The landings in time order: from ``sequence``, else the aircraft's (or the verification's) landing times."""
    rows = [r for r in ((doc.get("sequence") or {}).get("aircraft") or []) if r.get("landing_time_s") is not None]
    if rows:
        slots = [SlotView(r["callsign"], int(r.get("slot") or k), float(r["landing_time_s"]), r.get("wake_category"),
                          _float(r.get("earliest_s")), _float(r.get("target_s")), _float(r.get("delay_s")),
                          bool(r.get("fixed"))) for k, r in enumerate(rows, start=1)]
        return sorted(slots, key=lambda s: (s.landing_time, s.slot))
    verified = {a["callsign"]: a.get("landing_time") for a in (doc.get("verification") or {}).get("aircraft", [])}
    times = []
    for a in sorted(doc.get("aircraft", []), key=lambda a: a.get("order", 0)):
        t = a.get("landing_time_s")
        t = verified.get(a["callsign"]) if t is None else t
        if t is not None:
            times.append((float(t), a["callsign"]))
    times.sort(key=lambda item: item[0])
    return [SlotView(cs, k, t) for k, (t, cs) in enumerate(times, start=1)]


def _is_short(pair: str, gap: float, needed: float | None, verification: dict) -> bool:
    """Whether the verification failed the pair's spacing (from its reasons; without them, the gap against the
    need less the landing-time tolerance)."""
    if "reasons" in verification:
        return any((m := _SPACING_REASON.match(r)) is not None and m.group(1) == pair for r in verification["reasons"])
    tol = float((verification.get("tolerances") or {}).get("landing_time_s", 0.0))
    return needed is not None and gap < needed - tol


def landing_timeline(doc: dict) -> LandingTimeline:
    """The landing time line of a plan.json document; works without ``sequence`` and without a wake table."""
    slots = _landing_slots(doc)
    ver = doc.get("verification") or {}
    gaps: list[GapView] = []
    for g in ver.get("landings") or []:
        leader, follower = g["pair"].split("->", 1)
        needed = _float(g.get("needed_s"))
        gaps.append(GapView(leader, follower, float(g["gap_s"]), needed, g.get("wake"), _float(g.get("wake_nm")),
                            _is_short(g["pair"], float(g["gap_s"]), needed, ver)))
    if not gaps:
        gaps = [GapView(a.callsign, b.callsign, b.landing_time - a.landing_time)
                for a, b in itertools.pairwise(slots)]
    categories: dict[str, str] = {}
    for g in gaps:  # without ``sequence``: the categories from the verification's wake pairs
        if g.wake and "->" in g.wake:
            categories[g.leader], categories[g.follower] = g.wake.split("->", 1)
    slots = [s if s.wake_category or s.callsign not in categories else
             replace(s, wake_category=categories[s.callsign]) for s in slots]
    seq = doc.get("sequence") or {}
    wake = seq.get("wake")
    return LandingTimeline(slots, gaps, seq.get("strategy"), None if wake in (None, "none") else wake,
                           _float(seq.get("total_delay_s")))


def _extent(aircraft: list[AircraftView]) -> np.ndarray:
    """The paths' bounding box: the airspace of a plan.json written before it carried the geometry."""
    pts = np.concatenate([a.trajectory.positions for a in aircraft])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return np.stack([lo, np.maximum(hi, lo + 1e-3)], axis=1)


def plan_view(doc: dict) -> PlanView:
    """Build the view from a parsed plan.json document (older documents without geometry draw none)."""
    sc = doc["scenario"]
    aircraft = []
    for a in doc["aircraft"]:
        init = a["initial"]
        aircraft.append(AircraftView(
            callsign=a["callsign"], order=int(a["order"]), gate_time=a.get("gate_time_s"),
            landing_time=a.get("landing_time_s"), trajectory=Trajectory.from_dict(a["callsign"], a["trajectory"]),
            initial=_initial(a["callsign"], init), direct_path=np.asarray(init["direct_path"], float).reshape(-1, 3),
            limits=_limits(a.get("limits")), cas=_column(a["trajectory"], "cas"), envelope=_envelope(a.get("limits"))))
    aircraft.sort(key=lambda a: a.order)
    ver = doc.get("verification") or {}
    optimizer = doc.get("optimizer") or {}
    return PlanView(
        name=sc["name"], status=doc["status"], verified=bool(doc.get("verified")), aircraft=aircraft,
        airspace=np.asarray(sc["airspace"], float) if "airspace" in sc else _extent(aircraft),
        runway=np.asarray(sc.get("runway", [0, 0, 0, 0, 0]), float),
        obstacles=tuple(Superquadric(o["name"], tuple(o["center"]), tuple(o["semi_axes"]), int(o["p"]))
                        for o in sc.get("obstacles", [])),
        gates=tuple(Gate(g["name"], int(g["axis"]), float(g["position"]), int(g["direction"]),
                         tuple(tuple(b) for b in g["bounds"]), float(g["flight_path_angle"]), float(g["heading"]))
                    for g in sc.get("gates", [])),
        separation_nm=sc.get("separation_nm"),
        phase_names=list(optimizer.get("phases") or []),
        verification_pairs={p["pair"]: (p["min_distance_nm"], p["at_time_s"]) for p in ver.get("pairs", [])},
        timeline=landing_timeline(doc),
        procedures=sc.get("procedures"), elevation_nm=float(sc.get("elevation_nm") or 0.0),
    )


def _column(trajectory: dict, name: str) -> np.ndarray | None:
    return None if name not in trajectory else np.asarray(trajectory[name], float)


def _envelope(limits: dict | None) -> dict | None:
    return None if not limits or "vmo" not in limits else {k: limits[k] for k in ("type", "vmo", "final_approach_cas")}


def load_plan(path: str | Path) -> PlanView:
    """Read ``plan.json`` and build the view."""
    return plan_view(json.loads(Path(path).read_text(encoding="utf-8")))
