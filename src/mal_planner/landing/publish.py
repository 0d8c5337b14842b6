"""The published trajectories: sampled from the solution's interpolants, controls within the aircraft's limits."""

from __future__ import annotations

import math

import numpy as np

from mal_planner.ocp import PhaseSolution

OUTPUT_STEP_TURN_TIMES = 1.0 / 30.0
"""Default sampling step of the published trajectories, in turn times (thesis: 0.25 s)."""


def round_step(step: float) -> float:
    """The one of 1, 2, 2.5 and 5 times a power of ten nearest to ``step`` (by ratio): samples on a round grid."""
    power = 10.0 ** math.floor(math.log10(step))
    return min((m * power for m in (1.0, 2.0, 2.5, 5.0, 10.0)), key=lambda c: abs(math.log(c / step)))


def within_limits(u: np.ndarray, limits) -> np.ndarray:
    """Controls (n_h, n_v[, n_x]) rows moved into the load-factor and bank limits (n_v first, then n_h within
    +-tan(mu) n_v): the interpolant of a solution that rides a limit can pass it by 1e-4 between the points
    where the NLP holds it (campaign: n_v 1.3000x against 1.3, and a verification round to refine it)."""
    out = np.array(u, float, copy=True)
    out[:, 1] = np.clip(out[:, 1], *limits.n_v)
    if out.shape[1] > 2:  # the airspeed model's n_x
        out[:, 2] = np.clip(out[:, 2], *limits.n_x)
    cap = math.tan(limits.bank_angle_max) * out[:, 1]
    out[:, 0] = np.clip(out[:, 0], np.maximum(-cap, limits.n_h[0]), np.minimum(cap, limits.n_h[1]))
    return out


def published_times(phase: PhaseSolution, controls: slice, dt: float, control_tol: float,
                    max_rounds: int = 8) -> np.ndarray:
    """Sample times of one aircraft in one phase: the global grid ``k * dt``, the phase's ends and nodes, and
    wherever the controls, taken as linear between samples (as a follower flies them), would miss the
    solution's control interpolant by more than ``control_tol`` at an interval's midpoint, its midpoint
    (at most ``max_rounds`` halvings of an interval: where the interpolants of two mesh segments differ at
    their common break, the last interval before it stays 1/256 of its length).

    Where the optimal controls bend sharply (the first seconds of a plan, a turn's entry) a 0.25 s grid
    flown linearly drifted 0.0035 nm from the plan over 290 s and dipped below the floor before landing
    (campaign traffic-0083); 0.05 s everywhere fixed it at five times the samples.
    """
    grid = np.arange(np.floor(phase.t0 / dt) + 1, np.ceil(phase.tf / dt)) * dt
    t = np.union1d(np.concatenate([grid, [phase.t0, phase.tf]]), phase.t)
    u = phase.interpolate(t)[1][:, controls]
    for _ in range(max_rounds):
        mid = 0.5 * (t[:-1] + t[1:])
        u_mid = phase.interpolate(mid)[1][:, controls]
        bad = np.max(np.abs(u_mid - 0.5 * (u[:-1] + u[1:])), axis=1) > control_tol
        if not bad.any():
            break
        t = np.concatenate([t, mid[bad]])
        u = np.concatenate([u, u_mid[bad]])
        order = np.argsort(t, kind="stable")
        t, u = t[order], u[order]
    return t
