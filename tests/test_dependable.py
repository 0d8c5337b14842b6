"""Dependable planning: impossible requests refused up front, strict verification, replans never stuck."""

from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from test_verification import straight_level

from mal_planner.errors import InfeasibleRequest
from mal_planner.landing import LandingOptions
from mal_planner.landing.guess import straight_line_guess
from mal_planner.landing.publish import published_times
from mal_planner.landing.solve import LandingOptimizer
from mal_planner.ocp import PhaseMesh, PhaseSolution
from mal_planner.ocp.mesh import layout as mesh_layout
from mal_planner.options import PlanOptions
from mal_planner.pipeline import Planner
from mal_planner.scenario import load_scenario, parse_scenario, scenario_from_text
from mal_planner.sequencing.schedule import check_request, make_schedule
from mal_planner.sequencing.timing import earliest_landing_times, reachable_lower_bound
from mal_planner.verification import verify

COARSE = LandingOptions(mesh_tol=1e-4)
V = 0.04


@pytest.fixture(scope="module")
def thesis():
    return load_scenario("scenarios/thesis.yaml")


def edited(scenario, **aircraft_fields):
    """A copy of ``scenario`` with aircraft fields replaced: ``A1={"position": [...]}``."""
    data = scenario.config.model_dump(mode="json", exclude_none=True)
    for a in data["aircraft"]:
        a.update(aircraft_fields.get(a["callsign"], {}))
        if a.get("landing_time", 0) is None:
            a.pop("landing_time")
    return parse_scenario(data)


def test_separation_broken_at_the_start_is_refused(thesis) -> None:
    sc = edited(thesis, A2={"position": [1.3, 5.8, 0.28]})
    with pytest.raises(InfeasibleRequest, match=r"A1 and A2 are 0\.100 nm apart at the start"):
        check_request(sc)


def test_unreachable_landing_time_is_refused(thesis) -> None:
    sc = edited(thesis, A1={"landing_time": 100.0})
    bound = reachable_lower_bound(sc, sc.aircraft_by_callsign("A1"))
    assert 100.0 < bound < 155.0
    with pytest.raises(InfeasibleRequest, match=r"A1: landing time 100 s is earlier than it can reach the runway"):
        check_request(sc)


def test_aircraft_leaving_through_the_ceiling_is_refused(thesis) -> None:
    """The main job's replan: after 16.5 s of straight flight A2 (climbing at 5 deg) is at the ceiling; even a
    pushover at n_v = 0 takes it 0.0012 nm above: an impossible request, not solver noise."""
    sc = edited(thesis, A2={"position": [-1.15, 5.9, 0.3]})
    with pytest.raises(InfeasibleRequest, match=r"A2: at 0\.3000 nm climbing at 5\.0 deg it rises to 0\.3012 nm"):
        check_request(sc)
    check_request(edited(thesis, A2={"position": [-1.15, 5.9, 0.298]}))  # 0.0012 nm below: it can level off
    sc = edited(thesis, A3={"position": [3.0, 5.5, 0.0002], "flight_path_angle_deg": -3.0})
    with pytest.raises(InfeasibleRequest, match=r"A3: .* descending at 3\.0 deg .* below the airspace floor"):
        check_request(sc)


def test_landing_times_closer_than_the_spacing_are_refused(thesis) -> None:
    sc = edited(thesis, A2={"landing_time": 160.0})
    with pytest.raises(InfeasibleRequest, match=r"A1 and A2 land 5 s apart"):
        check_request(sc)


def test_gate_too_small_to_pass_is_refused(thesis) -> None:
    data = thesis.config.model_dump(mode="json", exclude_none=True)
    data["gates"][0]["bounds"] = {"x": [-1.0, 1.0], "z": [0.1, 0.105]}
    with pytest.raises(InfeasibleRequest, match="leaves no room to pass"):
        check_request(parse_scenario(data), gate_margin_nm=0.012)


def test_earliest_landing_is_turn_aware_and_above_the_bound(thesis) -> None:
    earliest = earliest_landing_times(thesis)
    for ac in thesis.aircraft:
        assert reachable_lower_bound(thesis, ac) <= earliest[ac.callsign] <= ac.landing_time
    # Pointing away from the runway costs a turn: the estimate grows, the straight-line bound does not.
    away = edited(thesis, A1={"heading_deg": 90.0})
    assert earliest_landing_times(away)["A1"] > earliest["A1"] + 10.0  # a 105 deg turn
    assert reachable_lower_bound(away, away.aircraft_by_callsign("A1")) == pytest.approx(
        reachable_lower_bound(thesis, thesis.aircraft_by_callsign("A1")))


def test_partly_fixed_times_keep_the_fixed_and_space_the_rest(thesis) -> None:
    sc = edited(thesis, A2={"landing_time": None}, A3={"landing_time": None})
    schedule = make_schedule(sc, earliest_landing_times(sc))
    times = schedule.time_list()
    assert schedule.times["A1"] == 155.0
    assert all(b - a >= sc.landing_spacing_s - 1e-9 for a, b in zip(times, times[1:], strict=False))


def test_verification_accepts_nothing_below_the_separation(thesis) -> None:
    """Two parallel aircraft 0.2498 nm apart (five_aircraft passed with that before): refused."""
    for gap, ok in ((0.2498, False), (0.2502, True)):
        a, b = np.array([-1.0, 5.0, 0.2]), np.array([-1.0 + gap, 5.0, 0.2])
        sc = thesis.with_initial_states({"A1": np.array([*a, 0.0, -math.pi / 2]),
                                         "A2": np.array([*b, 0.0, -math.pi / 2])})
        report = verify(sc, [straight_level("A1", a, -math.pi / 2, 10.0), straight_level("A2", b, -math.pi / 2, 10.0)])
        broken = [r for r in report.reasons if "nm apart" in r]
        assert bool(broken) != ok, (gap, report.reasons)


def test_verification_checks_the_published_bank_angle_exactly(thesis) -> None:
    """A bank of 45.05 deg (inside the old 0.1 deg tolerance) is refused; the controls are not clipped."""
    start = np.array([0.0, 5.0, 0.2])
    sc = thesis.with_initial_states({"A1": np.array([*start, 0.0, -math.pi / 2])})
    n_h = math.tan(math.radians(45.05))
    tr = straight_level("A1", start, -math.pi / 2, 2.0, controls=(n_h, 1.0))
    report = verify(sc, [tr])
    assert any("bank angle reaches 45.050 deg" in r for r in report.reasons), report.reasons
    assert report.aircraft[0].limit_violation_times_s


def test_planned_controls_keep_the_limits_without_clipping(thesis) -> None:
    result = Planner(PlanOptions(seed=0, landing=COARSE)).plan(thesis, reuse=False)
    assert result.verified, result.verification.reasons
    for tr in result.trajectories():
        lim = thesis.aircraft_by_callsign(tr.callsign).limits
        assert np.all(np.abs(tr.controls[:, 0]) <= math.tan(lim.bank_angle_max) * tr.controls[:, 1])
        assert np.all(tr.controls[:, 1] >= lim.n_v[0]) and np.all(tr.controls[:, 1] <= lim.n_v[1])
    assert result.verification.aircraft[0].max_position_deviation_nm < 5e-3


def test_a_failed_plan_never_leaves_the_planner_stuck(thesis) -> None:
    """A plan that fails with another aircraft set must not make the next warm start raise KeyError."""
    planner = Planner(PlanOptions(seed=0, landing=COARSE))
    assert planner.plan(thesis, start_time=0.0).verified
    two = replace(thesis, aircraft=thesis.aircraft[:2])
    planner.options = replace(planner.options, time_limit_s=0.05)
    failed = planner.plan(two, start_time=2.0)
    assert failed.failure is not None and failed.failure[0] == "timeout"
    planner.options = replace(planner.options, time_limit_s=None)
    again = planner.plan(two, start_time=2.0)
    assert again.verified, again.verification.reasons


def test_a_replan_starts_over_only_after_a_failed_replan(thesis, monkeypatch: pytest.MonkeyPatch) -> None:
    """A failing replan tries the warm start and optimizer-chosen landing times only (the aircraft keep the plans
    they fly); the next replan, after that failure, also starts over (cold, joint, fresh initializer)."""
    planner = Planner(PlanOptions(seed=0, landing=COARSE))
    assert planner.plan(thesis, start_time=0.0).verified
    tried: list[str] = []

    def failing(name: str):
        def attempt(self, scenario, start_time, deadline):
            tried.append(name)
            raise RuntimeError("no plan")
        return attempt

    for name in ("_warm_attempt", "_free_times_attempt", "_cold_same_order", "_joint_same_order", "_fresh_initializer"):
        monkeypatch.setattr(Planner, name, failing(name))
    assert planner.plan(thesis, start_time=2.0).failure is not None
    assert tried == ["_warm_attempt", "_free_times_attempt"]
    tried.clear()
    assert planner.plan(thesis, start_time=4.0).failure is not None
    assert tried[:2] == ["_warm_attempt", "_free_times_attempt"]
    assert {"_cold_same_order", "_fresh_initializer"} <= set(tried[2:])


def test_replan_just_before_a_landing_drops_the_landed_aircraft(thesis) -> None:
    planner = Planner(PlanOptions(seed=0, landing=COARSE))
    first = planner.plan(thesis, start_time=0.0)
    assert first.verified
    t = first.landing_times()["A1"] - 1.0
    states = {tr.callsign: tr.state_at(t) for tr in first.trajectories()}
    second = planner.plan(thesis.with_initial_states(states), start_time=t)
    assert "A1" not in second.order and second.verified, second.failure
    # Warm: no new initializer run; the others' previous plans were the guesses.
    assert [tr.callsign for tr in second.initial.trajectories] == ["A2", "A3"]
    assert second.initial.trajectories[0] is first.initial.by_callsign("A2")
    for cs in ("A2", "A3"):
        assert second.landing_times()[cs] + t == pytest.approx(first.landing_times()[cs], abs=1e-6)


def test_fixed_times_out_of_nearest_first_order_plan_verified(thesis) -> None:
    sc = edited(thesis, A1={"landing_time": 185.0}, A2={"landing_time": 170.0}, A3={"landing_time": 200.0})
    result = Planner(PlanOptions(seed=0, landing=COARSE)).plan(sc, reuse=False)
    assert result.order == ["A2", "A1", "A3"]
    assert result.verified, result.failure
    for cs, t in {"A1": 185.0, "A2": 170.0, "A3": 200.0}.items():
        assert result.landing_times()[cs] == pytest.approx(t, abs=1e-6)


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mal_planner.cli", *args], capture_output=True, text=True,
                          timeout=120)


@pytest.mark.parametrize(("args", "message"), [
    (["--seed", "-2"], "--seed: must be >= -1, got -2"),
    (["--mesh-tol", "0"], "--mesh-tol: must be > 0, got 0.0"),
    (["--mesh-tol", "nan"], "--mesh-tol: expected a finite number, got nan"),
    (["--time-limit", "-1"], "--time-limit: must be > 0, got -1.0"),
    (["--initializer", "ompl:Nope"], "--initializer: no such planner (known: multi-rrt, ompl:"),
    (["--out", "/proc/no/such"], "cannot create the folder"),
])
def test_cli_bad_options_exit_2_with_one_line(args, message) -> None:
    proc = run_cli("scenarios/thesis.yaml", *args)
    assert proc.returncode == 2 and message in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr


def test_cli_binary_scenario_and_impossible_request_exit_2(tmp_path: Path, thesis) -> None:
    binary = tmp_path / "x.yaml"
    binary.write_bytes(bytes(range(256)))
    proc = run_cli(str(binary))
    assert proc.returncode == 2 and "not a text" in proc.stderr and "Traceback" not in proc.stderr
    text = Path("scenarios/thesis.yaml").read_text()
    text = text.replace("position: [-1.8, 6.0, 0.25]", "position: [1.3, 5.8, 0.28]")
    close = tmp_path / "close.yaml"
    close.write_text(text)
    proc = run_cli(str(close), "--out", str(tmp_path / "o"))
    assert proc.returncode == 2 and "impossible request: A1 and A2 are 0.100 nm apart" in proc.stderr, proc.stderr


def test_cli_random_seed_is_reported(tmp_path: Path) -> None:
    proc = run_cli("scenarios/thesis.yaml", "--seed", "-1", "--initial-only", "--figures", "none", "--out",
                   str(tmp_path), "-q")
    assert proc.returncode == 0 and "random seed" in proc.stderr
    assert "exit codes" in run_cli("--help").stdout


def test_unknown_initializer_is_refused_when_the_planner_is_made() -> None:
    from mal_planner.errors import InvalidInput

    with pytest.raises(InvalidInput, match="unknown planner 'ompl:Nope'"):
        Planner(PlanOptions(initializer="ompl:Nope"))


@pytest.mark.parametrize("planner", ["ompl:PRM", "ompl:PRMstar"])
def test_threaded_ompl_planners_do_not_deadlock(planner: str) -> None:
    """PRM grows its roadmap in a thread; a Python stop callback deadlocked it (and the node ignored SIGINT)."""
    code = ("import numpy as np; from mal_planner.scenario import load_scenario; "
            "from mal_planner.initializer import make_planner, CollisionChecker; "
            "sc = load_scenario('scenarios/no_fly_zones.yaml'); ch = CollisionChecker.from_scenario(sc); "
            f"p = make_planner('{planner}').plan(ch, sc.aircraft[0].position, sc.runway_state[:3], "
            "np.random.default_rng(0)); print(len(p))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and int(proc.stdout.strip()) >= 2, proc.stderr


# Three regressions from the 200-scenario campaign (benchmarks/dependable_campaign.sh), each reduced to what
# made it fail.
def generated(airspace: str, body: str) -> str:
    """A scenario file as mal-traffic writes them (runway at the origin heading -90 deg), in short form."""
    return f"""
name: generated
gravity: 0.0052952
runway: {{position: [0.0, 0.0, 0.0], flight_path_angle_deg: 0.0, heading_deg: -90.0}}
airspace: {airspace}
separation: {{distance_nm: 0.25, landing_spacing_s: 15.0, max_landing_spacing_s: 30.0}}
limits: {{bank_angle_deg: 45.0, n_h: [-2.0, 2.0], n_v: [0.0, 2.0]}}
{body}"""


WESTBOUND = generated("{x: [-5.5, 5.5], y: [0.0, 8.0], z: [0.0, 0.4]}", """aircraft:
  - {callsign: T02, position: [2.8578, 3.5034, 0.1521], flight_path_angle_deg: 0.0, heading_deg: 177.0,
     speed: 0.04345, landing_time: 119.1}
""")


def test_a_turn_across_180_deg_is_not_a_full_circle_more() -> None:
    """Heading 177 deg, runway heading -90 deg, a left turn of 93 deg: the guess started at -183 deg, so the NLP
    asked for a right turn of 267 deg and the fixed landing time was infeasible (campaign traffic-0096)."""
    sc = scenario_from_text(WESTBOUND)
    guess = straight_line_guess(sc, ["T02"], [119.1])[0]
    # The guess starts at the aircraft's heading (smoothed), not a full circle away from it.
    assert abs(guess.states[0, 4] - math.radians(177.0)) < math.pi / 2
    assert abs(guess.states[-1, 4] - guess.states[0, 4]) < math.pi
    optimizer = LandingOptimizer(sc, [guess], COARSE)
    # A heading given a full circle away (e.g. a radar heading that wrapped) is the same parameter.
    turned = sc.with_initial_states({"T02": sc.aircraft[0].state0 - np.array([0, 0, 0, 0, 2 * math.pi])})
    assert np.array_equal(optimizer.problem.params(turned, [119.1]), optimizer.problem.params(sc, [119.1]))
    result = Planner(PlanOptions(seed=0, landing=COARSE)).plan(sc, reuse=False)
    assert result.verified, result.failure
    assert result.landing_times()["T02"] == pytest.approx(119.1, abs=1e-6)


CORNER = generated("{x: [-4.0, 4.0], y: [0.0, 6.5], z: [0.0, 0.3]}", """aircraft:
  - {callsign: T01, position: [0.1868, 5.0831, 0.2258], flight_path_angle_deg: 0.0, heading_deg: -131.3,
     speed: 0.04141, landing_time: 141.4}
  - {callsign: T02, position: [-2.9382, 5.016, 0.2336], flight_path_angle_deg: 0.0, heading_deg: -3.3,
     speed: 0.03783, landing_time: 162.8}
obstacles:
  - {type: superquadric, name: zone-1, center: [-1.039, 1.375, 0.15], semi_axes: [0.369, 0.416, 0.3], p: 50}
  - {type: superquadric, name: zone-2, center: [1.111, 3.617, 0.15], semi_axes: [0.44, 0.799, 0.3], p: 50}
""")


def test_a_cut_no_fly_zone_corner_is_refined_until_verified() -> None:
    """A path hugging a box-like zone's corner cut it by 0.04 nm between collocation points 1.1 s apart, and
    three rounds of halving the segment did not fix it (campaign traffic-0128); a short segment at the cut
    does."""
    sc = scenario_from_text(CORNER)
    result = Planner(PlanOptions(seed=0)).plan(sc, reuse=False)
    assert result.verified, result.failure


def test_published_controls_follow_a_sharply_bending_control() -> None:
    """Linear between the published samples, the controls stay within control_tol of the solution's control
    interpolant; a 0.25 s grid alone misses a sharp bend by far more (campaign traffic-0083: a 0.0035 nm drift
    over 290 s that put the flown path below the floor before landing)."""
    mesh = PhaseMesh((0.0, 1.0), (10,))
    lay = mesh_layout(mesh)
    t = 20.0 * (lay.tau + 1.0) / 2.0
    u = np.column_stack([1.0 + 0.3 * np.exp(-t), 0.9 + 0.01 * t])  # bends hard in the first seconds only
    phase = PhaseSolution("p", 0.0, 20.0, t, np.zeros((len(t), 5)), u, 0.0, lay)

    def worst_midpoint_miss(times: np.ndarray) -> float:
        mid = 0.5 * (times[:-1] + times[1:])
        uu, um = phase.interpolate(times)[1], phase.interpolate(mid)[1]
        return float(np.max(np.abs(um - 0.5 * (uu[:-1] + uu[1:]))))

    plain = published_times(phase, slice(0, 2), 0.25, math.inf)
    dense = published_times(phase, slice(0, 2), 0.25, 1e-5)
    assert worst_midpoint_miss(plain) > 1e-4
    assert worst_midpoint_miss(dense) <= 1e-5
    assert np.all(np.isin(plain, dense)) and np.all(np.diff(dense) > 0)
    assert len(dense) < 4 * len(plain)  # samples only where the controls bend


FAR_FROM_CONVERGED = generated("{x: [-4.5, 4.5], y: [0.0, 11.0], z: [0.0, 0.5]}", """aircraft:
  - {callsign: T01, position: [0.2324, 6.1661, 0.2671], flight_path_angle_deg: 0.0, heading_deg: -95.7,
     speed: 0.03653, landing_time: 189.9}
  - {callsign: T02, position: [1.7515, 6.0545, 0.2496], flight_path_angle_deg: 0.0, heading_deg: -148.1,
     speed: 0.03688, landing_time: 208.4}
obstacles:
  - {type: wall_with_hole, name: wall, axis: y, position: 3.407, thickness: 0.001,
     span: {x: [-4.5, 4.5], z: [0.0, 0.5]}, hole: {x: [-1.162, 0.184], z: [0.117, 0.22]}, p: 50}
""")


def test_a_plan_kept_far_above_the_mesh_tolerance_is_recovered_from() -> None:
    """T02's refined mesh found no solution, and its plan at mesh error 1.5e-2 (tolerance 1e-5) was kept: flown,
    its controls went 0.44 nm off and through the wall (campaign traffic-0131 at thesis size). Such a plan is
    now recovered from like a failed one; another guess gives one that verifies."""
    sc = scenario_from_text(FAR_FROM_CONVERGED)
    result = Planner(PlanOptions(seed=0, landing=LandingOptions(strategy="sequential"))).plan(sc, reuse=False)
    assert result.verified, result.failure
    assert [(r.callsign, r.success) for r in result.landing.recoveries][-1] == ("T02", True)
