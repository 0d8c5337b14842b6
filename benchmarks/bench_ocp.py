"""Timing benchmark of the OCP engine on a landing-sized synthetic problem.

Three point-mass aircraft (5 states each) fly jointly in phase 1 (15 states, pairwise
horizontal separation path constraints), then continue in five single-aircraft phases
to a common goal.  The 15 initial states are problem parameters, so a second solve
with perturbed initial states reuses the NLPs built for every mesh.

Run: PYTHONPATH=src python benchmarks/bench_ocp.py
"""

from __future__ import annotations

import logging
import time

import casadi as ca
import numpy as np

from mal_planner.ocp import OCPOptions, OCPSolver, Phase, PhaseGuess, PhaseMesh, Problem

AC_STATES = ["x", "y", "h", "v", "psi"]
AC_CONTROLS = ["turn", "climb", "acc"]
X_LB = [-30e3, -30e3, 0.0, 60.0, -2 * np.pi]
X_UB = [30e3, 30e3, 3000.0, 90.0, 2 * np.pi]
U_LB = [-0.05, -8.0, -1.0]
U_UB = [0.05, 8.0, 1.0]
SEP = 2000.0


def _aircraft_rhs(x: ca.SX, u: ca.SX) -> ca.SX:
    return ca.vertcat(x[3] * ca.cos(x[4]), x[3] * ca.sin(x[4]), u[1], u[2], u[0])


def _effort(u: ca.SX, k: int) -> ca.SX:
    return sum(1e-2 * (u[3 * i] / 0.05) ** 2 + 1e-3 * (u[3 * i + 2]) ** 2 for i in range(k))


def build_problem(x0: np.ndarray) -> Problem:
    n_ac = 3
    starts = x0.reshape(n_ac, 5)
    goals = [np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, 0.0])]

    def joint_rhs(x, u, t, p):
        return ca.vertcat(*[_aircraft_rhs(x[5 * i : 5 * i + 5], u[3 * i : 3 * i + 3]) for i in range(n_ac)])

    def sep(x, u, t, p):
        out = []
        for i in range(n_ac):
            for j in range(i + 1, n_ac):
                dx, dy = x[5 * i] - x[5 * j], x[5 * i + 1] - x[5 * j + 1]
                out.append((dx**2 + dy**2) / SEP**2)
        return ca.vertcat(*out)

    t1 = 60.0
    tg = np.linspace(0.0, t1, 5)
    joint_guess = np.hstack([_straight(s, t1, tg) for s in starts])
    joint = Phase(
        name="joint",
        states=[f"{s}{i}" for i in range(n_ac) for s in AC_STATES],
        controls=[f"{c}{i}" for i in range(n_ac) for c in AC_CONTROLS],
        dynamics=joint_rhs,
        lagrange=lambda x, u, t, p: _effort(u, n_ac),
        path=sep,
        path_lb=1.0,
        state_lb=X_LB * n_ac,
        state_ub=X_UB * n_ac,
        control_lb=U_LB * n_ac,
        control_ub=U_UB * n_ac,
        t0_bounds=(0.0, 0.0),
        tf_bounds=(20.0, 200.0),
        state_scale="auto",
        control_scale="auto",
        guess=PhaseGuess(t=tg, x=joint_guess, u=np.zeros((tg.size, 3 * n_ac))),
    )

    def single(name: str, ac: int, t_a: float, t_b: float, final: bool) -> Phase:
        s = starts[ac]
        xa = s + (t_a / 400.0) * (np.r_[goals[ac], 70.0, s[4]] - s)
        xb = s + (t_b / 400.0) * (np.r_[goals[ac], 70.0, s[4]] - s)
        kw = {}
        if final:
            g = goals[ac]
            kw = {
                "final_state_lb": [g[0] - 1.0, g[1] - 1.0, g[2], 60.0, -2 * np.pi],
                "final_state_ub": [g[0] + 1.0, g[1] + 1.0, g[2] + 1.0, 75.0, 2 * np.pi],
            }
        return Phase(
            name=name,
            states=AC_STATES,
            controls=AC_CONTROLS,
            dynamics=lambda x, u, t, p: _aircraft_rhs(x, u),
            lagrange=lambda x, u, t, p: _effort(u, 1),
            state_lb=X_LB,
            state_ub=X_UB,
            control_lb=U_LB,
            control_ub=U_UB,
            tf_bounds=(0.0, 2000.0),
            t0_bounds=(0.0, 2000.0),
            min_duration=1.0,
            state_scale="auto",
            control_scale="auto",
            mesh=PhaseMesh.uniform(3, 5),
            guess=PhaseGuess(t=[t_a, t_b], x=np.vstack([xa, xb]), u=np.zeros((2, 3))),
            **kw,
        )

    phases = [
        joint,
        single("a0", 0, t1, 400.0, True),
        single("a1", 1, t1, 400.0, True),
        single("a2_approach", 2, t1, 200.0, False),
        single("a2_base", 2, 200.0, 300.0, False),
        single("a2_final", 2, 300.0, 400.0, True),
    ]

    def events(e, p):
        return ca.vertcat(e["joint"].x0 - p)

    def mayer(e, p):
        return sum(e[n].tf for n in ("a0", "a1", "a2_final")) / 100.0

    prob = Problem(phases=phases, n_params=15, events=events, events_lb=0.0, events_ub=0.0, mayer=mayer)
    for i, name in enumerate(("a0", "a1", "a2_approach")):
        prob.link("joint", name, states=[(f"{s}{i}", s) for s in AC_STATES])
    prob.link("a2_approach", "a2_base")
    prob.link("a2_base", "a2_final")
    return prob


def _straight(s: np.ndarray, t1: float, tg: np.ndarray) -> np.ndarray:
    vx, vy = s[3] * np.cos(s[4]), s[3] * np.sin(s[4])
    return np.column_stack(
        [
            s[0] + vx * tg,
            s[1] + vy * tg,
            np.full_like(tg, s[2]),
            np.full_like(tg, s[3]),
            np.full_like(tg, s[4]),
        ]
    )


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    x0 = np.array(
        [
            [-20e3, 0.0, 1500.0, 80.0, 0.0],
            [0.0, -20e3, 1500.0, 80.0, np.pi / 2],
            [15e3, 15e3, 2000.0, 80.0, -3 * np.pi / 4],
        ]
    ).ravel()
    prob = build_problem(x0)
    for label, opts in (("refine", OCPOptions()), ("single mesh", OCPOptions(refine=False))):
        solver = OCPSolver(prob, opts)
        for k, p in enumerate((x0, x0 + np.tile([300.0, -200.0, 50.0, 2.0, 0.02], 3))):
            t = time.perf_counter()
            sol = solver.solve(params=p)
            wall = time.perf_counter() - t
            print(
                f"[{label}] solve {k}: J={sol.objective:.6f} success={sol.success} status={sol.status} "
                f"mesh_iters={len(sol.mesh_history)} nlp_iters={sol.iterations} nlp_time={sol.solve_time:.3f}s "
                f"wall={wall:.3f}s builds={solver.n_builds} max_err={sol.max_error:.2e}"
            )


if __name__ == "__main__":
    main()
