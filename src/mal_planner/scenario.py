"""Scenario files (YAML): validated on load, converted to the planner's units (nm, s, rad).

The file gives angles in degrees; everything returned by :func:`load_scenario` is in radians. Any
problem is reported as a :class:`ScenarioError` whose message is one line naming the file, the field
and the reason.

A file is local (the default: the runway frame in nm, speeds in nm/s) or places its runway on the Earth
(``runway: {threshold: {lat, lon, elevation_ft}, course_deg}``); then aircraft may be given in lat/lon/ft
with true tracks and speeds in kt. :func:`localize` converts such a file to the local frame (the one place,
through :class:`mal_planner.geo.GeoFrame`) before anything else sees it; airspace, obstacles and gates
stay in the runway frame (nm) in both kinds of file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Discriminator, Field, Tag, ValidationError, field_validator, model_validator

from mal_planner.dynamics import DYNAMICS_MODELS, ControlLimits, DynamicsModel, make_dynamics
from mal_planner.geo.frame import GeoFrame
from mal_planner.obstacles import Gate, Superquadric, wall_with_hole
from mal_planner.sequencing.problem import SequencingOptions, Strategy
from mal_planner.sequencing.wake import WakeTableName
from mal_planner.sequencing.wake import categories as wake_categories
from mal_planner.units import ft_to_nm, kt_to_nm_per_s

AXIS_INDEX = {"x": 0, "y": 1, "z": 2}

GEODETIC_ROUND_OFF = 1e-9
"""Relative to the airspace's largest extent: how near its boundary a converted geodetic position is taken to be
on it (the conversion's own round-off is about 1e-12 of the distance from the threshold)."""


class ScenarioError(ValueError):
    """A scenario that cannot be used; ``str()`` is a single line: ``file: field: reason``."""

    def __init__(self, source: str, field: str, reason: str) -> None:
        self.source, self.field, self.reason = source, field, reason
        super().__init__(f"{source}: {field}: {reason}" if field else f"{source}: {reason}")


Vec3 = tuple[float, float, float]
Interval = tuple[float, float]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _check_interval(value: Interval) -> Interval:
    if not value[0] < value[1]:
        raise ValueError(f"lower bound {value[0]} must be below upper bound {value[1]}")
    return value


class LimitsConfig(_Strict):
    bank_angle_deg: float = Field(45.0, gt=0.0, lt=90.0)
    n_h: Interval = (-2.0, 2.0)
    n_v: Interval = (0.0, 2.0)

    _intervals = field_validator("n_h", "n_v")(_check_interval)

    @field_validator("n_v")
    @classmethod
    def _nonnegative_nv(cls, value: Interval) -> Interval:
        if value[0] < 0.0:
            raise ValueError("the vertical load factor must be >= 0 (the bank angle is atan(n_h/n_v))")
        return value

    def to_limits(self) -> ControlLimits:
        return ControlLimits(n_h=self.n_h, n_v=self.n_v, bank_angle_max=float(np.radians(self.bank_angle_deg)))


class _AircraftCommon(_Strict):
    callsign: str = Field(min_length=1, max_length=16, pattern=r"^[A-Za-z0-9_]+$")
    flight_path_angle_deg: float = Field(ge=-30.0, le=30.0)
    model: str = "point_mass"
    wake_category: Literal["L", "M", "H", "J", "A", "B", "C", "D", "E", "F"] | None = None
    """ICAO (J, H, M, L) or RECAT-EU (A-F) wake-turbulence category; required by ``separation.wake``."""
    landing_time: float | None = Field(None, gt=0.0)
    """Fixed landing time in s (as in the thesis); omitted: taken from the sequencer."""
    target_time: float | None = Field(None, gt=0.0)
    """Target landing time in s for the sequencer; omitted: the earliest it can land (a free aircraft)."""
    latest_time: float | None = Field(None, gt=0.0)
    """Latest landing time in s (e.g. its fuel); omitted: none."""
    cost_early: float = Field(0.0, ge=0.0)
    """Cost per second of landing before the target (Beasley's g); 0: early is free."""
    cost_late: float = Field(1.0, ge=0.0)
    """Cost per second of landing after the target (Beasley's h); 1: delay in seconds."""
    limits: LimitsConfig | None = None
    """Per-aircraft limits; omitted: the scenario's limits."""

    @field_validator("model")
    @classmethod
    def _known_model(cls, value: str) -> str:
        if value not in DYNAMICS_MODELS:
            raise ValueError(f"unknown dynamics model {value!r} (known: {', '.join(sorted(DYNAMICS_MODELS))})")
        return value


class AircraftConfig(_AircraftCommon):
    """An aircraft in the local frame."""

    position: Vec3
    """Initial x, y, z in nm."""
    heading_deg: float = Field(ge=-360.0, le=360.0)
    speed: float = Field(gt=0.0, le=1.0)
    """Constant airspeed in nm/s."""


class GeoAircraftConfig(_AircraftCommon):
    """An aircraft on the Earth (needs a geodetic runway); the flight-path angle is the velocity's, as in the local
    format."""

    lat: float = Field(ge=-90.0, le=90.0)
    lon: float = Field(ge=-180.0, le=180.0)
    alt_ft: float = Field(ge=-1500.0, le=60000.0)
    """Altitude in ft, in the datum of the runway's ``elevation_ft``."""
    track_deg: float = Field(ge=-360.0, le=360.0)
    """True track, clockwise from true north at the aircraft."""
    speed_kt: float = Field(gt=0.0, le=3600.0)
    """Constant true airspeed in knots (no wind: also the ground speed)."""

    def to_local(self, frame: GeoFrame) -> AircraftConfig:
        heading, gamma = frame.direction_to_local(self.lat, self.lon, self.track_deg, self.flight_path_angle_deg)
        common = self.model_dump(include=set(_AircraftCommon.model_fields))
        return AircraftConfig(**{**common, "flight_path_angle_deg": math.degrees(gamma)},
                              position=tuple(float(v) for v in frame.to_local(self.lat, self.lon, self.alt_ft)),
                              heading_deg=math.degrees(heading), speed=kt_to_nm_per_s(self.speed_kt))


def _is_geodetic_aircraft(value: Any) -> str:
    geo = isinstance(value, dict) and bool({"lat", "lon", "alt_ft", "track_deg", "speed_kt"} & set(value))
    return "geodetic" if geo or isinstance(value, GeoAircraftConfig) else "local"


AnyAircraftConfig = Annotated[Annotated[AircraftConfig, Tag("local")] | Annotated[GeoAircraftConfig, Tag("geodetic")],
                              Discriminator(_is_geodetic_aircraft)]


class RunwayConfig(_Strict):
    """The runway in the local frame."""

    position: Vec3 = (0.0, 0.0, 0.0)
    flight_path_angle_deg: float = Field(0.0, ge=-10.0, le=10.0)
    heading_deg: float = -90.0


class ThresholdConfig(_Strict):
    lat: float = Field(ge=-90.0, le=90.0)
    lon: float = Field(ge=-180.0, le=180.0)
    elevation_ft: float = Field(0.0, ge=-1500.0, le=20000.0)
    """Height of the threshold in ft (the datum of the aircraft's ``alt_ft``)."""


class GeoRunwayConfig(_Strict):
    """The runway on the Earth: the origin of the local frame, which turns the landing direction to -y."""

    threshold: ThresholdConfig
    course_deg: float = Field(ge=0.0, lt=360.0)
    """True course of the landing direction, clockwise from true north."""
    flight_path_angle_deg: float = Field(0.0, ge=-10.0, le=10.0)

    def frame(self) -> GeoFrame:
        t = self.threshold
        return GeoFrame(lat_deg=t.lat, lon_deg=t.lon, elevation_ft=t.elevation_ft, course_deg=self.course_deg)


def _is_geodetic_runway(value: Any) -> str:
    geo = (isinstance(value, dict) and "threshold" in value) or isinstance(value, GeoRunwayConfig)
    return "geodetic" if geo else "local"


AnyRunwayConfig = Annotated[Annotated[RunwayConfig, Tag("local")] | Annotated[GeoRunwayConfig, Tag("geodetic")],
                            Discriminator(_is_geodetic_runway)]


class AirspaceConfig(_Strict):
    x: Interval
    y: Interval
    z: Interval

    _intervals = field_validator("x", "y", "z")(_check_interval)


def _is_even(value: int) -> int:
    if value < 2 or value % 2:
        raise ValueError(f"the exponent p must be an even integer >= 2, got {value}")
    return value


class SuperquadricConfig(_Strict):
    type: Literal["superquadric"] = "superquadric"
    name: str
    center: Vec3
    semi_axes: Vec3
    p: int = 2

    _even = field_validator("p")(_is_even)

    @field_validator("semi_axes")
    @classmethod
    def _positive(cls, value: Vec3) -> Vec3:
        if min(value) <= 0.0:
            raise ValueError("semi-axes must all be > 0")
        return value


class GateConfig(_Strict):
    name: str = "gate"
    axis: Literal["x", "y", "z"] = "y"
    position: float
    direction: Literal[-1, 1] = -1
    """Sign of the travel along ``axis`` when passing the gate."""
    bounds: dict[Literal["x", "y", "z"], Interval]
    """The hole's bounds along the two other axes."""
    flight_path_angle_deg: float = 0.0
    heading_deg: float = -90.0

    @model_validator(mode="after")
    def _two_other_axes(self) -> GateConfig:
        expected = set("xyz") - {self.axis}
        if set(self.bounds) != expected:
            raise ValueError(f"bounds must give exactly the axes {sorted(expected)}")
        for key, value in self.bounds.items():
            if not value[0] < value[1]:
                raise ValueError(f"bounds.{key}: lower bound must be below upper bound")
        return self

    def to_gate(self) -> Gate:
        axis = AXIS_INDEX[self.axis]
        others = [a for a in "xyz" if a != self.axis]
        return Gate(
            name=self.name,
            axis=axis,
            position=self.position,
            direction=self.direction,
            bounds=(tuple(self.bounds[others[0]]), tuple(self.bounds[others[1]])),
            flight_path_angle=float(np.radians(self.flight_path_angle_deg)),
            heading=float(np.radians(self.heading_deg)),
        )


class WallConfig(_Strict):
    """A thin wall with a rectangular hole; expands to four superquadrics and a gate."""

    type: Literal["wall_with_hole"]
    name: str = "wall"
    axis: Literal["x", "y", "z"] = "y"
    position: float
    """Coordinate of the wall's gate face (the thesis: y = 3, the wall spans [3, 3.001])."""
    thickness: float = Field(gt=0.0)
    span: dict[Literal["x", "y", "z"], Interval]
    hole: dict[Literal["x", "y", "z"], Interval]
    p: int = 50
    direction: Literal[-1, 1] = -1
    flight_path_angle_deg: float = 0.0
    heading_deg: float = -90.0

    _even = field_validator("p")(_is_even)

    @model_validator(mode="after")
    def _consistent(self) -> WallConfig:
        expected = set("xyz") - {self.axis}
        for label, value in (("span", self.span), ("hole", self.hole)):
            if set(value) != expected:
                raise ValueError(f"{label} must give exactly the axes {sorted(expected)}")
        for a in sorted(expected):
            (s0, s1), (h0, h1) = self.span[a], self.hole[a]
            if not s0 < h0 < h1 < s1:
                raise ValueError(f"hole.{a} {list(self.hole[a])} must lie strictly inside span.{a} {[s0, s1]}")
        return self

    def expand(self) -> tuple[list[Superquadric], GateConfig]:
        others = [a for a in "xyz" if a != self.axis]
        pieces = wall_with_hole(
            self.name,
            AXIS_INDEX[self.axis],
            self.position,
            self.thickness,
            (self.span[others[0]], self.span[others[1]]),
            (self.hole[others[0]], self.hole[others[1]]),
            self.p,
        )
        gate = GateConfig(
            name=f"{self.name}-hole",
            axis=self.axis,
            position=self.position,
            direction=self.direction,
            bounds=dict(self.hole),
            flight_path_angle_deg=self.flight_path_angle_deg,
            heading_deg=self.heading_deg,
        )
        return pieces, gate


ObstacleConfig = Annotated[SuperquadricConfig | WallConfig, Field(discriminator="type")]


class SeparationConfig(_Strict):
    distance_nm: float = Field(0.25, gt=0.0)
    """Minimum distance between any two airborne aircraft (a sphere, as in the thesis); with ``vertical_ft``, the
    horizontal minimum."""
    horizontal_nm: float | None = Field(None, gt=0.0)
    """The horizontal minimum of an ATC protected zone (another name for ``distance_nm``; give one of them)."""
    vertical_ft: float | None = Field(None, gt=0.0)
    """The vertical minimum (ICAO: 1000 ft): two aircraft are separated when they are ``distance_nm`` apart
    horizontally OR this far apart vertically (a cylinder, as ATC and BlueSky count it). None: the sphere."""
    landing_spacing_s: float = Field(15.0, gt=0.0)
    """Minimum time between successive landings."""
    max_landing_spacing_s: float = Field(30.0, gt=0.0)
    """Largest time between successive landings the sequencer aims for."""
    wake: WakeTableName = "none"
    """Wake-turbulence distance minima between successive landings (:mod:`mal_planner.sequencing.wake`):
    icao (Doc 4444, categories J/H/M/L), recat-eu (A-F) or none (``landing_spacing_s`` for every pair)."""

    @model_validator(mode="before")
    @classmethod
    def _horizontal(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("horizontal_nm") is not None:
            if "distance_nm" in data:
                raise ValueError("give distance_nm or horizontal_nm, not both")
            data = {**data, "distance_nm": data["horizontal_nm"]}
        return data

    @model_validator(mode="after")
    def _ordered(self) -> SeparationConfig:
        if self.max_landing_spacing_s <= self.landing_spacing_s:
            raise ValueError("max_landing_spacing_s must exceed landing_spacing_s")
        return self


class WindConfig(_Strict):
    """A constant horizontal wind: the air mass's velocity over the ground (0: still air, as in the thesis).

    Give ``speed_kt`` with ``from_deg`` (the direction it blows from, clockwise from true north, as METARs do;
    needs a runway on the Earth) or ``from_heading_deg`` (the local heading it blows from, in the convention of
    the aircraft's ``heading_deg``). The planner's aircraft then fly at their airspeed through the moving air:
    their ground speed is airspeed + wind, and gates and the runway are passed on their ground track, crabbed.
    """

    speed_kt: float = Field(ge=0.0, le=200.0)
    from_deg: float | None = Field(None, ge=0.0, le=360.0)
    from_heading_deg: float | None = Field(None, ge=-360.0, le=360.0)

    @model_validator(mode="after")
    def _one_direction(self) -> WindConfig:
        if (self.from_deg is None) == (self.from_heading_deg is None):
            raise ValueError("give the wind's direction as from_deg (true, needs a runway on the Earth) or "
                             "from_heading_deg (local), exactly one of them")
        return self

    def velocity(self, frame: GeoFrame | None) -> tuple[float, float]:
        """(w_x, w_y) in nm/s in the local frame."""
        speed = kt_to_nm_per_s(self.speed_kt)
        if self.from_heading_deg is not None:
            towards = math.radians(self.from_heading_deg) + math.pi
        else:
            assert frame is not None
            # blowing towards from_deg + 180 (true); the local heading of that track at the threshold
            towards = frame.heading_of_true_track(self.from_deg + 180.0)
        return speed * math.cos(towards), speed * math.sin(towards)


class SequencingConfig(_Strict):
    """How the landing order and the free landing times are decided (:mod:`mal_planner.sequencing`)."""

    strategy: Strategy = "fcfs"
    """fcfs: first come (turn-aware earliest landing), first served; optimal: the MILP that minimises the total
    delay against the earliest landing times."""
    max_shift: int | None = Field(None, ge=0)
    """optimal: no aircraft more than this many places from its first-come position (None: any order)."""
    time_limit_s: float = Field(10.0, gt=0.0)
    """optimal: the MILP returns the best order found when this runs out."""

    def options(self) -> SequencingOptions:
        return SequencingOptions(strategy=self.strategy, max_shift=self.max_shift, time_limit_s=self.time_limit_s)


class ScenarioConfig(_Strict):
    """The YAML file's schema."""

    name: str
    description: str = ""
    gravity: float = Field(0.0052952, gt=0.0)
    """g in nm/s^2."""
    runway: AnyRunwayConfig = RunwayConfig()
    airspace: AirspaceConfig
    aircraft: list[AnyAircraftConfig] = Field(min_length=1)
    obstacles: list[ObstacleConfig] = []
    gates: list[GateConfig] = []
    separation: SeparationConfig = SeparationConfig()
    sequencing: SequencingConfig = SequencingConfig()
    limits: LimitsConfig = LimitsConfig()
    wind: WindConfig | None = None

    @model_validator(mode="after")
    def _wind_direction_needs_north(self) -> ScenarioConfig:
        if self.wind is not None and self.wind.from_deg is not None and not isinstance(self.runway, GeoRunwayConfig):
            raise ValueError("wind.from_deg: a true wind direction needs the runway on the Earth (runway: {threshold: "
                             "..., course_deg}); in a local file give from_heading_deg")
        return self

    @model_validator(mode="after")
    def _unique_callsigns(self) -> ScenarioConfig:
        seen: set[str] = set()
        for i, ac in enumerate(self.aircraft):
            if ac.callsign in seen:
                raise ValueError(f"aircraft[{i}].callsign: duplicate callsign {ac.callsign!r}")
            seen.add(ac.callsign)
        return self

    @model_validator(mode="after")
    def _geodetic_needs_threshold(self) -> ScenarioConfig:
        if not isinstance(self.runway, GeoRunwayConfig):
            for i, ac in enumerate(self.aircraft):
                if isinstance(ac, GeoAircraftConfig):
                    raise ValueError(f"aircraft[{i}].lat: an aircraft in lat/lon needs the runway on the Earth "
                                     "(runway: {threshold: {lat, lon, elevation_ft}, course_deg})")
        return self

    @model_validator(mode="after")
    def _wake_categories(self) -> ScenarioConfig:
        known = wake_categories(self.separation.wake)
        for i, ac in enumerate(self.aircraft):
            if known and ac.wake_category not in known:
                raise ValueError(f"aircraft[{i}].wake_category: separation.wake {self.separation.wake} needs one of "
                                 f"{', '.join(known)}, got {ac.wake_category!r}")
        return self


@dataclass(frozen=True)
class Aircraft:
    """One aircraft in planner units: state0 = (x, y, z, gamma, heading) in nm and rad."""

    callsign: str
    state0: np.ndarray
    dynamics: DynamicsModel
    limits: ControlLimits
    wake_category: str | None = None
    landing_time: float | None = None
    target_time: float | None = None
    """The sequencer's target landing time (s; None: its earliest); see :class:`_AircraftCommon`."""
    latest_time: float | None = None
    cost_early: float = 0.0
    cost_late: float = 1.0

    @property
    def speed(self) -> float:
        return self.dynamics.speed

    @property
    def position(self) -> np.ndarray:
        return self.state0[:3]

    def heading_for_track(self, track: float, gamma: float) -> float:
        """The state (air-relative) heading that flies the ground track ``track`` at the flight-path angle ``gamma``
        (rad): the track itself in still air, crabbed into the wind otherwise. Gates and the runway give tracks."""
        if not self.dynamics.has_wind:
            return track
        return float(self.dynamics.heading_for_track(track, gamma))


@dataclass(frozen=True)
class Scenario:
    """A validated scenario in planner units (nm, s, rad)."""

    name: str
    description: str
    aircraft: tuple[Aircraft, ...]
    runway_state: np.ndarray
    """(x, y, z, gamma, heading) at touchdown; the heading is the runway's course, a ground track (see
    :meth:`runway_heading`)."""
    airspace: np.ndarray
    """(3, 2) array of [min, max] per axis."""
    obstacles: tuple[Superquadric, ...]
    gates: tuple[Gate, ...]
    separation_nm: float
    """The minimum distance (sphere), or the horizontal minimum when :attr:`vertical_separation_nm` is set."""
    landing_spacing_s: float
    max_landing_spacing_s: float
    gravity: float
    config: ScenarioConfig
    """The file's configuration in the local frame (a geodetic file's converted by :func:`localize`)."""
    source: str = "<scenario>"
    vertical_separation_nm: float | None = None
    """The vertical minimum of a cylindrical protected zone (separated: horizontally OR vertically); None: sphere."""
    geo_frame: GeoFrame | None = None
    """Where the local frame lies on the Earth, for a scenario whose runway has a threshold; None: local only."""
    wake: str = "none"
    """The wake-turbulence table between successive landings (``separation.wake``)."""
    sequencing: SequencingOptions = SequencingOptions()
    """How the order and the free landing times are decided (``sequencing:``)."""
    wind: tuple[float, float] = (0.0, 0.0)
    """The constant wind (w_x, w_y) in nm/s in the local frame (``wind:``); every aircraft's model carries it."""

    @property
    def separation_radius_nm(self) -> float:
        """Radius of the smallest sphere holding the protected zone: farther apart than this is separated."""
        return math.hypot(self.separation_nm, self.vertical_separation_nm or 0.0)

    def runway_heading(self, aircraft: Aircraft) -> float:
        """The state heading of ``aircraft`` at touchdown: the runway's course as its ground track (crabbed)."""
        return aircraft.heading_for_track(float(self.runway_state[4]), float(self.runway_state[3]))

    def final_ground_speed(self, aircraft: Aircraft) -> float:
        """Ground speed (nm/s) of ``aircraft`` on the final approach (the runway's course and flight-path angle):
        its airspeed in still air, else the wind triangle's (what a distance on final takes in time)."""
        if not aircraft.dynamics.has_wind:
            return aircraft.speed
        gamma, track = float(self.runway_state[3]), float(self.runway_state[4])
        return math.hypot(float(aircraft.dynamics.ground_speed_along(track, gamma)), aircraft.speed * math.sin(gamma))

    def with_wind(self, wind: tuple[float, float]) -> Scenario:
        """This scenario in another constant wind (w_x, w_y) [nm/s]: every aircraft's model carries it. The caller
        checks that it is below every airspeed (:func:`wind_error`)."""
        wx, wy = float(wind[0]), float(wind[1])
        aircraft = tuple(replace(a, dynamics=a.dynamics.with_wind(wx, wy)) for a in self.aircraft)
        return replace(self, aircraft=aircraft, wind=(wx, wy))

    def aircraft_by_callsign(self, callsign: str) -> Aircraft:
        for ac in self.aircraft:
            if ac.callsign == callsign:
                return ac
        raise KeyError(callsign)

    def in_airspace(self, points: np.ndarray, tol: float = 0.0) -> np.ndarray:
        pts = np.asarray(points, dtype=float)
        return np.all((pts >= self.airspace[:, 0] - tol) & (pts <= self.airspace[:, 1] + tol), axis=-1)

    def collides(self, points: np.ndarray) -> np.ndarray:
        """Exact containment test against every obstacle (True = inside some obstacle)."""
        pts = np.asarray(points, dtype=float)
        hit = np.zeros(pts.shape[:-1], dtype=bool)
        for ob in self.obstacles:
            hit |= ob.contains(pts)
        return hit

    def with_initial_states(self, states: dict[str, np.ndarray]) -> Scenario:
        """A copy with some aircraft's initial states replaced (e.g. from radar); others unchanged."""
        new = tuple(replace(a, state0=np.asarray(states[a.callsign], float)) if a.callsign in states else a
                    for a in self.aircraft)
        return replace(self, aircraft=new)


def _format_location(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif part in ("superquadric", "wall_with_hole", "local", "geodetic"):
            continue  # pydantic's discriminator tag, not a field of the file
        else:
            out += f".{part}" if out else str(part)
    return out


def localize(config: ScenarioConfig) -> tuple[ScenarioConfig, GeoFrame | None]:
    """The config in the local frame and the runway's frame on the Earth (None for a local file).

    The one place where geodetic inputs become local: the runway's threshold is the origin, its landing
    direction the heading -90 deg; aircraft given in lat/lon/ft/kt are converted by :class:`GeoFrame`.
    """
    if not isinstance(config.runway, GeoRunwayConfig):
        return config, None
    frame = config.runway.frame()
    runway = RunwayConfig(position=(0.0, 0.0, 0.0), flight_path_angle_deg=config.runway.flight_path_angle_deg,
                          heading_deg=-90.0)
    airspace = np.array([config.airspace.x, config.airspace.y, config.airspace.z], dtype=float)
    # A position given on the airspace's boundary converts to within the conversion's round-off of it (about
    # 1e-12 of its distance from the threshold): put it back on the boundary, so the file means what it says.
    snap = GEODETIC_ROUND_OFF * float(np.max(airspace[:, 1] - airspace[:, 0]))
    aircraft = []
    for ac in config.aircraft:
        if isinstance(ac, GeoAircraftConfig):
            ac = ac.to_local(frame)
            p = np.array(ac.position)
            near = (np.abs(p - airspace[:, 0]) <= snap) | (np.abs(p - airspace[:, 1]) <= snap)
            p[near] = np.clip(p, airspace[:, 0], airspace[:, 1])[near]
            ac = ac.model_copy(update={"position": tuple(float(v) for v in p)})
        aircraft.append(ac)
    return config.model_copy(update={"runway": runway, "aircraft": aircraft}), frame


def build_scenario(config: ScenarioConfig, source: str = "<scenario>") -> Scenario:
    """Convert a validated config to planner units and check the geometry (raises ScenarioError)."""
    given = config
    config, frame = localize(config)
    obstacles: list[Superquadric] = []
    gates = [g.to_gate() for g in config.gates]
    for spec in config.obstacles:
        if isinstance(spec, WallConfig):
            pieces, gate = spec.expand()
            obstacles.extend(pieces)
            gates.append(gate.to_gate())
        else:
            obstacles.append(Superquadric(spec.name, spec.center, spec.semi_axes, spec.p))
    airspace = np.array([config.airspace.x, config.airspace.y, config.airspace.z], dtype=float)
    wind = (0.0, 0.0) if config.wind is None else config.wind.velocity(frame)
    aircraft = []
    for i, ac in enumerate(config.aircraft):
        state0 = np.array([*ac.position, np.radians(ac.flight_path_angle_deg), np.radians(ac.heading_deg)])
        dyn = make_dynamics(ac.model, ac.speed, gravity=config.gravity, wind_x=wind[0], wind_y=wind[1])
        if math.hypot(*wind) >= ac.speed * math.cos(state0[3]):
            raise ScenarioError(source, "wind.speed_kt", f"{config.wind.speed_kt:g} kt is not below aircraft[{i}] "
                                f"{ac.callsign}'s airspeed: it could not make way against it")
        limits = ac.limits.to_limits() if ac.limits else (
            config.limits.to_limits() if "limits" in config.model_fields_set else dyn.default_limits)
        aircraft.append(Aircraft(ac.callsign, state0, dyn, limits, ac.wake_category, ac.landing_time,
                                 ac.target_time, ac.latest_time, ac.cost_early, ac.cost_late))
        where, what = f"aircraft[{i}].position", str(list(ac.position))
        if isinstance(geo := given.aircraft[i], GeoAircraftConfig):
            where = f"aircraft[{i}].lat/lon/alt_ft"
            what = (f"lat {geo.lat}, lon {geo.lon}, alt {geo.alt_ft} ft (local "
                    f"{[round(float(v), 3) for v in state0[:3]]} nm)")
        if not np.all((state0[:3] >= airspace[:, 0]) & (state0[:3] <= airspace[:, 1])):
            raise ScenarioError(source, where, f"{what} is outside the airspace")
        for ob in obstacles:
            if ob.contains(state0[:3]):
                raise ScenarioError(source, where, f"{what} is inside obstacle {ob.name!r}")
    runway = np.array([*config.runway.position, np.radians(config.runway.flight_path_angle_deg),
                       np.radians(config.runway.heading_deg)])
    if not np.all((runway[:3] >= airspace[:, 0]) & (runway[:3] <= airspace[:, 1])):
        raise ScenarioError(source, "runway.position", "is outside the airspace")
    return Scenario(
        name=config.name,
        description=config.description,
        aircraft=tuple(aircraft),
        runway_state=runway,
        airspace=airspace,
        obstacles=tuple(obstacles),
        gates=tuple(gates),
        separation_nm=config.separation.distance_nm,
        vertical_separation_nm=None if (ft := config.separation.vertical_ft) is None else ft_to_nm(ft),
        landing_spacing_s=config.separation.landing_spacing_s,
        max_landing_spacing_s=config.separation.max_landing_spacing_s,
        wake=config.separation.wake,
        sequencing=config.sequencing.options(),
        gravity=config.gravity,
        config=config,
        source=source,
        geo_frame=frame,
        wind=wind,
    )


def parse_scenario(data: Any, source: str = "<scenario>") -> Scenario:
    """Validate an already-parsed mapping (e.g. from YAML) and build the scenario."""
    if not isinstance(data, dict):
        raise ScenarioError(source, "", "the top level must be a mapping")
    try:
        config = ScenarioConfig.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        msg = err["msg"].removeprefix("Value error, ")
        raise ScenarioError(source, _format_location(err["loc"]), msg) from None
    return build_scenario(config, source)


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario YAML file."""
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(source, "", f"cannot read file ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise ScenarioError(source, "", f"not a text (UTF-8) file: byte {exc.start} is 0x{exc.object[exc.start]:02x}"
                            ) from None
    return scenario_from_text(text, source)


def scenario_from_text(text: str, source: str = "<scenario>") -> Scenario:
    """Validate a scenario file's text (``source`` names it in errors), as :func:`load_scenario` does."""
    if "\x00" in text:
        raise ScenarioError(source, "", "not a text file (it contains NUL bytes)")
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark is not None else ""
        raise ScenarioError(source, where, f"invalid YAML ({getattr(exc, 'problem', None) or exc})") from None
    return parse_scenario(data, source)
