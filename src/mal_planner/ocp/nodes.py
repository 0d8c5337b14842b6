"""The nonlinear part of a phase at one node, with its Jacobian and Hessian (GPOPS-II's derivative structure).

In an LGR transcription every nonlinear term depends on one node only: the dynamics and the path constraints
at node k, the integrand of the cost. Their derivatives are small dense blocks per node; the NLP's Jacobian and
the Hessian of its Lagrangian are these blocks scattered into a sparse pattern known in advance, plus
constants (the differentiation matrix, linkages). CasADi's automatic differentiation of the whole NLP graph
finds the same numbers by colouring the NLP's columns (about 50 directional sweeps of the graph on the landing
problem, each evaluating every node); here each node is differentiated once, in SX, and mapped over the nodes.
Measured on one aircraft's real-size NLP (1,166 variables, 5 intruders): constraint Jacobian 17.7 -> 1.2 ms,
Hessian 19 -> 2.1 ms (README, "Real terminal-area scale").

:class:`NodeFunctions` is built once per phase (it does not depend on the mesh): inputs are the node's scaled
states ``z`` and controls ``v``, the phase's scaled times ``t0``, ``tf``, the node's scaled half-duration copy
``h`` and the node's constants ``s`` (where it lies in the phase, 0..1), ``frac`` (its segment's share of the
phase) and ``w`` (its quadrature weight); outputs are the nonlinear defect part, the scaled path constraints
and the node's share of the integral.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from .problem import Phase


@dataclass(frozen=True)
class NodeFunctions:
    """``out(z, v, t0, tf, h, s, frac, w, p) -> (d ; c, q)``; ``jac`` its Jacobian in (z, v, t0, tf, h);
    ``hess(..., mu, sigma)`` the Hessian of mu' (d ; c) + sigma q in the same inputs."""

    out: ca.Function
    jac: ca.Function
    hess: ca.Function
    nx: int
    nu: int
    n_path: int
    n_in: int
    """Differentiated inputs: z, v, t0, tf, h (a node), or z_a, z_b, t0, tf (a midpoint)."""
    n_out: int
    grad: ca.Function | None = None
    """The gradient (a row) of the node's share of the integral in the same inputs (None: no integral)."""


def node_functions(phase: Phase, fun: ca.Function, n_params: int) -> NodeFunctions:
    """The node functions of ``phase`` from its ``(x, u, t, p) -> (f, l, c)`` function (see the module docstring).

    ``d = -T h frac f(x, u, t) / sx`` is the nonlinear part of the defect ``z D' + d``, ``c`` the path
    constraints divided by their scales and ``q = T h w l`` the node's share of the phase integral, with
    ``x = sx z``, ``u = su v``, ``t = T (t0 + (tf - t0) s)`` (T the phase's time scale).
    """
    nx, nu = phase.nx, phase.nu
    sx, su = phase.scales()
    st = float(phase.time_scale)
    n_path = fun.size1_out(2)
    sp = np.ones(n_path) if phase.path_scale is None else np.broadcast_to(
        np.asarray(phase.path_scale, float).reshape(-1), (n_path,))
    z, v = ca.SX.sym("z", nx), ca.SX.sym("v", nu)
    t0, tf, h = ca.SX.sym("t0"), ca.SX.sym("tf"), ca.SX.sym("h")
    s, frac, w = ca.SX.sym("s"), ca.SX.sym("frac"), ca.SX.sym("w")
    p = ca.SX.sym("p", n_params)
    f, lag, c = fun(ca.DM(sx) * z, ca.DM(su) * v, st * (t0 + (tf - t0) * s), p)
    out = ca.vertcat(-st * h * frac * f / ca.DM(sx), c / ca.DM(sp))
    q = st * h * w * lag
    inputs = ca.vertcat(z, v, t0, tf, h)
    args = [z, v, t0, tf, h, s, frac, w, p]
    mu, sigma = ca.SX.sym("mu", nx + n_path), ca.SX.sym("sigma")
    hess = ca.hessian(ca.dot(mu, out) + sigma * q, inputs)[0]
    return NodeFunctions(
        out=ca.Function(f"{phase.name}_node", args, [out, q]),
        jac=ca.Function(f"{phase.name}_node_jac", args, [ca.jacobian(out, inputs)]),
        hess=ca.Function(f"{phase.name}_node_hess", [*args, mu, sigma], [hess]),
        nx=nx, nu=nu, n_path=n_path, n_in=nx + nu + 3, n_out=nx + n_path,
        grad=ca.Function(f"{phase.name}_node_grad", args, [ca.jacobian(q, inputs)]),
    )


def midpoint_functions(phase: Phase, n_params: int) -> NodeFunctions | None:
    """``out(z_a, z_b, t0, tf, s, p) -> c(x, t, p) / scale`` at the middle of the chord between two consecutive
    nodes (``x = sx (z_a + z_b) / 2``, ``t = T (t0 + (tf - t0) s)``, ``s`` the middle's place in the phase): the
    phase's ``midpoint_path``, with its Jacobian and Hessian in (z_a, z_b, t0, tf); None without one."""
    if phase.midpoint_path is None:
        return None
    nx = phase.nx
    sx = ca.DM(phase.scales()[0])
    st = float(phase.time_scale)
    za, zb = ca.SX.sym("za", nx), ca.SX.sym("zb", nx)
    t0, tf, s, p = ca.SX.sym("t0"), ca.SX.sym("tf"), ca.SX.sym("s"), ca.SX.sym("p", n_params)
    raw = _col_sx(phase.midpoint_path(sx * (za + zb) / 2.0, st * (t0 + (tf - t0) * s), p))
    n = raw.numel()
    scale = np.ones(n) if phase.midpoint_path_scale is None else np.broadcast_to(
        np.asarray(phase.midpoint_path_scale, float).reshape(-1), (n,))
    out = raw / ca.DM(scale)
    inputs = ca.vertcat(za, zb, t0, tf)
    args = [za, zb, t0, tf, s, p]
    mu, sigma = ca.SX.sym("mu", n), ca.SX.sym("sigma")
    return NodeFunctions(
        out=ca.Function(f"{phase.name}_mid", args, [out]),
        jac=ca.Function(f"{phase.name}_mid_jac", args, [ca.jacobian(out, inputs)]),
        hess=ca.Function(f"{phase.name}_mid_hess", [*args, mu, sigma], [ca.hessian(ca.dot(mu, out), inputs)[0]]),
        nx=nx, nu=0, n_path=n, n_in=2 * nx + 2, n_out=n,
    )


def _col_sx(value) -> ca.SX:
    return ca.vertcat(*value) if isinstance(value, list | tuple) else value


def scatter(values: ca.MX, rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int],
            upper: bool = False) -> ca.MX:
    """The sparse matrix with the ``k``-th nonzero of ``values`` added at (rows[k], cols[k]) (entries with a
    negative row or column are left out; duplicates are summed); ``upper``: entries below the diagonal are left
    out too (the upper triangle of a symmetric matrix assembled from whole symmetric blocks)."""
    rows, cols = np.asarray(rows, int), np.asarray(cols, int)
    keep = (rows >= 0) & (cols >= 0)
    if upper:
        keep &= rows <= cols
    src = np.flatnonzero(keep)
    r, c = rows[keep], cols[keep]
    order = np.lexsort((r, c))  # column-major: the order of a CasADi sparsity's nonzeros
    r, c, src = r[order], c[order], src[order]
    key = c.astype(np.int64) * shape[0] + r
    unique, first, group = np.unique(key, return_index=True, return_inverse=True)
    sparsity = ca.Sparsity.triplet(shape[0], shape[1], r[first].tolist(), c[first].tolist())
    if len(unique) == len(key):
        return ca.MX(sparsity, ca.vec(values.nz[src.tolist()]))  # vec: the nonzeros of a row come as a row
    summing = ca.DM(ca.Sparsity.triplet(len(unique), values.nnz(), group.tolist(), src.tolist()),
                    np.ones(len(src)))
    return ca.MX(sparsity, ca.mtimes(summing, ca.vec(values.nz[:])))
