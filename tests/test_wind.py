"""Wind (issue 17): ground speed = airspeed + wind in the dynamics, the initializer's timing and the verification;
gates and the runway are ground tracks, flown crabbed; still air is planned exactly as without a wind."""

from __future__ import annotations

import math
from dataclasses import replace
from functools import cache
from pathlib import Path

import numpy as np
import pytest
import yaml

from mal_planner.errors import InfeasibleRequest
from mal_planner.initializer.frame import RunwayFrame
from mal_planner.landing import LandingOptions
from mal_planner.options import PlanOptions
from mal_planner.pipeline import Planner, PlanResult
from mal_planner.report import result_to_dict
from mal_planner.scenario import Scenario, ScenarioError, load_scenario, parse_scenario
from mal_planner.sequencing.schedule import check_request
from mal_planner.sequencing.timing import earliest_landing_times, reachable_lower_bound
from mal_planner.units import kt_to_nm_per_s
from mal_planner.verification import Tolerances, fly_all

COARSE = LandingOptions(mesh_tol=1e-4)
THESIS, GEODETIC = Path("scenarios/thesis.yaml"), Path("scenarios/thesis_geodetic.yaml")
HEAD = (20.0, -90.0)
"""20 kt from the local heading -90 deg: blowing towards +y, against the landing direction (-y)."""
TAIL = (20.0, 90.0)
CROSS = (20.0, 0.0)
"""20 kt from +x: blowing towards -x, across the final."""


def _data(path: Path = THESIS) -> dict:
    return yaml.safe_load(path.read_text())


def _thesis(wind: tuple[float, float] | None = None, free: bool = False, **edits: float) -> Scenario:
    """The thesis with a wind (kt, from_heading_deg); ``free``: no fixed landing times; ``edits``: landing times."""
    data = _data()
    if wind is not None:
        data["wind"] = {"speed_kt": wind[0], "from_heading_deg": wind[1]}
    for ac in data["aircraft"]:
        if free:
            ac.pop("landing_time")
        if ac["callsign"] in edits:
            ac["landing_time"] = edits[ac["callsign"]]
    return parse_scenario(data, "thesis+wind")


@cache
def _plan(wind: tuple[float, float] | None, free: bool = False) -> PlanResult:
    return Planner(PlanOptions(seed=0, landing=COARSE)).plan(_thesis(wind, free), reuse=False)


def test_zero_wind_plans_exactly_as_still_air() -> None:
    still = _plan(None)
    zero = Planner(PlanOptions(seed=0, landing=COARSE)).plan(_thesis((0.0, 0.0)), reuse=False)
    assert zero.verified and still.verified
    assert zero.landing.objective == still.landing.objective
    assert zero.landing.gate_times == still.landing.gate_times
    for a, b in zip(still.landing.trajectories, zero.landing.trajectories, strict=True):
        np.testing.assert_array_equal(b.states, a.states)


def test_helpers_fly_the_wind_triangle() -> None:
    """air_angles fly a segment (the ground velocity is along it) at length / (air_distance / V)."""
    dyn = _thesis(CROSS).aircraft[0].dynamics
    seg = np.array([[0.3, -2.0, 0.01], [-1.0, 0.2, 0.0], [0.5, 0.5, -0.02]])
    gamma, heading = dyn.air_angles(seg)
    velocity = dyn.rhs(np.vstack([np.zeros((3, 3)), gamma, heading]), np.zeros((2, 3)))[:3].T
    unit = seg / np.linalg.norm(seg, axis=1)[:, None]
    np.testing.assert_allclose(velocity, np.linalg.norm(velocity, axis=1)[:, None] * unit, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(velocity, axis=1),
                               np.linalg.norm(seg, axis=1) * dyn.speed / dyn.air_distance(seg), rtol=1e-12)
    # the crab on the thesis's final: heading into the wind by asin(w / V)
    crab = math.asin(kt_to_nm_per_s(20.0) / dyn.speed)
    assert dyn.heading_for_track(-math.pi / 2) == pytest.approx(-math.pi / 2 + crab, abs=1e-12)


def test_earliest_landing_headwind_later_than_still_air_later_than_tailwind() -> None:
    still, head, tail = _thesis(), _thesis(HEAD), _thesis(TAIL)
    e_still, e_head, e_tail = (earliest_landing_times(sc) for sc in (still, head, tail))
    for ac in still.aircraft:
        cs = ac.callsign
        assert e_head[cs] > e_still[cs] > e_tail[cs]
        bounds = [reachable_lower_bound(sc, sc.aircraft_by_callsign(cs)) for sc in (head, still, tail)]
        assert bounds[0] > bounds[1] > bounds[2]
        assert bounds[0] <= e_head[cs] and bounds[2] <= e_tail[cs]


def test_the_lower_bound_stays_true_in_a_wind() -> None:
    """155 s is impossible into a 20 kt headwind (A1's 5.9 nm at 124 kt over the ground), 140 s possible with the
    tailwind: neither request is judged by still air."""
    with pytest.raises(InfeasibleRequest, match=r"A1: landing time 155 s .* straight lines in the wind"):
        check_request(_thesis(HEAD))
    with pytest.raises(InfeasibleRequest, match=r"A1: landing time 140 s"):
        check_request(_thesis(A1=140.0))
    check_request(_thesis(TAIL, A1=140.0))


def test_headwind_free_times_plans_verified_and_lands_later() -> None:
    result = _plan(HEAD, free=True)
    assert result.verified, result.failure
    scenario = result.scenario
    for tr in result.landing.trajectories:
        ac = scenario.aircraft_by_callsign(tr.callsign)
        assert result.landing.landing_times[tr.callsign] >= reachable_lower_bound(scenario, ac)
    assert result.landing.landing_times["A1"] > 170.0  # 148 s at least in still air, 171.6 s into this wind


def test_crosswind_plans_verified_on_the_runway_course_crabbed() -> None:
    result = _plan(CROSS)
    assert result.verified, result.failure
    scenario, tol = result.scenario, Tolerances.for_scenario(result.scenario)
    crab = math.asin(kt_to_nm_per_s(20.0) / scenario.aircraft[0].speed)  # 7.98 deg
    for check in result.verification.aircraft:
        event = check.gate_events[0]
        # the flown (re-integrated) ground track is the gate's course, the heading is crabbed into the wind
        assert abs(math.remainder(event["track"] + math.pi / 2, 2 * math.pi)) <= tol.attitude
        assert event["heading"] == pytest.approx(-math.pi / 2 + crab, abs=tol.attitude)
        assert check.runway_error["track_error"] <= tol.attitude
    for tr in result.landing.trajectories:
        assert tr.states[-1, 4] == pytest.approx(-math.pi / 2 + crab, abs=tol.attitude)
    # the verification flew the wind: the same controls in still air miss the runway by far
    still = replace(scenario, aircraft=tuple(replace(ac, dynamics=ac.dynamics.with_wind(0.0, 0.0))
                                             for ac in scenario.aircraft))
    for (_, x), tr in zip(fly_all(result.landing.trajectories, still, tol), result.landing.trajectories, strict=True):
        assert np.linalg.norm(x[-1, :3] - scenario.runway_state[:3]) > 0.5, tr.callsign
    doc = result_to_dict(result)["scenario"]["wind"]
    assert doc["speed_kt"] == pytest.approx(20.0) and doc["from_heading_deg"] == 0.0
    assert doc["vector_nm_s"] == pytest.approx([-kt_to_nm_per_s(20.0), 0.0], abs=1e-15)


def test_a_turned_copy_turns_its_wind() -> None:
    """The initializer's runway frame turns the wind with the world: a turned copy's timing is the original's."""
    original = _thesis(CROSS)
    turned = RunwayFrame(1, (0.0, 0.0, 0.0)).scenario(original)
    assert turned.wind == pytest.approx((0.0, -kt_to_nm_per_s(20.0)), abs=1e-15)  # -x turned 90 deg left: -y
    assert all(tuple(ac.dynamics.wind) == turned.wind for ac in turned.aircraft)
    a, b = earliest_landing_times(original), earliest_landing_times(turned)
    assert b == pytest.approx(a, rel=1e-9)


@pytest.mark.parametrize(("wind", "message"), [
    ({"speed_kt": 150.0, "from_heading_deg": 0.0}, r"wind\.speed_kt: 150 kt is not below aircraft\[0\] A1's airspeed"),
    ({"speed_kt": 10.0}, r"wind: .*from_deg .* or from_heading_deg .*exactly one"),
    ({"speed_kt": 10.0, "from_deg": 90.0, "from_heading_deg": 0.0}, r"wind: .*exactly one"),
    ({"speed_kt": 10.0, "from_deg": 90.0}, r"wind\.from_deg: a true wind direction needs the runway on the Earth"),
])
def test_bad_wind_is_one_line_naming_it(wind: dict, message: str) -> None:
    data = _data()
    data["wind"] = wind
    with pytest.raises(ScenarioError, match=message) as info:
        parse_scenario(data, "thesis.yaml")
    assert "\n" not in str(info.value) and str(info.value).startswith("thesis.yaml: wind")


def test_a_true_wind_direction_on_a_geodetic_runway() -> None:
    """LFPG 27R lands on the true course 265.43 deg (local -y): a wind from 265.43 deg blows up the runway, against
    the landing (+y, a headwind); from 85.43 deg it is a tailwind (-y)."""
    speed = kt_to_nm_per_s(15.0)
    for from_deg, expected in ((265.43, (0.0, speed)), (85.43, (0.0, -speed))):
        data = _data(GEODETIC)
        data["wind"] = {"speed_kt": 15.0, "from_deg": from_deg}
        sc = parse_scenario(data)
        assert sc.wind == pytest.approx(expected, abs=1e-9 * speed)
        assert all(tuple(ac.dynamics.wind) == sc.wind for ac in sc.aircraft)
    assert load_scenario(GEODETIC).wind == (0.0, 0.0)


def test_a_wind_given_at_run_time_reaches_every_aircraft_and_too_strong_a_wind_leaves_one_out() -> None:
    """The node's ``wind`` topic: ``Scenario.with_wind`` puts the wind into every model; an aircraft whose airspeed
    is not above it is left out of the plan with the reason (it could not make way towards the runway)."""
    from mal_planner.ros.convert import wind_msg, wind_to_planner
    from mal_planner.ros.transport.cyclone import MessageTypes
    from mal_planner.service.inputs import build_plan_scenario
    from mal_planner.service.tracks import Track

    sc = load_scenario(THESIS)
    wind = (0.0, -kt_to_nm_per_s(10.0))
    windy = sc.with_wind(wind)
    assert windy.wind == wind
    assert all(a.dynamics.wind_y == wind[1] and a.dynamics.wind_x == 0.0 for a in windy.aircraft)
    assert sc.with_wind((0.0, 0.0)).aircraft[0].dynamics == sc.aircraft[0].dynamics  # still air: as loaded
    msg = wind_msg(MessageTypes(), 5.0, wind)
    assert wind_to_planner(msg, "runway") == pytest.approx(wind, abs=1e-15)
    msg.vector.z = 1.0
    with pytest.raises(ValueError, match="vertical"):
        wind_to_planner(msg, "runway")
    slow = Track("SLOW", 0.0, np.array([0.0, 5.0, 0.2, 0.0, -np.pi / 2]), kt_to_nm_per_s(8.0))
    a1 = sc.aircraft_by_callsign("A1")
    tracks = {"A1": Track("A1", 0.0, a1.state0.copy(), a1.speed), "SLOW": slow}
    inputs = build_plan_scenario(windy, tracks, 0.0, landing_shift=0.0)
    assert [a.callsign for a in inputs.scenario.aircraft] == ["A1"]
    assert "not below its horizontal airspeed" in inputs.left_out["SLOW"]
