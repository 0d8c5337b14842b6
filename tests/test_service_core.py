"""The service core (mal_planner.service): its rules on track sequences, and the node and the closed loop taking
the same decisions on the same radar tracks (one service, two adapters)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from dds_support import dds_env  # noqa: F401  (fixture)

from mal_planner.closedloop import ClosedLoopOptions, SimOptions, WindSpec
from mal_planner.closedloop.loop import ClosedLoop
from mal_planner.options import PlanOptions
from mal_planner.scenario import load_scenario
from mal_planner.service.book import Handout, Kept, Stale
from mal_planner.service.core import PlanningService
from mal_planner.service.policy import ReplanPolicy
from mal_planner.service.rules import ServiceRules
from mal_planner.service.tracks import Track
from mal_planner.trajectory import Reference
from mal_planner.units import nm_to_m

THESIS = "scenarios/thesis.yaml"


def _straight(t0: float, t1: float, y0: float) -> Reference:
    return Reference(np.array([t0, t1]), np.array([[0.0, y0, 0.1, 0.0, -math.pi / 2],
                                                   [0.0, y0 - 0.04 * (t1 - t0), 0.1, 0.0, -math.pi / 2]]))


def _track(cs: str, t: float, x: float, y: float) -> Track:
    return Track(cs, t, np.array([x, y, 0.1, 0.0, -math.pi / 2]), 0.04)


def test_the_policy_asks_for_new_aircraft_deviations_and_the_period_after_the_back_off() -> None:
    rules = ServiceRules(deviation_nm=0.05, min_interval_s=10.0, period_s=30.0)
    policy = ReplanPolicy(rules)
    flying = {"A": _straight(0.0, 100.0, 4.0)}

    def decide(t: float, tracks: dict[str, Track], last: float = 0.0, busy: bool = False) -> str | None:
        return policy.decide(t, tracks, flying, busy=busy, planned=True, last_arrival=last, first_track_at=0.0)

    on_plan = {"A": _track("A", 20.0, 0.0, 4.0 - 0.8)}
    assert decide(20.0, on_plan) is None
    strayed = {"A": _track("A", 20.0, 0.06, 4.0 - 0.8)}
    assert decide(20.0, strayed) == "A deviates 0.060 nm from its plan"
    assert decide(20.0, strayed, last=15.0) is None  # the back-off after the last plan (a failed one too)
    assert decide(20.0, strayed, busy=True) is None
    near_end = {"A": _track("A", 95.0, 0.06, 4.0 - 3.8)}  # within min_interval of its plan's end: flies on
    assert decide(95.0, near_end, last=80.0) is None
    assert decide(20.0, {**on_plan, "B": _track("B", 20.0, 1.0, 5.0)}) == "B has no plan"
    assert decide(31.0, on_plan) == "periodic replan"
    first = policy.decide(1.5, on_plan, {}, busy=False, planned=False, last_arrival=-math.inf, first_track_at=0.0)
    assert first == "initial plan (1 aircraft tracked)"
    settling = replace(rules, settle_time_s=2.0)
    assert ReplanPolicy(settling).decide(1.5, on_plan, {}, busy=False, planned=False, last_arrival=-math.inf,
                                         first_track_at=0.0) is None


@pytest.fixture(scope="module")
def thesis_loop() -> ClosedLoop:
    """A closed loop of the thesis in a wind the planner does not know (its plans drift off), first plan made."""
    scenario = load_scenario(THESIS)
    options = ClosedLoopOptions(sim=SimOptions(wind=WindSpec.from_knots(15.0, 0.0), seed=1), radar_noise_m=30.0,
                                planner_knows_wind=False, plan=PlanOptions(time_limit_s=120.0))
    loop = ClosedLoop(scenario, options)
    first = loop._first_plan()
    assert first.ok, first.message
    return loop


def test_a_late_plan_is_stale_and_a_failed_replan_keeps_the_plans_flown(thesis_loop: ClosedLoop) -> None:
    service = PlanningService(thesis_loop.base, thesis_loop.rules, thesis_loop.service.options)
    truth = {a.callsign: Track(a.callsign, 0.0, a.state0.copy(), a.speed) for a in thesis_loop.scenario.aircraft}
    request = service.request("initial plan", 0.0, tracks=truth, lead=False)
    result = thesis_loop.service.book.current.result
    (handout,) = service.finish(request, result, None, 0.0, 2.0)
    assert isinstance(handout, Handout) and set(handout.trajectories) == set(truth)
    for cs, tr in truth.items():  # every aircraft strays 0.3 nm east of its plan
        state = tr.state.copy()
        state[:3] = service.book.flying[cs].position(5.0) + [0.3, 0.0, 0.0]
        service.take_track(Track(cs, 5.0, state, tr.speed), "runway", "radar", 5.0, 5.0)
    failed = service.finish(service.request("test", 5.0), None, "optimizer failed: test", 6.0, 1.0)
    assert [type(e) for e in failed] == [Kept] and failed[0].since == 6.0 and failed[0].plan_start == 0.0
    late = service.request("test", 6.0, lead=False)
    (stale,) = service.finish(late, result, None, 9.0, 3.0)  # the old plan again: 0.3 nm from where they are
    assert isinstance(stale, Stale) and "not handed out" in stale.reason
    assert service.book.last_arrival == -math.inf  # the policy asks again at once


def test_the_node_and_the_closed_loop_decide_alike_on_the_same_radar_tracks(thesis_loop: ClosedLoop,
                                                                           dds_env) -> None:  # noqa: F811
    """The same noisy radar tracks (the thesis flown in an unknown 15 kt wind, a new aircraft at t = 20 s) go to
    the closed loop's service as the in-process loop feeds it and to a real planner node (built-in transport) as
    AircraftState messages through its subscription callback and its timer: both ask for the same plans at the
    same radar times, for the same reasons."""
    from mal_planner.ros.convert import planner_to_aircraft_state
    from mal_planner.ros.planner_node import PlannerNode

    loop, rules = thesis_loop, thesis_loop.rules
    overrides = {"deviation_threshold_m": float(nm_to_m(rules.deviation_nm)), "settle_time_s": 0.0,
                 "min_replan_interval_s": rules.min_interval_s, "track_timeout_s": rules.track_timeout_s,
                 "kept_plan_expiry_s": 0.0, "figures": "none"}
    node = PlannerNode(loop.scenario, overrides=overrides)
    try:
        clock = [0.0]
        node._clock = lambda: clock[0]
        truth = {a.callsign: Track(a.callsign, 0.0, a.state0.copy(), a.speed) for a in loop.scenario.aircraft}
        request = node.service.request("initial plan", 0.0, tracks=truth, lead=False)
        node.service.finish(request, loop.service.book.current.result, None, 0.0, 1.0)
        rng = np.random.default_rng(4)
        newcomer = np.array([-2.0, 5.5, 0.2, 0.0, -math.pi / 2])
        decisions: dict[str, list[tuple[float, str]]] = {"closed loop": [], "node": []}
        for k in range(1, 61):
            t = clock[0] = float(k)
            loop.sim.advance(t)
            tracks = [Track(a.callsign, t, a.state + np.r_[rng.normal(0.0, 30.0 / 1852.0, 3), 0.0, 0.0],
                            a.model.speed) for a in loop.sim.measurements()]
            if t >= 20.0:
                tracks.append(Track("X9", t, newcomer.copy(), 0.04))
                newcomer[1] -= 0.04
            for tr in tracks:
                loop.service.take_track(tr, "runway", "radar", t, t)
                node._on_state(planner_to_aircraft_state(node.types, tr.callsign, tr.stamp, tr.state, tr.speed),
                               "radar/tracks")
            loop.service.lose_tracks()
            loop.service.instruct(t)  # the closed loop's order: holds and the safety net, then the policy
            node._tick()
            if (reason := loop.service.poll(t)) is not None:
                decisions["closed loop"].append((t, reason))
                loop.service.refused(t)  # as if the replan failed: both back off alike
            if node.jobs.pending:
                job = node.jobs.take()
                decisions["node"].append((t, "; ".join(job.reasons)))
                node.service.refused(t)
                node.jobs.done(job, None)  # type: ignore[arg-type]
        assert decisions["node"] == decisions["closed loop"]
        # X9 flies no plan: both hold it (issue 32), and the node publishes the hold as its path
        assert loop.service.book.fallbacks["X9"].kind == node.service.book.fallbacks["X9"].kind == "hold"
        assert "X9" in node.publisher.published
        status = node.service.safety_net_status()  # what planner_status.json reports
        assert status["fallbacks"]["X9"] == "hold" and status["holds"] >= 1
        reasons = [r for _, r in decisions["node"]]
        assert any("deviates" in r for r in reasons) and "X9 has no plan" in reasons, decisions
    finally:
        node.stop()
