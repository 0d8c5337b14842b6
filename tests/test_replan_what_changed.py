"""A replan of what changed: the verification against fixed paths, the pipeline's replan of some aircraft among the
others, the service's choice of whom to replan, and the closed loop flying it."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from mal_planner.closedloop import ClosedLoopOptions, SimOptions, WindSpec
from mal_planner.closedloop.loop import run_closed_loop
from mal_planner.closedloop.metrics import measure
from mal_planner.options import PlanOptions
from mal_planner.pipeline import Planner
from mal_planner.pipeline.among import plan_among, plan_joining
from mal_planner.scenario import load_scenario
from mal_planner.scenario.traffic import FixedPath, Traffic
from mal_planner.service.subsets import AFFECT_SEPARATIONS, joining_traffic, traffic_for
from mal_planner.trajectory import Reference
from mal_planner.verification import verify

THESIS = "scenarios/thesis.yaml"


@pytest.fixture(scope="module")
def thesis_plan():
    scenario = load_scenario(THESIS)
    result = Planner(PlanOptions()).plan(scenario)
    assert result.verified
    return scenario, result


def _path(scenario, traj, start: float = 0.0, shift=(0.0, 0.0, 0.0)) -> FixedPath:
    states = traj.states.copy()
    states[:, :3] += np.asarray(shift)
    t, idx = np.unique(traj.t, return_index=True)
    path = FixedPath.cut(scenario.aircraft_by_callsign(traj.callsign), t, states[idx], start, lands=True)
    assert path is not None
    return path


def test_the_verification_checks_a_plan_against_fixed_paths(thesis_plan) -> None:
    scenario, result = thesis_plan
    first, *rest = result.landing.trajectories
    others = replace(scenario, aircraft=tuple(a for a in scenario.aircraft if a.callsign != first.callsign))
    fixed = _path(scenario, first)
    assert verify(others, rest, fixed=[fixed]).verified  # the plan as made: separated from the first aircraft
    # the first aircraft's path moved onto the second's: a loss of separation against a fixed path
    onto = rest[0].states[0, :3] - first.states[0, :3]
    report = verify(others, rest, fixed=[_path(scenario, first, shift=onto)])
    assert not report.verified
    assert any(f"{first.callsign}-{rest[0].callsign}" in r or f"{rest[0].callsign}-{first.callsign}" in r
               for r in report.reasons), report.reasons
    # two fixed paths on top of each other are not this plan's: not checked
    twin = FixedPath(replace(scenario.aircraft_by_callsign(first.callsign), callsign="TWIN"), fixed.t, fixed.states,
                     fixed.landing_time)
    assert verify(others, rest, fixed=[fixed, twin]).verified
    # a fixed aircraft landing one second after the second one: the landing spacing is checked against it
    late = FixedPath(fixed.aircraft, fixed.t, fixed.states, result.landing.landing_times[rest[0].callsign] + 1.0)
    report = verify(others, rest, fixed=[late])
    assert any("landings 1.00 s apart" in r for r in report.reasons), report.reasons


def test_a_replan_of_what_changed_keeps_the_others_and_is_verified_against_them(thesis_plan) -> None:
    scenario, result = thesis_plan
    start = 10.0
    trajectories = {tr.callsign: tr for tr in result.landing.trajectories}
    last = result.order[-1]
    paths = {cs: _path(scenario, tr, start) for cs, tr in trajectories.items()}
    here = paths[last].states[0].copy()
    here[:3] += [0.02, -0.02, 0.0]  # it strayed
    sub = replace(scenario, aircraft=(replace(scenario.aircraft_by_callsign(last), state0=here, landing_time=None),))
    traffic = Traffic((paths[last],), tuple(p for cs, p in paths.items() if cs != last))
    replanned = plan_among(Planner(PlanOptions()), sub, traffic, start_time=start)
    assert replanned.verified, replanned.failure
    assert [tr.callsign for tr in replanned.landing.trajectories] == [last]
    assert replanned.landing.landing_times[last] == pytest.approx(paths[last].landing_time, abs=1e-6)
    # the verification saw the fixed aircraft: every pair with the replanned one is in its report
    pairs = {frozenset(p.pair.split("-")) for p in replanned.verification.pairs}
    assert pairs == {frozenset((last, cs)) for cs in paths if cs != last}


def test_an_aircraft_without_a_plan_joins_after_the_others_clear_of_their_paths(thesis_plan) -> None:
    scenario, result = thesis_plan
    start = 10.0
    last = result.order[-1]
    trajectories = {tr.callsign: tr for tr in result.landing.trajectories}
    paths = {cs: _path(scenario, tr, start) for cs, tr in trajectories.items() if cs != last}
    here = trajectories[last].state_at(np.array([start]))[0]  # where it is (it flew no plan: say, a hold)
    me = replace(scenario.aircraft_by_callsign(last), state0=here, landing_time=None)
    joined = plan_joining(Planner(PlanOptions()), replace(scenario, aircraft=(me,)),
                          Traffic((), tuple(paths.values()), (last,)), start_time=start)
    assert joined.verified, joined.failure
    assert [tr.callsign for tr in joined.landing.trajectories] == [last]
    # it lands after the last fixed landing, at least the landing spacing behind it
    latest = max(p.landing_time for p in paths.values())
    assert joined.landing.landing_times[last] >= latest + scenario.landing_spacing_s - 1e-6
    pairs = {frozenset(p.pair.split("-")) for p in joined.verification.pairs}
    assert pairs == {frozenset((last, cs)) for cs in paths}


def _level(cs: str, y0: float, x: float, t_end: float = 100.0) -> Reference:
    t = np.array([0.0, t_end])
    return Reference(t, np.array([[x, y0, 0.1, 0.0, -math.pi / 2], [x, y0 - 0.04 * t_end, 0.1, 0.0, -math.pi / 2]]))


def test_the_service_replans_the_straying_aircraft_with_those_it_can_affect() -> None:
    scenario = load_scenario(THESIS)
    sep = scenario.separation_nm
    ac = {cs: replace(scenario.aircraft[0], callsign=cs) for cs in ("A", "B", "C", "D")}
    near, far = 0.5 * AFFECT_SEPARATIONS * sep, 3.0 * AFFECT_SEPARATIONS * sep
    plans = {"A": _level("A", 5.0, 0.0), "B": _level("B", 5.0, near), "D": _level("D", 5.0, far)}
    hold = {"C": _level("C", 5.0, -near)}  # near A, but flying a hold: it keeps it
    tracked = replace(scenario, aircraft=tuple(ac.values()))
    traffic = traffic_for({"A"}, tracked, plans | hold, plans, 10.0)
    assert traffic is not None
    assert traffic.callsigns == ("A", "B")
    assert {p.callsign: p.landing_time for p in traffic.fixed} == {"C": None, "D": pytest.approx(90.0)}
    assert traffic.replanned[0].t[0] == 0.0 and traffic.replanned[0].landing_time == pytest.approx(90.0)
    # a whole replan is due: an aircraft flies nothing, or everyone flying a plan is affected
    assert traffic_for({"A"}, tracked, plans, plans, 10.0) is None
    vector = {"C": _level("C", 5.0, -near, t_end=50.0)}  # ends before A lands: where C flies then is unknown
    assert traffic_for({"A"}, tracked, plans | vector, plans, 10.0) is None
    both = {cs: plans[cs] for cs in ("A", "B")}
    assert traffic_for({"A"}, tracked, both | hold | {"D": _level("D", 5.0, far)}, both, 10.0) is None


def test_aircraft_without_a_plan_join_among_everyone_flying_one() -> None:
    scenario = load_scenario(THESIS)
    ac = {cs: replace(scenario.aircraft[0], callsign=cs) for cs in ("A", "B", "C")}
    plans = {"A": _level("A", 5.0, 0.0), "B": _level("B", 5.0, 1.0)}
    tracked = replace(scenario, aircraft=tuple(ac.values()))
    traffic = joining_traffic({"C"}, tracked, plans, 10.0)
    assert traffic is not None and traffic.callsigns == ("C",) and traffic.replanned == ()
    assert {p.callsign: p.landing_time for p in traffic.fixed} == {"A": pytest.approx(90.0), "B": pytest.approx(90.0)}
    # a whole plan is due: nobody flies a plan, another aircraft flies none, or a plan ended
    assert joining_traffic({"A", "B", "C"}, tracked, {}, 10.0) is None
    assert joining_traffic({"C"}, tracked, {"A": plans["A"]}, 10.0) is None
    assert joining_traffic({"C"}, tracked, plans, 100.0) is None


def test_the_closed_loop_replans_what_changed_and_keeps_every_minimum() -> None:
    scenario = load_scenario(THESIS)
    wind = WindSpec.from_knots(15.0, math.radians(0.0))
    options = ClosedLoopOptions(sim=SimOptions(wind=wind), planner_knows_wind=False, replan_what_changed=True,
                                plan=replace(PlanOptions(), time_limit_s=20.0), max_time_s=90.0)
    run = run_closed_loop(scenario, options)
    m = measure(run)
    assert m.replans_what_changed >= 1, [(r.reason, r.message, r.kept) for r in run.replans]
    assert m.losses_of_separation == 0 and m.infringements == 0
    assert all(r.kept < len(scenario.aircraft) for r in run.replans)
