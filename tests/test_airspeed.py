"""The airspeed model: the point mass whose airspeed is a state, driven by thrust less drag from OpenAP; planned, flown
and verified against the type's envelope and the arrival procedures' speed rules."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from mal_planner.dynamics import AirspeedModel, make_dynamics
from mal_planner.performance import cas_of_tas, performance_of
from mal_planner.scenario import scenario_from_text
from mal_planner.trajectory import Trajectory
from mal_planner.units import ft_to_nm, kt_to_nm_per_s, nm_per_s_to_kt
from mal_planner.verification import verify
from mal_planner.verification.procedures import procedure_breaks

# 14 nm north of a runway landing south, 3,000 ft up at 240 kt true airspeed (about 230 kt CAS).
FAST = """
name: fast
runway: {{position: [0.0, 0.0, 0.0], flight_path_angle_deg: -3.0, heading_deg: -90.0}}
airspace: {{x: [-20.0, 20.0], y: [-5.0, 25.0], z: [0.0, 2.0]}}
aircraft:
  - {{callsign: FAST, position: [1.0, 14.0, 0.4937], flight_path_angle_deg: 0.0, heading_deg: -90.0,
     speed: {speed}, model: {model}}}
separation: {{distance_nm: 3.0, landing_spacing_s: 90.0, max_landing_spacing_s: 180.0}}
limits: {{bank_angle_deg: 30.0, n_h: [-1.0, 1.0], n_v: [0.7, 1.3]}}
procedures: {{aircraft_type: A320}}
"""


def fast(model: str = "point_mass_airspeed"):
    return scenario_from_text(FAST.format(speed=kt_to_nm_per_s(240.0), model=model))


def test_the_airspeed_is_a_state_driven_by_thrust_less_drag() -> None:
    model = make_dynamics("point_mass_airspeed", 0.07)
    assert isinstance(model, AirspeedModel) and model.n_states == 6 and model.n_controls == 3
    state = np.array([1.0, 2.0, 0.5, math.radians(-3.0), 0.3, 0.06])
    level = model.level_flight_control(state[3])
    rates = model.rhs(state, level)
    assert rates[5] == pytest.approx(0.0, abs=1e-15)  # n_x = sin(gamma): the speed holds on the glide path
    assert math.hypot(rates[0], rates[1], rates[2]) == pytest.approx(0.06)  # the state's airspeed, not 0.07
    idle = model.rhs(state, np.array([0.0, level[1], -0.04]))
    assert idle[5] == pytest.approx(model.gravity * (-0.04 - math.sin(state[3])))  # V' = g (n_x - sin gamma)
    x, u = ca.SX.sym("x", 6), ca.SX.sym("u", 3)
    symbolic = ca.Function("f", [x, u], [model.rhs(x, u)])(state, [0.0, level[1], -0.04])
    np.testing.assert_allclose(np.asarray(symbolic).ravel(), idle, rtol=1e-12)


def test_thrust_and_drag_come_from_openap() -> None:
    """The A320 slows at idle with its gear down in level flight by about 0.05 g (a 3.1 deg idle descent holds its
    speed) and gains at climb thrust; the scenario's airspeed-model aircraft get their type's band, a 6-entry first
    state."""
    band = performance_of("A320").longitudinal
    assert -0.07 < band.low < -0.04 and 0.02 < band.high < 0.1
    assert math.degrees(math.asin(-band.low)) == pytest.approx(3.1, abs=0.2)
    sc = fast()
    ac = sc.aircraft[0]
    assert ac.limits.n_x == (band.low, band.high)
    assert ac.state0.shape == (6,) and ac.state0[5] == pytest.approx(kt_to_nm_per_s(240.0))
    constant = fast("point_mass").aircraft[0]
    assert constant.state0.shape == (5,) and constant.limits.n_x == (0.0, 0.0)


def _glide(speeds_kt: tuple[float, float], x0: float = 10.0) -> Trajectory:
    """A straight 3 deg glide from x0 nm east to the threshold, slowing linearly between the two speeds (CAS at
    sea level, so TAS about equal), with the controls that fly it."""
    gamma = math.radians(-3.0)
    v0, v1 = (kt_to_nm_per_s(v) for v in speeds_kt)
    mean = 0.5 * (v0 + v1)
    duration = x0 / (mean * math.cos(gamma))
    t = np.linspace(0.0, duration, 200)
    v = v0 + (v1 - v0) * t / duration
    along = v0 * t + 0.5 * (v1 - v0) / duration * t**2
    x = np.column_stack([x0 - along * math.cos(gamma), np.zeros_like(t), -np.tan(gamma) * (x0 - along * math.cos(
        gamma)), np.full_like(t, gamma), np.full_like(t, math.pi), v])
    g = 0.0052952
    n_x = np.full_like(t, (v1 - v0) / duration / g + math.sin(gamma))
    return Trajectory("SLOWING", t, x, np.column_stack([np.zeros_like(t), np.full_like(t, math.cos(gamma)), n_x]))


def test_the_verification_checks_the_flown_airspeed() -> None:
    """A glide that slows from 210 to 140 kt keeps the final approach speed; one that slows only to 190 kt passes
    4 nm at 198 kt, lands at 190 kt and is refused, the breaks marked for the refinement (the NLP keeps the speed
    rules)."""
    text = """
name: glide
runway: {position: [0.0, 0.0, 0.0], flight_path_angle_deg: -3.0, heading_deg: 180.0}
airspace: {x: [-20.0, 20.0], y: [-20.0, 20.0], z: [-0.01, 3.0]}
aircraft:
  - {callsign: SLOWING, position: [10.0, 0.0, 0.5240777928304121], flight_path_angle_deg: -3.0, heading_deg: 180.0,
     speed: %r, model: point_mass_airspeed}
separation: {distance_nm: 3.0, landing_spacing_s: 90.0, max_landing_spacing_s: 180.0}
limits: {bank_angle_deg: 30.0}
procedures: {aircraft_type: A320}
"""
    for speeds, ok in (((210.0, 140.0), True), ((210.0, 190.0), False)):
        sc = scenario_from_text(text % kt_to_nm_per_s(speeds[0]))
        plan = _glide(speeds)
        np.testing.assert_allclose(sc.aircraft[0].state0, plan.states[0], atol=1e-12)
        report = verify(sc, [plan])
        speed_breaks = [r for r in report.reasons if "kt CAS" in r]
        assert (not speed_breaks) == ok, report.reasons
        if not ok:
            assert any("inside 4 nm" in b for b in speed_breaks) and any("lands at 190 kt" in b for b in speed_breaks)
            breaks = procedure_breaks(sc, sc.aircraft[0], plan.t, plan.states)
            assert all(b.kept_by_nlp for b in breaks if "kt CAS" in b.text)


def test_trajectories_carry_the_airspeed_to_json_and_back() -> None:
    plan = _glide((210.0, 150.0))
    data = plan.to_dict()
    assert data["airspeed"][0] == pytest.approx(kt_to_nm_per_s(210.0)) and "n_x" in data
    back = Trajectory.from_dict("SLOWING", data)
    np.testing.assert_array_equal(back.states, plan.states)
    np.testing.assert_array_equal(back.controls, plan.controls)
    assert back.state_names[-1] == "airspeed" and back.control_names[-1] == "n_x"


def test_the_optimizer_slows_an_arrival_down_to_its_final_approach_speed() -> None:
    """FAST starts at 230 kt CAS 14 nm out: its plan slows down to at most 180 kt inside 4 nm and stays above the
    A320's slowest final approach speed, within the 250-kt limit, and is verified; the constant-speed model's plan
    of the same aircraft breaks the final approach speed."""
    from mal_planner.options import PlanOptions, build_plan_options
    from mal_planner.pipeline import plan

    sc = fast()
    free = build_plan_options({"fixed_landing_times": False}, PlanOptions(seed=0))
    result = plan(sc, free)
    assert result.verification.verified, result.verification.reasons
    (tr,) = result.trajectories()
    cas = cas_of_tas(tr.states[:, 5], tr.states[:, 2] + sc.elevation_nm)
    inside = np.hypot(tr.states[:, 0], tr.states[:, 1]) < 4.0
    assert nm_per_s_to_kt(float(np.max(cas[inside]))) <= 180.0
    assert nm_per_s_to_kt(float(cas[0])) == pytest.approx(230.0, abs=3.0)
    assert float(np.min(cas)) >= performance_of("A320").final_approach_cas.low
    assert float(np.max(tr.states[:, 2])) <= sc.aircraft[0].state0[2] + ft_to_nm(10.0)  # no climb
    constant = fast("point_mass")
    kept = plan(constant, free)
    assert not kept.verification.verified
    assert any("inside 4 nm" in r for r in kept.verification.reasons)


def test_the_bluesky_closed_loop_says_it_flies_constant_speed_plans_only() -> None:
    """A bad start-up setting stops the start with one line naming the aircraft (before BlueSky starts)."""
    from mal_planner.closedloop.bluesky_sim import BlueSkySimulator

    with pytest.raises(ValueError, match=r"aircraft FAST: the BlueSky closed loop flies constant-speed plans only"):
        BlueSkySimulator(fast())


def test_the_sequencer_times_an_arrival_that_slows_down_and_loses_its_energy() -> None:
    """The nominal speed schedule takes longer than the first airspeed would; an aircraft higher up must fly farther
    to lose its energy at idle (per nm flown, whatever its speed), which bounds its landing from below."""
    from mal_planner.sequencing.timing import (
        earliest_landing_time,
        energy_distance,
        fastest_dynamics,
        flight_time,
        reachable_lower_bound,
    )

    sc = fast()
    ac = sc.aircraft[0]
    assert flight_time(sc, ac, 14.0) > 14.0 / ac.speed * 1.2  # from 240 kt down to the A320's 140 kt
    assert flight_time(fast("point_mass"), fast("point_mass").aircraft[0], 14.0) == pytest.approx(14.0 / ac.speed)
    assert energy_distance(fast("point_mass"), fast("point_mass").aircraft[0]) == 0.0
    high = scenario_from_text(FAST.format(speed=kt_to_nm_per_s(240.0), model="point_mass_airspeed").replace(
        "0.4937]", "1.6]"))  # 9,700 ft instead of 3,000 ft
    near, far = energy_distance(sc, ac), energy_distance(high, high.aircraft[0])
    assert far - near == pytest.approx((1.6 - 0.4937) / -ac.limits.n_x[0], rel=1e-9)  # the height alone
    assert far > 14.0 * 1.5  # farther than the straight way: it must stretch its path to land
    fastest = fastest_dynamics(high, high.aircraft[0]).speed  # its VMO as a true airspeed up there
    assert nm_per_s_to_kt(fastest) > 350.0
    assert reachable_lower_bound(high, high.aircraft[0]) == pytest.approx(far / fastest)
    assert earliest_landing_time(high, high.aircraft[0]) > earliest_landing_time(sc, ac) + 60.0


def test_airliners_through_a_wall_converge_on_their_lagrange_cost() -> None:
    """With fixed landing times the thesis passes the gate as late as it can; an airspeed-model aircraft's latest
    gate passage is its fastest way down, on its speed cones and idle thrust all the way, where the mesh did not
    converge (this pair: 79-90 s, mesh errors 6 times the tolerance and more, 'past the bounds'). Without that term
    the mesh converges within its tolerance (13 s)."""
    from mal_planner.campaign.traffic import TrafficSpec, generate_one
    from mal_planner.options import PlanOptions
    from mal_planner.pipeline import plan

    sc = generate_one(TrafficSpec(aircraft=(2, 2), profile="tma", layout="wall", flyable=True), 1).scenario
    assert sc.gates and all(a.dynamics.variable_airspeed for a in sc.aircraft)
    result = plan(sc, PlanOptions(seed=0))
    assert result.verification.verified, result.verification.reasons
    assert result.landing.status == "Solve_Succeeded" and not result.landing.recoveries
