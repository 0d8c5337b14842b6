"""Aircraft dynamics models: one definition, evaluated on NumPy arrays and on CasADi symbols.

The thesis's point-mass, constant-speed model ("State-space dynamic equations", chapter 2):

    x' = V cos(gamma) cos(phi) + w_x      gamma' = g/V (n_v - cos(gamma))
    y' = V cos(gamma) sin(phi) + w_y      phi'   = g/V n_h / cos(gamma)
    z' = V sin(gamma)

with an optional horizontal wind (w_x, w_y) (0 in the thesis): V is the airspeed, gamma and phi the air-relative
flight-path angle and heading, and the ground velocity is the air velocity plus the wind.

States are (x, y, z, gamma, phi) in nm and rad, controls (n_h, n_v) are load factors. Models live in a
registry keyed by name, so a scenario can give each aircraft its own model (e.g. a slower rotorcraft
with other limits, or :class:`AirspeedModel`, whose airspeed is a state) without touching the planner.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields, replace
from typing import Any, ClassVar

import casadi as ca
import numpy as np

STATE_NAMES: tuple[str, ...] = ("x", "y", "z", "gamma", "heading")
CONTROL_NAMES: tuple[str, ...] = ("n_h", "n_v")
AIRSPEED_STATE_NAMES: tuple[str, ...] = (*STATE_NAMES, "airspeed")
AIRSPEED_CONTROL_NAMES: tuple[str, ...] = (*CONTROL_NAMES, "n_x")
GRAVITY_NM_S2: float = 0.0052952
"""Acceleration due to gravity in nm/s^2 (the thesis's value)."""


def array_module(*values: Any):
    """Return ``casadi`` if any value is a CasADi type, else ``numpy``: the same code serves both."""
    return ca if any(isinstance(v, (ca.SX, ca.MX, ca.DM)) for v in values) else np


def _stack(xp, rows: list) -> Any:
    if xp is ca:
        return ca.vertcat(*rows)
    if all(np.ndim(r) == 0 for r in rows):  # one state (e.g. inside an ODE solver): the cheap path
        return np.array(rows, dtype=float)
    return np.array(rows)  # as np.stack for rows of one shape (the only valid input), four times cheaper


@dataclass(frozen=True)
class ControlLimits:
    """Bounds on the load factors and the bank angle of one vehicle."""

    n_h: tuple[float, float] = (-2.0, 2.0)
    n_v: tuple[float, float] = (0.0, 2.0)
    bank_angle_max: float = float(np.radians(45.0))
    """Largest |bank angle| in rad; the bank angle is atan(n_h / n_v) (thesis eq. 2-6)."""
    n_x: tuple[float, float] = (0.0, 0.0)
    """Longitudinal load factor (thrust - drag) / weight (:class:`AirspeedModel` only; the loader sets it from the
    aircraft type's performance)."""


@dataclass(frozen=True)
class DynamicsModel:
    """Point-mass, constant-speed aircraft (the thesis's model)."""

    speed: float
    """Constant airspeed V in nm/s."""
    gravity: float = GRAVITY_NM_S2
    wind_x: float = 0.0
    """Wind velocity along x in nm/s (the air mass's motion over the ground; 0: still air)."""
    wind_y: float = 0.0
    """Wind velocity along y in nm/s."""
    default_limits: ClassVar[ControlLimits] = ControlLimits()
    name: ClassVar[str] = "point_mass"
    state_names: ClassVar[tuple[str, ...]] = STATE_NAMES
    control_names: ClassVar[tuple[str, ...]] = CONTROL_NAMES
    variable_airspeed: ClassVar[bool] = False
    """True where the airspeed is a state (and n_x a control): :class:`AirspeedModel`."""

    @property
    def n_states(self) -> int:
        return len(self.state_names)

    @property
    def n_controls(self) -> int:
        return len(self.control_names)

    def airspeed(self, state: Any) -> Any:
        """The airspeed (nm/s) in ``state``: the constant V here."""
        return self.speed

    def rhs(self, state: Any, control: Any) -> Any:
        """Time derivative of ``state`` (rows x, y, z, gamma, phi; any trailing shape) under ``control``."""
        xp = array_module(state, control)
        return _stack(xp, self._point_mass_rates(xp, state, control))

    def _point_mass_rates(self, xp: Any, state: Any, control: Any) -> list:
        gamma, phi = state[3], state[4]
        n_h, n_v = control[0], control[1]
        v, g = self.airspeed(state), self.gravity
        cos_gamma = xp.cos(gamma)
        return [
            v * cos_gamma * xp.cos(phi) + self.wind_x,
            v * cos_gamma * xp.sin(phi) + self.wind_y,
            v * xp.sin(gamma),
            g / v * (n_v - cos_gamma),
            g / v * n_h / cos_gamma,
        ]

    def lagrange(self, state: Any, control: Any) -> Any:
        """The thesis's cost integrand: gamma'^2 + phi'^2 (rad^2/s^2)."""
        g_rate, h_rate = self.angle_rates(state, control)
        return g_rate**2 + h_rate**2

    def angle_rates(self, state: Any, control: Any) -> tuple[Any, Any]:
        """(gamma', phi'): the rates in the thesis's Lagrange cost."""
        rates = self.rhs(state, control)
        return rates[3], rates[4]

    def rk4_step(self, state: np.ndarray, control: np.ndarray, h: float) -> np.ndarray:
        """One classical Runge-Kutta step of ``h`` seconds under a constant ``control`` (simulation and
        feasibility checks; the verification integrates with its own, independent scheme)."""
        k1 = self.rhs(state, control)
        k2 = self.rhs(state + h / 2 * k1, control)
        k3 = self.rhs(state + h / 2 * k2, control)
        k4 = self.rhs(state + h * k3, control)
        return state + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    @property
    def wind(self) -> np.ndarray:
        """(w_x, w_y) in nm/s."""
        return np.array([self.wind_x, self.wind_y], dtype=float)

    @property
    def has_wind(self) -> bool:
        return bool(np.any(np.asarray(self.wind_x) != 0.0) or np.any(np.asarray(self.wind_y) != 0.0))

    def heading_for_track(self, track: Any, gamma: Any = 0.0) -> Any:
        """Air heading whose ground track is ``track`` (rad) in this wind: the track less the wind-correction
        (crab) angle. Equal to ``track`` in still air; NumPy only."""
        v_h = self.speed * np.cos(gamma)
        cross = -self.wind_x * np.sin(track) + self.wind_y * np.cos(track)
        return track - np.arcsin(np.clip(cross / v_h, -1.0, 1.0))

    def ground_speed_along(self, track: Any, gamma: Any = 0.0) -> Any:
        """Horizontal ground speed (nm/s) flying the ground track ``track`` (rad) in this wind (the wind
        triangle); <= 0 where the wind is too strong to make way along it. NumPy only."""
        v_h = self.speed * np.cos(gamma)
        along = self.wind_x * np.cos(track) + self.wind_y * np.sin(track)
        cross = -self.wind_x * np.sin(track) + self.wind_y * np.cos(track)
        return along + np.sqrt(np.maximum(v_h**2 - cross**2, 0.0))

    def with_wind(self, wind_x: Any, wind_y: Any) -> DynamicsModel:
        """This model in another wind (nm/s)."""
        return replace(self, wind_x=wind_x, wind_y=wind_y)

    @property
    def fastest_ground_speed(self) -> float:
        """An upper bound of the ground speed (nm/s): V + |w| (V in still air)."""
        return float(self.speed + np.hypot(self.wind_x, self.wind_y))

    def ground_track(self, gamma: float, heading: float) -> float:
        """Ground track (rad) of the air-relative (gamma, heading); ``heading`` itself in still air."""
        if not self.has_wind:
            return heading
        v_h = self.speed * math.cos(gamma)
        return math.atan2(v_h * math.sin(heading) + self.wind_y, v_h * math.cos(heading) + self.wind_x)

    def _ground_speed_3d(self, unit: np.ndarray) -> np.ndarray:
        """Ground speed s along unit ground directions (rows (..., 3)): |s d - w| = V, the wind horizontal."""
        along = unit[..., 0] * self.wind_x + unit[..., 1] * self.wind_y
        return along + np.sqrt(along**2 + self.speed**2 - self.wind_x**2 - self.wind_y**2)

    def air_distance(self, segments: np.ndarray) -> np.ndarray:
        """Distance (nm) flown through the air along straight ground segments (rows (..., 3)): their length x V /
        the ground speed along them, so that the time to fly one is this / V. Their length in still air."""
        seg = np.asarray(segments, dtype=float)
        length = np.linalg.norm(seg, axis=-1) if seg.ndim > 1 else np.linalg.norm(seg)  # the callers' own norms
        if not self.has_wind:
            return length
        unit = seg / np.where(length > 0.0, length, 1.0)[..., None]
        return length * self.speed / self._ground_speed_3d(unit)

    def air_angles(self, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Air-relative (gamma, heading) (rad) that fly straight along ground segments (rows (..., 3), non-zero):
        the crabbed heading, and the flight-path angle of the air velocity. The segments' own angles in still
        air."""
        seg = np.asarray(segments, dtype=float)
        length = np.linalg.norm(seg, axis=-1)
        if not self.has_wind:
            return np.arcsin(np.clip(seg[..., 2] / length, -1.0, 1.0)), np.arctan2(seg[..., 1], seg[..., 0])
        unit = seg / length[..., None]
        air = self._ground_speed_3d(unit)[..., None] * unit - np.array([self.wind_x, self.wind_y, 0.0])
        return np.arcsin(np.clip(air[..., 2] / self.speed, -1.0, 1.0)), np.arctan2(air[..., 1], air[..., 0])

    def level_flight_control(self, gamma: Any = 0.0) -> np.ndarray:
        """Controls that hold gamma and heading constant (n_h = 0, n_v = cos gamma)."""
        return np.array([0.0, np.cos(gamma)])

    def initial_state(self, position: Any, gamma: float, heading: float) -> np.ndarray:
        """The state at ``position`` flying (``gamma``, ``heading``) at the model's airspeed."""
        return np.array([*position, gamma, heading], dtype=float)


@dataclass(frozen=True)
class AirspeedModel(DynamicsModel):
    """The thesis's point mass with its airspeed as a sixth state, driven by the longitudinal load factor n_x =
    (thrust - drag) / weight: V' = g (n_x - sin gamma) (the energy equation of the point mass; e.g. Vinh, *Flight
    Mechanics of High-Performance Aircraft*, 1993, eq. 3.4). A descent at idle thrust (n_x < 0 but small) slows the
    aircraft only a little: the "down or slow down" of arrival procedures. ``speed`` is the airspeed it starts with
    (the guesses fly it)."""

    name: ClassVar[str] = "point_mass_airspeed"
    state_names: ClassVar[tuple[str, ...]] = AIRSPEED_STATE_NAMES
    control_names: ClassVar[tuple[str, ...]] = AIRSPEED_CONTROL_NAMES
    variable_airspeed: ClassVar[bool] = True

    def airspeed(self, state: Any) -> Any:
        return state[5]

    def rhs(self, state: Any, control: Any) -> Any:
        xp = array_module(state, control)
        rows = self._point_mass_rates(xp, state, control)
        return _stack(xp, [*rows, self.gravity * (control[2] - xp.sin(state[3]))])

    def lagrange(self, state: Any, control: Any) -> Any:
        """gamma'^2 + phi'^2 + (V' / V)^2: the relative speed change costs as much as a turn at the same rate."""
        rates = self.rhs(state, control)
        return rates[3] ** 2 + rates[4] ** 2 + (rates[5] / state[5]) ** 2

    def level_flight_control(self, gamma: Any = 0.0) -> np.ndarray:
        """Controls that hold gamma, heading and airspeed constant."""
        return np.array([0.0, np.cos(gamma), np.sin(gamma)])

    def initial_state(self, position: Any, gamma: float, heading: float) -> np.ndarray:
        return np.array([*position, gamma, heading, self.speed], dtype=float)


def stacked_model(models: Sequence[DynamicsModel], index: Any = None) -> DynamicsModel:
    """One model standing for several vehicles of one type, to evaluate them all in one NumPy call.

    Every parameter that differs between ``models`` becomes an array with one entry per column, so
    ``rhs`` on states of shape (5, n) (one vehicle per column) applies each vehicle's own parameters: the
    same equations, broadcast over the columns. Columns are the models in order, or ``models[index[j]]``
    for column j when ``index`` is given. NumPy only (the parameters of a CasADi model stay scalars).
    """
    first = models[0]
    if any(type(m) is not type(first) for m in models):
        raise TypeError("stacked_model needs models of one type")
    columns = np.arange(len(models)) if index is None else np.asarray(index, int)
    changes = {}
    for f in fields(first):
        if not f.init:
            continue
        values = [getattr(m, f.name) for m in models]
        if any(v != values[0] for v in values):
            changes[f.name] = np.asarray(values, float)[columns]
    return replace(first, **changes) if changes else first


def bank_angle(n_h: Any, n_v: Any) -> Any:
    """Bank angle mu = atan(n_h / n_v) (thesis eq. 2-6), well defined for n_v >= 0."""
    xp = array_module(n_h, n_v)
    return xp.arctan2(n_h, n_v) if xp is np else ca.atan2(n_h, n_v)


def bank_limit_residuals(n_h: Any, n_v: Any, bank_angle_max: float) -> Any:
    """Linear form of |atan(n_h/n_v)| <= mu_max for n_v >= 0: both residuals must be <= 0.

    The arctangent form has a singular derivative at n_v = 0; |n_h| <= tan(mu_max) n_v is the same set
    (given n_v >= 0) and is linear, which the NLP solver prefers.
    """
    xp = array_module(n_h, n_v)
    t = float(np.tan(bank_angle_max))
    return _stack(xp, [n_h - t * n_v, -n_h - t * n_v])


@dataclass(frozen=True)
class Rotorcraft(DynamicsModel):
    """A slower vehicle with gentler limits: same point-mass equations, other defaults."""

    name: ClassVar[str] = "rotorcraft"
    default_limits: ClassVar[ControlLimits] = ControlLimits(
        n_h=(-1.0, 1.0), n_v=(0.0, 1.5), bank_angle_max=float(np.radians(30.0))
    )


DYNAMICS_MODELS: dict[str, type[DynamicsModel]] = {}


def register_dynamics(cls: type[DynamicsModel]) -> type[DynamicsModel]:
    """Class decorator/function adding a model to the registry under ``cls.name``."""
    DYNAMICS_MODELS[cls.name] = cls
    return cls


register_dynamics(DynamicsModel)
register_dynamics(Rotorcraft)
register_dynamics(AirspeedModel)


def make_dynamics(name: str, speed: float, **params: float) -> DynamicsModel:
    """Instantiate the registered model ``name``; KeyError names the known models."""
    try:
        cls = DYNAMICS_MODELS[name]
    except KeyError:
        known = ", ".join(sorted(DYNAMICS_MODELS))
        raise KeyError(f"unknown dynamics model {name!r} (known: {known})") from None
    return cls(speed=speed, **params)
