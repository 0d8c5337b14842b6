"""What the figures show, read from a ``plan.json`` document alone (schema in the README).

The node renders its figures in another process from the saved file, and ``mal-figures`` re-renders
any saved plan, so nothing here needs the planner's live objects.
"""

from __future__ import annotations

import itertools
import json
from dataclasses import dataclass, field
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
    return ControlLimits(tuple(doc["n_h"]), tuple(doc["n_v"]), float(doc["bank_angle_max"]))


def _initial(callsign: str, doc: dict) -> Trajectory:
    wp = doc["waypoints"]
    states = np.zeros((len(wp["t"]), 5))
    states[:, :3] = np.column_stack([wp["x"], wp["y"], wp["z"]])
    return Trajectory(callsign, np.asarray(wp["t"], float), states)


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
            limits=_limits(a.get("limits"))))
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
    )


def load_plan(path: str | Path) -> PlanView:
    """Read ``plan.json`` and build the view."""
    return plan_view(json.loads(Path(path).read_text(encoding="utf-8")))
