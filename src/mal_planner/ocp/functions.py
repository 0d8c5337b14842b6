"""A phase's callbacks as one CasADi function, and the helpers that shape what the callbacks return."""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np

from .problem import Phase


def column(value: object) -> ca.SX:
    """A callback's return value (SX, MX, a list of them, or numbers) as one column."""
    if isinstance(value, list | tuple):
        return ca.vertcat(*value) if value else ca.SX(0, 1)
    return value if isinstance(value, (ca.SX, ca.MX)) else ca.DM(value)


def bound_vector(values: Sequence[float] | float | None, n: int, default: float) -> np.ndarray:
    """``values`` (a scalar or ``n`` of them) as ``n`` floats; None: ``default`` everywhere."""
    if values is None:
        return np.full(n, default)
    return np.broadcast_to(np.asarray(values, dtype=float).reshape(-1), (n,)).copy()


def phase_function(phase: Phase, n_params: int) -> ca.Function:
    """``(x, u, t, p) -> (xdot, lagrange, path)`` as one SX Function, built once per phase."""
    x = ca.SX.sym("x", phase.nx)
    u = ca.SX.sym("u", phase.nu)
    t = ca.SX.sym("t")
    p = ca.SX.sym("p", n_params)
    xdot = column(phase.dynamics(x, u, t, p))
    if xdot.shape != (phase.nx, 1):
        raise ValueError(f"phase {phase.name!r}: dynamics must return {phase.nx} values, got {xdot.shape}")
    lag = column(phase.lagrange(x, u, t, p)) if phase.lagrange else ca.SX(0)
    path = column(phase.path(x, u, t, p)) if phase.path else ca.SX(0, 1)
    return ca.Function(f"{phase.name}_f", [x, u, t, p], [xdot, lag, path], ["x", "u", "t", "p"], ["f", "l", "c"])
