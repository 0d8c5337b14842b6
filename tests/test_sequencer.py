"""The landing sequencer of chapter 4 on the thesis, five-aircraft and no-fly-zone scenarios."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mal_planner.initializer.planners import path_length
from mal_planner.initializer.sequencer import InitialPlan, plan_initial
from mal_planner.scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


@pytest.fixture(scope="module")
def thesis():
    return load_scenario(SCENARIOS / "thesis.yaml")


@pytest.fixture(scope="module")
def thesis_plan(thesis):
    return plan_initial(thesis, "multi-rrt", seed=0)


@pytest.fixture(scope="module")
def five_plan():
    scenario = load_scenario(SCENARIOS / "five_aircraft.yaml")
    return scenario, plan_initial(scenario, "multi-rrt", seed=1, runs_per_aircraft=2)


def check_plan(scenario, plan: InitialPlan) -> None:
    trs = plan.trajectories
    assert sorted(tr.callsign for tr in trs) == sorted(ac.callsign for ac in scenario.aircraft)
    assert [tr.order for tr in trs] == list(range(1, len(trs) + 1))
    direct = [path_length(tr.direct_path) for tr in trs]
    assert direct == sorted(direct), "landing order must follow the direct path length"
    assert trs[0].waypoint is None and np.array_equal(trs[0].waypoints, trs[0].direct_path)
    for prev, tr in zip(trs[:-1], trs[1:], strict=True):
        gap = tr.landing_time - prev.landing_time
        assert scenario.landing_spacing_s - 1e-9 <= gap <= scenario.max_landing_spacing_s + 1e-9
        assert tr.waypoint is not None
        i = tr.waypoint_index
        np.testing.assert_array_equal(tr.waypoints[i], tr.waypoint)
        assert tr.times[i] * tr.speed > 0.5 * tr.path_length
    for tr in trs:
        ac = scenario.aircraft_by_callsign(tr.callsign)
        np.testing.assert_array_equal(tr.waypoints[0], ac.position)
        np.testing.assert_array_equal(tr.waypoints[-1], scenario.runway_state[:3])
        seg = np.linalg.norm(np.diff(tr.waypoints, axis=0), axis=1)
        assert np.all(seg > 1e-9), "repeated consecutive points"
        np.testing.assert_allclose(tr.times, np.concatenate([[0.0], np.cumsum(seg)]) / ac.speed)
        assert tr.landing_time == pytest.approx(tr.path_length / ac.speed)
        assert np.all(tr.waypoints >= scenario.airspace[:, 0]) and np.all(tr.waypoints <= scenario.airspace[:, 1])
        for gate in scenario.gates:
            tg = tr.gate_times[gate.name]
            assert tg is not None and 0.0 < tg < tr.landing_time
            p = tr.position_at(np.array([tg]))[0]
            assert p[gate.axis] == pytest.approx(gate.position, abs=1e-9)
            assert gate.in_hole(p)
        t, states = tr.sample(1.0)
        assert states.shape == (len(t), 5) and t[0] == 0.0 and t[-1] == pytest.approx(tr.landing_time)
        np.testing.assert_allclose(states[0, :3], ac.position)
        np.testing.assert_allclose(states[-1, :3], scenario.runway_state[:3], atol=1e-9)
        step = np.linalg.norm(np.diff(states[:, :3], axis=0), axis=1)
        assert np.all(step <= ac.speed * np.diff(t) + 1e-9)  # constant speed, corners cut at most
        assert np.all(np.abs(states[:, 3]) <= np.pi / 2)


def test_thesis_plan(thesis, thesis_plan):
    check_plan(thesis, thesis_plan)
    assert thesis_plan.planner == "multi-rrt" and thesis_plan.seed == 0
    assert thesis_plan.collision_checks["segments"] > 0 and thesis_plan.timings["total"] > 0


def test_five_aircraft_plan(five_plan):
    check_plan(*five_plan)
    assert len(five_plan[1].trajectories) == 5


def test_same_seed_same_result_different_seed_differs(thesis, thesis_plan):
    again = plan_initial(thesis, "multi-rrt", seed=0)
    for a, b in zip(thesis_plan.trajectories, again.trajectories, strict=True):
        assert a.callsign == b.callsign
        np.testing.assert_array_equal(a.waypoints, b.waypoints)
    other = plan_initial(thesis, "multi-rrt", seed=1)
    check_plan(thesis, other)
    assert any(
        not np.array_equal(a.waypoint, b.waypoint)
        for a, b in zip(thesis_plan.trajectories[1:], other.trajectories[1:], strict=True)
    )


def test_ompl_planner_in_sequencer(thesis):
    plan = plan_initial(thesis, "ompl:RRTConnect", seed=2, runs_per_aircraft=1)
    check_plan(thesis, plan)
    assert plan.planner == "ompl:RRTConnect"


def test_no_fly_zones_avoided():
    scenario = load_scenario(SCENARIOS / "no_fly_zones.yaml")
    plan = plan_initial(scenario, "multi-rrt", seed=3)
    check_plan(scenario, plan)
    for tr in plan.trajectories:
        for path in (tr.waypoints, tr.direct_path):
            s = np.linspace(0.0, 1.0, 2001)[:, None]
            dense = np.concatenate([a + s * (b - a) for a, b in zip(path[:-1], path[1:], strict=True)])
            for ob in scenario.obstacles:
                assert not ob.contains(dense).any(), f"{tr.callsign} enters {ob.name}"
