"""Random arrival traffic: scenario files that look like arrival streams converging on one runway.

The runway is at the origin, heading -90 deg (aircraft land flying towards -y). Every scenario has an
approach fix on the far side of the runway: the hole of a wall (layout ``wall``) or a point on the
extended centre line (layout ``no-fly-zones``). Aircraft are strung along the arrival stream: the k-th
has a path length to the runway (to the fix, then straight in) about 15-30 s of flight longer than the
(k-1)-th, at a bearing from the fix within +-70 deg of the approach axis, beyond the fix; altitudes rise
with distance like a glide slope plus jitter; headings point at the fix +-40 deg; speeds 0.04 nm/s +-10 %.
Positions too close to another aircraft (3-D distance below the separation + margin) are redrawn.
No-fly zones (1-3 ellipsoids, p = 2, or boxes, p = 50, from the ground up) keep clear of the aircraft, of
each other and of a corridor around the final approach, so the runway stays reachable. Unless the user
fixes it, the airspace grows to hold the stream (at least the thesis's x [-3, 3], y [0, 6], z [0, 0.3]).

Each scenario ``i`` draws from ``numpy.random.default_rng([seed, i])``: the same seed gives byte-identical
files, and scenario i does not depend on how many are generated. Every text is validated with the
scenario loader before it is returned.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib.metadata import version
from typing import Any

import numpy as np
import yaml

from mal_planner.campaign.metrics import ray_clearance_nm
from mal_planner.obstacles import Superquadric
from mal_planner.scenario import Scenario, ScenarioError, parse_scenario

GENERATOR_VERSION = 1
LAYOUTS = ("wall", "no-fly-zones")
LANDING_TIME_MODES = ("free", "fixed")
SPEED_NM_S = 0.04
SEPARATION_NM = 0.25
SEPARATION_MARGIN_NM = 0.25
"""Initial 3-D distance of any two aircraft is at least the separation plus this."""
MAX_BEARING_DEG = 70.0
HEADING_DEVIATION_DEG = 40.0
GLIDE_SLOPE = 0.04
"""Altitude per distance to the runway (nm/nm, about 2.3 deg) before jitter."""
LANDING_GAP_S = (15.0, 30.0)
MIN_AIRSPACE = ((-3.0, 3.0), (0.0, 6.0), (0.0, 0.3))
ZONE_CLEARANCE_NM = 0.5
"""No-fly zones keep this far (ray distance) from every aircraft and from the approach fix."""
ATTEMPTS = 200


class TrafficError(ValueError):
    """The requested traffic cannot be generated (e.g. a fixed airspace too small for the stream)."""


@dataclass(frozen=True)
class TrafficSpec:
    aircraft: tuple[int, int]
    """Smallest and largest number of aircraft per scenario (drawn uniformly)."""
    seed: int = 0
    layout: str = "mixed"
    """wall, no-fly-zones or mixed (each scenario draws one)."""
    landing_times: str = "free"
    """free (no landing times in the file), fixed (a feasible-looking schedule) or mixed."""
    airspace_nm: tuple[float, float] | None = None
    """Fixed x and y extents (x centred on the runway, y from 0); None: grows with the stream."""

    def describe(self) -> str:
        n0, n1 = self.aircraft
        space = "auto" if self.airspace_nm is None else f"{self.airspace_nm[0]:g} {self.airspace_nm[1]:g}"
        return (f"--aircraft {n0 if n0 == n1 else f'{n0}-{n1}'} --seed {self.seed} --layout {self.layout} "
                f"--landing-times {self.landing_times} --airspace-nm {space}")


@dataclass(frozen=True)
class GeneratedScenario:
    file_name: str
    text: str
    scenario: Scenario


def _r(value: float, digits: int = 4) -> float:
    return float(round(float(value), digits))


@dataclass
class _Geometry:
    """The parts of one scenario being drawn (nm, deg)."""

    fix: np.ndarray
    """Approach fix (x, y): aircraft fly to it, then straight in along -y."""
    ahead_nm: float
    """Every aircraft starts at least this far beyond the fix (in y)."""
    wall: dict[str, Any] | None = None


class _Draw:
    """One scenario's random draws, in a fixed order."""

    def __init__(self, spec: TrafficSpec, index: int) -> None:
        self.spec, self.index = spec, index
        self.rng = np.random.default_rng([spec.seed, index])
        n0, n1 = spec.aircraft
        self.n = int(self.rng.integers(n0, n1 + 1))
        self.layout = spec.layout if spec.layout != "mixed" else LAYOUTS[int(self.rng.integers(2))]
        self.times_mode = (spec.landing_times if spec.landing_times != "mixed"
                           else LANDING_TIME_MODES[int(self.rng.integers(2))])

    def geometry(self) -> _Geometry:
        rng = self.rng
        if self.layout == "wall":
            wall_y, hole_x = rng.uniform(2.5, 3.5), rng.uniform(-0.5, 0.5)
            half_width, hole_z, half_height = rng.uniform(0.6, 1.1), rng.uniform(0.12, 0.18), rng.uniform(0.04, 0.06)
            wall = {"position": _r(wall_y, 3), "hole_x": (_r(hole_x - half_width, 3), _r(hole_x + half_width, 3)),
                    "hole_z": (_r(hole_z - half_height, 3), _r(hole_z + half_height, 3))}
            return _Geometry(np.array([hole_x, wall_y]), 1.5, wall)
        return _Geometry(np.array([0.0, rng.uniform(2.0, 3.0)]), 0.5)

    def aircraft(self, geo: _Geometry, airspace_xy: tuple[float, float] | None) -> list[dict[str, float]]:
        """Positions (x, y, z), headings and speeds of the stream; TrafficError if they do not fit."""
        rng = self.rng
        fix_y = float(geo.fix[1])
        path = fix_y + rng.uniform(2.0, 3.0)  # path length of the first aircraft to the runway
        placed: list[dict[str, float]] = []
        for _ in range(self.n):
            speed = SPEED_NM_S * rng.uniform(0.9, 1.1)
            for _try in range(ATTEMPTS):
                radius = path - fix_y
                limit = math.degrees(math.acos(min(1.0, geo.ahead_nm / radius)))
                bearing = float(rng.normal(0.0, 35.0))  # deg from the approach axis (+y), seen from the fix
                if abs(bearing) > min(MAX_BEARING_DEG, limit):
                    continue
                x, y = geo.fix + radius * np.array([math.sin(math.radians(bearing)), math.cos(math.radians(bearing))])
                z = max(0.08, GLIDE_SLOPE * math.hypot(x, y) + rng.uniform(-0.03, 0.03))
                if airspace_xy is not None and (abs(x) > airspace_xy[0] / 2 - 0.3 or y > airspace_xy[1] - 0.3):
                    continue
                p = np.array([x, y, z])
                if all(np.linalg.norm(p - q["p"]) >= SEPARATION_NM + SEPARATION_MARGIN_NM for q in placed):
                    to_fix = math.degrees(math.atan2(fix_y - y, geo.fix[0] - x))
                    heading = to_fix + rng.uniform(-HEADING_DEVIATION_DEG, HEADING_DEVIATION_DEG)
                    heading = (heading + 180.0) % 360.0 - 180.0
                    placed.append({"p": p, "heading": heading, "speed": speed})
                    break
            else:
                raise TrafficError(f"no room for aircraft {len(placed) + 1} of {self.n}")
            path += speed * rng.uniform(*LANDING_GAP_S)
        return placed

    def zones(self, geo: _Geometry, aircraft: list[dict[str, float]], airspace: np.ndarray) -> list[Superquadric]:
        """1-3 no-fly zones clear of the aircraft, the fix, each other and the final-approach corridor."""
        rng = self.rng
        count = int(rng.integers(1, 4))
        points = np.array([a["p"] for a in aircraft] + [[geo.fix[0], geo.fix[1], 0.15]])
        far_y = float(max(points[:, 1]))
        reach_x = float(max(np.abs(points[:, 0]).max(), 1.5))
        zmax = float(airspace[2, 1])
        zones: list[Superquadric] = []
        for k in range(count):
            for _try in range(ATTEMPTS):
                box = bool(rng.integers(2))
                a, b = rng.uniform(0.3, 0.9, size=2)
                cx, cy = rng.uniform(-reach_x, reach_x), rng.uniform(1.0, max(1.5, 0.8 * far_y))
                if box:
                    zone = Superquadric(f"zone-{k + 1}", (_r(cx, 3), _r(cy, 3), _r(zmax / 2, 3)),
                                        (_r(a, 3), _r(b, 3), _r(zmax, 3)), 50)
                else:
                    zone = Superquadric(f"zone-{k + 1}", (_r(cx, 3), _r(cy, 3), 0.0), (_r(a, 3), _r(b, 3),
                                                                                      _r(1.5 * zmax, 3)), 2)
                lo, hi = zone.bounding_box()[:2].T
                corridor_lo, corridor_hi = np.array([-0.6, -1.0]), np.array([0.6, geo.fix[1] + 0.5])
                if np.all(lo < corridor_hi) and np.all(hi > corridor_lo):
                    continue
                if np.any(lo < airspace[:2, 0] + 0.2) or np.any(hi > airspace[:2, 1] - 0.2):
                    continue
                if np.min(ray_clearance_nm(zone, points)) < ZONE_CLEARANCE_NM:
                    continue
                if any(_boxes_overlap(zone, other, 0.3) for other in zones):
                    continue
                zones.append(zone)
                break
        if not zones:
            raise TrafficError("no room for a no-fly zone")
        return zones


def _boxes_overlap(a: Superquadric, b: Superquadric, gap: float) -> bool:
    box_a, box_b = a.bounding_box()[:2], b.bounding_box()[:2]
    return bool(np.all(box_a[:, 0] - gap < box_b[:, 1]) and np.all(box_b[:, 0] - gap < box_a[:, 1]))


def _ceil(value: float, step: float) -> float:
    return _r(math.ceil(value / step - 1e-9) * step, 3)


def _airspace(aircraft: list[dict[str, float]], fixed_xy: tuple[float, float] | None) -> np.ndarray:
    p = np.array([a["p"] for a in aircraft])
    z_top = max(MIN_AIRSPACE[2][1], _ceil(float(p[:, 2].max()) + 0.05, 0.1))
    if fixed_xy is not None:
        half, top = fixed_xy[0] / 2.0, fixed_xy[1]
    else:
        half = max(MIN_AIRSPACE[0][1], _ceil(float(np.abs(p[:, 0]).max()) + 1.0, 0.5))
        top = max(MIN_AIRSPACE[1][1], _ceil(float(p[:, 1].max()) + 1.0, 0.5))
    return np.array([[-half, half], [0.0, top], [0.0, z_top]])


def fixed_schedule(scenario: Scenario, rng: np.random.Generator) -> dict[str, float]:
    """Landing times: by earliest time with some adjacent swaps; each >= its earliest + 5-25 s slack and
    >= the previous landing + the minimum spacing + 1-8 s."""
    from mal_planner.initializer.timing import earliest_landing_times

    earliest = earliest_landing_times(scenario)
    order = sorted(earliest, key=lambda cs: (earliest[cs], cs))
    i = 0
    while i < len(order) - 1:
        if rng.random() < 0.3:
            order[i], order[i + 1] = order[i + 1], order[i]
            i += 1
        i += 1
    times: dict[str, float] = {}
    previous = -math.inf
    for cs in order:
        t = max(earliest[cs] + rng.uniform(5.0, 25.0), previous + scenario.landing_spacing_s + rng.uniform(1.0, 8.0))
        times[cs] = previous = _ceil(t, 0.1)
    return times


def file_name(index: int, n: int, layout: str) -> str:
    return f"traffic-{index:04d}-n{n}-{layout}.yaml"


def _document(name: str, aircraft: list[dict[str, float]], airspace: np.ndarray, geo: _Geometry,
              zones: list[Superquadric], landing: dict[str, float] | None) -> dict[str, Any]:
    entries = []
    for i, a in enumerate(aircraft):
        cs = f"T{i + 1:02d}"
        entry: dict[str, Any] = {"callsign": cs, "position": [_r(v) for v in a["p"]], "flight_path_angle_deg": 0.0,
                                 "heading_deg": _r(a["heading"], 1), "speed": _r(a["speed"], 5)}
        if landing is not None:
            entry["landing_time"] = landing[cs]
        entries.append(entry)
    obstacles: list[dict[str, Any]] = []
    if geo.wall is not None:
        obstacles.append({"type": "wall_with_hole", "name": "wall", "axis": "y", "position": geo.wall["position"],
                          "thickness": 0.001,
                          "span": {"x": [_r(v) for v in airspace[0]], "z": [_r(v) for v in airspace[2]]},
                          "hole": {"x": list(geo.wall["hole_x"]), "z": list(geo.wall["hole_z"])}, "p": 50})
    for zone in zones:
        obstacles.append({"type": "superquadric", "name": zone.name, "center": list(zone.center),
                          "semi_axes": list(zone.semi_axes), "p": zone.p})
    kind = "wall with a hole" if geo.wall else "no-fly zones"
    return {"name": name, "description": f"{len(aircraft)} arriving aircraft ({kind})",
            "gravity": 0.0052952,
            "runway": {"position": [0.0, 0.0, 0.0], "flight_path_angle_deg": 0.0, "heading_deg": -90.0},
            "airspace": {k: [_r(v) for v in airspace[i]] for i, k in enumerate("xyz")},
            "aircraft": entries, "obstacles": obstacles,
            "separation": {"distance_nm": SEPARATION_NM, "landing_spacing_s": 15.0, "max_landing_spacing_s": 30.0},
            "limits": {"bank_angle_deg": 45.0, "n_h": [-2.0, 2.0], "n_v": [0.0, 2.0]}}


def _text(document: dict[str, Any], spec: TrafficSpec, index: int, draw: _Draw) -> str:
    header = (f"# Generated by mal-traffic {GENERATOR_VERSION} (mal-planner {version('mal-planner')}): "
              f"scenario {index}\n"
              f"# parameters: {spec.describe()}\n"
              f"# drawn: {draw.n} aircraft, layout {draw.layout}, landing times {draw.times_mode}; "
              f"rng numpy default_rng([{spec.seed}, {index}])\n")
    return header + yaml.safe_dump(document, sort_keys=False, default_flow_style=None, width=120)


def generate_one(spec: TrafficSpec, index: int) -> GeneratedScenario:
    """Scenario ``index`` of ``spec``, validated; TrafficError when no valid one is found in ATTEMPTS draws."""
    draw = _Draw(spec, index)
    name = file_name(index, draw.n, draw.layout)
    problem = ""
    for _attempt in range(ATTEMPTS):
        geo = draw.geometry()
        try:
            aircraft = draw.aircraft(geo, spec.airspace_nm)
            airspace = _airspace(aircraft, spec.airspace_nm)
            zones = draw.zones(geo, aircraft, airspace) if draw.layout == "no-fly-zones" else []
        except TrafficError as exc:
            problem = str(exc)
            continue
        document = _document(name.removesuffix(".yaml"), aircraft, airspace, geo, zones, None)
        try:
            scenario = parse_scenario(yaml.safe_load(_text(document, spec, index, draw)), name)
            if draw.times_mode == "fixed":
                document = _document(name.removesuffix(".yaml"), aircraft, airspace, geo, zones,
                                     fixed_schedule(scenario, draw.rng))
            text = _text(document, spec, index, draw)
            scenario = parse_scenario(yaml.safe_load(text), name)
        except ScenarioError as exc:
            problem = str(exc)
            continue
        return GeneratedScenario(name, text, scenario)
    raise TrafficError(f"scenario {index}: no valid {draw.n}-aircraft {draw.layout} traffic in {ATTEMPTS} draws "
                       f"(last problem: {problem})")


def generate(spec: TrafficSpec, count: int) -> list[GeneratedScenario]:
    return [generate_one(spec, i) for i in range(count)]
