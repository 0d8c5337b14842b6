"""What keeps the landing NLP small as N grows: screened separation pairs, short phases on small meshes."""

from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np
import pytest

from mal_planner.landing import AircraftGuess, LandingOptions, plan_layout
from mal_planner.landing.pairs import PairScreen, all_pairs, close_unconstrained, count, screen_pairs
from mal_planner.landing.problem import _scaled_mesh
from mal_planner.ocp import PhaseMesh
from mal_planner.options import PlanOptions
from mal_planner.pipeline import Planner
from mal_planner.scales import Scales
from mal_planner.scenario import load_scenario


def _straight(callsign: str, start: tuple[float, float], end: tuple[float, float], t_land: float) -> AircraftGuess:
    t = np.linspace(0.0, t_land, 101)
    s = t / t_land
    xy = np.outer(1 - s, start) + np.outer(s, end)
    states = np.column_stack([xy, np.full_like(t, 0.1), np.zeros_like(t), np.zeros_like(t)])
    return AircraftGuess(callsign, t, states, t_land, None)


def test_screening_keeps_only_the_pairs_that_come_close() -> None:
    """A and B converge on the same point at the same time; C stays 5 nm away from both all along."""
    guesses = [_straight("A", (0.0, 0.0), (2.0, 0.0), 100.0), _straight("B", (2.0, 2.0), (2.0, 0.1), 101.0),
               _straight("C", (0.0, 5.0), (0.0, 8.0), 102.0)]
    layout = plan_layout(["A", "B", "C"], [g.landing_time for g in guesses], None)
    # In units of a turn radius of 1 nm and a turn time of 1 s: within 0.5 nm, 5 s around each phase.
    pairs = screen_pairs(layout, guesses, Scales(1.0, 1.0, 0.25), PairScreen(near=0.5, slack=5.0))
    assert count(all_pairs(layout)) == 4  # phase 1: AB AC BC; phase 2: BC
    assert pairs[0] == {(0, 1)} and pairs[1] == set() and pairs[2] == set()
    # The same check on "solved" samples: an unconstrained pair that came close is reported.
    t = np.linspace(0.0, 100.0, 11)
    x = np.hstack([g.state_at(t) for g in guesses])
    close = close_unconstrained(layout, [(t, x), (t, x[:, 5:]), (t, x[:, 10:])], [set(), set(), set()], 0.3,
                                [5, 5, 5])
    assert close[0] == {(0, 1)}


def test_short_phases_get_small_meshes() -> None:
    mesh = PhaseMesh.uniform(4, 6)
    assert _scaled_mesh(mesh, 200.0, 20.0).degrees == (6,) * 10  # one per 20 s, however long the phase
    assert _scaled_mesh(mesh, 20.0, 20.0).degrees == (6,)
    assert _scaled_mesh(mesh, 10.0, 20.0).degrees == (3,)
    assert _scaled_mesh(mesh, 15.0, 20.0).degrees == (5,)
    assert _scaled_mesh(mesh, 0.5, 20.0).degrees == (3,)


@pytest.mark.slow
@pytest.mark.parametrize("strategy", ["joint", "sequential"])
def test_pairs_screened_out_are_added_back_when_they_come_close(caplog, strategy) -> None:
    """With no pair (joint) or intruder (sequential) constrained up front, the solve lets aircraft come close;
    the optimizer then adds those and re-solves, and the plan is verified (the verification checks every
    pair)."""
    scenario = load_scenario("scenarios/five_aircraft.yaml")
    nothing = PairScreen(near=-math.inf, near_separations=-math.inf, recheck=10.0 / 3.0)  # re-check within 1 nm
    landing = replace(LandingOptions(), pair_screen=nothing, strategy=strategy)
    planner = Planner(PlanOptions(seed=0, landing=landing))
    with caplog.at_level(logging.INFO, logger="mal_planner.optimizer"):
        result = planner.plan(scenario)
    assert result.landing.strategy == strategy
    assert any("came close; re-solving" in r.getMessage() for r in caplog.records)
    if strategy == "joint":
        added = planner._optimizer.pairs
        assert 0 < count(added) < count(all_pairs(planner._optimizer.layout))
    else:
        assert [p.trajectories[0].callsign for p in result.landing.parts] == result.order
    assert result.verified, result.verification.reasons if result.verification else result.failure
    assert min(p.min_distance_nm for p in result.verification.pairs) >= scenario.separation_nm


def test_auto_strategy_plans_the_thesis_jointly_and_larger_streams_one_at_a_time() -> None:
    from mal_planner.landing.solve import uses_sequential

    options = LandingOptions()
    assert not uses_sequential(options, 3) and uses_sequential(options, options.sequential_from)
    assert not uses_sequential(replace(options, strategy="joint"), 20)
    assert uses_sequential(replace(options, strategy="sequential"), 2)


def test_controls_riding_a_bound_overshoot_it_far_less_between_collocation_points() -> None:
    """Minimum-time double integrator (bang-bang u = +-1) on a coarse mesh: the degree N-1 control interpolant
    overshoots the bound between collocation points; ``bound_controls_between`` cuts that (measured 0.29 ->
    0.03 at a switch inside a segment; where the control rides the bound, as in the campaign's failures,
    the verification then found none)."""
    import casadi as ca

    from mal_planner.ocp import OCPOptions, OCPSolver, Phase, Problem

    overshoot = {}
    for between in (False, True):
        phase = Phase(name="p", states=["x", "v"], controls=["u"],
                      dynamics=lambda x, u, t, p: ca.vertcat(x[1], u[0]), lagrange=lambda x, u, t, p: 1e-3 * u[0] ** 2,
                      state_lb=[-10, -10], state_ub=[10, 10], control_lb=[-1.0], control_ub=[1.0],
                      initial_state_lb=[0, 0], initial_state_ub=[0, 0], final_state_lb=[1, 0], final_state_ub=[1, 0],
                      t0_bounds=(0, 0), tf_bounds=(0.5, 10), mesh=PhaseMesh.uniform(3, 5),
                      bound_controls_between=between)
        sol = OCPSolver(Problem(phases=[phase], mayer=lambda e, p: e[0].tf), OCPOptions(refine=False)).solve()
        assert sol.success
        _, u = sol.phases[0].interpolate(np.linspace(sol.phases[0].t0, sol.phases[0].tf, 2001))
        overshoot[between] = float(np.abs(u).max()) - 1.0
    assert overshoot[False] > 0.1 and overshoot[True] < overshoot[False] / 5


def test_a_sequential_plan_that_stops_hands_out_the_aircraft_planned_before() -> None:
    """Partial plans (issue 32): the parts a sequential solve made before its first failed one, as one successful
    result with their trajectories and times only."""
    from mal_planner.landing.aircraft_plans import planned_prefix

    scenario = load_scenario("scenarios/thesis.yaml")
    landing = replace(PlanOptions().landing, strategy="sequential")
    result = Planner(PlanOptions(seed=0, landing=landing, verify=False)).plan(scenario)
    parts = result.landing.parts
    first_two = [p.trajectories[0].callsign for p in parts[:2]]
    stopped = replace(result.landing, success=False, parts=[*parts[:2], replace(parts[2], success=False)])
    prefix = planned_prefix(stopped)
    assert prefix is not None and prefix.success and prefix.status.startswith("partial: 2 aircraft")
    assert [tr.callsign for tr in prefix.trajectories] == first_two
    assert set(prefix.landing_times) == set(prefix.gate_times) == set(prefix.required_landing_times) == set(first_two)
    assert planned_prefix(replace(result.landing, parts=[replace(parts[0], success=False)])) is None
    # A fallback that plans fewer aircraft does not replace it, and a partial plan is not followed by the joint NLP
    # (which would take the replan's time and leave nothing to hand out).
    from mal_planner.pipeline.partial import better as _better

    fewer = replace(stopped, parts=[parts[0], replace(parts[1], success=False)])
    assert _better(stopped, fewer, partial=True) is stopped and _better(fewer, stopped, partial=True) is stopped
    assert _better(stopped, fewer, partial=False) is fewer and _better(stopped, result.landing, True) is result.landing
    named = [name for name, _ in Planner(PlanOptions(landing=landing, partial=True))._attempts(scenario, warm=False)]
    assert not any("joint" in name for name in named) and "solve" in named
    named = [name for name, _ in Planner(PlanOptions(landing=landing))._attempts(scenario, warm=False)]
    assert "joint solve" in named


def test_a_partial_plan_leaves_out_an_aircraft_that_finds_no_plan_and_plans_the_others() -> None:
    """Partial plans (the service's): the first aircraft in landing order cannot make its slot (157 s, where its
    turns need about 160 s) even after the recoveries; it is left out and the two after it are planned without it,
    verified (the mesh refined where the verification asks), and handed out with it unplanned. Without partial plans
    the same request fails."""
    scenario = load_scenario("scenarios/thesis.yaml")
    a1, a2, a3 = scenario.aircraft
    scenario = replace(scenario, aircraft=(replace(a1, landing_time=175.0), replace(a2, landing_time=157.0),
                                           replace(a3, landing_time=200.0)))
    landing = replace(PlanOptions().landing, strategy="sequential")
    result = Planner(PlanOptions(seed=0, landing=landing, partial=True)).plan(scenario)
    assert result.unplanned == ("A2",) and result.verified
    assert sorted(tr.callsign for tr in result.landing.trajectories) == ["A1", "A3"]
    assert Planner(PlanOptions(seed=0, landing=landing)).plan(scenario).failure is not None
