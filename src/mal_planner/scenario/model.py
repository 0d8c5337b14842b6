"""The scenario in planner units (nm, s, rad): aircraft, airspace, obstacles, minima, wind and sequencing options.

:mod:`mal_planner.scenario.loader` builds it from a validated file (:mod:`mal_planner.scenario.schema`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from mal_planner.dynamics import ControlLimits, DynamicsModel
from mal_planner.errors import InvalidInput
from mal_planner.geodesy import GeoFrame
from mal_planner.obstacles import Gate, Superquadric
from mal_planner.performance import performance_of
from mal_planner.scenario.procedures import Procedures
from mal_planner.scenario.sequencing import SequencingOptions
from mal_planner.units import ft_to_nm

if TYPE_CHECKING:
    from mal_planner.scenario.schema import ScenarioConfig


class ScenarioError(InvalidInput):
    """A scenario that cannot be used; ``str()`` is a single line: ``file: field: reason``."""

    named_in_reason = False

    def __init__(self, source: str, field: str, reason: str) -> None:
        self.source, self.field, self.reason = source, field, reason
        super().__init__(f"{source}: {field}: {reason}" if field else f"{source}: {reason}")


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
    type_code: str | None = None
    """ICAO type designator (None: the scenario's procedures' default type, if any)."""

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
    procedures: Procedures | None = None
    """The arrival procedures every plan keeps (``procedures:``); None: none (the thesis's airspace)."""
    spacing_reserve_s: float = 0.0
    """What the schedule and the optimizer keep beyond each pair's landing spacing (s): the plan options' margin
    (:attr:`~mal_planner.landing.margins.SafetyMargins.spacing_s`, set by :func:`~mal_planner.options.scenario_for`),
    not the file's; the minima themselves are unchanged."""

    @property
    def elevation_nm(self) -> float:
        """The threshold's elevation (nm; 0 for a local scenario): the local z plus this is the altitude."""
        return 0.0 if self.geo_frame is None else ft_to_nm(self.geo_frame.elevation_ft)

    def type_of(self, aircraft: Aircraft) -> str | None:
        """The ICAO type ``aircraft`` flies as: its own, else the procedures' default (None: no type)."""
        return aircraft.type_code or (self.procedures.default_type if self.procedures else None)

    def descent_rate_limit(self, aircraft: Aircraft) -> float | None:
        """The steepest descent (nm/s, > 0) the procedures and ``aircraft``'s type allow (OpenAP's steepest
        constant-CAS descent); None without procedures."""
        if self.procedures is None:
            return None
        return min(self.procedures.max_descent_rate, -performance_of(self.type_of(aircraft)).descent_rate.low)

    @property
    def separation_radius_nm(self) -> float:
        """Radius of the smallest sphere holding the protected zone: farther apart than this is separated."""
        return math.hypot(self.separation_nm, self.vertical_separation_nm or 0.0)

    def runway_heading(self, aircraft: Aircraft) -> float:
        """The state heading of ``aircraft`` at touchdown: the runway's course as its ground track (crabbed)."""
        return aircraft.heading_for_track(float(self.runway_state[4]), float(self.runway_state[3]))

    def final_ground_speed(self, aircraft: Aircraft, airspeed: float | None = None) -> float:
        """Ground speed (nm/s) of ``aircraft`` on the final approach (the runway's course and flight-path angle) at
        ``airspeed`` (None: its model's): the airspeed in still air, else the wind triangle's (what a distance on
        final takes in time)."""
        dynamics = aircraft.dynamics if airspeed is None else replace(aircraft.dynamics, speed=airspeed)
        if not dynamics.has_wind:
            return dynamics.speed
        gamma, track = float(self.runway_state[3]), float(self.runway_state[4])
        return math.hypot(float(dynamics.ground_speed_along(track, gamma)), dynamics.speed * math.sin(gamma))

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
