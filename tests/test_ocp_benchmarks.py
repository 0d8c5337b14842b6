"""Standard optimal-control benchmarks for the LGR/hp engine (each well under a second)."""

from __future__ import annotations

import logging

import casadi as ca
import numpy as np
import pytest

from mal_planner.ocp import OCPOptions, OCPSolver, Phase, PhaseGuess, PhaseMesh, Problem


def _double_integrator(name: str, **kw) -> Phase:
    return Phase(
        name=name,
        states=["x", "v"],
        controls=["u"],
        dynamics=lambda x, u, t, p: ca.vertcat(x[1], u[0]),
        lagrange=lambda x, u, t, p: 0.5 * u[0] ** 2,
        **kw,
    )


def _bryson_denham(ell: float, mesh: PhaseMesh | None = None) -> Problem:
    kw = {"mesh": mesh} if mesh else {}
    ph = _double_integrator(
        "bd",
        state_lb=[-10.0, -10.0],
        state_ub=[ell, 10.0],
        initial_state_lb=[0.0, 1.0],
        initial_state_ub=[0.0, 1.0],
        final_state_lb=[0.0, -1.0],
        final_state_ub=[0.0, -1.0],
        t0_bounds=(0.0, 0.0),
        tf_bounds=(1.0, 1.0),
        guess=PhaseGuess(t=[0.0, 1.0], x=[[0.0, 1.0], [0.0, -1.0]], u=[[0.0], [0.0]]),
        **kw,
    )
    return Problem(phases=[ph])


def test_bryson_denham_state_constrained_hp() -> None:
    # The state-error estimate barely sees the corners of the constrained arc x = 1/9 at
    # t = 1/3 and 2/3, so a tolerance below the requested cost accuracy is used.
    records = []
    opts = OCPOptions(mesh_tol=1e-8, callback=records.append)
    sol = OCPSolver(_bryson_denham(1.0 / 9.0), opts).solve()
    assert sol.success and sol.mesh_converged
    assert sol.objective == pytest.approx(4.0, rel=1e-4)
    assert len(sol.mesh_history) >= 2 and records == sol.mesh_history
    assert sol.mesh_history[-1].segments[0] > 4  # refinement split segments
    x, _ = sol.interpolate("bd", np.array([0.5]))
    assert x[0, 0] == pytest.approx(1.0 / 9.0, abs=1e-4)
    assert sol.phases[0].q == pytest.approx(sol.objective, rel=1e-10)


def test_bryson_denham_unconstrained_single_mesh() -> None:
    sol = OCPSolver(_bryson_denham(1.0, PhaseMesh.uniform(1, 4))).solve()
    assert sol.success and len(sol.mesh_history) == 1
    assert sol.objective == pytest.approx(2.0, rel=1e-9)


def test_brachistochrone_min_time(caplog: pytest.LogCaptureFixture) -> None:
    g = 9.81  # y positive downwards, u measured from the vertical

    ph = Phase(
        name="slide",
        states=["x", "y", "v"],
        controls=["u"],
        dynamics=lambda x, u, t, p: ca.vertcat(x[2] * ca.sin(u[0]), x[2] * ca.cos(u[0]), g * ca.cos(u[0])),
        state_lb=[0.0, 0.0, 0.0],
        state_ub=[10.0, 10.0, 50.0],
        initial_state_lb=[0.0, 0.0, 0.0],
        initial_state_ub=[0.0, 0.0, 0.0],
        final_state_lb=[2.0, 2.0, 0.0],
        final_state_ub=[2.0, 2.0, 50.0],
        control_lb=0.0,
        control_ub=np.pi,
        t0_bounds=(0.0, 0.0),
        tf_bounds=(0.05, 10.0),
        guess=PhaseGuess(t=[0.0, 1.0], x=[[0.0, 0.0, 0.0], [2.0, 2.0, 6.0]], u=[[1.0], [1.0]]),
    )
    with caplog.at_level(logging.INFO, logger="mal_planner.ocp"):
        sol = OCPSolver(Problem(phases=[ph], mayer=lambda e, p: e[0].tf)).solve()
    assert sol.success
    assert sol.objective == pytest.approx(0.82434, rel=1e-4)
    assert sol.phases[0].tf == pytest.approx(sol.objective)
    assert "mesh iter 0" in caplog.text


def _three_phase_bd() -> Problem:
    """Bryson-Denham as unconstrained / on-constraint / unconstrained phases.

    ``p[0]`` is the constraint level l; the interior times are free.  The optimum has
    switch times 3l and 1 - 3l and J = 4/(9 l); every arc is a cubic, so LGR is exact.
    """
    mesh = PhaseMesh.uniform(1, 4)
    path = {"path": lambda x, u, t, p: x[0] - p[0], "path_ub": 0.0}
    a = _double_integrator(
        "rise",
        initial_state_lb=[0.0, 1.0],
        initial_state_ub=[0.0, 1.0],
        final_state_lb=[-10.0, 0.0],
        final_state_ub=[10.0, 0.0],
        t0_bounds=(0.0, 0.0),
        tf_bounds=(0.05, 0.95),
        mesh=mesh,
        guess=PhaseGuess(t=[0.0, 0.3], x=[[0.0, 1.0], [0.1, 0.0]], u=[[-6.0], [0.0]]),
        **path,
    )
    b = _double_integrator(
        "arc",
        tf_bounds=(0.05, 0.95),
        mesh=mesh,
        guess=PhaseGuess(t=[0.3, 0.7], x=[[0.1, 0.0], [0.1, 0.0]], u=[[0.0], [0.0]]),
        **path,
    )
    c = _double_integrator(
        "fall",
        final_state_lb=[0.0, -1.0],
        final_state_ub=[0.0, -1.0],
        tf_bounds=(1.0, 1.0),
        mesh=mesh,
        guess=PhaseGuess(t=[0.7, 1.0], x=[[0.1, 0.0], [0.0, -1.0]], u=[[-6.0], [0.0]]),
        **path,
    )
    prob = Problem(
        phases=[a, b, c],
        n_params=1,
        events=lambda e, p: ca.vertcat(e["rise"].xf[0] - p[0], e["arc"].xf[0] - p[0], e["arc"].xf[1]),
        events_lb=0.0,
        events_ub=0.0,
    )
    prob.link("rise", "arc")
    prob.link("arc", "fall", states=["x", ("v", "v")])
    return prob


def test_multiphase_linkage_params_and_nlp_cache() -> None:
    solver = OCPSolver(_three_phase_bd())
    sol = solver.solve(params=[1.0 / 9.0])
    assert sol.success
    assert sol.objective == pytest.approx(4.0, rel=1e-7)
    # J is quadratic in the switch time, so a 1e-8 KKT tolerance pins it to ~1e-4 only.
    assert sol.phase("rise").tf == pytest.approx(1.0 / 3.0, abs=2e-4)
    assert sol.phase("arc").t0 == pytest.approx(sol.phase("rise").tf, abs=1e-12)
    assert sol.phase("fall").t0 == pytest.approx(2.0 / 3.0, abs=2e-4)
    np.testing.assert_allclose(sol.phase("arc").x[0], sol.phase("rise").x[-1], atol=1e-10)
    assert solver.n_builds == 1

    # New parameter value, same guess: the cached NLP is reused as is.
    sol2 = solver.solve(params=[1.0 / 12.0])
    assert sol2.success and solver.n_builds == 1
    assert sol2.objective == pytest.approx(16.0 / 3.0, rel=1e-7)
    assert sol2.phase("rise").tf == pytest.approx(0.25, abs=2e-4)

    # Warm starts from a solution use the warm-option NLP: built once, then cached too.
    for k, ell in enumerate((1.0 / 10.0, 1.0 / 11.0)):
        sol3 = solver.solve(params=[ell], guess=sol2, meshes=sol2.meshes)
        assert sol3.success and solver.n_builds == 2
        assert sol3.objective == pytest.approx(4.0 / (9.0 * ell), rel=1e-7)
        assert sol3.mesh_history[0].build_time == 0.0 or k == 0


def test_nlp_failure_is_reported() -> None:
    ph = _double_integrator(
        "bad",
        initial_state_lb=[0.0, 0.0],
        initial_state_ub=[0.0, 0.0],
        control_lb=-1.0,
        control_ub=1.0,
        t0_bounds=(0.0, 0.0),
        tf_bounds=(1.0, 1.0),
        mesh=PhaseMesh.uniform(2, 3),
    )
    prob = Problem(phases=[ph], events=lambda e, p: e[0].xf[0], events_lb=5.0)  # unreachable
    sol = OCPSolver(prob, OCPOptions(max_iter=200)).solve()
    assert not sol.success and not sol.nlp_success
    assert len(sol.mesh_history) == 1 and not sol.mesh_history[0].nlp_success


def test_an_infeasible_warm_solve_is_retried_cold_unless_told_not_to() -> None:
    """A replan's caller has a surer recovery for an infeasible warm solve than the cold retry (sequential.py)."""
    ph = _double_integrator("bad", initial_state_lb=[0.0, 0.0], initial_state_ub=[0.0, 0.0], control_lb=-1.0,
                            control_ub=1.0, t0_bounds=(0.0, 0.0), tf_bounds=(1.0, 1.0), mesh=PhaseMesh.uniform(2, 3))
    prob = Problem(phases=[ph], events=lambda e, p: e[0].xf[0], events_lb=5.0)  # unreachable
    guess = [PhaseGuess(t=[0.0, 1.0], x=[[0.0, 0.0], [0.5, 1.0]], u=[[1.0], [1.0]])]
    statuses = {}
    for retry in (True, False):
        solver = OCPSolver(prob, OCPOptions(max_iter=200))
        sol = solver.solve(guess=guess, warm=True, retry_infeasible=retry)
        statuses[retry] = sol.mesh_history[0].status
        assert not sol.success
        assert solver.n_builds == (2 if retry else 1)  # the warm NLP, then the cold one only when retried
    assert statuses[False] == "Infeasible_Problem_Detected"


def test_scaled_units_reach_ipopt_with_the_same_numbers() -> None:
    """Bryson-Denham posed in other units (lengths x50, times x100) with the matching scales is the same NLP:
    the same IPOPT iterations and mesh, the solution in the new units. Unscaled, IPOPT sees other numbers."""
    mesh = PhaseMesh.uniform(2, 5)

    def problem(length: float, time_: float, scaled: bool) -> Problem:
        ell, speed, accel = length / 9.0, length / time_, length / time_**2
        ph = _double_integrator(
            "bd", mesh=mesh,
            state_lb=[-10.0 * length, -10.0 * speed], state_ub=[10.0 * length, 10.0 * speed],
            initial_state_lb=[0.0, speed], initial_state_ub=[0.0, speed],
            final_state_lb=[0.0, -speed], final_state_ub=[0.0, -speed],
            t0_bounds=(0.0, 0.0), tf_bounds=(time_, time_),
            guess=PhaseGuess(t=[0.0, time_], x=[[0.0, speed], [0.0, -speed]], u=[[0.0], [0.0]]),
            path=lambda x, u, t, p: x[0] - ell, path_ub=0.0,
            **({"state_scale": [length, speed], "control_scale": [accel], "time_scale": time_,
                "path_scale": length} if scaled else {}),
        )
        return Problem(phases=[ph], objective_scale=length**2 / time_**3 if scaled else 1.0)

    length, time_ = 50.0, 100.0
    reference = OCPSolver(problem(1.0, 1.0, False), OCPOptions(refine=False)).solve()
    scaled = OCPSolver(problem(length, time_, True), OCPOptions(refine=False)).solve()
    raw = OCPSolver(problem(length, time_, False), OCPOptions(refine=False)).solve()
    assert reference.success and scaled.success
    assert scaled.iterations == reference.iterations and raw.iterations != reference.iterations
    assert scaled.objective == pytest.approx(reference.objective * length**2 / time_**3, rel=1e-9)
    assert scaled.phases[0].t == pytest.approx(reference.phases[0].t * time_, rel=1e-9)
    assert scaled.phases[0].x[:, 0] == pytest.approx(reference.phases[0].x[:, 0] * length, rel=1e-6, abs=1e-9)


def _derivatives_both_ways(problem: Problem, params, lam_f: float = 0.7, seed: int = 0):
    """The objective's gradient, the constraint Jacobian and the Lagrangian's Hessian of ``problem``'s NLP at a
    random point near its guess, from the nodes' own derivatives and from CasADi's differentiation of the whole
    NLP."""
    from mal_planner.ocp.transcription import Transcription

    solver = OCPSolver(problem)
    meshes = tuple(ph.mesh for ph in problem.phases)
    structured = Transcription(problem, meshes, solver._funcs, solver._nlp_opts[False], None, solver._nodes)
    plain = Transcription(problem, meshes, solver._funcs, solver._nlp_opts[False], None, None)
    rng = np.random.default_rng(seed)
    w = plain.initial_guess(None)
    w = w * (1.0 + 0.01 * rng.standard_normal(w.size)) + 0.01 * rng.standard_normal(w.size)
    args = {"x": w, "p": params}
    lam = {"lam_f": lam_f, "lam_g": rng.standard_normal(plain.lbg.size)}
    out = []
    for name, extra in (("nlp_grad_f", {}), ("nlp_jac_g", {}), ("nlp_hess_l", lam)):
        a = plain.solver.get_function(name)(**args, **extra)
        b = structured.solver.get_function(name)(**args, **extra)
        key = list(a)[-1]
        out.append((np.asarray(a[key].full()), np.asarray(b[key].full())))
    return out


@pytest.mark.parametrize("case", ["three_phase_bryson_denham", "thesis", "no_fly_zones"])
def test_node_derivatives_equal_casadi_s_differentiation(case: str) -> None:
    """The gradient, Jacobian and Hessian IPOPT gets are assembled from each node's derivatives (ocp.nodes); they
    must be CasADi's own, entry for entry: linkages, events, path constraints, time-dependent terms and scales
    included."""
    if case != "three_phase_bryson_denham":  # scenarios: the wall's gate; an ellipsoid and a box at midpoints too
        from mal_planner.initializer.sequencer import plan_initial
        from mal_planner.landing.base import LandingOptions
        from mal_planner.landing.solve import LandingOptimizer, make_guesses
        from mal_planner.scenario import load_scenario

        sc = load_scenario(f"scenarios/{case}.yaml")
        options = LandingOptions(strategy="joint")
        opt = LandingOptimizer(sc, make_guesses(sc, plan_initial(sc, seed=0), options), options)
        problem, params = opt.problem.problem, opt.problem.params(sc, opt.landing_times)
    else:
        problem, params = _three_phase_bd(), np.array([1.0 / 9.0])
    for plain, structured in _derivatives_both_ways(problem, params):
        assert np.abs(plain).max() > 0.0
        np.testing.assert_allclose(structured, plain, rtol=0.0, atol=1e-10 * np.abs(plain).max())
