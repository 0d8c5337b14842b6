"""Mesh layout, error estimate and ph refinement (Patterson, Hager & Rao 2015).

Node ordering of a phase with segments of N_1..N_S LGR points: the collocation points of
segment s occupy indices ``off_s .. off_s+N_s-1``; the non-collocated end of segment s is
the first point of segment s+1 (state continuity by sharing), and the last node (index
``Nc = sum N_s``) is the phase end.  Controls live on the ``Nc`` collocation nodes.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from .lgr import diff_matrix, integration_matrix, lagrange_matrix, lgr_nodes, lgr_weights, support_points
from .problem import PhaseMesh


@dataclass(frozen=True)
class MeshLayout:
    """Numeric data of one phase mesh, independent of the problem."""

    mesh: PhaseMesh
    tau: np.ndarray  # (Nk,) phase tau in [-1, 1] of all nodes
    offsets: np.ndarray  # (S+1,) index of the first node of each segment, last = Nc
    D: ca.DM  # (Nc, Nk) block differentiation matrix w.r.t. local segment tau
    w: np.ndarray  # (Nc,) quadrature weights scaled to phase tau (sum = 2)
    frac: np.ndarray  # (Nc,) segment length as a fraction of the phase, per collocation point

    @property
    def n_col(self) -> int:
        return int(self.offsets[-1])

    @property
    def n_nodes(self) -> int:
        return int(self.offsets[-1]) + 1


@lru_cache(maxsize=256)
def layout(mesh: PhaseMesh) -> MeshLayout:
    """Build (once per mesh) the node positions and block matrices."""
    degs = mesh.degrees
    offsets = np.concatenate([[0], np.cumsum(degs)]).astype(int)
    nc = int(offsets[-1])
    tau = np.empty(nc + 1)
    dmat = np.zeros((nc, nc + 1))
    w = np.empty(nc)
    frac = np.empty(nc)
    for s, n in enumerate(degs):
        a, b = mesh.breaks[s], mesh.breaks[s + 1]
        o = offsets[s]
        tau[o : o + n] = -1.0 + 2.0 * (a + (b - a) * (lgr_nodes(n) + 1.0) / 2.0)
        dmat[o : o + n, o : o + n + 1] = diff_matrix(n)
        w[o : o + n] = (b - a) * lgr_weights(n)
        frac[o : o + n] = b - a
    tau[nc] = 1.0
    return MeshLayout(mesh, tau, offsets, ca.sparsify(ca.DM(dmat)), w, frac)


@lru_cache(maxsize=64)
def _estimate_matrices(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Interpolation of a degree-N segment onto M = N+1 LGR points (+end) and I_M."""
    m = n + 1
    tm = lgr_nodes(m)
    lx = lagrange_matrix(support_points(n), np.append(tm, 1.0))  # (M+1, N+1)
    lu = np.ones((m, 1)) if n == 1 else lagrange_matrix(lgr_nodes(n), tm)  # (M, N)
    return lx, lu, integration_matrix(m)


@lru_cache(maxsize=256)
def between_matrix(mesh: PhaseMesh) -> np.ndarray:
    """(P, Nc): the per-segment control interpolants (degree N-1 through the collocation points) at the
    midpoints between consecutive collocation points and at each segment's end."""
    rows = []
    offsets = np.concatenate([[0], np.cumsum(mesh.degrees)]).astype(int)
    nc = int(offsets[-1])
    for s, n in enumerate(mesh.degrees):
        if n < 2:
            continue
        tau = lgr_nodes(n)
        points = np.append(0.5 * (tau[:-1] + tau[1:]), [0.5 * (tau[-1] + 1.0), 1.0])
        block = np.zeros((len(points), nc))
        block[:, offsets[s]:offsets[s] + n] = lagrange_matrix(tau, points)
        rows.append(block)
    return np.vstack(rows) if rows else np.zeros((0, nc))


Evaluator = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def estimate_errors(
    lay: MeshLayout, t0: float, tf: float, x: np.ndarray, u: np.ndarray, f_eval: Evaluator
) -> np.ndarray:
    """Relative state error per segment.

    The state polynomial is sampled at M = N+1 LGR points; the dynamics there (with the
    degree N-1 control interpolant) are integrated from the segment start with the
    M-point Radau integration matrix.  Error = max over points/components of
    ``|x_quad - x_poly| / (1 + max |x_poly|)``.  ``x`` is (nx, Nk), ``u`` (nu, Nc);
    ``f_eval(X, U, T)`` evaluates the dynamics column-wise in one call.
    """
    mesh = lay.mesh
    xs, us, ts, info = [], [], [], []
    for s, n in enumerate(mesh.degrees):
        o = lay.offsets[s]
        lx, lu, _ = _estimate_matrices(n)
        xp = x[:, o : o + n + 1] @ lx.T  # (nx, M+1)
        up = u[:, o : o + n] @ lu.T  # (nu, M)
        a, b = mesh.breaks[s], mesh.breaks[s + 1]
        tau_loc = lgr_nodes(n + 1)
        tph = -1.0 + 2.0 * (a + (b - a) * (tau_loc + 1.0) / 2.0)
        ts.append(t0 + (tf - t0) * (tph + 1.0) / 2.0)
        xs.append(xp)
        us.append(up)
        info.append((n, b - a))
    fx = f_eval(np.hstack([xp[:, :-1] for xp in xs]), np.hstack(us), np.concatenate(ts))
    errs = np.empty(mesh.n_segments)
    col = 0
    for s, (n, h) in enumerate(info):
        m = n + 1
        _, _, imat = _estimate_matrices(n)
        xp = xs[s]
        f = fx[:, col : col + m]
        col += m
        xq = xp[:, :1] + (tf - t0) / 2.0 * h * (f @ imat.T)  # (nx, M) at points 2..M+1
        scale = 1.0 + np.max(np.abs(xp), axis=1, keepdims=True)
        errs[s] = float(np.max(np.abs(xq - xp[:, 1:]) / scale)) if xp.size else 0.0
    return errs


OVERSHOOT_SAMPLES_PER_POINT = 4
"""Samples per collocation point at which :func:`control_overshoot` evaluates a segment's control interpolant."""


def control_overshoot(lay: MeshLayout, u: np.ndarray, lb: np.ndarray, ub: np.ndarray,
                      path: Callable[[np.ndarray], np.ndarray] | None = None,
                      path_lb: np.ndarray | None = None, path_ub: np.ndarray | None = None) -> np.ndarray:
    """Per segment, how far the control interpolant passes the control bounds (and ``path``'s, if given) anywhere
    in the segment (controls' own units; 0 where it stays within).

    The NLP holds the bounds at the collocation points and at the midpoints between them; a high-degree
    interpolant of a control that rides a bound can still bulge past it in between. ``u`` is (Nc, nu);
    ``path`` maps (nu, K) controls to (nc, K) values.
    """
    out = np.zeros(lay.mesh.n_segments)
    for s, n in enumerate(lay.mesh.degrees):
        o = lay.offsets[s]
        seg = u[o:o + n]
        at = np.linspace(-1.0, 1.0, OVERSHOOT_SAMPLES_PER_POINT * n + 1)
        v = seg if n == 1 else lagrange_matrix(lgr_nodes(n), at) @ seg
        excess = np.maximum(lb - v, v - ub)
        worst = float(np.max(excess)) if excess.size else 0.0
        if path is not None:
            c = np.asarray(path(v.T))
            worst = max(worst, float(np.max(np.maximum(path_lb[:, None] - c, c - path_ub[:, None]))))
        out[s] = max(worst, 0.0)
    return out


def path_overshoot(lay: MeshLayout, t0: float, tf: float, x: np.ndarray, u: np.ndarray,
                   path: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray],
                   lb: np.ndarray, ub: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """Per segment, whether some path value passes its bounds by more than its ``tol`` anywhere in the segment,
    on the state polynomial and the control interpolant. ``x`` is (Nk, nx), ``u`` (Nc, nu); ``path(X, U, T)``
    maps columns to (nc, K) values."""
    mesh = lay.mesh
    xs, us, ts, owner = [], [], [], []
    for s, n in enumerate(mesh.degrees):
        o = lay.offsets[s]
        at = np.linspace(-1.0, 1.0, OVERSHOOT_SAMPLES_PER_POINT * n + 1)
        xs.append(lagrange_matrix(support_points(n), at) @ x[o:o + n + 1])
        us.append(u[o:o + 1].repeat(at.size, axis=0) if n == 1 else lagrange_matrix(lgr_nodes(n), at) @ u[o:o + n])
        a, b = mesh.breaks[s], mesh.breaks[s + 1]
        ts.append(t0 + (tf - t0) * (a + (b - a) * (at + 1.0) / 2.0))
        owner.append(np.full(at.size, s))
    c = path(np.vstack(xs).T, np.vstack(us).T, np.concatenate(ts))
    excess = np.maximum(lb[:, None] - c, c - ub[:, None]) - tol[:, None]
    bad = np.any(excess > 0.0, axis=0)
    out = np.zeros(mesh.n_segments, bool)
    out[np.concatenate(owner)[bad]] = True
    return out


def state_overshoot(lay: MeshLayout, x: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> np.ndarray:
    """Per segment and state (n_segments, nx): how far the state polynomial passes the state bounds between the
    segment's points, beyond what the points themselves pass them (a given initial state may lie outside; 0 where it
    stays within). ``x`` is (Nk, nx). The NLP holds the bounds at the points only: a polynomial that rides a bound
    bulges past it in between."""
    out = np.zeros((lay.mesh.n_segments, x.shape[1]))
    for s, n in enumerate(lay.mesh.degrees):
        o = lay.offsets[s]
        points = x[o:o + n + 1]
        v = lagrange_matrix(support_points(n), np.linspace(-1.0, 1.0, OVERSHOOT_SAMPLES_PER_POINT * n + 1)) @ points
        at_points = np.maximum(np.max(np.maximum(lb - points, points - ub), axis=0), 0.0)
        out[s] = np.maximum(np.max(np.maximum(lb - v, v - ub), axis=0) - at_points, 0.0)
    return out


SegmentErrors = dict[tuple[float, float], tuple[int, float]]
"""A phase's segments by their breaks (rounded) -> (degree, estimated error), to compare mesh iterations."""


def segment_errors(mesh: PhaseMesh, errors: np.ndarray) -> SegmentErrors:
    return {(round(mesh.breaks[s], 12), round(mesh.breaks[s + 1], 12)): (n, float(errors[s]))
            for s, n in enumerate(mesh.degrees)}


def refine(mesh: PhaseMesh, errors: np.ndarray, tol: float, n_min: int, n_max: int,
           previous: SegmentErrors | None = None, split: np.ndarray | None = None) -> PhaseMesh:
    """One ph step on the segments whose error exceeds ``tol``.

    The degree is raised by P = ceil(log(e/tol) / log N) + 1 while N + P <= n_max (Patterson, Hager & Rao 2015,
    plus one: on the landing problem the error fell by a factor 1.3-10 per step, not N^P, and the extra degree
    saved 10 % of the planning time over thesis-size and terminal-area scenarios).
    A segment is split in two halves instead when that bound is passed, or when its error fell by less than
    half since ``previous`` (the last iteration's errors) raised its degree: there the solution is not smooth
    (a constraint becomes active, a kink), and raising the degree one step at a time took five iterations to
    gain a factor of three (real-size traffic, at the final approach). Halves keep the segment's degree
    before that raise (at least ``n_min``); the paper's split into ceil((N + P) / n_min) segments of degree
    n_min raised the error tenfold on the thesis (8.4e-5 -> 8.0e-4) and the refinement oscillated.
    Segments marked in ``split`` (their control interpolant bulges past a bound, see :func:`control_overshoot`)
    are halved whatever their error: a higher degree would bulge more.
    """
    breaks: list[float] = [mesh.breaks[0]]
    degs: list[int] = []
    for s, n in enumerate(mesh.degrees):
        a, b = mesh.breaks[s], mesh.breaks[s + 1]
        e = float(errors[s])
        if split is not None and split[s]:
            breaks.extend([0.5 * (a + b), b])
            degs.extend([max(n, n_min)] * 2)
            continue
        if not e > tol:
            breaks.append(b)
            degs.append(n)
            continue
        before = (previous or {}).get((round(a, 12), round(b, 12)))
        stalled = before is not None and before[0] < n and e > 0.5 * before[1]
        p = max(1, math.ceil(math.log(e / tol) / math.log(max(n, 2)))) + 1
        if n + p <= n_max and not stalled:
            breaks.append(b)
            degs.append(n + p)
        else:
            breaks.extend([0.5 * (a + b), b])
            degs.extend([max(before[0] if stalled else n, n_min)] * 2)
    breaks[-1] = 1.0
    return PhaseMesh(tuple(breaks), tuple(degs))
