"""Service reliability under faults (issue 22): lost tracks withdraw their plans, failed replans say how old
the kept plan is, bursts of new callsigns, implausible radar input, a killed recorder or launcher.

Real processes on real DDS (loopback), once per backend where the node is involved.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from dds_support import Snippet, coarse_params, dds_env, snippet  # noqa: F401  (fixtures)
from test_planner_node import SCENARIO, dump_on_failure, start_planner, wait_for

pytestmark = pytest.mark.usefixtures("dds_env")


# Radar: the scenario's aircraft flown straight on at 5 Hz with wall-clock stamps; an aircraft whose
# callsign is named in the file ``stop`` is no longer published.
RADAR = """
import os, time
from mal_planner.ros.transport import create_node
from mal_planner.ros.convert import planner_to_aircraft_state
from mal_planner.service.tracks import extrapolate
from mal_planner.scenario import load_scenario
node = create_node("radar")
pub = node.create_publisher("mal_msgs/msg/AircraftState", "radar/tracks", 100)
deadline = time.monotonic() + 20
while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
    time.sleep(0.05)
sc = load_scenario(%(scenario)r)
t0 = time.time()
print("radar on", flush=True)
stopped = set()
while True:
    if os.path.exists(%(stop)r) and not stopped:
        stopped = set(open(%(stop)r).read().split())
        print("STOPPED " + repr(time.time()), flush=True)
    now = time.time()
    for a in sc.aircraft:
        if a.callsign not in stopped:
            state = extrapolate(a.state0, a.speed, min(now - t0, 20.0))
            pub.publish(planner_to_aircraft_state(node.types, a.callsign, now, state, a.speed))
    time.sleep(0.2)
"""

# Listener: prints every landing_plan (callsigns) and every path (callsign, number of poses) with the time.
LISTENER = """
import json
import time
from mal_planner.ros.transport import QOS_LATCHED, create_node
node = create_node("listener")
def plan(m):
    print("PLAN " + repr(time.time()) + " " + ",".join(sorted(a.callsign for a in m.aircraft)), flush=True)
def diag(m):
    kv = {v.key: v.value for v in m.status[0].values}
    print("DIAG " + repr(time.time()) + " " + m.status[0].message + " | " + repr(kv), flush=True)
node.create_subscription("mal_msgs/msg/LandingPlan", "landing_plan", plan, QOS_LATCHED)
node.create_subscription("diagnostic_msgs/msg/DiagnosticArray", "diagnostics", diag, QOS_LATCHED)
for cs in ("A1", "A2", "A3"):
    node.create_subscription("nav_msgs/msg/Path", f"aircraft/{cs}/path",
        lambda m, cs=cs: print("PATH " + repr(time.time()) + " " + cs + " " + str(len(m.poses)), flush=True),
        QOS_LATCHED)
print("listening", flush=True)
node.spin()
"""


def test_lost_track_withdraws_its_plan(backend_snippet, snippet, tmp_path: Path) -> None:  # noqa: F811
    """A2's radar stops after the first plan: within track_timeout_s (+ a tick) its path is an empty Path, its
    entry leaves landing_plan and a diagnostic names it; A1 and A3 keep their plans."""
    timeout_s = 2.0
    params = tmp_path / "planner.params.yaml"
    params.write_text(coarse_params(f"    deviation_threshold_m: 0.0\n    figures: false\n"
                                    f"    track_timeout_s: {timeout_s}\n"), encoding="utf-8")
    planner = start_planner(backend_snippet, params)
    with dump_on_failure(planner=planner):
        wait_for(planner, "planner ready", 30)
        listener = snippet(LISTENER)
        listener.wait_for_line("listening")
        stop = tmp_path / "stop"
        radar = snippet(RADAR % {"scenario": str(SCENARIO), "stop": str(stop)})
        radar.wait_for_line("radar on", 30)
        wait_for(planner, "plan #1", 150)
        assert listener.wait_for_line("PLAN ", 30).endswith(" A1,A2,A3")
        stop.write_text("A2", encoding="utf-8")
        stopped = float(radar.wait_for_line("STOPPED ", 10).split()[1])
        seen: dict[str, float] = {}
        deadline = time.monotonic() + timeout_s + 10.0
        while time.monotonic() < deadline and not {"path", "plan", "diag"} <= set(seen):
            line = listener.wait_for_line("", deadline - time.monotonic())
            kind, t, rest = line.split(" ", 2)
            if kind == "PATH" and rest == "A2 0":
                seen["path"] = float(t)
            elif kind == "PLAN" and rest == "A1,A3":
                seen["plan"] = float(t)
            elif kind == "DIAG" and "plan of A2 withdrawn: track lost" in rest:
                seen["diag"] = float(t)
            elif kind == "PATH" and rest.endswith(" 0"):
                pytest.fail(f"another aircraft's plan was withdrawn: {line}")
        assert {"path", "plan", "diag"} <= set(seen), listener.output
        delays = {k: v - stopped for k, v in seen.items()}
        print("withdrawal delays after the last A2 message [s]:", delays)
        assert all(d <= timeout_s + 1.0 for d in delays.values()), delays
        assert planner.proc.poll() is None


# Radar status listener: one JSON line per DiagnosticArray with the radar status values.
RADAR_STATUS = """
import json
from mal_planner.ros.transport import QOS_LATCHED, create_node
node = create_node("radar_status")
def diag(m):
    for st in m.status:
        if st.name.endswith(": radar"):
            print("RADAR " + json.dumps({kv.key: kv.value for kv in st.values}), flush=True)
node.create_subscription("diagnostic_msgs/msg/DiagnosticArray", "diagnostics", diag, QOS_LATCHED)
print("listening", flush=True)
node.spin()
"""

# Bad radar input for G1 between good messages, then a burst of 100 new callsigns within one second.
INTAKE = """
import math, os, time
from mal_planner.ros.transport import create_node
from mal_planner.ros.convert import planner_to_aircraft_state
node = create_node("radar")
T = node.types
pub = node.create_publisher("mal_msgs/msg/AircraftState", "radar/tracks", %(depth)d)
deadline = time.monotonic() + 20
while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
    time.sleep(0.05)
t0 = time.time() - 5.0
def g1(t, dy=0.0, heading=-math.pi / 2, x=0.5):
    return planner_to_aircraft_state(T, "G1", t0 + t, [x, 5.0 - 0.04 * t + dy, 0.2, 0.0, heading], 0.04)
for k in range(10):
    pub.publish(g1(0.1 * k))
    time.sleep(0.01)
no_frame = g1(1.0)
no_frame.header.frame_id = ""
pub.publish(no_frame)
pub.publish(g1(1.0, heading=1.0e6))
pub.publish(g1(1.0, dy=-2.5))  # 2.5 nm within 0.1 s
pub.publish(g1(10.0))  # 9 s ahead of the newest track
pub.publish(g1(0.9, x=0.6))  # another state for a stamp already held
pub.publish(planner_to_aircraft_state(T, "Z0", 0.0, [0.5, 5.0, 0.2, 0.0, -1.57], 0.04))  # no time origin of 0
pub.publish(g1(1.0))  # good again: G1 is not frozen
print("bad input sent", flush=True)
while not os.path.exists(%(go)r):
    time.sleep(0.02)
start = time.monotonic()
for k in range(100):
    x, y = -2.5 + 0.05 * k, 1.0 + 0.04 * k
    stamp = t0 + 1.0 + time.monotonic() - start  # radar time goes on from G1's last track
    pub.publish(planner_to_aircraft_state(T, f"B{k:03d}", stamp, [x, y, 0.2, 0.0, -1.57], 0.04))
print("BURST %%.3f s" %% (time.monotonic() - start), flush=True)
time.sleep(60)
"""


def _radar_until(listener: Snippet, done, timeout: float) -> dict[str, int]:
    """The radar status values (as ints) once ``done(values)`` holds; fail with the last one otherwise."""
    last: dict[str, int] = {}
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = listener.wait_for_line("RADAR ", deadline - time.monotonic())
        last = {k: int(v) for k, v in json.loads(line[len("RADAR "):]).items()}
        if done(last):
            return last
    pytest.fail(f"radar status never satisfied the test: {last}")


def test_radar_intake_gates_and_burst(backend_snippet, snippet, tmp_path: Path) -> None:  # noqa: F811
    """Implausible radar messages are refused with a reason, counted by reason on the radar status, and do not
    freeze the aircraft; then 100 new callsigns published within one second are all tracked."""
    params = tmp_path / "planner.params.yaml"
    params.write_text(coarse_params("    min_aircraft: 1000\n    figures: false\n"), encoding="utf-8")
    planner = start_planner(backend_snippet, params)
    with dump_on_failure(planner=planner):
        wait_for(planner, "planner ready", 30)
        listener = snippet(RADAR_STATUS)
        listener.wait_for_line("listening")
        go = tmp_path / "go"
        radar = snippet(INTAKE % {"depth": 100, "go": str(go)})
        radar.wait_for_line("bad input sent", 30)
        gates = _radar_until(listener, lambda v: v["accepted"] >= 11 and v["rejected"] >= 6, 30)
        assert gates["accepted"] == 11 and gates["rejected"] == 6, gates
        for key in ("frame", "heading", "jump", "future", "conflict", "stamp"):
            assert gates[f"rejected.{key}"] == 1, (key, gates)
        assert gates["tracked"] == 1
        text = "\n".join(planner.output + [planner.lines.get() for _ in range(planner.lines.qsize())])
        for reason in ("empty frame_id", "heading 1e+06 rad", "jump of 4637 m in 0.10 s", "9.1 s ahead of the newest",
                       "another state with the same stamp", "stamp 0 is not set"):
            assert reason in text, reason
        go.touch()
        burst = float(radar.wait_for_line("BURST ", 30).split()[1])
        assert burst < 1.0
        final = _radar_until(listener, lambda v: v["tracked"] >= 101, 30)
        print(f"burst of 100 new callsigns in {burst:.3f} s: {final['tracked'] - 1}/100 tracked; status {final}")
        assert final["tracked"] == 101 and final["rejected"] == 6
        assert planner.proc.poll() is None


# Listener: the first landing_plan as one JSON line (callsign -> status, verified, reason).
PLAN_ENTRIES = """
import json
from mal_planner.ros.transport import QOS_LATCHED, create_node
node = create_node("plan_entries")
plans = []
node.create_subscription("mal_msgs/msg/LandingPlan", "landing_plan", plans.append, QOS_LATCHED)
print("listening", flush=True)
while not plans:
    node.spin_once(0.1)
print("PLAN " + json.dumps({a.callsign: [a.status, a.verified, a.reason] for a in plans[0].aircraft}), flush=True)
"""


def test_a_pair_too_close_at_the_start_leaves_the_others_planned(backend_snippet, snippet, tmp_path: Path  # noqa: F811
                                                                ) -> None:
    """A4 starts 0.1 nm behind A1 (separation 0.25 nm): no plan can separate them, so both are reported with the
    reason on landing_plan, and A2 and A3 are planned, verified and published."""
    import yaml

    data = yaml.safe_load(SCENARIO.read_text(encoding="utf-8"))
    a1 = data["aircraft"][0]
    data["aircraft"].append({**a1, "callsign": "A4", "position": [a1["position"][0], a1["position"][1] - 0.1,
                                                                   a1["position"][2]], "landing_time": 215.0})
    scenario = tmp_path / "close_pair.yaml"
    scenario.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    params = tmp_path / "planner.params.yaml"
    full = coarse_params("    deviation_threshold_m: 0.0\n    figures: false\n    min_aircraft: 4\n").replace(
        "verify: false", "verify: true").replace("refine: false", "refine: true").replace("1.0e-3", "1.0e-5")
    params.write_text(full, encoding="utf-8")  # the others verified: as the node is configured by default
    planner = start_planner(backend_snippet, params, scenario=scenario)
    with dump_on_failure(planner=planner):
        wait_for(planner, "planner ready", 30)
        listener = snippet(PLAN_ENTRIES)
        listener.wait_for_line("listening")
        snippet(RADAR % {"scenario": str(scenario), "stop": str(tmp_path / "never")}).wait_for_line("radar on", 30)
        wait_for(planner, "plan #1", 150)
        entries = json.loads(listener.wait_for_line("PLAN ", 30)[len("PLAN "):])
        assert entries["A2"][:2] == [0, True] and entries["A3"][:2] == [0, True]  # OPTIMAL, verified
        for cs, other in (("A1", "A4"), ("A4", "A1")):
            status, verified, reason = entries[cs]
            assert status == 2 and not verified  # FAILED
            assert reason.startswith(f"lost separation with {other} at the plan start (0.1") and "0.25 nm" in reason


def test_a_bad_parameter_in_the_file_stops_the_start_with_one_line(backend_snippet, tmp_path: Path  # noqa: F811
                                                                   ) -> None:
    """Issue 31: an operator who typed ``degree: 1000`` gets exit 2 and one line naming the file, the parameter, the
    value and the range, before any plan (not the default and a log line), on both backends."""
    params = tmp_path / "planner.params.yaml"
    params.write_text(coarse_params("    figures: false\n").replace("degree: 5", "degree: 1000"), encoding="utf-8")
    planner = start_planner(backend_snippet, params)
    with dump_on_failure(planner=planner):
        line = wait_for(planner, "cannot start", 30)
        assert planner.proc.wait(30) == 2
        assert f"params file {params}: parameter 'degree': must be <= 16, got 1000" in line
        assert not any("planner ready" in out for out in planner.output)


def test_a_second_planner_under_the_same_name_refuses_to_start(backend_snippet, tmp_path: Path) -> None:  # noqa: F811
    """Two planners on one domain and namespace would both publish plans: the second exits 2 naming the first;
    another namespace, or --allow-duplicate, starts."""
    params = tmp_path / "planner.params.yaml"
    params.write_text(coarse_params("    figures: false\n"), encoding="utf-8")
    first = start_planner(backend_snippet, params)
    with dump_on_failure(first=first):
        wait_for(first, "planner ready", 30)
        second = start_planner(backend_snippet, params)
        with dump_on_failure(second=second):
            line = wait_for(second, "another planner answers as /planner on ROS_DOMAIN_ID", 60)
            assert second.proc.wait(30) == 2 and "--allow-duplicate" in line
        elsewhere = start_planner(backend_snippet, params, "--namespace", "tower2")
        forced = start_planner(backend_snippet, params, "--allow-duplicate")
        with dump_on_failure(elsewhere=elsewhere, forced=forced):
            wait_for(elsewhere, "planner ready", 60)
            wait_for(forced, "planner ready", 60)
        assert first.proc.poll() is None


@pytest.mark.parametrize(("name", "value", "why"), [
    ("degree", 1000, "must be <= 16"), ("segments", 100000, "must be <= 64"), ("output_dt", 1e-9, "must be >= 0.01"),
    ("settle_time_s", 1e12, "must be <= 600"), ("frame_id", "", "expected a frame name"),
    ("initializer", "ompl:NoSuchPlanner", "no such planner (known: multi-rrt, ompl:"),
    ("wake_table", "faa", "expected one of scenario, icao, recat-eu, none"),
    ("sequencing", "fifo", "expected one of scenario, fcfs, optimal"),
])
def test_bad_parameters_are_refused_with_a_reason(name: str, value: object, why: str) -> None:
    """On `ros2 param set` (NodeParams.updated) and in the params file (check_parameter): one line naming the
    parameter, the value and the range."""
    from mal_planner.ros.node_params import PARAMETERS, NodeParams

    defaults = NodeParams()
    with pytest.raises(ValueError) as err:
        defaults.updated({name: value})
    text = str(err.value)
    assert text.startswith(f"parameter {name!r}: ") and why in text and "\n" not in text, text
    assert defaults.updated({name: PARAMETERS[name].ros_default()}) == defaults  # the defaults are in range


def test_check_track_gates() -> None:
    """Issue 22: empty frame, heading range, stamp 0, a jump it cannot fly, a stamp too far ahead of the newest."""
    import numpy as np

    from mal_planner.service.tracks import Track, check_track

    def track(stamp: float = 100.0, y: float = 5.0, heading: float = -1.57) -> Track:
        return Track("A1", stamp, np.array([0.5, y, 0.2, 0.0, heading]), 0.04)

    prev = track(99.9)
    assert check_track(track(), "runway", "runway", previous=prev, jump_tol_nm=0.25) is None
    assert check_track(track(), "", "runway").key == "frame"
    assert check_track(track(heading=1e6), "runway", "runway").key == "heading"
    assert check_track(track(stamp=0.0), "runway", "runway").key == "stamp"
    assert check_track(track(y=2.5), "runway", "runway", previous=prev, jump_tol_nm=0.25).key == "jump"
    assert check_track(track(y=4.8), "runway", "runway", previous=track(90.0), jump_tol_nm=0.25) is None  # 10 s
    assert check_track(track(stamp=109.0), "runway", "runway", newest=100.0, max_ahead_s=2.0).key == "future"
    assert check_track(track(stamp=101.0), "runway", "runway", newest=100.0, max_ahead_s=2.0) is None
