"""Independent verification of planned trajectories.

Deliberately shares nothing with the transcription: it re-integrates each aircraft from its initial
state under the planned controls (the dynamics model's own right-hand side, by a fixed-step Runge-Kutta
method of order 6 on the plan's control samples, all aircraft at once; see :func:`fly`), samples the flown
trajectory densely and checks the airspace, the exact obstacle geometry (and every crossing of a gate plane), the
separation of every pair of airborne aircraft, the load factors and the bank angle, the gate and runway
conditions (their headings are ground tracks: in a scenario's wind the flown, air-relative heading must be the
crabbed one; the flown track is reported too). ``verified`` is True only when every check holds.

The safety minima (airspace, obstacles, the hole, separation, load factors, bank angle) allow NO tolerance
on the unsafe side. The flown trajectory is known at dense samples; between them the true path departs
from the straight chord by at most ``dt^2/8 * a_max`` (a_max: the largest acceleration the load-factor
limits allow), and that bound is added on the safe side: obstacles are inflated by it, the separation
and the airspace are required with it to spare. The published controls are linear between their
samples (that is how :func:`fly` flies them), so checking the samples against the (convex) limits is
exact. Tolerances apply only to accuracy: how closely the flown path matches the published one, and how
closely it meets the runway and gate attitudes and positions.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

from mal_planner.dynamics import DynamicsModel, stacked_model
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.trajectory import Trajectory
from mal_planner.units import nm_to_ft
from mal_planner.wake import wake_distance_nm


@dataclass(frozen=True)
class Tolerances:
    """Accuracy tolerances, in planner units (nm, s, rad). None of them relaxes a safety minimum.

    The defaults are the thesis's; :meth:`for_scenario` gives every scenario its own, relative to its turn
    radius and turn time (:class:`mal_planner.scales.Scales`), which is what :func:`verify` uses by default.
    """

    sample_dt: float = 0.05
    """Sampling step of the flown trajectory (the issue asked for <= 0.1 s; T / 150)."""
    deviation_nm: float = 0.005
    """Largest position difference between the published and the re-integrated trajectory (about 9 m in the
    thesis; the scenario's path accuracy L / 60: the optimizer's separation margin is twice this, so the
    published paths keep the separation as well)."""
    deviation_angle: float = math.radians(1.0)
    position_nm: float = 1e-3
    """How close to the runway threshold the flown trajectory must end (a fifth of the path accuracy)."""
    attitude: float = math.radians(0.5)
    """Slack on the flown gate and runway attitudes (the flown path drifts from the plan a little)."""
    landing_time_s: float = 1e-3
    """How closely a flown landing meets a fixed landing time (T / 7500)."""
    integration_step_s: float = 0.25
    """Longest step of the fixed-step integration in :func:`fly` (the plan's sample intervals are split to it; T / 15
    for a scenario: its error at 0.5 s steps is 1.4e-12 nm, see :func:`fly`)."""
    rtol: float = 1e-9
    atol: float = 1e-11
    """Tolerances of :func:`fly_reference`, the adaptive SciPy integration kept as a cross-check."""

    @classmethod
    def for_scenario(cls, scenario: Scenario) -> Tolerances:
        """The tolerances of ``scenario``: the thesis's values as fractions of its turn radius L and turn time T
        (thesis: L = 0.302 nm, T = 7.55 s)."""
        scales = Scales.of(scenario)
        return cls(sample_dt=scales.seconds(1.0 / 150.0), deviation_nm=scales.accuracy_nm,
                   position_nm=0.2 * scales.accuracy_nm, landing_time_s=scales.seconds(1.0 / 7500.0),
                   integration_step_s=scales.seconds(1.0 / 15.0))


@dataclass
class AircraftCheck:
    callsign: str
    landing_time: float
    max_position_deviation_nm: float
    max_angle_deviation: float
    bank_min_deg: float
    bank_max_deg: float
    n_v_min: float
    airspace_violation_nm: float
    obstacle_hits: list[str] = field(default_factory=list)
    obstacle_hit_times_s: list[float] = field(default_factory=list)
    gate_events: list[dict] = field(default_factory=list)
    runway_error: dict = field(default_factory=dict)
    limit_violation_times_s: list[float] = field(default_factory=list)
    """Times at which the controls break a limit, the flown path leaves the airspace or misses the hole, or (for
    refining the mesh) the flown path drifts fastest from the published one when it drifts too far."""


@dataclass
class PairCheck:
    pair: str
    min_distance_nm: float
    at_time_s: float
    violation_times_s: list[float] = field(default_factory=list)
    """Times of the local minima of the distance below the required separation."""


@dataclass
class LandingGap:
    """Two consecutive landings: the time between them against the time they need."""

    pair: str
    """leader->follower."""
    gap_s: float
    needed_s: float
    """The scenario's landing spacing, or the wake minimum at the follower's speed when that is more."""
    wake: str | None = None
    """leader->follower categories when a wake table applies."""
    wake_nm: float | None = None
    """The table's distance (the radar minimum where the table lists none)."""


@dataclass
class VerificationReport:
    verified: bool
    reasons: list[str]
    aircraft: list[AircraftCheck]
    pairs: list[PairCheck]
    tolerances: Tolerances
    by_aircraft: dict[str, list[str]] = field(default_factory=dict)
    """The reasons that concern each aircraft (a separation failure concerns both)."""
    landings: list[LandingGap] = field(default_factory=list)
    """Consecutive landings in landing order."""

    def aircraft_verified(self, callsign: str) -> bool:
        return not self.by_aircraft.get(callsign)

    def to_dict(self) -> dict:
        return asdict(self)

    def violating_callsigns(self) -> set[str]:
        """The aircraft with a violation time (both of a pair that comes too close)."""
        out = {cs for p in self.pairs if p.violation_times_s for cs in p.pair.split("-")}
        return out | {a.callsign for a in self.aircraft if a.obstacle_hit_times_s or a.limit_violation_times_s}

    def violation_times(self) -> list[float]:
        """Times at which a safety minimum is broken (for refining the mesh there)."""
        times = [t for p in self.pairs for t in p.violation_times_s]
        times += [t for a in self.aircraft for t in a.obstacle_hit_times_s + a.limit_violation_times_s]
        return sorted(times)


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
    """One step of the Runge-Kutta method above for every column: x (5, n), dt (n,), u (stages, 2, n)."""
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
    """(n, stages, 2) controls at the stages of each step."""
    out_t: np.ndarray
    """(m,) dense sample times."""
    out_step: np.ndarray
    """(m,) index of the integration node each sample is reached from (the state before that step)."""
    out_dt: np.ndarray
    """(m,) time from that node to the sample (0 at a node, less than the step otherwise)."""
    out_u: np.ndarray
    """(m, stages, 2) controls at the stages of that last short step."""


def _stage_controls(t0: np.ndarray, dt: np.ndarray, t1: np.ndarray, tp: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Controls, linear between the samples (tp, up) of one piece, at the stages of steps t0 -> t0 + dt."""
    times = t0[:, None] + _RK_C * dt[:, None]
    times[:, _RK_C == 1.0] = t1[:, None]  # the step's exact end (a plan sample where the controls have a kink)
    return np.stack([np.interp(times, tp, up[:, 0]), np.interp(times, tp, up[:, 1])], axis=-1)


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
    stages = len(_RK_B)
    out_t.append(t_plan[-1:])
    out_step.append(np.array([done]))
    out_dt.append(np.zeros(1))
    out_u.append(np.zeros((1, stages, 2)))
    dt = np.concatenate(dts) if dts else np.zeros(0)
    u = np.concatenate(us) if us else np.zeros((0, stages, 2))
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
    result: list[tuple[np.ndarray, np.ndarray]] = [(np.zeros(0), np.zeros((0, 5)))] * len(trajectories)
    groups: dict[type, list[int]] = {}
    for i, ac in enumerate(aircraft):
        groups.setdefault(type(ac.dynamics), []).append(i)
    stages = len(_RK_B)
    for members in groups.values():
        models = [aircraft[i].dynamics for i in members]
        steps = max(len(schedules[i].dt) for i in members)
        dt = np.zeros((steps, len(members)))
        u = np.zeros((steps, stages, 2, len(members)))
        for col, i in enumerate(members):
            n = len(schedules[i].dt)
            dt[:n, col] = schedules[i].dt
            u[:n, :, :, col] = schedules[i].u
        nodes = np.empty((steps + 1, 5, len(members)))
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
            return model.rhs(x, np.array([np.interp(time, tp, up[:, 0]), np.interp(time, tp, up[:, 1])]))

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


def chord_error_bound(aircraft, t: np.ndarray) -> float:
    """Largest distance (nm) between the path and the chord between two samples ``t`` apart.

    A constant-speed point mass accelerates at g sqrt((n_v - cos gamma)^2 + n_h^2) at most (a constant wind adds
    none); a curve with acceleration <= a stays within dt^2 a / 8 of its chord over a step dt.
    """
    lim = aircraft.limits
    a_max = aircraft.dynamics.gravity * math.hypot(max(abs(lim.n_v[0] - 1.0), lim.n_v[1] + 1.0),
                                                   max(abs(lim.n_h[0]), abs(lim.n_h[1])))
    dt = float(np.max(np.diff(t))) if len(t) > 1 else 0.0
    return dt * dt * a_max / 8.0


def _gate_crossings(gate, t: np.ndarray, states: np.ndarray) -> list[dict]:
    """Every crossing of the gate plane, linearly interpolated between dense samples."""
    d = gate.signed_distance(states[:, :3])
    events = []
    for k in np.flatnonzero((d[:-1] > 0) & (d[1:] <= 0) | (d[:-1] < 0) & (d[1:] >= 0)):
        w = d[k] / (d[k] - d[k + 1]) if d[k] != d[k + 1] else 0.0
        point = states[k] + w * (states[k + 1] - states[k])
        events.append({
            "gate": gate.name,
            "time_s": float(t[k] + w * (t[k + 1] - t[k])),
            "position": point[:3].tolist(),
            "in_hole": bool(gate.in_hole(point[:3])),
            "direction_ok": bool(d[k] > 0),
            "gamma": float(point[3]),
            "heading": float(point[4]),
        })
    return events


def _angle_error(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))


def verify(scenario: Scenario, trajectories: list[Trajectory], tol: Tolerances | None = None,
           landing_times: dict[str, float] | None = None) -> VerificationReport:
    """Check planned trajectories (with controls) against the scenario; see the module docstring.

    ``landing_times`` are the landing times the plan must meet (relative to its start), if fixed.

    Cost (median of 5, 2 shared cores): thesis plan 0.072 s (0.92 s with the former per-aircraft SciPy
    integration), five_aircraft 0.089 s (1.73 s), a 10-aircraft wall plan (1587 samples on the longest
    trajectory) 0.20 s (2.93 s). Most of it is the integration, whose sequential steps are the plan's
    sample intervals of the longest trajectory, each step for all aircraft at once.
    """
    tol = tol or Tolerances.for_scenario(scenario)
    reasons: list[str] = []
    by_aircraft: dict[str, list[str]] = {t.callsign: [] for t in trajectories}

    def fail(callsigns: tuple[str, ...], text: str) -> None:
        reasons.append(text)
        for callsign in callsigns:
            by_aircraft.setdefault(callsign, []).append(text)

    checks: list[AircraftCheck] = []
    flown: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for traj in trajectories:
        if traj.controls is None:
            raise ValueError(f"{traj.callsign}: verification needs controls")
    for traj, (t, x) in zip(trajectories, fly_all(trajectories, scenario, tol), strict=True):
        cs = traj.callsign
        aircraft = scenario.aircraft_by_callsign(cs)
        flown[cs] = (t, x)
        solved = traj.state_at(t)
        pos_dev = float(np.max(np.linalg.norm(solved[:, :3] - x[:, :3], axis=1)))
        ang_dev = float(np.max(np.abs(np.remainder(solved[:, 3:] - x[:, 3:] + np.pi, 2 * np.pi) - np.pi)))
        if pos_dev > tol.deviation_nm:
            fail((cs,), f"{cs}: re-integrated path deviates {pos_dev:.4g} nm from the plan")
            # Refine where the deviation grows fastest: the mesh is least accurate there.
            growth = np.diff(np.linalg.norm(solved[:, :3] - x[:, :3], axis=1)) / np.maximum(np.diff(t), 1e-9)
            accuracy_times = t[np.argsort(growth)[-3:]].tolist()
        else:
            accuracy_times = []
        if ang_dev > tol.deviation_angle:
            fail((cs,), f"{cs}: re-integrated angles deviate {math.degrees(ang_dev):.3g} deg from the plan")
        chord = chord_error_bound(aircraft, t)
        limit_times: list[float] = list(accuracy_times)
        space = _path_in_space(scenario, cs, t, x, chord)
        violation, hits, hit_times = space.airspace_violation_nm, space.obstacles, space.obstacle_times
        for text in space.reasons:
            fail((cs,), text)
        limit_times += space.airspace_times
        # Gates: every plane crossing must be in the hole, in the right direction, with the set attitude.
        events = []
        for gate in scenario.gates:
            crossings = _gate_crossings(gate, t, x)
            if not crossings and gate.signed_distance(aircraft.state0[:3]) > 0:
                fail((cs,), f"{cs}: never passes gate {gate.name!r}")
            # The gate's heading is a ground track: in a wind the flown (air) heading is crabbed.
            gate_heading = aircraft.heading_for_track(gate.heading, gate.flight_path_angle)
            for ev in crossings:
                ev["track"] = aircraft.dynamics.ground_track(ev["gamma"], ev["heading"])
                ev["gamma_error"] = _angle_error(ev["gamma"], gate.flight_path_angle)
                ev["heading_error"] = _angle_error(ev["heading"], gate_heading)
                if not gate.in_hole(np.array(ev["position"]), -chord):
                    fail((cs,), f"{cs}: crosses the plane of {gate.name!r} outside the hole at "
                                   f"{np.round(ev['position'], 4).tolist()}")
                    limit_times.append(ev["time_s"])
                if not ev["direction_ok"]:
                    fail((cs,), f"{cs}: crosses {gate.name!r} backwards at t={ev['time_s']:.2f} s")
                if ev["gamma_error"] > tol.attitude or ev["heading_error"] > tol.attitude:
                    g_err, h_err = math.degrees(ev["gamma_error"]), math.degrees(ev["heading_error"])
                    fail((cs,), f"{cs}: attitude at {gate.name!r} off by {g_err:.3g} / {h_err:.3g} deg")
            events.extend(crossings)
        # Load factors and bank angle, exactly as published (linear between samples: the limits are convex).
        n_h, n_v = traj.controls[:, 0], traj.controls[:, 1]
        lim = aircraft.limits
        bank = np.degrees(np.arctan2(n_h, n_v))
        cap = np.tan(lim.bank_angle_max) * n_v
        bad = (np.abs(n_h) > cap) | (n_h < lim.n_h[0]) | (n_h > lim.n_h[1]) | (n_v < lim.n_v[0]) | (n_v > lim.n_v[1])
        if np.any(np.abs(n_h) > cap):
            fail((cs,), f"{cs}: bank angle reaches {np.max(np.abs(bank)):.3f} deg (limit "
                        f"{math.degrees(lim.bank_angle_max):.1f}) at t={traj.t[np.argmax(np.abs(bank))]:.2f} s")
        if np.any(bad & ~(np.abs(n_h) > cap)):
            k = int(np.flatnonzero(bad)[0])
            fail((cs,), f"{cs}: load factors ({n_h[k]:.4g}, {n_v[k]:.4g}) outside n_h {list(lim.n_h)}, "
                        f"n_v {list(lim.n_v)} at t={traj.t[k]:.2f} s")
        limit_times += traj.t[bad].tolist()
        # Runway.
        final = x[-1]
        rw = scenario.runway_state
        runway = {
            "position_error_nm": float(np.linalg.norm(final[:3] - rw[:3])),
            "gamma_error": _angle_error(final[3], rw[3]),
            "heading_error": _angle_error(final[4], scenario.runway_heading(aircraft)),  # crabbed in a wind
            "track_error": _angle_error(aircraft.dynamics.ground_track(final[3], final[4]), rw[4]),
        }
        if runway["position_error_nm"] > tol.position_nm + tol.deviation_nm:
            fail((cs,), f"{cs}: ends {runway['position_error_nm']:.4g} nm from the runway")
        if runway["gamma_error"] > tol.attitude or runway["heading_error"] > tol.attitude:
            fail((cs,), f"{cs}: runway attitude off by {math.degrees(runway['gamma_error']):.3g} / "
                           f"{math.degrees(runway['heading_error']):.3g} deg")
        if landing_times is not None and cs in landing_times and \
                abs(t[-1] - landing_times[cs]) > tol.landing_time_s:
            fail((cs,), f"{cs}: lands at {t[-1]:.3f} s, not the fixed {landing_times[cs]:.3f} s")
        checks.append(AircraftCheck(cs, float(t[-1]), pos_dev, ang_dev, float(np.min(bank)), float(np.max(bank)),
                                    float(np.min(n_v)), violation, hits, hit_times, events, runway, limit_times))
    # Landing-time spacing in landing order.
    order = sorted(checks, key=lambda c: c.landing_time)
    landings: list[LandingGap] = []
    for a, b in itertools.pairwise(order):
        gap = b.landing_time - a.landing_time
        record = LandingGap(f"{a.callsign}->{b.callsign}", gap, scenario.landing_spacing_s)
        landings.append(record)
        if gap < scenario.landing_spacing_s - tol.landing_time_s:
            fail((a.callsign, b.callsign), f"{a.callsign}->{b.callsign}: landings {gap:.2f} s apart "
                                           f"(minimum {scenario.landing_spacing_s:.1f} s)")
        if scenario.wake != "none":
            # The wake table's distance, flown by the follower at its own speed (checked here, not taken from
            # the schedule's spacing), with no tolerance: the schedule keeps a margin for round-off.
            lead, follow = scenario.aircraft_by_callsign(a.callsign), scenario.aircraft_by_callsign(b.callsign)
            nm = wake_distance_nm(scenario.wake, lead.wake_category, follow.wake_category, scenario.separation_nm)
            record.wake, record.wake_nm = f"{lead.wake_category}->{follow.wake_category}", nm
            need = nm / scenario.final_ground_speed(follow)  # on final at its ground speed (longer into a headwind)
            record.needed_s = max(record.needed_s, need)
            if gap < need:
                fail((a.callsign, b.callsign), f"{a.callsign}->{b.callsign}: landings {gap:.2f} s apart, the "
                                               f"{scenario.wake} wake minimum {lead.wake_category}->"
                                               f"{follow.wake_category} of {nm:g} nm needs {need:.1f} s")
    pairs = _separation(flown, scenario, tol, fail)
    return VerificationReport(not reasons, reasons, checks, pairs, tol, by_aircraft, landings)


@dataclass
class _SpaceCheck:
    airspace_violation_nm: float
    airspace_times: list[float]
    obstacles: list[str]
    obstacle_times: list[float]
    reasons: list[str]


def _path_in_space(scenario: Scenario, cs: str, t: np.ndarray, x: np.ndarray, chord: float) -> _SpaceCheck:
    """Airspace and obstacles along a sampled path whose chords are within ``chord`` of it."""
    reasons: list[str] = []
    # Airspace, with the chord error to spare (not at the given initial state, which may lie on a bound).
    spare = np.where(t > t[0], chord, 0.0)[:, None]
    below = scenario.airspace[:, 0] - x[:, :3] + spare
    above = x[:, :3] - scenario.airspace[:, 1] + spare
    out_of_space = np.max(np.maximum(below, above), axis=1)
    violation = float(max(np.max(out_of_space), 0.0))
    if violation > 0.0:
        k = int(np.argmax(out_of_space))
        reasons.append(f"{cs}: leaves the airspace by {violation:.3g} nm at t={t[k]:.2f} s")
    # Obstacles, inflated by the chord error: exact containment of every sample and every chord.
    hits, hit_times = [], []
    for ob in scenario.obstacles:
        grown = ob.inflated(chord)
        inside = grown.contains(x[:, :3])
        inside[:-1] |= grown.segment_hits(x[:-1, :3], x[1:, :3])
        if np.any(inside):
            hits.append(ob.name)
            hit_times += t[inside].tolist()
            reasons.append(f"{cs}: enters obstacle {ob.name!r} at t={t[inside][0]:.2f} s")
    return _SpaceCheck(violation, t[out_of_space > 0.0].tolist(), hits, hit_times, reasons)


def flown_path_infringements(scenario: Scenario, aircraft, t: np.ndarray, x: np.ndarray) -> list[str]:
    """Airspace exits and obstacle entries of a flown track (samples ``t``, states ``x``), one line each: the
    checks :func:`verify` makes on a re-integrated plan, for tracks flown in closed loop."""
    return _path_in_space(scenario, aircraft.callsign, t, x, chord_error_bound(aircraft, t)).reasons


def separation_checks(flown: dict[str, tuple[np.ndarray, np.ndarray]], scenario: Scenario, fail) -> list[PairCheck]:
    """Closest approach of every pair of flown tracks (``fail(callsigns, text)`` for each loss), as :func:`verify`
    checks plans: on the union of both tracks' samples, the chord errors taken off."""
    return _separation(flown, scenario, Tolerances.for_scenario(scenario), fail)


def _separation(flown: dict[str, tuple[np.ndarray, np.ndarray]], scenario: Scenario, tol: Tolerances,
                fail) -> list[PairCheck]:
    """Minimum distance of every pair while both are airborne, on a common dense grid.

    Each pair has its own grid (the union of both aircraft's samples while both fly); the grids of all pairs
    are concatenated and evaluated at once, with the same arithmetic per sample as pair by pair.
    """
    spare_of = {cs: chord_error_bound(scenario.aircraft_by_callsign(cs), t) for cs, (t, _) in flown.items()}
    names, grids = [], []
    for (a, (ta, xa)), (b, (tb, xb)) in itertools.combinations(flown.items(), 2):
        t_end = min(ta[-1], tb[-1])
        t_start = max(ta[0], tb[0])
        if t_end <= t_start:
            continue
        # On the union of both sample grids both chords are linear, so the closest approach on each interval
        # is exact; each path departs from its chords by at most its chord error: both are taken off. A pair a
        # coarse grid proves separated is evaluated only where its closest approach can be (see _far_apart).
        windows = _far_apart(scenario, a, b, ta, xa, tb, xb, t_start, t_end, spare_of[a] + spare_of[b])
        for lo, hi in windows or [(t_start, t_end)]:
            grid = np.union1d(ta[(ta >= lo) & (ta <= hi)], tb[(tb >= lo) & (tb <= hi)])
            names.append((a, b))
            grids.append(np.union1d(grid, [lo, hi]))
    checks: list[PairCheck] = []
    for k in range(0, len(names), PAIRS_PER_BATCH):  # batches bound the memory (20 aircraft: 600 -> 200 MB)
        checks += _closest_approaches(names[k:k + PAIRS_PER_BATCH], grids[k:k + PAIRS_PER_BATCH], flown, spare_of,
                                      scenario, fail)
    pairs: dict[str, PairCheck] = {}
    for check in checks:  # a pair evaluated in windows: its closest one, and every violation (none: it is proven)
        best = pairs.get(check.pair)
        if best is None or check.min_distance_nm < best.min_distance_nm:
            check.violation_times_s = (best.violation_times_s if best else []) + check.violation_times_s
            pairs[check.pair] = check
        else:
            best.violation_times_s += check.violation_times_s
    return list(pairs.values())


PAIRS_PER_BATCH = 16


def _far_apart(scenario: Scenario, a: str, b: str, ta: np.ndarray, xa: np.ndarray, tb: np.ndarray, xb: np.ndarray,
               t_start: float, t_end: float, spare: float) -> list[tuple[float, float]] | None:
    """The time windows that can hold a pair's closest approach when a coarse grid proves the pair separated,
    else None (the pair is checked all along).

    Between grid times dt apart, two aircraft at speeds V_a and V_b close in by at most (V_a + V_b) dt / 2 from
    the nearer grid time, so a pair whose grid distances all exceed the separation by that (plus both chord
    errors) is separated all along; its smallest distance lies in an interval whose lower bound is below the
    grid's smallest distance, which is one or a few. The dense check all along was most of the verification's
    time at 20 aircraft of a terminal area. The grid step is separation / (V_a + V_b): half a separation of slack.
    V_a + V_b (airspeeds) bounds the closing speed in a wind too: a uniform wind moves both alike, so their relative
    velocity is that of their air velocities.
    """
    speeds = scenario.aircraft_by_callsign(a).speed + scenario.aircraft_by_callsign(b).speed
    radius = scenario.separation_radius_nm  # farther apart than this is separated, also for a cylinder
    dt = radius / speeds
    grid = np.append(np.arange(t_start, t_end, dt), t_end)
    if len(grid) < 3:
        return None
    pa = np.column_stack([np.interp(grid, ta, xa[:, k]) for k in range(3)])
    pb = np.column_stack([np.interp(grid, tb, xb[:, k]) for k in range(3)])
    dist = np.linalg.norm(pa - pb, axis=1)
    lower = np.minimum(dist[:-1], dist[1:]) - 0.5 * speeds * np.diff(grid)
    if lower.min() - spare <= radius:
        return None
    keep = np.flatnonzero(lower <= dist.min())
    return [(float(grid[k]), float(grid[k + 1])) for k in keep]


def _closest_approaches(names: list[tuple[str, str]], grids: list[np.ndarray],
                        flown: dict[str, tuple[np.ndarray, np.ndarray]], spare_of: dict[str, float],
                        scenario: Scenario, fail) -> list[PairCheck]:
    """Closest approach of each pair on its grid, all pairs of the batch evaluated at once."""
    counts = np.array([len(g) for g in grids])
    first = np.cumsum(counts) - counts
    last = first + counts - 1
    grid = np.concatenate(grids)
    pair = np.repeat(np.arange(len(grids)), counts)
    # Positions of both aircraft of every pair on its grid (coordinates in rows, so the sums below are cheap).
    pa, pb = np.empty((3, len(grid))), np.empty((3, len(grid)))
    for j, (a, b) in enumerate(names):
        part = slice(first[j], last[j] + 1)
        for out, (t, x) in ((pa, flown[a]), (pb, flown[b])):
            for k in range(3):
                out[k, part] = np.interp(grids[j], t, x[:, k])
    rel = pa - pb
    step = np.zeros_like(rel)  # rel[i+1] - rel[i] within a pair; 0 at a pair's last sample
    step[:, :-1] = np.diff(rel, axis=1)
    step[:, last] = 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        s_min = np.clip(np.nan_to_num(-np.sum(rel * step, axis=0) / np.sum(step * step, axis=0)), 0.0, 1.0)
    near = rel + s_min * step
    closest = np.sqrt(np.sum(near * near, axis=0))
    closest[last] = np.sqrt(np.sum(rel[:, last] * rel[:, last], axis=0))
    spare = np.array([spare_of[a] + spare_of[b] for a, b in names])[pair]
    dist = closest - spare
    gap = np.zeros(len(grid))
    gap[:-1] = np.diff(grid)
    at = grid + s_min * gap
    at[last] = grid[last]
    low = dist < scenario.separation_nm
    if scenario.vertical_separation_nm is not None:  # a cylinder: separated horizontally OR vertically
        low, ratio, s_at = _cylinder_chords(rel, step, spare, scenario.separation_nm, scenario.vertical_separation_nm)
        dist = scenario.separation_nm * ratio
        at = grid + s_at * gap
        at[last] = grid[last]
    left = np.ones(len(grid), bool)
    left[1:] = dist[1:] <= dist[:-1]
    left[first] = True
    right = np.ones(len(grid), bool)
    right[:-1] = dist[:-1] <= dist[1:]
    right[last] = True
    violations = np.flatnonzero(low & left & right)
    pairs = []
    for j, (a, b) in enumerate(names):
        k = first[j] + int(np.argmin(dist[first[j]:last[j] + 1]))
        mine = violations[(violations >= first[j]) & (violations <= last[j])]
        pairs.append(PairCheck(f"{a}-{b}", float(dist[k]), float(at[k]), at[mine].tolist()))
        if scenario.vertical_separation_nm is not None:
            if len(mine):
                # Told at the closest horizontal approach on the violating chords (the ratio is often flat there).
                dh, r0 = step[:2, mine], rel[:2, mine]
                dd = np.sum(dh * dh, axis=0)
                s_h = np.clip(-np.sum(r0 * dh, axis=0) / np.where(dd > 0.0, dd, 1.0), 0.0, 1.0)
                i = int(np.argmin(np.linalg.norm(r0 + s_h * dh, axis=0)))
                k, s_k = int(mine[i]), float(s_h[i])
                p = rel[:, k] + s_k * step[:, k]
                fail((a, b), f"{a}-{b}: {math.hypot(p[0], p[1]):.4f} nm apart horizontally and "
                             f"{nm_to_ft(abs(p[2])):.0f} ft vertically at t={grid[k] + s_k * gap[k]:.2f} s "
                             f"(minima {scenario.separation_nm} nm or "
                             f"{nm_to_ft(scenario.vertical_separation_nm):.0f} ft)")
        elif dist[k] < scenario.separation_nm:
            fail((a, b), f"{a}-{b}: {dist[k]:.4f} nm apart at t={at[k]:.2f} s "
                           f"(minimum {scenario.separation_nm} nm)")
    return pairs


def _cylinder_chords(rel: np.ndarray, step: np.ndarray, spare: np.ndarray, h_min: float, v_min: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A cylindrical protected zone on the chords rel + s step, s in [0, 1] (columns; spare: the chord errors).

    Returns, per chord: whether some s has h < H + spare AND |dz| < V + spare (exact: the first set is the inside
    of a quadratic's roots, the second an interval); the smallest max((h - spare) / H, (|dz| - spare) / V) over the
    chord (the pair's separation in minima, < 1 inside; a convex function: its minimum lies at an end, at the
    smallest h, at dz = 0, or where the two terms are equal); and the s where it is reached.
    """
    h0, dh, z0, dz = rel[:2], step[:2], rel[2], step[2]
    qa, qb = np.sum(dh * dh, axis=0), 2.0 * np.sum(h0 * dh, axis=0)
    qc = np.sum(h0 * h0, axis=0)
    big_h, big_v = h_min + spare, v_min + spare
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = qb * qb - 4.0 * qa * (qc - big_h * big_h)
        root = np.sqrt(np.maximum(disc, 0.0))
        flat = qa <= 0.0
        h_lo = np.where(flat, np.where(qc < big_h * big_h, -np.inf, np.inf), (-qb - root) / (2.0 * qa))
        h_hi = np.where(flat, np.where(qc < big_h * big_h, np.inf, -np.inf), (-qb + root) / (2.0 * qa))
        h_lo, h_hi = np.where(~flat & (disc <= 0.0), np.inf, h_lo), np.where(~flat & (disc <= 0.0), -np.inf, h_hi)
        level = dz == 0.0
        v_a, v_b = (-big_v - z0) / dz, (big_v - z0) / dz
        v_lo = np.where(level, np.where(np.abs(z0) < big_v, -np.inf, np.inf), np.minimum(v_a, v_b))
        v_hi = np.where(level, np.where(np.abs(z0) < big_v, np.inf, -np.inf), np.maximum(v_a, v_b))
    inside = np.maximum.reduce([np.zeros_like(qa), h_lo, v_lo]) < np.minimum.reduce([np.ones_like(qa), h_hi, v_hi])
    # Candidates of the smallest ratio: the ends, the smallest h, dz = 0, and where both terms are equal.
    k = h_min / v_min
    cands = [np.zeros_like(qa), np.ones_like(qa)]
    with np.errstate(divide="ignore", invalid="ignore"):
        cands.append(np.where(qa > 0.0, -qb / (2.0 * qa), 0.0))
        cands.append(np.where(level, 0.0, -z0 / dz))
        for sign in (1.0, -1.0):  # h(s) = k (sign dz(s) - spare) + spare, squared: a quadratic in s
            c1, c0 = k * sign * dz, k * (sign * z0 - spare) + spare
            a2, b2, c2 = qa - c1 * c1, qb - 2.0 * c1 * c0, qc - c0 * c0
            d2 = np.sqrt(np.maximum(b2 * b2 - 4.0 * a2 * c2, 0.0))
            for r in ((-b2 - d2) / (2.0 * a2), (-b2 + d2) / (2.0 * a2)):
                cands.append(np.where(np.abs(a2) > 1e-300, r, np.where(b2 != 0.0, -c2 / b2, 0.0)))
    best_ratio = np.full(qa.shape, np.inf)
    best_s = np.zeros_like(qa)
    for s in cands:
        s = np.clip(np.nan_to_num(s, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
        h = np.sqrt(np.maximum(qa * s * s + qb * s + qc, 0.0))
        ratio = np.maximum((h - spare) / h_min, (np.abs(z0 + s * dz) - spare) / v_min)
        better = ratio < best_ratio
        best_ratio, best_s = np.where(better, ratio, best_ratio), np.where(better, s, best_s)
    return inside, best_ratio, best_s
