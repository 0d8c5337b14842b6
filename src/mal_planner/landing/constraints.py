"""The nonlinear constraints of the landing problem's phases: the protected zone of a pair, the aircraft planned
before (intruders), and each phase's dynamics, cost integrand, obstacles, separations and bank limit."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np

from mal_planner.dynamics import bank_limit_residuals
from mal_planner.landing.margins import Margins
from mal_planner.landing.profile import floor_height
from mal_planner.landing.speeds import SpeedRules
from mal_planner.obstacles import Superquadric
from mal_planner.scales import Scales
from mal_planner.scenario import Aircraft, Scenario

LANDED_DISTANCE2 = 1e2
"""The squared distance (in separations^2) a separation constraint sees once the intruder has landed: far away."""
CYLINDER_P = 50
"""Exponent of the smooth cylinder: ||(h / H, dz / V)||_p >= 2^(1/p) implies max(h / H, |dz| / V) >= 1, so the
optimizer keeps 2^(1/50) - 1 = 1.4 % more than the minima where one of them alone separates (the wall's p)."""


@dataclass(frozen=True)
class ProtectedZone:
    """The separation constraint of one pair, as the NLP sees it.

    A sphere (the thesis): the squared distance >= (S + margin)^2, scaled by that. A cylinder (ATC: separated
    horizontally by H OR vertically by V): ln(A^(p/2) + B^(p/2)) / p >= ln(2) / p with A = h^2 / H'^2 and
    B = dz^2 / V'^2, H' and V' the minima plus the margin; a smooth, conservative form of max(A, B) >= 1 (see
    :data:`CYLINDER_P`), dimensionless like the obstacles' ln of the p-norm.
    """

    horizontal_nm: float
    vertical_nm: float | None

    @classmethod
    def of(cls, scenario: Scenario, margins: Margins) -> ProtectedZone:
        vertical = scenario.vertical_separation_nm
        return cls(scenario.separation_nm + margins.separation_nm,
                   None if vertical is None else vertical + margins.separation_nm)

    def measure(self, d):
        """The constrained expression of a relative position ``d`` (3 rows)."""
        if self.vertical_nm is None:
            return ca.sumsqr(d)
        a = (d[0] ** 2 + d[1] ** 2) / self.horizontal_nm**2
        b = d[2] ** 2 / self.vertical_nm**2
        return ca.log(a ** (CYLINDER_P // 2) + b ** (CYLINDER_P // 2)) / CYLINDER_P

    @property
    def lower(self) -> float:
        return self.horizontal_nm**2 if self.vertical_nm is None else math.log(2.0) / CYLINDER_P

    @property
    def scale(self) -> float:
        return self.horizontal_nm**2 if self.vertical_nm is None else 1.0

    @property
    def landed(self) -> float:
        """What a constraint sees once the intruder has landed: far away."""
        return LANDED_DISTANCE2 * self.lower if self.vertical_nm is None else self.lower + 1.0


@dataclass(frozen=True)
class Intruder:
    """An aircraft whose trajectory is fixed (planned before): the others keep separated from it while it flies."""

    callsign: str
    position: ca.Function
    """t (s) -> (x, y, z) nm, a smooth interpolant of the planned path."""
    t_end: float
    """It has landed after this time."""

    @classmethod
    def from_trajectory(cls, t: np.ndarray, positions: np.ndarray, callsign: str, dt: float) -> Intruder:
        """A B-spline through the path sampled every ``dt`` seconds."""
        grid = np.append(np.arange(t[0], t[-1] - 0.5 * dt, dt), t[-1])
        values = np.column_stack([np.interp(grid, t, positions[:, k]) for k in range(3)])
        return cls(callsign, ca.interpolant(f"{callsign}_path", "bspline", [grid], values.ravel()), float(t[-1]))


@dataclass(frozen=True, eq=False)
class PhaseConstraints:
    """The functions of one phase with the aircraft ``j = 0, 1, ...`` airborne in it (states and controls stacked,
    each aircraft's as many as its dynamics model has), and the bounds, scales and tolerances of its path rows: the
    obstacles of each aircraft (:attr:`relevant`), the floors, the speed rows, then the separations of the ``pairs``
    and of every aircraft from every intruder."""

    aircraft: list[Aircraft]
    relevant: list[list[Superquadric]]
    """Per aircraft, the (inflated) obstacles that overlap the box its state bounds allow."""
    bulky: list[list[Superquadric]]
    """Per aircraft, the relevant obstacles with some volume: checked at the chords' middles too."""
    pairs: list[tuple[int, int]]
    zone: ProtectedZone
    intruders: tuple[Intruder, ...]
    margins: Margins
    scenario: Scenario

    @classmethod
    def of(cls, scenario: Scenario, aircraft: list[Aircraft], x_lb: list[float], x_ub: list[float],
           pairs: list[tuple[int, int]], margins: Margins, scales: Scales,
           intruders: tuple[Intruder, ...]) -> PhaseConstraints:
        """The constraints of ``aircraft`` within the state bounds ``x_lb``, ``x_ub`` keeping ``pairs`` (indices
        into ``aircraft``) and the ``intruders`` apart."""
        obstacles = [ob.inflated(margins.inflation_nm(min(ob.semi_axes) >= scales.length_nm))
                     for ob in scenario.obstacles]
        # An obstacle matters to an aircraft in this phase only if it overlaps the box the state bounds allow
        # (e.g. the wall, which lies on the approach side of its gate, is irrelevant after the gate).
        at = state_offsets(aircraft)
        relevant = [
            [ob for ob in obstacles if _overlaps(ob.bounding_box(), x_lb[at[j]:at[j] + 3], x_ub[at[j]:at[j] + 3])]
            for j in range(len(aircraft))
        ]
        # The obstacles with some volume and the separations again at the middle of every chord between two nodes
        # (a thin wall is crossed only at its gate event, where its phase ends: the state bounds keep each side of
        # its plane).
        bulky = [[ob for ob in relevant[j] if min(ob.semi_axes) >= scales.length_nm] for j in range(len(aircraft))]
        return cls(aircraft, relevant, bulky, pairs, ProtectedZone.of(scenario, margins), intruders, margins, scenario)

    @property
    def n_aircraft(self) -> int:
        return len(self.aircraft)

    @property
    def n_separations(self) -> int:
        return len(self.pairs) + self.n_aircraft * len(self.intruders)

    @property
    def n_bulky(self) -> int:
        return sum(len(b) for b in self.bulky)

    @cached_property
    def _at(self) -> list[int]:
        return state_offsets(self.aircraft)

    @cached_property
    def _u_at(self) -> list[int]:
        return control_offsets(self.aircraft)

    def state(self, x, j: int):
        """Aircraft ``j``'s states in the stacked ``x``."""
        return x[self._at[j]:self._at[j] + self.aircraft[j].dynamics.n_states]

    def control(self, u, j: int):
        """Aircraft ``j``'s controls in the stacked ``u``."""
        return u[self._u_at[j]:self._u_at[j] + self.aircraft[j].dynamics.n_controls]

    def position(self, x, j: int):
        return x[self._at[j]:self._at[j] + 3]

    def dynamics(self, x, u, t, p):
        return ca.vertcat(*[ac.dynamics.rhs(self.state(x, j), self.control(u, j))
                            for j, ac in enumerate(self.aircraft)])

    def lagrange(self, x, u, t, p):
        return sum(ac.dynamics.lagrange(self.state(x, j), self.control(u, j)) for j, ac in enumerate(self.aircraft))

    def separations(self, x, t) -> list:
        zone = self.zone
        out = [zone.measure(self.position(x, a) - self.position(x, b)) for a, b in self.pairs]
        for j in range(self.n_aircraft):
            for other in self.intruders:  # once it has landed, an intruder no longer counts
                row = zone.measure(self.position(x, j) - other.position(t))
                out.append(ca.if_else(t <= other.t_end, row, zone.landed))
        return out

    def path(self, x, u, t, p):
        out = []
        for j in range(self.n_aircraft):
            px, py, pz = (self.position(x, j)[k] for k in range(3))
            # ln(F)/p = ln of the p-norm: the thesis's constraint divided by p, the same feasible set with
            # p times smaller derivatives (p = 50 for the wall).
            out += [ob.log_pnorm(px, py, pz) / ob.p for ob in self.relevant[j]]
        return ca.vertcat(*out, *self.floors(x), *self.speeds(x, t), *self.separations(x, t))

    def floors(self, x) -> list:
        """Each aircraft's height above the procedures' floor (:mod:`mal_planner.landing.profile`); none without
        procedures."""
        runway_z = float(self.scenario.runway_state[2])
        out = []
        for j, ac in enumerate(self.aircraft):
            pos = self.position(x, j)
            floor = floor_height(self.scenario, ac, pos[0], pos[1], self.margins.airspace_nm)
            if floor is not None:
                out.append(pos[2] - runway_z - floor)
        return out

    @property
    def n_floors(self) -> int:
        return 0 if self.scenario.procedures is None else self.n_aircraft

    @cached_property
    def _speed_rules(self) -> list[SpeedRules | None]:
        return [SpeedRules.of(self.scenario, ac, self.margins.speed_share) for ac in self.aircraft]

    def speeds(self, x, t) -> list:
        """Each airspeed-model aircraft's calibrated airspeed below its highest and above its lowest
        (:mod:`mal_planner.landing.speeds`), as shares of its final approach speed."""
        out = []
        for j, rules in enumerate(self._speed_rules):
            if rules is not None:
                out += rules.rows(self.state(x, j), self.scenario, self.aircraft[j], t)
        return out

    @property
    def n_speeds(self) -> int:
        return sum(0 if r is None else r.n_rows for r in self._speed_rules)

    def midpoint(self, x, t, p):
        return ca.vertcat(*[ob.log_pnorm(*(self.position(x, j)[k] for k in range(3))) / ob.p
                            for j in range(self.n_aircraft) for ob in self.bulky[j]], *self.separations(x, t))

    def bank(self, u):  # linear in the controls: enforced at the collocation points and between them
        return ca.vertcat(*[bank_limit_residuals(self.control(u, j)[0], self.control(u, j)[1],
                                                 ac.limits.bank_angle_max - self.margins.bank_rad)
                            for j, ac in enumerate(self.aircraft)])

    def path_bounds(self) -> tuple[list[float], list[float], list[float]]:
        """Lower and upper bounds and scales of the path rows."""
        p_lb, p_ub = [], []
        for j in range(self.n_aircraft):
            p_lb += [self.margins.clearance] * len(self.relevant[j])
            p_ub += [math.inf] * len(self.relevant[j])
        p_lb += [self.margins.airspace_nm] * self.n_floors
        p_ub += [math.inf] * self.n_floors
        p_lb += [0.0] * self.n_speeds
        p_ub += [math.inf] * self.n_speeds
        n_sep = self.n_separations
        p_lb += [self.zone.lower] * n_sep
        p_ub += [math.inf] * n_sep
        # Obstacle rows are dimensionless already; squared distances are scaled by the squared separation.
        p_scale = [1.0] * (len(p_lb) - n_sep) + [self.zone.scale] * n_sep
        return p_lb, p_ub, p_scale

    def path_overshoot_tol(self) -> list[float]:
        """Between the points, a bulky obstacle's row may pass its bound only while the path keeps half the
        obstacle margin (on the largest semi-axis: the smallest ln-norm change per nm); thin pieces and
        separations: unchecked."""
        margins = self.margins
        return [margins.clearance - math.log1p(-0.5 * margins.obstacle_nm / max(ob.semi_axes)) if ob in self.bulky[j]
                else math.inf for j in range(self.n_aircraft) for ob in self.relevant[j]] + \
            [math.inf] * (self.n_floors + self.n_speeds + self.n_separations)


def state_offsets(aircraft: list[Aircraft]) -> list[int]:
    """Where each aircraft's states start in the stacked state vector."""
    return np.concatenate([[0], np.cumsum([ac.dynamics.n_states for ac in aircraft])[:-1]]).astype(int).tolist()


def control_offsets(aircraft: list[Aircraft]) -> list[int]:
    """Where each aircraft's controls start in the stacked control vector."""
    return np.concatenate([[0], np.cumsum([ac.dynamics.n_controls for ac in aircraft])[:-1]]).astype(int).tolist()


def _overlaps(box: np.ndarray, lo: list[float], hi: list[float]) -> bool:
    """True if the (3, 2) box and the bounds [lo, hi] share a volume (not just a face)."""
    return all(box[k, 0] < hi[k] and box[k, 1] > lo[k] for k in range(3))
