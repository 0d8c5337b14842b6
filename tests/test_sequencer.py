"""The landing sequencer of chapter 4 on the thesis, five-aircraft and no-fly-zone scenarios."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mal_planner.initializer.sequencer import InitialPlan, plan_initial
from mal_planner.scenario import load_scenario, parse_scenario
from mal_planner.sequencing.timing import dubins_path_length

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
    schedule = plan.schedule
    assert schedule is not None and list(schedule.order) == [tr.callsign for tr in trs]
    for prev, tr in zip(trs[:-1], trs[1:], strict=True):
        assert tr.scheduled_time - prev.scheduled_time >= scenario.landing_spacing_s - 1e-9
    for tr in trs:
        ac = scenario.aircraft_by_callsign(tr.callsign)
        if ac.landing_time is not None:
            assert tr.scheduled_time == ac.landing_time
        else:
            assert tr.scheduled_time >= schedule.earliest[tr.callsign]
        dubins, straight = dubins_path_length(scenario, ac)
        flown = (tr.path_length + dubins - straight) / ac.speed  # the turns lengthen the polyline
        if tr.waypoint is None:
            np.testing.assert_array_equal(tr.waypoints, tr.direct_path)
            assert flown <= tr.scheduled_time + 5.0 + 1e-9
        else:
            np.testing.assert_array_equal(tr.waypoints[tr.waypoint_index], tr.waypoint)
            assert abs(flown - tr.scheduled_time) <= 5.0 + 1e-9
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


def test_fixed_times_in_another_order_set_the_order(thesis):
    """Landing order follows fixed landing times, even when they are not nearest-first."""
    times = {"A1": 185.0, "A2": 170.0, "A3": 200.0}
    scenario = _with_landing_times(thesis, times)
    plan = plan_initial(scenario, "multi-rrt", seed=0)
    check_plan(scenario, plan)
    assert [tr.callsign for tr in plan.trajectories] == ["A2", "A1", "A3"]


def test_free_times_first_come_first_served(thesis):
    """Without fixed times the order follows the turn-aware earliest landing and the minimum spacing."""
    scenario = _with_landing_times(thesis, {})
    plan = plan_initial(scenario, "multi-rrt", seed=0)
    check_plan(scenario, plan)
    earliest = plan.schedule.earliest
    assert [tr.callsign for tr in plan.trajectories] == sorted(earliest, key=earliest.get)


def test_wall_close_to_the_runway_two_aircraft():
    """The thesis's "first leg > half" rule left no waypoint when the wall is near the runway."""
    scenario = load_scenario(SCENARIOS / "thesis.yaml")
    data = scenario.config.model_dump(mode="json", exclude_none=True)
    data["aircraft"] = [{**a, "landing_time": None} for a in data["aircraft"][:2]]
    for a in data["aircraft"]:
        a.pop("landing_time")
    data["obstacles"] = [{"type": "wall_with_hole", "name": "wall", "axis": "y", "position": 0.8, "thickness": 0.001,
                          "span": {"x": [-3, 3], "z": [0, 0.3]}, "hole": {"x": [-0.5, 0.5], "z": [0.02, 0.12]}}]
    data["gates"] = []
    scenario = parse_scenario(data)
    plan = plan_initial(scenario, "multi-rrt", seed=0)
    check_plan(scenario, plan)


def _with_landing_times(scenario, times: dict[str, float]):
    data = scenario.config.model_dump(mode="json", exclude_none=True)
    for a in data["aircraft"]:
        a.pop("landing_time", None)
        if a["callsign"] in times:
            a["landing_time"] = times[a["callsign"]]
    return parse_scenario(data)
