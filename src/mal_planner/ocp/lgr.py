"""Legendre-Gauss-Radau (LGR) nodes, weights and matrices.

Flipped-Radau convention used by GPOPS-II (Garg et al. 2010): the N collocation points
``tau_1 = -1 < tau_2 < ... < tau_N < 1`` are the roots of ``P_{N-1} + P_N``; the
non-collocated point ``tau_{N+1} = +1`` closes the interval.  The state polynomial
of degree N is supported on all N+1 points, so the differentiation matrix is N x (N+1).

Every function here is cached per degree: the mesh refinement loop asks for the same
few degrees over and over and must not recompute them.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.polynomial import legendre as npleg


@lru_cache(maxsize=64)
def _lgr(n: int) -> tuple[np.ndarray, np.ndarray]:
    if n < 1:
        raise ValueError("LGR needs at least one point")
    if n == 1:
        return np.array([-1.0]), np.array([2.0])
    coef = np.zeros(n + 1)
    coef[n - 1] = 1.0
    coef[n] = 1.0
    tau = np.sort(np.real(npleg.legroots(coef)))
    tau[0] = -1.0
    # Newton polish of the interior roots (companion eigenvalues lose a few digits).
    dcoef = npleg.legder(coef)
    for _ in range(3):
        tau[1:] -= npleg.legval(tau[1:], coef) / npleg.legval(tau[1:], dcoef)
    pnm1 = npleg.legval(tau, np.eye(n)[n - 1])
    w = (1.0 - tau) / (n**2 * pnm1**2)
    w[0] = 2.0 / n**2
    tau.setflags(write=False)
    w.setflags(write=False)
    return tau, w


def lgr_nodes(n: int) -> np.ndarray:
    """N flipped-LGR collocation points on [-1, 1) (first one is -1)."""
    return _lgr(n)[0]


def lgr_weights(n: int) -> np.ndarray:
    """LGR quadrature weights; exact for polynomials of degree <= 2N-2."""
    return _lgr(n)[1]


def support_points(n: int) -> np.ndarray:
    """The N collocation points plus the non-collocated end point +1 (N+1 values)."""
    return _support(n)


@lru_cache(maxsize=64)
def _support(n: int) -> np.ndarray:
    s = np.append(lgr_nodes(n), 1.0)
    s.setflags(write=False)
    return s


def barycentric_weights(s: np.ndarray) -> np.ndarray:
    """Barycentric weights of the Lagrange basis on the support points ``s``."""
    diff = s[:, None] - s[None, :]
    np.fill_diagonal(diff, 1.0)
    return 1.0 / np.prod(diff, axis=1)


def lagrange_matrix(s: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Matrix L with ``L @ f(s) = p(x)`` for the interpolant p of data on ``s``."""
    s = np.asarray(s, dtype=float)
    x = np.atleast_1d(np.asarray(x, dtype=float))
    lam = barycentric_weights(s)
    diff = x[:, None] - s[None, :]
    exact = diff == 0.0
    diff[exact] = 1.0
    terms = lam[None, :] / diff
    mat = terms / terms.sum(axis=1, keepdims=True)
    rows = exact.any(axis=1)
    if rows.any():
        mat[rows] = exact[rows].astype(float)
    return mat


@lru_cache(maxsize=64)
def diff_matrix(n: int) -> np.ndarray:
    """LGR differentiation matrix D (N x N+1): ``D @ X(support) = dX/dtau(collocation)``."""
    s = support_points(n)
    lam = barycentric_weights(s)
    diff = s[:, None] - s[None, :]
    np.fill_diagonal(diff, 1.0)
    full = (lam[None, :] / lam[:, None]) / diff
    np.fill_diagonal(full, 0.0)
    np.fill_diagonal(full, -full.sum(axis=1))
    d = full[:n].copy()
    d.setflags(write=False)
    return d


@lru_cache(maxsize=64)
def integration_matrix(n: int) -> np.ndarray:
    """LGR integration matrix I (N x N) = inv(D[:, 1:]).

    Since the rows of D sum to zero, ``X[1:] = X[0] + I @ dX/dtau`` at the collocation
    points; this is the implicit Radau integrator used by the mesh error estimate.
    """
    i = np.linalg.inv(diff_matrix(n)[:, 1:])
    i.setflags(write=False)
    return i
