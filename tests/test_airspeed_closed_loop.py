"""The airspeed model in the service and the closed loop: the guidance keeps the plan's times by speed, references
and predictions carry the airspeed, the service plans from the tracks' airspeeds, and airliners land in wind."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_airspeed import fast

from mal_planner.campaign.traffic import TrafficSpec, generate_one
from mal_planner.closedloop import ClosedLoopOptions, GuidanceGains, SimOptions, WindSpec, guidance_controls
from mal_planner.closedloop.loop import run_closed_loop
from mal_planner.closedloop.metrics import measure
from mal_planner.dynamics import ControlLimits, make_dynamics
from mal_planner.performance import cas_of_tas
from mal_planner.service.book import _speed_then
from mal_planner.service.inputs import build_plan_scenario
from mal_planner.service.tracks import Track
from mal_planner.trajectory import Reference
from mal_planner.units import kt_to_nm_per_s

V = kt_to_nm_per_s(200.0)


def _level_east(seconds: float, speed: float = V, airspeed: bool = True) -> Reference:
    """A straight level plan along x at ``speed``, from x = 0 at t = 0."""
    t = np.linspace(0.0, seconds, 61)
    states = np.column_stack([speed * t, np.zeros_like(t), np.full_like(t, 0.5), np.zeros_like(t), np.zeros_like(t)])
    return Reference(t, np.column_stack([states, np.full_like(t, speed)]) if airspeed else states)


def test_the_guidance_takes_out_lateness_by_speed_within_the_thrust_band() -> None:
    model = make_dynamics("point_mass_airspeed", V)
    limits = ControlLimits(n_x=(-0.05, 0.05))
    gains = GuidanceGains.for_turn_time(15.0)
    ref = _level_east(300.0)
    on_time = np.array([V * 100.0, 0.0, 0.5, 0.0, 0.0, V])
    behind = on_time.copy()
    behind[0] -= V * 5.0  # 5 s late: faster
    ahead = on_time.copy()
    ahead[0] += V * 5.0  # 5 s early: slower
    wind = np.zeros(2)
    u_on, u_late, u_early = (guidance_controls(model, limits, gains, x, wind, ref, 100.0) for x in (on_time, behind,
                                                                                                        ahead))
    assert u_on.shape == (3,) and u_on[2] == pytest.approx(0.0, abs=1e-9)  # level, on time: the speed holds
    assert u_late[2] > 0.0 > u_early[2]
    assert limits.n_x[0] <= u_early[2] and u_late[2] <= limits.n_x[1]
    # the airspeed that keeps the ground speed in a head wind is higher: the aircraft speeds up on time too
    head = guidance_controls(model, limits, gains, on_time, np.array([-kt_to_nm_per_s(20.0), 0.0]), ref, 100.0)
    assert head[2] > 0.0
    # a constant-speed aircraft gets the two load factors it had
    assert guidance_controls(make_dynamics("point_mass", V), limits, gains, on_time[:5], wind, ref, 100.0).shape == (2,)


def test_references_and_predictions_carry_the_airspeed() -> None:
    t = np.array([0.0, 10.0, 20.0])
    states = np.column_stack([t * V, 0 * t, 0 * t + 0.5, 0 * t, 0 * t, [V, 0.9 * V, 0.8 * V]])
    ref = Reference(t, states)
    assert ref.has_airspeed and ref.airspeed(15.0) == pytest.approx(0.85 * V)
    np.testing.assert_allclose(ref.states(6)[:, 5], states[:, 5])
    assert ref.states(5).shape == (3, 5)
    plain = Reference(t, states[:, :5])
    assert plain.airspeed(5.0) is None
    with pytest.raises(ValueError, match="carries no airspeed"):
        plain.states(6)
    # an aircraft 2 kt faster than its plan now is 2 kt faster than its plan ten seconds on, where the plan slows
    assert _speed_then(ref, V + kt_to_nm_per_s(2.0), 0.0, 10.0) == pytest.approx(0.9 * V + kt_to_nm_per_s(2.0))
    assert _speed_then(plain, V, 0.0, 10.0) == V


def test_the_service_plans_an_airspeed_model_aircraft_from_its_tracked_airspeed() -> None:
    sc = fast()
    start = sc.aircraft[0].state0
    slower = kt_to_nm_per_s(210.0)
    inputs = build_plan_scenario(sc, {"FAST": Track("FAST", 0.0, start[:5].copy(), slower, None)}, 0.0, 0.0)
    ac = inputs.scenario.aircraft[0]
    assert ac.state0.shape == (6,) and ac.state0[5] == pytest.approx(slower) and ac.speed == pytest.approx(slower)
    # a track faster than 250 kt CAS at 3,000 ft (a tail wind nobody measured) starts at the limit less the share
    too_fast = kt_to_nm_per_s(300.0)
    inputs = build_plan_scenario(sc, {"FAST": Track("FAST", 0.0, start[:5].copy(), too_fast, None)}, 0.0, 0.0)
    ac = inputs.scenario.aircraft[0]
    cas = cas_of_tas(ac.state0[5], ac.state0[2] + sc.elevation_nm)
    assert cas == pytest.approx(0.99 * kt_to_nm_per_s(250.0)) and ac.speed == pytest.approx(ac.state0[5])


def test_the_traffic_generator_writes_airliners() -> None:
    flyable = generate_one(TrafficSpec(aircraft=(3, 3), profile="tma", flyable=True), 0)
    plain = generate_one(TrafficSpec(aircraft=(3, 3), profile="tma"), 0)
    assert all(a.dynamics.variable_airspeed for a in flyable.scenario.aircraft)
    assert flyable.scenario.procedures is not None and "--flyable" in flyable.text
    np.testing.assert_allclose([a.state0[:5] for a in flyable.scenario.aircraft],
                               [a.state0 for a in plain.scenario.aircraft])  # the same draws


def test_an_airliner_is_flown_in_closed_loop_in_wind_and_gusts() -> None:
    """The service plans the airspeed model from radar, the simulator flies it with speed control: it lands,
    slowing from 240 kt to its final approach speed, within a few knots of its plan's airspeed."""
    sc = fast()
    wind = WindSpec.from_knots(15.0, math.radians(30.0), gust_kt=2.0)
    options = ClosedLoopOptions(sim=SimOptions(wind=wind, seed=1), radar_noise_m=30.0)
    run = run_closed_loop(sc, options)
    m = measure(run)
    assert m.success and m.landed == 1, m.failures
    flown = np.asarray(run.sim.aircraft[0].states)
    assert flown.shape[1] == 6 and flown[-1, 5] < 0.75 * flown[0, 5]  # slowed down to its final approach speed
    assert run.sim.aircraft[0].deviation_nm < 0.1 * sc.separation_nm


def test_flown_plans_land_further_apart_than_the_minimum_by_the_threshold_time() -> None:
    """The along-track error an aircraft may carry before the service replans is the threshold; on final it stays
    (no deceleration left at idle on a 3-deg path): flown plans space their landings by that time more."""
    from dataclasses import replace

    from mal_planner.options import PlanOptions
    from mal_planner.options.plan import resolve_flown, scenario_for, slowest_final_speed
    from mal_planner.performance import performance_of
    from mal_planner.sequencing.schedule import landing_spacing, planned_spacing

    sc = fast()
    threshold = 0.1
    opts = resolve_flown(replace(PlanOptions(), tracking_margins=True, tracking_threshold_nm=threshold), sc)
    final = performance_of("A320").final_approach_cas.low  # the airliner's slowest final, not its 240 kt
    assert slowest_final_speed(sc) == pytest.approx(final)
    assert opts.landing.margins.spacing_s == pytest.approx(threshold / final)
    planned = scenario_for(opts, sc)
    ac = sc.aircraft[0]
    assert planned_spacing(planned, ac, ac) == pytest.approx(landing_spacing(sc, ac, ac) + threshold / final)
    assert planned_spacing(scenario_for(PlanOptions(), sc), ac, ac) == landing_spacing(sc, ac, ac)  # open loop


def test_the_profile_figure_draws_calibrated_airspeeds_and_the_rules(tmp_path) -> None:
    """plan.json carries each sample's CAS, the type's speeds and the procedures; the figure draws them against the
    track miles to go (0 at the threshold)."""
    import json

    from mal_planner.figures import style
    from mal_planner.figures.data import load_plan
    from mal_planner.figures.profiles import distance_to_threshold, figure_profiles, has_profiles
    from mal_planner.pipeline import plan
    from mal_planner.report import result_to_dict
    from mal_planner.units import nm_per_s_to_kt

    result = plan(fast())
    doc = result_to_dict(result)
    (tmp_path / "plan.json").write_text(json.dumps(doc), encoding="utf-8")
    view = load_plan(tmp_path / "plan.json")
    assert has_profiles(view) and view.procedures is not None and view.aircraft[0].envelope["type"] == "A320"
    a = view.aircraft[0]
    assert 140.0 < nm_per_s_to_kt(a.cas[-1]) <= nm_per_s_to_kt(a.envelope["final_approach_cas"][1])
    assert distance_to_threshold(view, a)[-1] == 0.0 and distance_to_threshold(view, a)[0] > 13.0
    fig = figure_profiles(view, style.color_map(view.callsigns))
    speeds = fig.axes[0].lines[0].get_ydata()
    np.testing.assert_allclose(speeds, nm_per_s_to_kt(a.cas))
    style.save(fig, tmp_path / "profiles.png")
    assert (tmp_path / "profiles.png").stat().st_size > 10_000


SHORT_FINAL = """
name: short-final
runway: {position: [0.0, 0.0, 0.0], flight_path_angle_deg: -3.0, heading_deg: -90.0}
airspace: {x: [-20.0, 20.0], y: [-5.0, 25.0], z: [0.0, 2.0]}
aircraft:
  - {callsign: SHORT, position: [0.01, 0.8, 0.0425], flight_path_angle_deg: -3.0, heading_deg: -90.5,
     speed: 0.0389, model: point_mass_airspeed}
  - {callsign: WIDE, position: [5.0, 12.0, 0.6], flight_path_angle_deg: 0.0, heading_deg: -90.0, speed: 0.0556,
     model: point_mass_airspeed}
separation: {distance_nm: 3.0, landing_spacing_s: 90.0, max_landing_spacing_s: 180.0}
limits: {bank_angle_deg: 30.0, n_h: [-1.0, 1.0], n_v: [0.7, 1.3]}
procedures: {aircraft_type: A320}
"""


def test_an_aircraft_on_short_final_flies_straight_in() -> None:
    """0.8 nm out on the centreline at 140 kt (CDG 12:32: EJU875P really landed 22 s later): not routed back out
    through the final approach fix, no turn margin in its slot, so it lands in about 21 s, verified (it was sent away
    from the runway and back, which the rules refuse)."""
    from mal_planner.initializer.approach import direction, established
    from mal_planner.pipeline import plan
    from mal_planner.scenario import scenario_from_text

    sc = scenario_from_text(SHORT_FINAL)
    rw = sc.runway_state
    final = direction(float(rw[3]), float(rw[4]))
    assert established(sc.aircraft[0], rw[:3], final) == pytest.approx(0.8)
    assert established(sc.aircraft[1], rw[:3], final) is None  # 5 nm off the centreline's cone
    result = plan(sc)
    assert result.verified, result.verification.reasons
    flight = 0.8 / sc.aircraft[0].speed
    assert result.initial.schedule.times["SHORT"] == pytest.approx(flight, abs=1.0)  # before: through the fix, 9 s
    assert result.landing_times()["SHORT"] == pytest.approx(flight, abs=2.0)          # of margin on top
