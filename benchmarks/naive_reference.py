"""A naive reference for the landing optimizer: one fixed uniform mesh, trapezoidal collocation, CasADi Opti.

The same problem as ``mal_planner.landing`` (the multi-phase problem of :mod:`mal_planner.landing.layout`:
phases split at the gate passages and landings, every aircraft airborne in a phase is in it, continuity
between phases), written the straightforward way so that ``benchmarks/bench_scaling.py`` can show what the
project's transcription buys:

* one uniform time step: the phases share about ``intervals`` trapezoidal intervals in proportion to their
  guessed durations (at least 2 each); no hp refinement, no error estimate;
* per node Python loops building CasADi ``Opti`` (MX) expressions; IPOPT with its default options
  (only the print level and the iteration limit set);
* every obstacle checked for every aircraft at every node (no relevance filter).

It reuses the project's single definitions: the aircraft model (``DynamicsModel.rhs``, ``angle_rates``,
``bank_limit_residuals``), the obstacles' ``log_pnorm``, the gate, the separation, the safety margins of the
real NLP (:class:`SafetyMargins`, so both solve the same feasible set), the phase layout (``layout_for``),
and the initial guess from the same initializer (``plan_initial`` multi-rrt, seed 0, ``make_guesses``).
Cost as in the thesis: -sum t_gate + sum of the integrals of gamma'^2 + heading'^2; the landing times are
the fixed ones of the schedule (the scenario's where it gives them). The solution is then checked by the
project's independent verification (reported, not required: the trapezoidal mesh is not refined).

Run alone: .venv/bin/python benchmarks/naive_reference.py scenarios/thesis.yaml [--intervals 100] [--json F]
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
import time
from pathlib import Path

T_PROCESS = time.perf_counter()

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402

from mal_planner import jsonio  # noqa: E402
from mal_planner.dynamics import bank_limit_residuals  # noqa: E402
from mal_planner.initializer import plan_initial  # noqa: E402
from mal_planner.landing.base import LandingOptions  # noqa: E402
from mal_planner.landing.problem import GAMMA_BOUND, HEADING_BOUND, SafetyMargins, phase_guess  # noqa: E402
from mal_planner.landing.solve import layout_for, make_guesses  # noqa: E402
from mal_planner.scales import Scales  # noqa: E402
from mal_planner.scenario import load_scenario  # noqa: E402
from mal_planner.trajectory import Trajectory  # noqa: E402
from mal_planner.verification import verify  # noqa: E402


def _wrap_near(target: float, reference: float) -> float:
    return target + 2.0 * math.pi * round((reference - target) / (2.0 * math.pi))


def solve_naive(scenario_path: str | Path, intervals: int = 100, seed: int = 0, max_iter: int = 3000) -> dict:
    """Build and solve the fixed-mesh NLP; a JSON-ready dict of sizes, times, IPOPT outcome, verification."""
    t_start = time.perf_counter()
    sc = load_scenario(scenario_path)
    initial = plan_initial(sc, "multi-rrt", seed=seed)
    guesses = make_guesses(sc, initial, LandingOptions())  # landing order, fixed landing times
    layout = layout_for(sc, guesses)
    t_init = time.perf_counter() - t_start

    t_build0 = time.perf_counter()
    m = SafetyMargins().in_nm(Scales.of(sc))
    gate = sc.gates[0] if sc.gates else None
    aircraft = [sc.aircraft_by_callsign(cs) for cs in layout.callsigns]
    obstacles = [ob.inflated(m.obstacle_nm) for ob in sc.obstacles]
    lo = sc.airspace[:, 0] + m.airspace_nm
    hi = sc.airspace[:, 1] - m.airspace_nm
    sep2 = (sc.separation_nm + m.separation_nm) ** 2
    n_ph = layout.n_phases
    guess_t = [0.0] + [ev.time_guess for ev in layout.events]
    total = guess_t[-1]
    steps = [max(2, round(intervals * (guess_t[k + 1] - guess_t[k]) / total)) for k in range(n_ph)]

    opti = ca.Opti()
    T = opti.variable(n_ph)  # event times: end of each phase
    opti.set_initial(T, guess_t[1:])
    X: list[dict[int, ca.MX]] = []
    U: list[dict[int, ca.MX]] = []
    cost = 0
    for k in range(n_ph):
        t0 = 0 if k == 0 else T[k - 1]
        h = (T[k] - t0) / steps[k]
        opti.subject_to(T[k] - t0 >= 1e-2)
        who = layout.airborne(k)
        pg = phase_guess(who, aircraft, guesses, (guess_t[k], guess_t[k + 1]), samples=steps[k] + 1)
        X.append({})
        U.append({})
        for j, i in enumerate(who):
            ac = aircraft[i]
            x = opti.variable(5, steps[k] + 1)
            u = opti.variable(2, steps[k] + 1)
            X[k][i], U[k][i] = x, u
            opti.set_initial(x, pg.x[:, 5 * j:5 * j + 5].T)
            opti.set_initial(u, pg.u[:, 2 * j:2 * j + 2].T)
            y_lo, y_hi = lo.copy(), hi.copy()
            if gate is not None:  # each aircraft stays on its side of the gate plane in this phase
                bound = gate.position
                if layout.approaching(k, i):
                    (y_lo if gate.direction < 0 else y_hi)[gate.axis] = bound
                else:
                    (y_hi if gate.direction < 0 else y_lo)[gate.axis] = bound
            rates = []
            for n in range(steps[k] + 1):
                xn, un = x[:, n], u[:, n]
                start = k == 0 and n == 0  # the radar state may sit on the airspace boundary
                for a in range(3):
                    if not start:
                        opti.subject_to(opti.bounded(y_lo[a], xn[a], y_hi[a]))
                opti.subject_to(opti.bounded(-GAMMA_BOUND, xn[3], GAMMA_BOUND))
                opti.subject_to(opti.bounded(-HEADING_BOUND, xn[4], HEADING_BOUND))
                opti.subject_to(opti.bounded(ac.limits.n_h[0] + m.load_factor, un[0], ac.limits.n_h[1] - m.load_factor))
                opti.subject_to(opti.bounded(ac.limits.n_v[0] + m.load_factor, un[1], ac.limits.n_v[1] - m.load_factor))
                opti.subject_to(bank_limit_residuals(un[0], un[1], ac.limits.bank_angle_max - m.bank_rad) <= 0)
                for ob in obstacles:
                    opti.subject_to(ob.log_pnorm(xn[0], xn[1], xn[2]) / ob.p >= m.clearance)
                g_rate, h_rate = ac.dynamics.angle_rates(xn, un)
                rates.append(g_rate**2 + h_rate**2)
            for n in range(steps[k]):  # trapezoidal collocation
                f0 = ac.dynamics.rhs(x[:, n], u[:, n])
                f1 = ac.dynamics.rhs(x[:, n + 1], u[:, n + 1])
                opti.subject_to(x[:, n + 1] == x[:, n] + h / 2 * (f0 + f1))
                cost += h / 2 * (rates[n] + rates[n + 1])
        for a, b in itertools.combinations(who, 2):  # separation of every airborne pair at every node
            for n in range(steps[k] + 1):
                opti.subject_to(ca.sumsqr(X[k][a][:3, n] - X[k][b][:3, n]) >= sep2)
        ev = layout.events[k]
        xe = X[k][ev.aircraft][:, -1]
        heading_guess = float(guesses[ev.aircraft].state_at(np.array([guess_t[k + 1]]))[0, 4])
        if ev.kind == "gate":
            assert gate is not None
            opti.subject_to(xe[gate.axis] == gate.position)
            for (b_lo, b_hi), ax in zip(gate.bounds, gate.other_axes, strict=True):
                opti.subject_to(opti.bounded(b_lo + m.hole_nm, xe[ax], b_hi - m.hole_nm))
            opti.subject_to(xe[3] == gate.flight_path_angle)
            opti.subject_to(xe[4] == _wrap_near(gate.heading, heading_guess))
            cost -= T[k]
        else:
            rw = sc.runway_state
            opti.subject_to(xe[:3] == np.clip(rw[:3], lo, hi))
            opti.subject_to(xe[3] == float(rw[3]))
            opti.subject_to(xe[4] == _wrap_near(float(rw[4]), heading_guess))
            opti.subject_to(T[k] == guesses[ev.aircraft].landing_time)
    for i, ac in enumerate(aircraft):  # initial states; continuity between phases
        opti.subject_to(X[0][i][:, 0] == ac.state0)
    for k in range(n_ph - 1):
        for i in layout.airborne(k + 1):
            opti.subject_to(X[k][i][:, -1] == X[k + 1][i][:, 0])
    opti.minimize(cost)
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes", "max_iter": max_iter})
    build_s = time.perf_counter() - t_build0
    jac_nnz = int(ca.jacobian_sparsity(opti.g, opti.x).nnz())

    t_solve0 = time.perf_counter()
    try:
        sol = opti.solve()
        value = sol.value
    except RuntimeError:  # IPOPT did not succeed: report its status and the last iterate
        value = opti.debug.value
    solve_s = time.perf_counter() - t_solve0
    stats = opti.stats()

    out = {
        "scenario": str(scenario_path), "n_aircraft": len(aircraft), "intervals": int(sum(steps)),
        "intervals_per_phase": steps, "phases": [layout.phase_name(k) for k in range(n_ph)],
        "variables": int(opti.nx), "constraints": int(opti.ng), "jac_nnz": jac_nnz,
        "initializer_s": t_init, "build_s": build_s, "solve_s": solve_s, "optimizer_s": build_s + solve_s,
        "iterations": int(stats.get("iter_count", -1)), "status": str(stats.get("return_status", "")),
        "success": bool(stats.get("success", False)), "objective": float(value(opti.f)),
    }
    times = [0.0] + [float(v) for v in np.atleast_1d(value(T))]
    trajectories = []
    for i, cs in enumerate(layout.callsigns):
        ts, xs, us, ps = [], [], [], []
        for k in range(n_ph):
            if i in X[k]:
                ts.append(np.linspace(times[k], times[k + 1], steps[k] + 1))
                xs.append(np.asarray(value(X[k][i])).T)
                us.append(np.asarray(value(U[k][i])).T)
                ps.append(np.full(steps[k] + 1, k))
        trajectories.append(Trajectory(cs, np.concatenate(ts), np.concatenate(xs), np.concatenate(us),
                                       np.concatenate(ps)))
    out["gate_times"] = {layout.callsigns[ev.aircraft]: times[k + 1] for k, ev in enumerate(layout.events)
                         if ev.kind == "gate"}
    try:
        report = verify(sc, trajectories, landing_times={g.callsign: g.landing_time for g in guesses})
        out["verified"], out["verification_reasons"] = bool(report.verified), list(report.reasons[:3])
    except Exception as exc:  # the verification of a failed solve may itself fail: a reason, not a crash
        out["verified"], out["verification_reasons"] = False, [f"verification error: {exc}"]
    out["process_s_in_child"] = time.perf_counter() - T_PROCESS
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("scenario", nargs="?", default="scenarios/thesis.yaml")
    p.add_argument("--intervals", type=int, default=100, help="trapezoidal intervals in all (default 100)")
    p.add_argument("--seed", type=int, default=0, help="initializer seed (default 0)")
    p.add_argument("--json", type=Path, default=None, help="write the result here (default: stdout)")
    args = p.parse_args(argv)
    result = solve_naive(args.scenario, args.intervals, args.seed)
    text = jsonio.dumps(result, indent=1)
    if args.json:
        args.json.write_text(text, encoding="utf-8")
    else:
        print(text)
    print(f"naive: {result['status']} in {result['iterations']} iterations, build {result['build_s']:.2f} s, "
          f"solve {result['solve_s']:.2f} s, verified {result['verified']}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
