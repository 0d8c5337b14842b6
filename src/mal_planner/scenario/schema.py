"""The scenario file's schema (pydantic): every field, its unit, its range and its checks.

Angles are in degrees, lengths in nm, speeds in nm/s (or kt and ft in a geodetic file, see
:class:`GeoAircraftConfig`); :mod:`mal_planner.scenario.loader` converts a validated file to planner units.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Discriminator, Field, Tag, field_validator, model_validator

from mal_planner.dynamics import DYNAMICS_MODELS, ControlLimits
from mal_planner.geodesy import GeoFrame
from mal_planner.scenario.obstacle_schema import GateConfig, ObstacleConfig
from mal_planner.scenario.procedures import ProceduresConfig
from mal_planner.scenario.quantities import Interval, Strict, Vec3, quantity
from mal_planner.scenario.sequencing import SequencingOptions, Strategy
from mal_planner.units import kt_to_nm_per_s
from mal_planner.wake import WakeTableName
from mal_planner.wake import categories as wake_categories

GEODETIC_ROUND_OFF = 1e-9
"""Relative to the airspace's largest extent: how near its boundary a converted geodetic position is taken to be
on it (the conversion's own round-off is about 1e-12 of the distance from the threshold)."""


def _check_interval(value: Interval) -> Interval:
    if not value[0] < value[1]:
        raise ValueError(f"lower bound {value[0]} must be below upper bound {value[1]}")
    return value


class LimitsConfig(Strict):
    bank_angle_deg: float = quantity("deg", 45.0, gt=0.0, lt=90.0)
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


class _AircraftCommon(Strict):
    callsign: str = Field(min_length=1, max_length=16, pattern=r"^[A-Za-z0-9_]+$")
    flight_path_angle_deg: float = quantity("deg", ge=-30.0, le=30.0)
    model: str = "point_mass"
    wake_category: Literal["L", "M", "H", "J", "A", "B", "C", "D", "E", "F"] | None = None
    """ICAO (J, H, M, L) or RECAT-EU (A-F) wake-turbulence category; required by ``separation.wake``."""
    aircraft_type: str | None = Field(None, pattern=r"^[A-Za-z0-9]{2,4}$")
    """ICAO type designator (e.g. A320, B738); its performance comes from OpenAP (:mod:`mal_planner.performance`).
    None: the ``procedures``' default type."""
    landing_time: float | None = quantity("s", None, gt=0.0)
    """Fixed landing time in s (as in the thesis); omitted: taken from the sequencer."""
    target_time: float | None = quantity("s", None, gt=0.0)
    """Target landing time in s for the sequencer; omitted: the earliest it can land (a free aircraft)."""
    latest_time: float | None = quantity("s", None, gt=0.0)
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

    position: Vec3 = quantity("nm")
    """Initial x, y, z in nm."""
    heading_deg: float = quantity("deg", ge=-360.0, le=360.0)
    speed: float = quantity("nm/s", gt=0.0, le=1.0)
    """Airspeed in nm/s: constant (the thesis's ``point_mass``), or the first (``point_mass_airspeed``)."""


class GeoAircraftConfig(_AircraftCommon):
    """An aircraft on the Earth (needs a geodetic runway); the flight-path angle is the velocity's, as in the local
    format."""

    lat: float = quantity("deg", ge=-90.0, le=90.0)
    lon: float = quantity("deg", ge=-180.0, le=180.0)
    alt_ft: float = quantity("ft", ge=-1500.0, le=60000.0)
    """Altitude in ft, in the datum of the runway's ``elevation_ft``."""
    track_deg: float = quantity("deg", ge=-360.0, le=360.0)
    """True track, clockwise from true north at the aircraft."""
    speed_kt: float = quantity("kt", gt=0.0, le=3600.0)
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


class RunwayConfig(Strict):
    """The runway in the local frame."""

    position: Vec3 = quantity("nm", (0.0, 0.0, 0.0))
    flight_path_angle_deg: float = quantity("deg", 0.0, ge=-10.0, le=10.0)
    heading_deg: float = quantity("deg", -90.0)


class ThresholdConfig(Strict):
    lat: float = quantity("deg", ge=-90.0, le=90.0)
    lon: float = quantity("deg", ge=-180.0, le=180.0)
    elevation_ft: float = quantity("ft", 0.0, ge=-1500.0, le=20000.0)
    """Height of the threshold in ft (the datum of the aircraft's ``alt_ft``)."""


class GeoRunwayConfig(Strict):
    """The runway on the Earth: the origin of the local frame, which turns the landing direction to -y."""

    threshold: ThresholdConfig
    course_deg: float = quantity("deg", ge=0.0, lt=360.0)
    """True course of the landing direction, clockwise from true north."""
    flight_path_angle_deg: float = quantity("deg", 0.0, ge=-10.0, le=10.0)

    def frame(self) -> GeoFrame:
        t = self.threshold
        return GeoFrame(lat_deg=t.lat, lon_deg=t.lon, elevation_ft=t.elevation_ft, course_deg=self.course_deg)


def _is_geodetic_runway(value: Any) -> str:
    geo = (isinstance(value, dict) and "threshold" in value) or isinstance(value, GeoRunwayConfig)
    return "geodetic" if geo else "local"


AnyRunwayConfig = Annotated[Annotated[RunwayConfig, Tag("local")] | Annotated[GeoRunwayConfig, Tag("geodetic")],
                            Discriminator(_is_geodetic_runway)]


class AirspaceConfig(Strict):
    x: Interval = quantity("nm")
    y: Interval = quantity("nm")
    z: Interval = quantity("nm")

    _intervals = field_validator("x", "y", "z")(_check_interval)




class SeparationConfig(Strict):
    distance_nm: float = quantity("nm", 0.25, gt=0.0)
    """Minimum distance between any two airborne aircraft (a sphere, as in the thesis); with ``vertical_ft``, the
    horizontal minimum."""
    horizontal_nm: float | None = quantity("nm", None, gt=0.0)
    """The horizontal minimum of an ATC protected zone (another name for ``distance_nm``; give one of them)."""
    vertical_ft: float | None = quantity("ft", None, gt=0.0)
    """The vertical minimum (ICAO: 1000 ft): two aircraft are separated when they are ``distance_nm`` apart
    horizontally OR this far apart vertically (a cylinder, as ATC and BlueSky count it). None: the sphere."""
    landing_spacing_s: float = quantity("s", 15.0, gt=0.0)
    """Minimum time between successive landings."""
    max_landing_spacing_s: float = quantity("s", 30.0, gt=0.0)
    """Largest time between successive landings the sequencer aims for."""
    wake: WakeTableName = "none"
    """Wake-turbulence distance minima between successive landings (:mod:`mal_planner.wake`):
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


class WindConfig(Strict):
    """A constant horizontal wind: the air mass's velocity over the ground (0: still air, as in the thesis).

    Give ``speed_kt`` with ``from_deg`` (the direction it blows from, clockwise from true north, as METARs do;
    needs a runway on the Earth) or ``from_heading_deg`` (the local heading it blows from, in the convention of
    the aircraft's ``heading_deg``). The planner's aircraft then fly at their airspeed through the moving air:
    their ground speed is airspeed + wind, and gates and the runway are passed on their ground track, crabbed.
    """

    speed_kt: float = quantity("kt", ge=0.0, le=200.0)
    from_deg: float | None = quantity("deg", None, ge=0.0, le=360.0)
    from_heading_deg: float | None = quantity("deg", None, ge=-360.0, le=360.0)

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


class SequencingConfig(Strict):
    """How the landing order and the free landing times are decided (:mod:`mal_planner.sequencing`)."""

    strategy: Strategy = "fcfs"
    """fcfs: first come (turn-aware earliest landing), first served; optimal: the MILP that minimises the total
    delay against the earliest landing times."""
    max_shift: int | None = Field(None, ge=0)
    """optimal: no aircraft more than this many places from its first-come position (None: any order)."""
    time_limit_s: float = quantity("s", 10.0, gt=0.0)
    """optimal: the MILP returns the best order found when this runs out."""

    def options(self) -> SequencingOptions:
        return SequencingOptions(strategy=self.strategy, max_shift=self.max_shift, time_limit_s=self.time_limit_s)


class ScenarioConfig(Strict):
    """The YAML file's schema."""

    name: str
    description: str = ""
    gravity: float = quantity("nm/s^2", 0.0052952, gt=0.0)
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
    procedures: ProceduresConfig | None = None
    """The arrival procedures plans keep (:mod:`mal_planner.scenario.procedures`); None: none (the thesis)."""

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
