"""Random arrival traffic: scenario files that look like arrival streams converging on one runway.

The runway is at the origin, heading -90 deg (aircraft land flying towards -y). Every scenario has an
approach fix on the far side of the runway: the hole of a wall (layout ``wall``) or a point on the
extended centre line (layout ``no-fly-zones``). Aircraft are strung along the arrival stream: the k-th
has a path length to the runway (to the fix, then straight in) a few tens of seconds of flight longer than
the (k-1)-th, at a bearing from the fix within some tens of degrees of the approach axis, beyond the fix;
altitudes rise with distance like a glide slope plus jitter; headings point at the fix +-40 deg. Positions
too close to another aircraft (3-D distance below the separation + margin) are redrawn. No-fly zones
(ellipsoids, p = 2, or boxes, p = 50, from the ground up) keep clear of the aircraft, of each other and of a
corridor around the final approach, so the runway stays reachable. Unless the user fixes it, the airspace
grows to hold the stream.

Two profiles give the numbers (:data:`PROFILES`): ``thesis`` (the thesis's 6-nm box, 0.25 nm separation,
45 deg bank; generator version 1's files, but for fixed landing times, which now keep the spacing each pair
needs on the common approach) and ``tma`` (a real terminal area: 45 nm across,
3 nm separation, 90 s landing spacing, 30 deg bank, half the files with a 3 deg glide path at the runway).

With ``wake="mixed"`` (``mal-traffic --wake mixed``) every aircraft gets an ICAO wake-turbulence category
(HEAVY, MEDIUM or LIGHT, shares :data:`WAKE_SHARES`), and the file asks for the ICAO wake minima
(``separation.wake: icao``) and the optimal sequence (``sequencing.strategy: optimal``); fixed landing times keep
the wake minimum of each consecutive pair (:func:`fixed_schedule` spaces by
:func:`~mal_planner.sequencing.schedule.landing_spacing`, which includes it). The categories come from their
own random stream, ``default_rng([seed, i, WAKE_STREAM])``, so the aircraft, obstacles and airspace are those
of the same seed without wake (fixed landing times differ: they keep the wake minima).

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
from mal_planner.dynamics import AirspeedModel
from mal_planner.obstacles import Superquadric
from mal_planner.performance import DEFAULT_TYPE
from mal_planner.profiles import PROFILES, THESIS, TrafficProfile
from mal_planner.scenario import Scenario, ScenarioError, parse_scenario

GENERATOR_VERSION = 2
LAYOUTS = ("wall", "no-fly-zones")
LANDING_TIME_MODES = ("free", "fixed")
ATTEMPTS = 200

FLYABLE_MODEL = AirspeedModel.name
"""``mal-traffic --flyable``: every aircraft flies the airspeed model, under the default procedures of
:data:`~mal_planner.performance.DEFAULT_TYPE` (the traffic names no types)."""
WAKE_MODES = ("none", "mixed")
"""``mal-traffic --wake``: none (no categories, no wake minima: the files as before) or mixed."""
WAKE_TABLE = "icao"
"""The wake table mixed traffic asks for (``separation.wake``; :mod:`mal_planner.wake`)."""
WAKE_SHARES: dict[str, float] = {"H": 0.20, "M": 0.65, "L": 0.15}
"""Share of each ICAO category among the arrivals of mixed traffic (fractions of the aircraft, summing to 1).
Assumed, not measured: mostly MEDIUM (A320/B737 class) with a fifth HEAVY, as at a large airport with long-haul
traffic; LIGHT is more common than at a hub (a few per cent there), so that every entry of the ICAO table
(H->H 4 nm, H->M 5, H->L 6, M->L 5) occurs often enough to matter. No SUPER (J)."""
WAKE_STREAM = 1
"""Third entry of the categories' seed ``[seed, index, WAKE_STREAM]``: a stream apart from the geometry's
``[seed, index]``."""
WAKE_STRATEGY = "optimal"
"""The sequencing strategy mixed traffic asks for (``sequencing.strategy``): the sequence of least total delay."""


SEPARATION_MARGIN_NM = THESIS.separation_margin_nm
"""The thesis profile's margin (kept for its users)."""


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
    """Fixed x and y extents (x centred on the runway, y from the profile's lower edge); None: grows."""
    profile: str = "thesis"
    """A key of :data:`PROFILES`."""
    wake: str = "none"
    """A value of :data:`WAKE_MODES`: none, or mixed (categories drawn by :data:`WAKE_SHARES`)."""
    flyable: bool = False
    """Airliners: the airspeed model and the default arrival procedures (the same draws otherwise)."""

    @property
    def numbers(self) -> TrafficProfile:
        return PROFILES[self.profile]

    def describe(self) -> str:
        n0, n1 = self.aircraft
        space = "auto" if self.airspace_nm is None else f"{self.airspace_nm[0]:g} {self.airspace_nm[1]:g}"
        text = (f"--aircraft {n0 if n0 == n1 else f'{n0}-{n1}'} --seed {self.seed} --layout {self.layout} "
                f"--landing-times {self.landing_times} --airspace-nm {space}")
        text = text if self.profile == "thesis" else f"{text} --profile {self.profile}"
        text = text if self.wake == "none" else f"{text} --wake {self.wake}"
        return f"{text} --flyable" if self.flyable else text


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
        self.spec, self.index, self.profile = spec, index, spec.numbers
        self.rng = np.random.default_rng([spec.seed, index])
        n0, n1 = spec.aircraft
        self.n = int(self.rng.integers(n0, n1 + 1))
        self.layout = spec.layout if spec.layout != "mixed" else LAYOUTS[int(self.rng.integers(2))]
        self.times_mode = (spec.landing_times if spec.landing_times != "mixed"
                           else LANDING_TIME_MODES[int(self.rng.integers(2))])
        share = self.profile.glide_path_share  # drawn only where the profile has glide paths (thesis: as before)
        self.glide_deg = self.profile.glide_path_deg if share > 0.0 and self.rng.random() < share else 0.0
        self.wake = wake_categories(spec, index, self.n)

    def geometry(self) -> _Geometry:
        rng, pr = self.rng, self.profile
        if self.layout == "wall":
            wall_y, hole_x = rng.uniform(*pr.wall_fix_y_nm), rng.uniform(*pr.hole_x_nm)
            half_width, hole_z = rng.uniform(*pr.hole_half_width_nm), rng.uniform(*pr.hole_z_nm)
            half_height = rng.uniform(*pr.hole_half_height_nm)
            if self.glide_deg:  # the hole on the glide path: the gate is the final approach fix
                hole_z = wall_y * math.tan(math.radians(self.glide_deg))
            wall = {"position": _r(wall_y, 3), "hole_x": (_r(hole_x - half_width, 3), _r(hole_x + half_width, 3)),
                    "hole_z": (_r(hole_z - half_height, 3), _r(hole_z + half_height, 3))}
            return _Geometry(np.array([hole_x, wall_y]), pr.wall_ahead_nm, wall)
        return _Geometry(np.array([0.0, rng.uniform(*pr.fix_y_nm)]), pr.fix_ahead_nm)

    def aircraft(self, geo: _Geometry, airspace_xy: tuple[float, float] | None) -> list[dict[str, float]]:
        """Positions (x, y, z), headings and speeds of the stream; TrafficError if they do not fit."""
        rng, pr = self.rng, self.profile
        fix_y = float(geo.fix[1])
        path = fix_y + rng.uniform(*pr.first_beyond_fix_nm)  # path length of the first aircraft to the runway
        placed: list[dict[str, float]] = []
        for _ in range(self.n):
            speed = pr.speed_nm_s * rng.uniform(*pr.speed_spread)
            for _try in range(ATTEMPTS):
                radius = path - fix_y
                limit = math.degrees(math.acos(min(1.0, geo.ahead_nm / radius)))
                bearing = float(rng.normal(0.0, pr.bearing_sigma_deg))  # deg from the approach axis, seen from the fix
                if abs(bearing) > min(pr.max_bearing_deg, limit):
                    continue
                x, y = geo.fix + radius * np.array([math.sin(math.radians(bearing)), math.cos(math.radians(bearing))])
                z = max(pr.altitude_nm[0], pr.glide_slope * math.hypot(x, y)
                        + rng.uniform(-pr.altitude_jitter_nm, pr.altitude_jitter_nm))
                z = min(z, pr.altitude_nm[1])
                if airspace_xy is not None and (abs(x) > airspace_xy[0] / 2 - pr.edge_nm
                                                or y > airspace_xy[1] - pr.edge_nm):
                    continue
                p = np.array([x, y, z])
                if all(np.linalg.norm(p - q["p"]) >= pr.separation_nm + pr.separation_margin_nm for q in placed):
                    to_fix = math.degrees(math.atan2(fix_y - y, geo.fix[0] - x))
                    heading = to_fix + rng.uniform(-pr.heading_deviation_deg, pr.heading_deviation_deg)
                    heading = (heading + 180.0) % 360.0 - 180.0
                    placed.append({"p": p, "heading": heading, "speed": speed})
                    break
            else:
                raise TrafficError(f"no room for aircraft {len(placed) + 1} of {self.n}")
            path += speed * rng.uniform(*pr.landing_gap_s)
        return placed

    def zones(self, geo: _Geometry, aircraft: list[dict[str, float]], airspace: np.ndarray) -> list[Superquadric]:
        """No-fly zones clear of the aircraft, the fix, each other and the final-approach corridor."""
        rng, pr = self.rng, self.profile
        count = int(rng.integers(pr.zone_count[0], pr.zone_count[1] + 1))
        points = np.array([a["p"] for a in aircraft] + [[geo.fix[0], geo.fix[1], pr.fix_point_z_nm]])
        far_y = float(max(points[:, 1]))
        reach_x = float(max(np.abs(points[:, 0]).max(), pr.zone_reach_nm))
        zmax = float(airspace[2, 1])
        zones: list[Superquadric] = []
        y0, y1, y_share = pr.zone_y_nm
        for k in range(count):
            for _try in range(ATTEMPTS):
                box = bool(rng.integers(2))
                a, b = rng.uniform(*pr.zone_semi_axis_nm, size=2)
                cx, cy = rng.uniform(-reach_x, reach_x), rng.uniform(y0, max(y1, y_share * far_y))
                if box:
                    zone = Superquadric(f"zone-{k + 1}", (_r(cx, 3), _r(cy, 3), _r(zmax / 2, 3)),
                                        (_r(a, 3), _r(b, 3), _r(zmax, 3)), 50)
                else:
                    zone = Superquadric(f"zone-{k + 1}", (_r(cx, 3), _r(cy, 3), 0.0), (_r(a, 3), _r(b, 3),
                                                                                      _r(1.5 * zmax, 3)), 2)
                lo, hi = zone.bounding_box()[:2].T
                corridor_lo = np.array([-pr.corridor_half_width_nm, -pr.corridor_behind_runway_nm])
                corridor_hi = np.array([pr.corridor_half_width_nm, geo.fix[1] + pr.corridor_beyond_fix_nm])
                if np.all(lo < corridor_hi) and np.all(hi > corridor_lo):
                    continue
                if np.any(lo < airspace[:2, 0] + pr.zone_edge_nm) or np.any(hi > airspace[:2, 1] - pr.zone_edge_nm):
                    continue
                if np.min(ray_clearance_nm(zone, points)) < pr.zone_clearance_nm:
                    continue
                if any(_boxes_overlap(zone, other, pr.zone_gap_nm) for other in zones):
                    continue
                zones.append(zone)
                break
        if not zones:
            raise TrafficError("no room for a no-fly zone")
        return zones


def wake_categories(spec: TrafficSpec, index: int, n: int) -> tuple[str, ...]:
    """The wake category of each of scenario ``index``'s ``n`` aircraft (stream order; none without wake), drawn
    by :data:`WAKE_SHARES` from their own stream ``default_rng([seed, index, WAKE_STREAM])``."""
    if spec.wake == "none":
        return ()
    if spec.wake != "mixed":
        raise TrafficError(f"wake: expected one of {', '.join(WAKE_MODES)}, got {spec.wake!r}")
    rng = np.random.default_rng([spec.seed, index, WAKE_STREAM])
    names = list(WAKE_SHARES)
    return tuple(str(c) for c in rng.choice(names, size=n, p=[WAKE_SHARES[c] for c in names]))


def wake_mix_text(categories: tuple[str, ...]) -> str:
    """``"2 H, 5 M, 1 L"``: the count of each category, in the order of :data:`WAKE_SHARES`."""
    return ", ".join(f"{categories.count(c)} {c}" for c in WAKE_SHARES if c in categories)


def _boxes_overlap(a: Superquadric, b: Superquadric, gap: float) -> bool:
    box_a, box_b = a.bounding_box()[:2], b.bounding_box()[:2]
    return bool(np.all(box_a[:, 0] - gap < box_b[:, 1]) and np.all(box_b[:, 0] - gap < box_a[:, 1]))


def _ceil(value: float, step: float) -> float:
    return _r(math.ceil(value / step - 1e-9) * step, 3)


def _airspace(aircraft: list[dict[str, float]], fixed_xy: tuple[float, float] | None,
              pr: TrafficProfile) -> np.ndarray:
    p = np.array([a["p"] for a in aircraft])
    (x_lo, x_hi), (y_lo, y_hi), (z_lo, z_hi) = pr.min_airspace
    z_top = max(z_hi, _ceil(float(p[:, 2].max()) + 0.05, 0.1))
    if fixed_xy is not None:
        half, top = fixed_xy[0] / 2.0, fixed_xy[1]
    else:
        step, spare = pr.airspace_step_nm, pr.airspace_spare_nm
        half = max(x_hi, _ceil(float(np.abs(p[:, 0]).max()) + spare, step))
        top = max(y_hi, _ceil(float(p[:, 1].max()) + spare, step))
    return np.array([[-half, half], [y_lo, top], [z_lo, z_top]])


def fixed_schedule(scenario: Scenario, rng: np.random.Generator,
                   profile: TrafficProfile = THESIS) -> dict[str, float]:
    """Landing times: by earliest time with some adjacent swaps; each >= its earliest + the profile's slack and
    >= the previous landing + the spacing the pair needs (:func:`~mal_planner.sequencing.schedule.slot_in_order`)
    + a little, rounded up to 0.1 s."""
    from mal_planner.sequencing.schedule import slot_in_order
    from mal_planner.sequencing.timing import earliest_landing_times

    earliest = earliest_landing_times(scenario)
    order = sorted(earliest, key=lambda cs: (earliest[cs], cs))
    i = 0
    while i < len(order) - 1:
        if rng.random() < 0.3:
            order[i], order[i + 1] = order[i + 1], order[i]
            i += 1
        i += 1
    return slot_in_order(scenario, [scenario.aircraft_by_callsign(cs) for cs in order],
                         lambda ac: earliest[ac.callsign] + rng.uniform(*profile.fixed_slack_s),
                         extra=lambda: rng.uniform(*profile.fixed_spacing_extra_s),
                         rounding=lambda t: _ceil(t, 0.1))


def file_name(index: int, n: int, layout: str) -> str:
    return f"traffic-{index:04d}-n{n}-{layout}.yaml"


def _document(name: str, draw: _Draw, aircraft: list[dict[str, float]], airspace: np.ndarray, geo: _Geometry,
              zones: list[Superquadric], landing: dict[str, float] | None) -> dict[str, Any]:
    pr = draw.profile
    entries = []
    for i, a in enumerate(aircraft):
        cs = f"T{i + 1:02d}"
        entry: dict[str, Any] = {"callsign": cs, "position": [_r(v) for v in a["p"]], "flight_path_angle_deg": 0.0,
                                 "heading_deg": _r(a["heading"], 1), "speed": _r(a["speed"], 5)}
        if draw.wake:
            entry["wake_category"] = draw.wake[i]
        if draw.spec.flyable:
            entry["model"] = FLYABLE_MODEL
        if landing is not None:
            entry["landing_time"] = landing[cs]
        entries.append(entry)
    obstacles: list[dict[str, Any]] = []
    if geo.wall is not None:
        wall: dict[str, Any] = {
            "type": "wall_with_hole", "name": "wall", "axis": "y", "position": geo.wall["position"],
            "thickness": pr.wall_thickness_nm,
            "span": {"x": [_r(v) for v in airspace[0]], "z": [_r(v) for v in airspace[2]]},
            "hole": {"x": list(geo.wall["hole_x"]), "z": list(geo.wall["hole_z"])}, "p": 50}
        if draw.glide_deg:
            wall["flight_path_angle_deg"] = -draw.glide_deg
        obstacles.append(wall)
    for zone in zones:
        obstacles.append({"type": "superquadric", "name": zone.name, "center": list(zone.center),
                          "semi_axes": list(zone.semi_axes), "p": zone.p})
    kind = "wall with a hole" if geo.wall else "no-fly zones"
    glide = f", {draw.glide_deg:g} deg glide path" if draw.glide_deg else ""
    wake = f", wake {wake_mix_text(draw.wake)}" if draw.wake else ""
    separation: dict[str, Any] = {"distance_nm": pr.separation_nm, "landing_spacing_s": pr.landing_spacing_s,
                                  "max_landing_spacing_s": pr.max_landing_spacing_s}
    if draw.wake:
        separation["wake"] = WAKE_TABLE
    document: dict[str, Any] = {
        "name": name, "description": f"{len(aircraft)} arriving aircraft ({kind}{glide}{wake})",
        "gravity": 0.0052952,
        "runway": {"position": [0.0, 0.0, 0.0], "flight_path_angle_deg": -draw.glide_deg or 0.0, "heading_deg": -90.0},
        "airspace": {k: [_r(v) for v in airspace[i]] for i, k in enumerate("xyz")},
        "aircraft": entries, "obstacles": obstacles, "separation": separation,
        "limits": {"bank_angle_deg": pr.bank_angle_deg, "n_h": list(pr.n_h), "n_v": list(pr.n_v)}}
    if draw.wake:
        document["sequencing"] = {"strategy": WAKE_STRATEGY}
    if draw.spec.flyable:
        document["procedures"] = {"aircraft_type": DEFAULT_TYPE}
    return document


def _text(document: dict[str, Any], spec: TrafficSpec, index: int, draw: _Draw) -> str:
    header = (f"# Generated by mal-traffic {GENERATOR_VERSION} (mal-planner {version('mal-planner')}): "
              f"scenario {index}\n"
              f"# parameters: {spec.describe()}\n"
              f"# drawn: {draw.n} aircraft, layout {draw.layout}, landing times {draw.times_mode}"
              + (f", wake categories {' '.join(draw.wake)} (default_rng([{spec.seed}, {index}, {WAKE_STREAM}]))"
                 if draw.wake else "")
              + f"; rng numpy default_rng([{spec.seed}, {index}])\n")
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
            airspace = _airspace(aircraft, spec.airspace_nm, draw.profile)
            zones = draw.zones(geo, aircraft, airspace) if draw.layout == "no-fly-zones" else []
        except TrafficError as exc:
            problem = str(exc)
            continue
        document = _document(name.removesuffix(".yaml"), draw, aircraft, airspace, geo, zones, None)
        try:
            scenario = parse_scenario(yaml.safe_load(_text(document, spec, index, draw)), name)
            if draw.times_mode == "fixed":
                document = _document(name.removesuffix(".yaml"), draw, aircraft, airspace, geo, zones,
                                     fixed_schedule(scenario, draw.rng, draw.profile))
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
