"""Solution containers and interpolation."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .lgr import lagrange_matrix, lgr_nodes, support_points
from .mesh import MeshLayout


@dataclass
class PhaseSolution:
    """One phase: node times/states (all Nk nodes), controls (Nk; last = last collocation)."""

    name: str
    t0: float
    tf: float
    t: np.ndarray  # (Nk,)
    x: np.ndarray  # (Nk, nx)
    u: np.ndarray  # (Nk, nu)
    q: float
    layout: MeshLayout

    def interpolate(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """States from the per-segment Lagrange polynomials, controls from the per-segment interpolants.

        Returns ``x (K, nx)`` and ``u (K, nu)``; times outside the phase are clamped.
        """
        tq = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), min(self.t0, self.tf), max(self.t0, self.tf))
        dur = self.tf - self.t0
        tau = -1.0 + 2.0 * (tq - self.t0) / dur if dur != 0.0 else np.full(tq.shape, -1.0)
        lay = self.layout
        frac = (tau + 1.0) / 2.0
        brk = np.asarray(lay.mesh.breaks)
        # A time at a mesh break belongs to the segment that starts there (its first collocation point);
        # round-off in the time -> fraction mapping must not hand it to the previous segment's end.
        near = np.abs(frac[:, None] - brk[None, :]) <= 1e-12 * max(1.0, abs(dur))
        frac = np.where(near.any(axis=1), brk[np.argmax(near, axis=1)], frac)
        seg = np.clip(np.searchsorted(brk, frac, side="right") - 1, 0, lay.mesh.n_segments - 1)
        x = np.empty((tq.size, self.x.shape[1]))
        u = np.empty((tq.size, self.u.shape[1]))
        for s in np.unique(seg):
            idx = np.nonzero(seg == s)[0]
            n = lay.mesh.degrees[s]
            o = lay.offsets[s]
            a, b = brk[s], brk[s + 1]
            loc = 2.0 * (frac[idx] - a) / (b - a) - 1.0
            x[idx] = lagrange_matrix(support_points(n), loc) @ self.x[o : o + n + 1]
            # Controls: the degree N-1 interpolant through the segment's collocation points, the same
            # control the mesh error estimate integrates with.
            u[idx] = self.u[o : o + 1] if n == 1 else lagrange_matrix(lgr_nodes(n), loc) @ self.u[o : o + n]
        return x, u


@dataclass
class MeshIteration:
    """Record of one mesh iteration (also logged at INFO on ``mal_planner.ocp``)."""

    iteration: int
    segments: tuple[int, ...]
    degrees: tuple[tuple[int, ...], ...]
    max_error: float
    errors: tuple[np.ndarray, ...]
    nlp_iterations: int
    nlp_time: float
    build_time: float  # 0 when the NLP came from the cache
    status: str
    nlp_success: bool


@dataclass
class OCPSolution:
    """Result of :meth:`OCPSolver.solve`.

    ``success`` requires the final NLP to have converged and, when refinement was on, the
    mesh error to be below tolerance.  ``solve_time`` sums the NLP solves of all mesh
    iterations (without NLP construction).
    """

    phases: list[PhaseSolution]
    objective: float
    status: str
    success: bool
    nlp_success: bool
    mesh_converged: bool
    iterations: int
    solve_time: float
    max_error: float
    mesh_history: list[MeshIteration] = field(default_factory=list)
    w: np.ndarray | None = None

    def phase(self, key: int | str) -> PhaseSolution:
        if isinstance(key, str):
            return next(p for p in self.phases if p.name == key)
        return self.phases[key]

    def phase_times(self, phase: int) -> tuple[float, float]:
        p = self.phases[phase]
        return p.t0, p.tf

    def interpolate(self, phase: int | str, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        return self.phase(phase).interpolate(t)

    @property
    def meshes(self) -> tuple:
        return tuple(p.layout.mesh for p in self.phases)
