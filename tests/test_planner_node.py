"""Planner node on real DDS (loopback): replayed radar in, paths/plans out, services, restart, bad input.

Every test runs the node as a separate process with coarse optimizer settings (no mesh refinement) and
its own ROS_DOMAIN_ID; subscribers and service clients are separate processes too.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import queue
import sys
import time
from pathlib import Path

import pytest
from dds_support import Snippet, coarse_params, dds_env, snippet  # noqa: F401  (fixtures)

REPO = Path(__file__).resolve().parents[1]
BAG = REPO / "data" / "thesis_radar.mcap"
SCENARIO = REPO / "scenarios" / "thesis.yaml"
M_PER_NM = 1852.0
BAG_T0 = 1_700_000_000.0  # first stamp in data/thesis_radar.mcap


pytestmark = pytest.mark.usefixtures("dds_env")


def params_file(tmp_path: Path, extra: str = "") -> Path:
    path = tmp_path / "planner.params.yaml"
    path.write_text(coarse_params("    deviation_threshold_m: 0.0\n    figures: false\n" + extra), encoding="utf-8")
    return path


def start_planner(snippet, params: Path, *extra: str) -> Snippet:  # noqa: F811
    args = ["--scenario", str(SCENARIO), "--params", str(params), *extra]
    return snippet(f"import sys\nfrom mal_planner.ros.planner_node import main\nsys.exit(main({args!r}))\n")


def start_replay(snippet, rate: float) -> Snippet:  # noqa: F811
    args = [str(BAG), "--rate", str(rate), "--wait-for-subscribers", "10"]
    return snippet(f"import sys\nfrom mal_planner.ros.replay import main\nsys.exit(main({args!r}))\n")


@contextlib.contextmanager
def dump_on_failure(**snips: Snippet):
    """On a failure, print the children's output (the planner's log explains most failures)."""
    try:
        yield
    except BaseException:
        for name, snip in snips.items():
            while not snip.lines.empty():
                snip.output.append(snip.lines.get_nowait())
            print(f"---- {name} ----\n" + "\n".join(snip.output[-80:]))
        raise


def wait_for(snip: Snippet, text: str, timeout: float = 90.0) -> str:
    """Block until the child prints a line containing ``text`` (output kept in ``snip.output``)."""
    deadline = time.monotonic() + timeout
    while (left := deadline - time.monotonic()) > 0:
        try:
            line = snip.lines.get(timeout=min(left, 0.1))
        except queue.Empty:
            if snip.proc.poll() is not None and snip.lines.empty():
                break
            continue
        snip.output.append(line)
        if text in line:
            return line
    snip.stop()
    pytest.fail(f"child did not print {text!r}; output:\n" + "\n".join(snip.output[-60:]))


# Subscriber process: latched landing plan + paths -> one JSON line with what the test checks.
PATH_LISTENER = """
import json, math
from mal_planner.ros.transport import QOS_LATCHED, create_node
from mal_planner.ros.convert import msg_to_time
node = create_node("path_listener")
got = {}
plans = []
node.create_subscription("mal_msgs/msg/LandingPlan", "landing_plan", plans.append, QOS_LATCHED)
for cs in ("A1", "A2", "A3"):
    node.create_subscription("nav_msgs/msg/Path", f"aircraft/{cs}/path", lambda m, cs=cs: got.__setitem__(cs, m),
                             QOS_LATCHED)
print("listening", flush=True)
while True:
    node.spin_once(0.1)
    if plans and set(got) == {"A1", "A2", "A3"} and all(
            msg_to_time(got[a.callsign]) == msg_to_time(plans[-1]) for a in plans[-1].aircraft):
        break
plan = plans[-1]
out = {"plan_stamp": msg_to_time(plan), "plan_frame": plan.header.frame_id,
       "order": [a.callsign for a in sorted(plan.aircraft, key=lambda a: a.order)],
       "status": [a.status for a in plan.aircraft], "landing": {a.callsign: a.landing_time for a in plan.aircraft},
       "paths": {}}
for cs, path in got.items():
    if not path.poses:
        out["paths"][cs] = {"n": 0, "stamp": msg_to_time(path)}
        continue
    stamps = [msg_to_time(p) for p in path.poses]
    pos = [(p.pose.position.x, p.pose.position.y, p.pose.position.z) for p in path.poses]
    q = path.poses[len(path.poses) // 2].pose.orientation
    frames = sorted({p.header.frame_id for p in path.poses})
    out["paths"][cs] = {"n": len(stamps), "frame": path.header.frame_id, "frames": frames,
                        "stamps": stamps, "first": pos[0], "last": pos[-1],
                        "min": [min(c) for c in zip(*pos)], "max": [max(c) for c in zip(*pos)],
                        "qnorm": math.sqrt(q.x**2 + q.y**2 + q.z**2 + q.w**2)}
print("RESULT " + json.dumps(out), flush=True)
"""

# Client process: Trigger, then PlanLanding with explicit states of A1 and A3 (flown 30 s straight on).
CLIENT = """
import json
from mal_planner.ros.transport import create_node
from mal_planner.ros.convert import planner_to_aircraft_state, msg_to_time
from mal_planner.ros.state_store import extrapolate
from mal_planner.scenario import load_scenario
node = create_node("client")
trigger = node.create_client("std_srvs/srv/Trigger", "plan")
landing = node.create_client("mal_msgs/srv/PlanLanding", "plan_landing")
assert trigger.wait_for_service(20) and landing.wait_for_service(20)
print("calling", flush=True)
Trigger = node.types.srv("std_srvs/srv/Trigger")
res = trigger.call(Trigger.Request(), timeout_sec=150)
print("TRIGGER " + json.dumps({"success": res.success, "message": res.message}), flush=True)
sc = load_scenario(%(scenario)r)
stamp = %(t0)r + 30.0
states = [planner_to_aircraft_state(node.types, a.callsign, stamp, extrapolate(a.state0, a.speed, 30.0), a.speed)
          for a in sc.aircraft if a.callsign != "A2"]
Srv = node.types.srv("mal_msgs/srv/PlanLanding")
res = landing.call(Srv.Request(aircraft=states), timeout_sec=150)
print("LANDING " + json.dumps({"success": res.success, "message": res.message, "n_paths": len(res.paths),
      "plan_stamp": msg_to_time(res.plan), "order": [a.callsign for a in res.plan.aircraft],
      "first_pose_stamp": msg_to_time(res.paths[0].poses[0]) if res.paths else None}), flush=True)
"""

# Publisher of bad input (and one valid no-fly zone) from a separate process.
BAD_INPUT = """
import math, os, time
from mal_planner.ros.transport import create_node
from mal_planner.ros.convert import planner_to_aircraft_state
node = create_node("bad_radar")
pub = node.create_publisher("mal_msgs/msg/AircraftState", "radar/tracks", 10)
nfz = node.create_publisher("mal_msgs/msg/NoFlyZone", "airspace/no_fly_zones", 10)
T = node.types
deadline = time.monotonic() + 10
while (pub.get_subscription_count() < 1 or nfz.get_subscription_count() < 1) and time.monotonic() < deadline:
    time.sleep(0.05)
print("ready", flush=True)
go = %(go)r
while go and not os.path.exists(go):
    time.sleep(0.02)
def state(cs, **kw):
    msg = planner_to_aircraft_state(T, cs, 1.0e9, [0.5, 5.0, 0.2, 0.0, -1.57], 0.04)
    for k, v in kw.items():
        setattr(msg, k, v)
    return msg
for _ in range(%(repeat)d):
    nan_state = state("NAN1")
    nan_state.position.x = math.nan
    pub.publish(nan_state)
    bad_frame = state("FRM1")
    bad_frame.header.frame_id = "map"
    pub.publish(bad_frame)
    pub.publish(state("KTS1", speed=250.0 * 1852.0))
    time.sleep(0.2)
zone = lambda **kw: T.msg("mal_msgs/msg/NoFlyZone")(name=kw.get("name", "storm"),
    center=T.msg("geometry_msgs/msg/Point")(x=0.0, y=8000.0, z=300.0),
    semi_axes=T.msg("geometry_msgs/msg/Vector3")(x=500.0, y=500.0, z=200.0), p=kw.get("p", 2))
if %(nfz)r:
    nfz.publish(zone(p=3))
    nfz.publish(zone(name="storm"))
time.sleep(0.5)
print("published", flush=True)
"""


def test_replay_to_paths_services_and_latched(snippet, tmp_path: Path) -> None:  # noqa: F811
    """Replayed radar -> planner -> paths in a separate subscriber; both services; late subscriber; NaN input."""
    planner = start_planner(snippet, params_file(tmp_path))
    with dump_on_failure(planner=planner):
        wait_for(planner, "planner ready", 30)
        listener = snippet(PATH_LISTENER)
        listener.wait_for_line("listening")
        start_replay(snippet, 2.0)
        wait_for(planner, "plan #1", 150)
        result = json.loads(listener.wait_for_line("RESULT ", 30)[len("RESULT "):])

        assert result["plan_frame"] == "runway"
        assert BAG_T0 < result["plan_stamp"] < BAG_T0 + 20.0
        assert sorted(result["order"]) == ["A1", "A2", "A3"]
        assert result["status"] == [0, 0, 0]  # OPTIMAL
        for rank, cs in enumerate(result["order"]):
            p = result["paths"][cs]
            assert p["frame"] == "runway" and p["frames"] == ["runway"]
            stamps = p["stamps"]
            assert stamps[0] == pytest.approx(result["plan_stamp"], abs=1e-6)
            assert all(b > a for a, b in zip(stamps, stamps[1:], strict=False))
            assert stamps[-1] - stamps[0] == pytest.approx(result["landing"][cs], abs=1e-3)
            # metres within the thesis airspace [-3, 3] x [0, 6] x [0, 0.3] nm (+ a little slack)
            assert p["min"][0] > -3.05 * M_PER_NM and p["max"][0] < 3.05 * M_PER_NM
            assert p["min"][1] > -0.05 * M_PER_NM and p["max"][1] < 6.05 * M_PER_NM
            assert p["min"][2] > -0.05 * M_PER_NM and p["max"][2] < 0.35 * M_PER_NM
            assert p["max"][1] > 2.0 * M_PER_NM  # genuinely metres, not nm
            assert max(abs(c) for c in p["last"]) < 50.0  # ends at the runway threshold
            assert p["qnorm"] == pytest.approx(1.0, abs=1e-6)
            if rank:  # landing order = order of the landing times
                assert result["landing"][cs] > result["landing"][result["order"][rank - 1]]

        # Services from a client process; radar callbacks keep running while the service waits for its plan.
        go = tmp_path / "go"
        bad = snippet(BAD_INPUT % {"repeat": 1, "go": str(go), "nfz": False})
        bad.wait_for_line("ready", 30)
        client = snippet(CLIENT % {"scenario": str(SCENARIO), "t0": BAG_T0})
        client.wait_for_line("calling", 30)
        wait_for(planner, "plan requested: service plan", 30)
        go.touch()  # NaN radar input while the Trigger call waits for its plan
        wait_for(planner, "bad AircraftState on radar/tracks for 'NAN1'", 30)
        assert not any("TRIGGER" in line for line in list(client.lines.queue))  # the call is still waiting
        trig = json.loads(client.wait_for_line("TRIGGER ", 150)[len("TRIGGER "):])
        assert trig["success"], trig
        bad.wait_for_line("published", 30)
        landing = json.loads(client.wait_for_line("LANDING ", 150)[len("LANDING "):])
        assert landing["success"], landing
        assert landing["n_paths"] == 2 and sorted(landing["order"]) == ["A1", "A3"]
        assert landing["plan_stamp"] == pytest.approx(BAG_T0 + 30.0)
        assert landing["first_pose_stamp"] == pytest.approx(BAG_T0 + 30.0)

        # A late subscriber still gets the latched plan and paths (the explicit-state plan, published last;
        # A2, no longer planned, has an empty path).
        late = snippet(PATH_LISTENER)
        late_result = json.loads(late.wait_for_line("RESULT ", 30)[len("RESULT "):])
        assert late_result["plan_stamp"] == pytest.approx(BAG_T0 + 30.0)
        assert sorted(late_result["order"]) == ["A1", "A3"]
        assert late_result["paths"]["A2"]["n"] == 0
        assert late_result["paths"]["A1"]["stamps"][0] == pytest.approx(BAG_T0 + 30.0)
        assert planner.proc.poll() is None
        if os.environ.get("MAL_TEST_VERBOSE"):
            while not planner.lines.empty():
                planner.output.append(planner.lines.get_nowait())
            print("\n".join(line for line in planner.output if "plan #" in line or "requested" in line))


def test_restart_in_the_middle_of_a_replay(snippet, tmp_path: Path) -> None:  # noqa: F811
    """Kill the planner while the bag plays; a new planner picks the radar up and publishes a new plan."""
    params = params_file(tmp_path)
    first = start_planner(snippet, params)
    wait_for(first, "planner ready", 30)
    started = time.monotonic()
    start_replay(snippet, 0.5)  # 40 s of wall time
    wait_for(first, "plan #1", 150)
    time.sleep(max(0.0, 14.0 - (time.monotonic() - started)))  # at least 7 s into the bag
    first.proc.kill()
    first.proc.wait()
    second = start_planner(snippet, params)
    wait_for(second, "planner ready", 30)
    line = wait_for(second, "first radar message", 30)
    first_stamp = float(line.rsplit("t=", 1)[1].split(")")[0])
    assert first_stamp > BAG_T0 + 5.0  # joined in the middle of the replay
    wait_for(second, "plan #1", 150)
    listener = snippet(PATH_LISTENER)
    result = json.loads(listener.wait_for_line("RESULT ", 30)[len("RESULT "):])
    assert result["plan_stamp"] >= first_stamp
    assert sorted(result["paths"]) == ["A1", "A2", "A3"]


def test_bad_input_is_logged_and_ignored(snippet, tmp_path: Path) -> None:  # noqa: F811
    """NaN, wrong frame, absurd speed, invalid no-fly zone and a bad parameter: one log line each, node lives."""
    params = params_file(tmp_path, "    mesh_tol: -1.0\n    min_aircraft: 5\n    bogus: 1\n")
    planner = start_planner(snippet, params)
    wait_for(planner, "planner ready", 30)
    text = "\n".join(planner.output)
    assert "parameter 'mesh_tol'" in text and "using the default" in text
    assert "unknown parameter 'bogus'" in text
    snippet(BAD_INPUT % {"repeat": 3, "go": "", "nfz": True}).wait_for_line("published", 30)
    wait_for(planner, "added no-fly zone 'storm'", 20)
    text = "\n".join(planner.output)
    assert "'NAN1'" in text and "non-finite x" in text
    assert "'FRM1'" in text and "unknown frame 'map'" in text
    assert "'KTS1'" in text and "m/s (units?)" in text
    assert "bad NoFlyZone" in text and "p must be an even integer" in text
    assert sum("'NAN1'" in line for line in planner.output) == 1  # rate-limited: one line, not a flood
    client = snippet("""
from mal_planner.ros.transport import create_node
node = create_node("client")
cli = node.create_client("std_srvs/srv/Trigger", "plan")
assert cli.wait_for_service(20)
res = cli.call(node.types.srv("std_srvs/srv/Trigger").Request(), timeout_sec=30)
print("TRIGGER", res.success, res.message, flush=True)
""")
    assert client.wait_for_line("TRIGGER", 40) == "TRIGGER False no radar tracks yet"
    assert planner.proc.poll() is None


def test_params_file_errors_are_one_line(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    from mal_planner.ros.node_params import read_params_file

    log = logging.getLogger("test")
    bad = tmp_path / "bad.yaml"
    bad.write_text("planner:\n  ros__parameters: {seed: [1,\n", encoding="utf-8")
    with caplog.at_level(logging.ERROR):
        assert read_params_file(bad, "planner", "", log) == {}
        assert read_params_file(tmp_path / "missing.yaml", "planner", "", log) == {}
    assert len(caplog.records) == 2
    assert all("\n" not in r.getMessage() for r in caplog.records)
    assert str(bad) in caplog.records[0].getMessage() and "invalid" in caplog.records[0].getMessage()
    assert "cannot read" in caplog.records[1].getMessage()


def test_plan_scenario_extrapolates_and_adds_unknown_aircraft() -> None:
    import numpy as np

    from mal_planner.ros.plan_scenario import build_plan_scenario
    from mal_planner.ros.state_store import Track
    from mal_planner.scenario import load_scenario

    sc = load_scenario(SCENARIO)
    a1 = sc.aircraft_by_callsign("A1")
    tracks = {"A1": Track("A1", 10.0, a1.state0.copy(), a1.speed),
              "X9": Track("X9", 12.0, np.array([0.0, 5.0, 0.2, 0.0, -np.pi / 2]), 0.05, "H"),
              "FAR": Track("FAR", 12.0, np.array([0.0, 9.0, 0.2, 0.0, -np.pi / 2]), 0.05)}
    inputs = build_plan_scenario(sc, tracks, 12.0, landing_shift=2.0)
    assert [a.callsign for a in inputs.scenario.aircraft] == ["A1", "X9"]  # A2/A3 not on radar: left out
    assert "FAR" in inputs.left_out
    moved = inputs.scenario.aircraft_by_callsign("A1").state0[:3] - a1.state0[:3]
    assert np.linalg.norm(moved) == pytest.approx(2.0 * a1.speed)
    x9 = inputs.scenario.aircraft_by_callsign("X9")
    assert x9.speed == pytest.approx(0.05)
    # an unknown aircraft (X9) keeps A1's fixed landing time and lands after it, spaced (issue 10)
    assert inputs.scenario.aircraft_by_callsign("A1").landing_time == pytest.approx(153.0)
    assert 153.0 + sc.landing_spacing_s <= x9.landing_time <= 153.0 + sc.max_landing_spacing_s
    only_a1 = build_plan_scenario(sc, {"A1": tracks["A1"]}, 12.0, landing_shift=2.0)
    assert only_a1.scenario.aircraft[0].landing_time == pytest.approx(153.0)


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-v"]))
