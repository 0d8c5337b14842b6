"""Initial guesses sampled onto a phase's transcription nodes."""

from __future__ import annotations

from typing import Protocol

import numpy as np

from .mesh import MeshLayout
from .problem import Phase, PhaseGuess


class GuessSource(Protocol):
    """Anything that can be sampled like a previous solution (used for warm starts)."""

    def phase_times(self, phase: int) -> tuple[float, float]: ...

    def interpolate(self, phase: int, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


def sample_guess(ph: Phase, g: PhaseGuess | None, lay: MeshLayout) -> tuple[float, float, np.ndarray, np.ndarray]:
    """``(t0, tf, X (nx, Nk), U (nu, Nc))`` of ``g`` linearly interpolated onto the nodes of ``lay``."""
    nk, nc = lay.n_nodes, lay.n_col
    if g is None:
        # Straight line between the (finite) endpoint bound midpoints: a poor but legal start.
        b = ph.bounds()
        lo = np.clip(0.0, ph.t0_bounds[0], ph.t0_bounds[1])
        hi = np.clip(max(lo + 1.0, ph.tf_bounds[0]), ph.tf_bounds[0], ph.tf_bounds[1])
        xa = _mid(b["x0_lb"], b["x0_ub"], b["x_lb"], b["x_ub"])
        xb = _mid(b["xf_lb"], b["xf_ub"], b["x_lb"], b["x_ub"])
        s = (lay.tau + 1.0) / 2.0
        x = xa[:, None] + (xb - xa)[:, None] * s[None, :]
        u = np.tile(_mid(b["u_lb"], b["u_ub"], b["u_lb"], b["u_ub"])[:, None], (1, nc))
        return float(lo), float(hi), x, u
    t0, tf = float(g.t[0]), float(g.t[-1])
    tn = t0 + (tf - t0) * (lay.tau + 1.0) / 2.0
    x = np.vstack([np.interp(tn, g.t, g.x[:, j]) for j in range(ph.nx)]) if ph.nx else np.zeros((0, nk))
    u = np.vstack([np.interp(tn[:nc], g.t, g.u[:, j]) for j in range(ph.nu)]) if ph.nu else np.zeros((0, nc))
    return t0, tf, x, u


def _mid(lb: np.ndarray, ub: np.ndarray, glb: np.ndarray, gub: np.ndarray) -> np.ndarray:
    both = np.isfinite(lb) & np.isfinite(ub)
    mid = np.where(both, 0.5 * (np.where(both, lb, 0) + np.where(both, ub, 0)), 0.0)
    return np.clip(mid, glb, gub)
