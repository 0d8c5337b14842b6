"""The plan flown again: each aircraft re-integrated from its initial state under the published controls."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from mal_planner.dynamics import DynamicsModel, stacked_model
from mal_planner.scenario import Scenario
from mal_planner.trajectory import Trajectory
from mal_planner.verification.report import Tolerances

# Butcher's explicit 7-stage Runge-Kutta method of order 6 (J. C. Butcher, Numerical Methods for Ordinary
# Differential Equations, 2nd ed., Wiley 2008, section 346); tests/test_verification.py checks its order.
_RK_C = np.array([0.0, 1 / 3, 2 / 3, 1 / 3, 1 / 2, 1 / 2, 1.0])
_RK_A = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [1 / 3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.0, 2 / 3, 0.0, 0.0, 0.0, 0.0, 0.0],
    [1 / 12, 1 / 3, -1 / 12, 0.0, 0.0, 0.0, 0.0],
    [-1 / 16, 9 / 8, -3 / 16, -3 / 8, 0.0, 0.0, 0.0],
    [0.0, 9 / 8, -3 / 8, -3 / 4, 1 / 2, 0.0, 0.0],
    [9 / 44, -9 / 11, 63 / 44, 18 / 11, 0.0, -16 / 11, 0.0],
])
_RK_B = np.array([11 / 120, 0.0, 27 / 40, 27 / 40, -4 / 15, -4 / 15, 11 / 120])


def _rk_step(model: DynamicsModel, x: np.ndarray, dt: np.ndarray, u: np.ndarray) -> np.ndarray:
    """One step of the Runge-Kutta method above for every column: x (states, n), dt (n,), u (stages, controls,
    n)."""
    k = np.empty((len(_RK_B), *x.shape))
    flat = k.reshape(len(_RK_B), -1)
    for s in range(len(_RK_B)):
        xs = x if s == 0 else x + dt * (_RK_A[s, :s] @ flat[:s]).reshape(x.shape)
        k[s] = model.rhs(xs, u[s])
    return x + dt * (_RK_B @ flat).reshape(x.shape)


@dataclass
class _Schedule:
    """How one aircraft is flown: its integration steps, then the dense samples taken from them."""

    dt: np.ndarray
    """(n,) integration steps, in order; each lies inside one linear piece of the controls."""
    u: np.ndarray
    """(n, stages, controls) controls at the stages of each step."""
    out_t: np.ndarray
    """(m,) dense sample times."""
    out_step: np.ndarray
    """(m,) index of the integration node each sample is reached from (the state before that step)."""
    out_dt: np.ndarray
    """(m,) time from that node to the sample (0 at a node, less than the step otherwise)."""
    out_u: np.ndarray
    """(m, stages, controls) controls at the stages of that last short step."""


def _stage_controls(t0: np.ndarray, dt: np.ndarray, t1: np.ndarray, tp: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Controls, linear between the samples (tp, up) of one piece, at the stages of steps t0 -> t0 + dt."""
    times = t0[:, None] + _RK_C * dt[:, None]
    times[:, _RK_C == 1.0] = t1[:, None]  # the step's exact end (a plan sample where the controls have a kink)
    return np.stack([np.interp(times, tp, up[:, k]) for k in range(up.shape[1])], axis=-1)


def _schedule(traj: Trajectory, tol: Tolerances) -> _Schedule:
    """Integration steps and dense samples of one aircraft, piece by piece (see :func:`fly`)."""
    t_plan, u_plan = np.asarray(traj.t, float), np.asarray(traj.controls, float)
    cuts = [0, *(np.flatnonzero(np.diff(t_plan) <= 0.0) + 1).tolist(), len(t_plan)]
    dts, us, out_t, out_step, out_dt, out_u = [], [], [], [], [], []
    done = 0  # integration steps of the pieces before
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        tp, up = t_plan[a:b], u_plan[a:b]
        if len(tp) < 2:
            continue
        # Integration nodes: the plan's samples (the controls' kinks), each interval split evenly into steps
        # of at most tol.integration_step_s.
        gaps = np.diff(tp)
        m = np.maximum(1, np.ceil(gaps / tol.integration_step_s - 1e-9)).astype(int)
        interval = np.repeat(np.arange(len(gaps)), m)
        j = np.arange(len(interval)) - np.repeat(np.cumsum(m) - m, m)
        nodes = np.append(tp[interval] + gaps[interval] * (j / m[interval]), tp[-1])
        dt = np.diff(nodes)
        dts.append(dt)
        us.append(_stage_controls(nodes[:-1], dt, nodes[1:], tp, up))
        # Dense samples (the last one is the next piece's first, or the end): each is one short step from the
        # node before it, with the same controls.
        n = max(2, int(math.ceil((tp[-1] - tp[0]) / tol.sample_dt)) + 1)
        grid = np.union1d(np.linspace(tp[0], tp[-1], n), tp)[:-1]
        k = np.clip(np.searchsorted(nodes, grid, side="right") - 1, 0, len(nodes) - 2)
        delta = grid - nodes[k]
        out_t.append(grid)
        out_step.append(done + k)
        out_dt.append(delta)
        out_u.append(_stage_controls(nodes[k], delta, grid, tp, up))
        done += len(dt)
    stages, width = len(_RK_B), u_plan.shape[1]
    out_t.append(t_plan[-1:])
    out_step.append(np.array([done]))
    out_dt.append(np.zeros(1))
    out_u.append(np.zeros((1, stages, width)))
    dt = np.concatenate(dts) if dts else np.zeros(0)
    u = np.concatenate(us) if us else np.zeros((0, stages, width))
    return _Schedule(dt, u, *(np.concatenate(v) for v in (out_t, out_step, out_dt, out_u)))


def fly_all(trajectories: list[Trajectory], scenario: Scenario, tol: Tolerances) -> list[tuple[np.ndarray, np.ndarray]]:
    """:func:`fly` for several aircraft at once (same result), vectorised over the aircraft.

    All aircraft of one dynamics type advance together, step k of each at once (an aircraft with fewer steps
    takes steps of length 0, which leave its state unchanged); the dense samples between the nodes are then
    computed all at once, each by one short step from the node before it.
    """
    schedules = []
    for traj in trajectories:
        if traj.controls is None:
            raise ValueError(f"{traj.callsign}: flying needs controls")
        schedules.append(_schedule(traj, tol))
    aircraft = [scenario.aircraft_by_callsign(traj.callsign) for traj in trajectories]
    result: list[tuple[np.ndarray, np.ndarray]] = [(np.zeros(0), np.zeros((0, ac.dynamics.n_states)))
                                                   for ac in aircraft]
    groups: dict[type, list[int]] = {}
    for i, ac in enumerate(aircraft):
        groups.setdefault(type(ac.dynamics), []).append(i)
    stages = len(_RK_B)
    for members in groups.values():
        models = [aircraft[i].dynamics for i in members]
        steps = max(len(schedules[i].dt) for i in members)
        dt = np.zeros((steps, len(members)))
        u = np.zeros((steps, stages, models[0].n_controls, len(members)))
        for col, i in enumerate(members):
            n = len(schedules[i].dt)
            dt[:n, col] = schedules[i].dt
            u[:n, :, :, col] = schedules[i].u
        nodes = np.empty((steps + 1, models[0].n_states, len(members)))
        nodes[0] = np.stack([aircraft[i].state0.astype(float) for i in members], axis=1)
        model = stacked_model(models)
        for k in range(steps):
            nodes[k + 1] = _rk_step(model, nodes[k], dt[k], u[k])
        # Dense samples of the whole group in one short step each.
        counts = [len(schedules[i].out_t) for i in members]
        col = np.repeat(np.arange(len(members)), counts)
        step = np.concatenate([schedules[i].out_step for i in members])
        out_dt = np.concatenate([schedules[i].out_dt for i in members])
        out_u = np.concatenate([schedules[i].out_u for i in members]).transpose(1, 2, 0)
        dense = _rk_step(stacked_model(models, col), nodes[step, :, col].T, out_dt, out_u).T
        for i, part in zip(members, np.split(dense, np.cumsum(counts)[:-1]), strict=True):
            result[i] = (schedules[i].out_t, part)
    return result


def fly(traj: Trajectory, scenario: Scenario, tol: Tolerances) -> tuple[np.ndarray, np.ndarray]:
    """Re-integrate one aircraft from its scenario initial state under the plan's controls.

    The controls are taken as linear between consecutive samples of the plan; a time that appears twice
    marks a jump of the control (e.g. at a phase boundary): the first sample ends one piece, the second
    starts the next, and the integration restarts there. Returns dense times (step <= tol.sample_dt)
    and states.

    The integration is Butcher's explicit Runge-Kutta method of order 6 with fixed steps: the plan's sample
    intervals, each split evenly into steps of at most ``tol.integration_step_s`` (0.25 s), so the controls
    are linear and the integrand smooth inside every step (no step straddles a kink or a jump). A dense
    sample between two nodes is one short step from the node before it. It is much more accurate than the
    adaptive SciPy solve_ivp(DOP853, rtol=1e-9, atol=1e-11) used before (kept as :func:`fly_reference`).
    Measured against DOP853 at rtol=1e-13 restarted at every plan sample, on the plans of
    scenarios/thesis.yaml, scenarios/five_aircraft.yaml and a 10-aircraft wall scenario (samples <= 0.25 s
    apart): largest position error 9e-14 nm, angles 1.2e-14 rad (round-off); the former integration's was
    1.5e-6 to 2.6e-6 nm, which is also how far the two differ. On controls sampled 2 s apart the error is
    3e-9 nm at 2 s steps, 5e-11 at 1 s, 1.4e-12 at 0.5 s and 1.5e-13 at 0.25 s (order 6, then round-off).
    """
    if traj.controls is None:
        raise ValueError(f"{traj.callsign}: flying needs controls")
    return fly_all([traj], scenario, tol)[0]


def fly_reference(traj: Trajectory, scenario: Scenario, tol: Tolerances) -> tuple[np.ndarray, np.ndarray]:
    """:func:`fly` by SciPy's adaptive solve_ivp (DOP853, tol.rtol and tol.atol), one piece at a time.

    Slower; kept as an independent cross-check of :func:`fly` (same pieces, same dense times).
    """
    assert traj.controls is not None
    model = scenario.aircraft_by_callsign(traj.callsign).dynamics
    t_plan, u_plan = np.asarray(traj.t, float), np.asarray(traj.controls, float)
    cuts = [0, *(np.flatnonzero(np.diff(t_plan) <= 0.0) + 1).tolist(), len(t_plan)]
    times: list[np.ndarray] = []
    states: list[np.ndarray] = []
    state = scenario.aircraft_by_callsign(traj.callsign).state0.astype(float)
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        tp, up = t_plan[a:b], u_plan[a:b]
        if len(tp) < 2:
            continue

        def rhs(time: float, x: np.ndarray, tp=tp, up=up) -> np.ndarray:
            return model.rhs(x, np.array([np.interp(time, tp, up[:, k]) for k in range(up.shape[1])]))

        n = max(2, int(math.ceil((tp[-1] - tp[0]) / tol.sample_dt)) + 1)
        grid = np.union1d(np.linspace(tp[0], tp[-1], n), tp)
        sol = solve_ivp(rhs, (tp[0], tp[-1]), state, method="DOP853", t_eval=grid, rtol=tol.rtol, atol=tol.atol)
        if not sol.success:
            raise RuntimeError(f"{traj.callsign}: re-integration failed after t={tp[0]:.2f} s: {sol.message}")
        times.append(grid[:-1])
        states.append(sol.y.T[:-1])
        state = sol.y[:, -1]
    times.append(t_plan[-1:])
    states.append(state[None, :])
    return np.concatenate(times), np.concatenate(states)
