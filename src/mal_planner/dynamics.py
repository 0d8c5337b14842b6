"""Aircraft dynamics models: one definition, evaluated on NumPy arrays and on CasADi symbols.

The thesis's point-mass, constant-speed model ("State-space dynamic equations", chapter 2):

    x' = V cos(gamma) cos(phi)      gamma' = g/V (n_v - cos(gamma))
    y' = V cos(gamma) sin(phi)      phi'   = g/V n_h / cos(gamma)
    z' = V sin(gamma)

States are (x, y, z, gamma, phi) in nm and rad, controls (n_h, n_v) are load factors. Models live in a
registry keyed by name, so a scenario can give each aircraft its own model (e.g. a slower rotorcraft
with other limits) without touching the planner.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields, replace
from typing import Any, ClassVar

import casadi as ca
import numpy as np

STATE_NAMES: tuple[str, ...] = ("x", "y", "z", "gamma", "heading")
CONTROL_NAMES: tuple[str, ...] = ("n_h", "n_v")
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


@dataclass(frozen=True)
class DynamicsModel:
    """Point-mass, constant-speed aircraft (the thesis's model)."""

    speed: float
    """Constant airspeed V in nm/s."""
    gravity: float = GRAVITY_NM_S2
    default_limits: ClassVar[ControlLimits] = ControlLimits()
    name: ClassVar[str] = "point_mass"
    state_names: ClassVar[tuple[str, ...]] = STATE_NAMES
    control_names: ClassVar[tuple[str, ...]] = CONTROL_NAMES

    @property
    def n_states(self) -> int:
        return len(self.state_names)

    @property
    def n_controls(self) -> int:
        return len(self.control_names)

    def rhs(self, state: Any, control: Any) -> Any:
        """Time derivative of ``state`` (rows x, y, z, gamma, phi; any trailing shape) under ``control``."""
        xp = array_module(state, control)
        gamma, phi = state[3], state[4]
        n_h, n_v = control[0], control[1]
        v, g = self.speed, self.gravity
        cos_gamma = xp.cos(gamma)
        return _stack(
            xp,
            [
                v * cos_gamma * xp.cos(phi),
                v * cos_gamma * xp.sin(phi),
                v * xp.sin(gamma),
                g / v * (n_v - cos_gamma),
                g / v * n_h / cos_gamma,
            ],
        )

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

    def level_flight_control(self, gamma: Any = 0.0) -> np.ndarray:
        """Controls that hold gamma and heading constant (n_h = 0, n_v = cos gamma)."""
        return np.array([0.0, np.cos(gamma)])


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


def make_dynamics(name: str, speed: float, **params: float) -> DynamicsModel:
    """Instantiate the registered model ``name``; KeyError names the known models."""
    try:
        cls = DYNAMICS_MODELS[name]
    except KeyError:
        known = ", ".join(sorted(DYNAMICS_MODELS))
        raise KeyError(f"unknown dynamics model {name!r} (known: {known})") from None
    return cls(speed=speed, **params)
