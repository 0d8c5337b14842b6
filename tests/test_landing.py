"""The landing problem on the OCP engine: thesis reproduction (coarse), options, replanning."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from mal_planner.landing import LandingOptions, plan_layout
from mal_planner.landing.meshes import split_segments
from mal_planner.landing.solve import LandingOptimizer, make_guesses
from mal_planner.ocp import PhaseMesh
from mal_planner.options import PlanOptions
from mal_planner.pipeline import Planner, plan
from mal_planner.scales import Scales
from mal_planner.scenario import load_scenario

# The default settings (mesh tolerance 1e-6): coarser meshes solve but do not pass the verification.
COARSE = LandingOptions()
THESIS_T_OBS = {"A1": 79.77, "A2": 94.96, "A3": 109.96}  # Table 6-1


@pytest.fixture(scope="module")
def thesis():
    return load_scenario("scenarios/thesis.yaml")


@pytest.fixture(scope="module")
def thesis_initial(thesis):
    from mal_planner.initializer import plan_initial

    return plan_initial(thesis, seed=0)


@pytest.fixture(scope="module")
def thesis_result(thesis, thesis_initial):
    return plan(thesis, PlanOptions(seed=0, landing=COARSE), initial=thesis_initial)


def test_layout_orders_events_and_drops_passed_gates() -> None:
    lay = plan_layout(["A", "B", "C"], [155, 170, 185], [80, 95, 110])
    assert [(e.kind, e.aircraft) for e in lay.events] == [("gate", 0), ("gate", 1), ("gate", 2),
                                                          ("land", 0), ("land", 1), ("land", 2)]
    assert lay.airborne(3) == [0, 1, 2] and lay.airborne(4) == [1, 2] and lay.airborne(5) == [2]
    assert lay.approaching(0, 0) and not lay.approaching(1, 0) and lay.approaching(1, 1)
    # Interleaved events, and an aircraft already past its gate (replan) has no gate event.
    lay2 = plan_layout(["A", "B"], [60, 120], [None, 70])
    assert [(e.kind, e.aircraft) for e in lay2.events] == [("land", 0), ("gate", 1), ("land", 1)]
    assert not lay2.approaching(0, 0) and lay2.approaching(0, 1)
    # Guesses that contradict the landing order are put in order.
    lay3 = plan_layout(["A", "B"], [100, 90], [50, 40])
    times = {(e.kind, e.aircraft): e.time_guess for e in lay3.events}
    assert times[("land", 1)] > times[("land", 0)] and times[("gate", 1)] > times[("gate", 0)]


def test_split_segments() -> None:
    mesh = PhaseMesh.uniform(4, 5)
    # A short segment around the times of each segment that has some (1 s on each side of a 100 s phase) ...
    out = split_segments(mesh, 0.0, 100.0, [10.0, 12.0, 90.0], 1.0)
    assert out.breaks == pytest.approx((0.0, 0.09, 0.13, 0.25, 0.5, 0.75, 0.89, 0.91, 1.0))
    assert out.degrees == (5,) * 8
    # ... that ends with the segment when the times come within half the pad of its end ...
    out = split_segments(mesh, 0.0, 100.0, [22.0, 24.8], 1.0)
    assert out.breaks == pytest.approx((0.0, 0.21, 0.25, 0.5, 0.75, 1.0))
    # ... and a segment the times nearly cover is halved; times outside the phase split nothing.
    out = split_segments(mesh, 0.0, 100.0, [1.0, 24.0, 150.0], 1.0)
    assert out.breaks == pytest.approx((0.0, 0.125, 0.25, 0.5, 0.75, 1.0)) and out.degrees == (5,) * 5


def test_thesis_reproduction_is_verified(thesis_result) -> None:
    res = thesis_result
    assert res.optimized and res.verification is not None
    assert res.verification.verified, res.verification.reasons
    assert res.order == ["A1", "A2", "A3"]
    for cs, t_obs in THESIS_T_OBS.items():
        assert res.landing.gate_times[cs] >= t_obs - 0.3
        assert res.landing.gate_times[cs] <= res.landing.landing_times[cs]
    assert res.landing.landing_times == pytest.approx({"A1": 155.0, "A2": 170.0, "A3": 185.0})
    assert res.landing.objective == pytest.approx(-284.34, abs=0.05)
    # Separation of every pair, including after the gate on the shared final approach.
    assert {p.pair for p in res.verification.pairs} == {"A1-A2", "A1-A3", "A2-A3"}
    assert min(p.min_distance_nm for p in res.verification.pairs) >= 0.25


def test_solution_satisfies_dynamics_bank_and_gate(thesis, thesis_result) -> None:
    sc = thesis
    for tr in thesis_result.landing.trajectories:
        ac = sc.aircraft_by_callsign(tr.callsign)
        np.testing.assert_allclose(tr.states[0], ac.state0, atol=1e-6)
        # The threshold is crossed inside the airspace margin (1e-3 nm above the floor, inside its edge).
        margin = COARSE.margins.in_nm(Scales.of(sc)).airspace_nm
        np.testing.assert_allclose(tr.states[-1, :3], sc.runway_state[:3] + [0.0, margin, margin], atol=1e-6)
        # The published controls keep the limits exactly (no clipping after the solve, no tolerance).
        bank = np.degrees(np.arctan2(tr.controls[:, 0], tr.controls[:, 1]))
        assert np.max(np.abs(bank)) <= 45.0
        assert np.all(tr.controls[:, 1] >= 0.0)
        # Each aircraft is on the approach side of the wall before its gate time and beyond it after.
        t_gate = thesis_result.landing.gate_times[tr.callsign]
        assert np.all(tr.states[tr.t < t_gate - 1e-6, 1] >= 3.0 - 1e-7)
        assert np.all(tr.states[tr.t > t_gate + 1e-6, 1] <= 3.0 + 1e-7)
        at_gate = tr.state_at(t_gate)
        assert -1.0 <= at_gate[0] <= 1.0 and 0.1 <= at_gate[2] <= 0.2
        assert at_gate[3] == pytest.approx(0.0, abs=1e-6)
        assert math.remainder(at_gate[4] + math.pi / 2, 2 * math.pi) == pytest.approx(0.0, abs=1e-6)


def test_mesh_history_reported(thesis_result) -> None:
    stats = thesis_result.landing.stats()
    assert stats["mesh_iterations"] and stats["mesh_iterations"][-1]["max_error"] <= 1e-4
    assert all(m["nlp_iterations"] > 0 for m in stats["mesh_iterations"])


def test_straight_line_guess_also_converges(thesis, thesis_initial) -> None:
    opts = replace(COARSE, guess="straight")
    res = plan(thesis, PlanOptions(seed=0, landing=opts), initial=thesis_initial)
    assert res.optimized and res.verification.verified, res.verification.reasons
    assert res.landing.gate_times["A1"] >= THESIS_T_OBS["A1"] - 0.3


def test_free_landing_times_keep_spacing(thesis, thesis_initial) -> None:
    # Two mesh iterations: the spacing and the early landings show on a coarse mesh; the refinement towards the
    # tolerance stalls here (below) and took 2 minutes of the suite.
    opts = replace(COARSE, fixed_landing_times=False, max_mesh_iterations=2)
    res = plan(thesis, PlanOptions(seed=0, landing=opts, refinement_rounds=0), initial=thesis_initial)
    # Known limitation: with free times the fastest A1 rides its bank limit (bang-bang controls) and the mesh
    # stalls near 3e-6; its flown path then ends ~0.007 nm off the threshold, which the strict verification
    # reports. The solution itself must still be optimal and keep the spacing.
    assert res.optimized and res.verification is not None
    assert all("apart" not in r and "obstacle" not in r for r in res.verification.reasons)
    times = [res.landing.landing_times[cs] for cs in res.order]
    assert all(b - a >= thesis.landing_spacing_s - 1e-4 for a, b in zip(times, times[1:], strict=False))
    # Landing as early as possible: no later than with the thesis's fixed times.
    assert times[-1] < 185.0


def test_replan_reuses_the_nlp_and_keeps_absolute_landing_times(thesis) -> None:
    planner = Planner(PlanOptions(seed=0, landing=replace(COARSE)))
    first = planner.plan(thesis, start_time=100.0)
    assert first.optimized
    builds = planner._optimizer.solver.n_builds
    dt = 10.0
    states = {}
    for tr in first.trajectories():
        state = tr.state_at(dt)
        state[:3] += [0.005, -0.005, -0.001]  # the aircraft are slightly off their plan
        states[tr.callsign] = state
    second = planner.plan(thesis.with_initial_states(states), start_time=100.0 + dt)
    assert second.optimized and second.verification.verified, second.verification.reasons
    # Same NLP, warm-started (the strict verification may still refine the mesh afterwards).
    assert second.landing.mesh_history[0].build_time == 0.0 and planner._optimizer.solver.n_builds >= builds
    for cs, t_land in first.landing_times().items():
        assert second.landing_times()[cs] + dt == pytest.approx(t_land, abs=1e-6)
        # The schedule in the replan's clock: the node reports each aircraft's target and delay from it.
        assert second.initial.schedule.target[cs] + dt == pytest.approx(first.initial.schedule.target[cs])
    assert second.landing.nlp_iterations < first.landing.nlp_iterations


def test_a_replans_mesh_is_the_previous_one_without_the_segments_flown() -> None:
    """Cut once a whole segment is flown (before that: the same mesh, so a joint NLP stays cached); a sliver of a
    segment joins the next one; past the phase's end, one segment."""
    from mal_planner.landing.meshes import mesh_after
    from mal_planner.ocp import PhaseMesh

    mesh = PhaseMesh((0.0, 0.25, 0.5, 0.75, 1.0), (6, 7, 8, 9))
    assert mesh_after(mesh, 10.0, 110.0, 30.0) is mesh
    cut = mesh_after(mesh, 10.0, 110.0, 36.0)  # 26 % flown: the second segment from 26 % on
    assert cut.degrees == (7, 8, 9)
    assert np.allclose(cut.breaks, [0.0, 24 / 74, 49 / 74, 1.0])
    assert mesh_after(mesh, 10.0, 110.0, 80.0).degrees == (9,)  # 70 %: 5 % of the third segment left, merged
    assert mesh_after(mesh, 10.0, 110.0, 200.0).n_segments == 1


def test_optimizer_rebuilds_when_an_aircraft_has_passed_the_gate(thesis) -> None:
    planner = Planner(PlanOptions(seed=0, landing=replace(COARSE)))
    first = planner.plan(thesis, start_time=0.0)
    dt = first.landing.gate_times["A1"] + 5.0
    states = {tr.callsign: tr.state_at(dt) for tr in first.trajectories()}
    second = planner.plan(thesis.with_initial_states(states), start_time=dt)
    assert second.optimized and second.verification.verified, second.verification.reasons
    assert second.gate_times()["A1"] is None and second.gate_times()["A2"] is not None


def test_landing_optimizer_without_gate_and_the_zone_margin_of_flown_plans() -> None:
    """No wall: no gate events. A flown plan keeps the replan threshold (ten path accuracies) from the no-fly zones,
    an open-loop plan only its two-accuracy margin (less half of it between collocation points)."""
    sc = load_scenario("scenarios/no_fly_zones.yaml")
    res = plan(sc, PlanOptions(seed=0, landing=COARSE))
    assert res.optimized and res.verification.verified, res.verification.reasons
    assert all(g is None for g in res.landing.gate_times.values())
    assert len(res.landing.layout.events) == len(sc.aircraft)
    flown = plan(sc, PlanOptions(seed=0, landing=COARSE, tracking_margins=True))
    assert flown.verification.verified, flown.verification.reasons
    accuracy = Scales.of(sc).accuracy_nm
    zone = sc.obstacles[0].inflated(10.0 * accuracy)  # the ellipsoid the aircraft fly around
    assert any(zone.contains(tr.states[:, :3]).any() for tr in res.trajectories())
    assert not any(zone.contains(tr.states[:, :3]).any() for tr in flown.trajectories())


def test_guesses_start_at_the_true_state(thesis, thesis_initial) -> None:
    initial = thesis_initial
    guesses = make_guesses(thesis, initial, COARSE)
    for g in guesses:
        np.testing.assert_allclose(g.states[0, :3], thesis.aircraft_by_callsign(g.callsign).position)
        assert g.landing_time == thesis.aircraft_by_callsign(g.callsign).landing_time
        assert g.gate_time is not None and 0 < g.gate_time < g.landing_time
    opt = LandingOptimizer(thesis, guesses, replace(COARSE))
    assert opt.layout.n_phases == 6


def test_initial_states_just_outside_the_airspace_are_clipped(thesis) -> None:
    from mal_planner.pipeline import inside_airspace

    a1 = thesis.aircraft_by_callsign("A1").state0.copy()
    a1[2] = 0.3004  # radar noise above the ceiling
    moved = inside_airspace(thesis.with_initial_states({"A1": a1}))
    assert moved.aircraft_by_callsign("A1").state0[2] == 0.3
    a1[2] = 0.5
    with pytest.raises(ValueError, match="A1: initial position .* outside the airspace"):
        inside_airspace(thesis.with_initial_states({"A1": a1}))


def test_initial_states_at_the_edge_are_moved_off_it(thesis) -> None:
    """Outside: onto the airspace shrunk by the optimizer's margin. On the floor descending: up by the margin and
    twice the height it loses before a full pull-up turns it (v^2 sin^2 gamma / (2 g cos gamma (n_v,max - cos
    gamma))). Heading away from the face it lies on (the thesis's A2 on y = 6): left alone."""
    from mal_planner.airspace_entry import TURN_AWAY_FACTOR, inside_airspace

    a1 = thesis.aircraft_by_callsign("A1")
    state = a1.state0.copy()
    state[2] = 0.3004
    moved = inside_airspace(thesis.with_initial_states({"A1": state}), margin_nm=0.001)
    assert moved.aircraft_by_callsign("A1").state0[2] == pytest.approx(0.299)
    state[2], state[3] = 0.0, np.radians(-1.0)
    moved = inside_airspace(thesis.with_initial_states({"A1": state}), margin_nm=0.001)
    v, g, gamma = a1.speed, a1.dynamics.gravity, state[3]
    drop = (v * np.sin(gamma)) ** 2 / (2 * g * np.cos(gamma) * (a1.limits.n_v[1] - np.cos(gamma)))
    assert moved.aircraft_by_callsign("A1").state0[2] == pytest.approx(0.001 + TURN_AWAY_FACTOR * drop, rel=1e-9)
    assert drop > 0 and np.array_equal(moved.aircraft_by_callsign("A1").state0[3:], state[3:])
    assert inside_airspace(thesis, margin_nm=0.001) is thesis


def test_a_pass_that_left_every_aircraft_out_is_a_failure_not_an_index_error() -> None:
    """A sequential replan whose every aircraft is left out (closed loop, 10 airliners, traffic-0006) combined no
    part: it raised IndexError ("list index out of range"), and the service logged only that."""
    from mal_planner.landing.aircraft_plans import combine

    result = combine([], 0, None, 0.0, solved=[])
    assert not result.success and result.status == "no aircraft planned" and result.trajectories == []


def test_flown_plans_pass_a_hole_the_replan_threshold_inside_its_edges_where_it_has_room() -> None:
    """traffic-0031 of the 20-aircraft set: the hole 3.8 nm wide and 0.175 nm high, the replan threshold 0.15 nm. A
    flown plan's gate event keeps the threshold inside the wide sides, half the room inside the narrow ones; an
    open-loop plan only the obstacle and gate margins."""
    from mal_planner.landing.margins import SafetyMargins
    from mal_planner.options.plan import tracking_margins

    sc = load_scenario("scenarios/tma_12.yaml")
    scales = Scales.of(sc)
    open_loop = SafetyMargins().in_nm(scales)
    flown = tracking_margins(SafetyMargins(), scales, 0.15, math.radians(30.0)).in_nm(scales)
    base = open_loop.hole_nm
    assert flown.hole_nm == pytest.approx(base)
    assert open_loop.gate_inset_nm(-1.161, 2.653) == pytest.approx(base)
    assert flown.gate_inset_nm(-1.161, 2.653) == pytest.approx(base + 0.15)
    assert flown.gate_inset_nm(0.393, 0.568) == pytest.approx(base + 0.5 * (0.0875 - base))
    assert flown.gate_inset_nm(0.0, 1.5 * base) == pytest.approx(base)  # no room: the open-loop inset
