"""Planner node on real DDS (loopback): replayed radar in, paths/plans out, services, restart, bad input.

Every test runs the node as a separate process with coarse optimizer settings (no mesh refinement) and
its own ROS_DOMAIN_ID, once per backend (built-in Cyclone, and rclpy on a real ROS 2 Jazzy): the planner
and the replay run on the backend under test (``backend_snippet``); subscribers and service clients are
separate processes on the built-in backend (``snippet``), so the rclpy runs check interop as well.
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
GEO_SCENARIO = REPO / "scenarios" / "thesis_geodetic.yaml"  # the thesis at CDG 27R: the same local frame
M_PER_NM = 1852.0
BAG_T0 = 1_700_000_000.0  # first stamp in data/thesis_radar.mcap


pytestmark = pytest.mark.usefixtures("dds_env")


def params_file(tmp_path: Path, extra: str = "") -> Path:
    path = tmp_path / "planner.params.yaml"
    path.write_text(coarse_params("    deviation_threshold_m: 0.0\n    figures: false\n" + extra), encoding="utf-8")
    return path


def start_planner(start, params: Path, *extra: str, scenario: Path = SCENARIO) -> Snippet:
    args = ["--scenario", str(scenario), "--params", str(params), *extra]
    return start(f"import sys\nfrom mal_planner.ros.planner_node import main\nsys.exit(main({args!r}))\n")


def start_replay(start, rate: float) -> Snippet:
    args = [str(BAG), "--rate", str(rate), "--wait-for-subscribers", "10"]
    return start(f"import sys\nfrom mal_planner.ros.replay import main\nsys.exit(main({args!r}))\n")


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
diags = []
node.create_subscription("diagnostic_msgs/msg/DiagnosticArray", "diagnostics", diags.append, QOS_LATCHED)
for cs in ("A1", "A2", "A3"):
    node.create_subscription("nav_msgs/msg/Path", f"aircraft/{cs}/path", lambda m, cs=cs: got.__setitem__(cs, m),
                             QOS_LATCHED)
print("listening", flush=True)
while True:
    node.spin_once(0.1)
    if plans and diags and diags[-1].status[0].values[0].value != "0" and set(got) == {"A1", "A2", "A3"} and all(
            msg_to_time(got[a.callsign]) == msg_to_time(plans[-1]) for a in plans[-1].aircraft):
        break
plan = plans[-1]
diag = {kv.key: kv.value for kv in diags[-1].status[0].values}
out = {"plan_stamp": msg_to_time(plan), "plan_frame": plan.header.frame_id, "diag_plans": diag["plans"],
       "order": [a.callsign for a in sorted(plan.aircraft, key=lambda a: a.order)],
       "status": [a.status for a in plan.aircraft], "landing": {a.callsign: a.landing_time for a in plan.aircraft},
       "geodetic": plan.geodetic, "origin": [plan.origin_latitude, plan.origin_longitude, plan.origin_altitude,
                                             plan.course],
       "sequence": {a.callsign: [a.wake_category, a.target_time, a.delay] for a in plan.aircraft},
       "lat_lon_alt": {a.callsign: [list(a.latitude), list(a.longitude), list(a.altitude)] for a in plan.aircraft},
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
from mal_planner.service.tracks import extrapolate
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
      "error_code": res.error_code, "ERROR_NONE": Srv.Response.ERROR_NONE,
      "plan_stamp": msg_to_time(res.plan), "order": [a.callsign for a in res.plan.aircraft],
      "first_pose_stamp": msg_to_time(res.paths[0].poses[0]) if res.paths else None}), flush=True)
"""

# Parameter client process (rcl_interfaces services, as `ros2 param` uses them): a refused value, then a
# failed plan (1 IPOPT iteration) that keeps the last plan, then recovery.
PARAMS_CLIENT = """
import json, time
from mal_planner.ros.transport import QOS_LATCHED, create_node
from mal_planner.ros.transport._common import value_from_msg, value_to_msg
from mal_planner.ros.convert import byte_value, msg_to_time
node = create_node("param_client")
T = node.types
setp = node.create_client("rcl_interfaces/srv/SetParameters", "/planner/set_parameters")
getp = node.create_client("rcl_interfaces/srv/GetParameters", "/planner/get_parameters")
trigger = node.create_client("std_srvs/srv/Trigger", "/plan")
diags, plans = [], []
node.create_subscription("diagnostic_msgs/msg/DiagnosticArray", "/diagnostics", diags.append, QOS_LATCHED)
node.create_subscription("mal_msgs/msg/LandingPlan", "/landing_plan", plans.append, QOS_LATCHED)
assert setp.wait_for_service(20) and getp.wait_for_service(20) and trigger.wait_for_service(20)
def set_(name, value):
    param = T.msg("rcl_interfaces/msg/Parameter")(name=name,
        value=value_to_msg(T.msg("rcl_interfaces/msg/ParameterValue"), value))
    res = setp.call(T.srv("rcl_interfaces/srv/SetParameters").Request(parameters=[param]), timeout_sec=20)
    return [res.results[0].successful, res.results[0].reason]
def get(name):
    res = getp.call(T.srv("rcl_interfaces/srv/GetParameters").Request(names=[name]), timeout_sec=20)
    return value_from_msg(res.values[0])
def settle(seconds):
    end = time.monotonic() + seconds
    while time.monotonic() < end or not plans or not diags:
        node.spin_once(0.05)
Trigger = T.srv("std_srvs/srv/Trigger")
settle(0.5)
descp = node.create_client("rcl_interfaces/srv/DescribeParameters", "/planner/describe_parameters")
assert descp.wait_for_service(20)
desc = descp.call(T.srv("rcl_interfaces/srv/DescribeParameters").Request(names=["degree", "output_dt"]),
                  timeout_sec=20).descriptors
out = {"ranges": [[desc[0].integer_range[0].from_value, desc[0].integer_range[0].to_value],
                  [desc[1].floating_point_range[0].from_value, desc[1].floating_point_range[0].to_value]]}
out |= {"stamp_before": msg_to_time(plans[-1]), "bad": set_("replan_period_s", -1.0),
       "after_bad": get("replan_period_s"), "set_iter": set_("max_nlp_iterations", 1)}
res = trigger.call(Trigger.Request(), timeout_sec=150)
out["failed"] = [res.success, res.message]
settle(1.0)
out["diag_failed"] = [byte_value(diags[-1].status[0].level), diags[-1].status[0].message]
out["diag_failed_values"] = {kv.key: kv.value for kv in diags[-1].status[0].values}
out["stamp_after_fail"] = msg_to_time(plans[-1])
out["kept"] = [plans[-1].kept_failure, msg_to_time(plans[-1].kept_since), len(plans[-1].aircraft)]
out["set_back"] = set_("max_nlp_iterations", 3000)
res = trigger.call(Trigger.Request(), timeout_sec=150)
out["recovered"] = [res.success, res.message]
settle(1.0)
out["diag_recovered"] = byte_value(diags[-1].status[0].level)
out["fresh"] = [plans[-1].kept_failure, msg_to_time(plans[-1].kept_since), len(plans[-1].aircraft)]
# a kept plan expires: withdrawn kept_plan_expiry_s after the first failed replan
set_("kept_plan_expiry_s", 1.0)
set_("max_nlp_iterations", 1)
res = trigger.call(Trigger.Request(), timeout_sec=150)
settle(2.5)
out["expired"] = [res.success, len([a for a in plans[-1].aircraft if a.status != 3]), diags[-1].status[0].message]
print("PARAMS " + json.dumps(out), flush=True)
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
    if %(issue10)r:  # plausible alone, implausible in context (issue 10)
        pub.publish(planner_to_aircraft_state(T, "GOOD1", 1.0e9 + 100.0, [0.5, 5.0, 0.2, 0.0, -1.57], 0.04))
        pub.publish(state("OLD1"))  # 100 s older than GOOD1 (track_timeout_s 30)
        future = planner_to_aircraft_state(T, "FUT1", time.time() + 3600.0, [0.5, 5.0, 0.2, 0.0, -1.57], 0.04)
        pub.publish(future)
        low = state("LOW1")
        low.position.z = -600.0
        pub.publish(low)
        pub.publish(state("A1", speed=0.4 * 1852.0))  # ten times the scenario's speed of A1
    time.sleep(0.2)
zone = lambda **kw: T.msg("mal_msgs/msg/NoFlyZone")(name=kw.get("name", "storm"),
    center=T.msg("geometry_msgs/msg/Point")(x=0.0, y=8000.0, z=300.0),
    semi_axes=T.msg("geometry_msgs/msg/Vector3")(x=500.0, y=500.0, z=200.0), p=kw.get("p", 2))
if %(nfz)r:
    nfz.publish(zone(p=3))
    nfz.publish(zone(name="storm"))
    from mal_planner.ros.convert import wind_msg
    wind = node.create_publisher("geometry_msgs/msg/Vector3Stamped", "wind", 10)
    deadline = time.monotonic() + 10
    while wind.get_subscription_count() < 1 and time.monotonic() < deadline:
        time.sleep(0.05)
    bad_wind = wind_msg(T, 1.0e9, [0.0, -0.005])
    bad_wind.header.frame_id = "map"
    wind.publish(bad_wind)
    wind.publish(wind_msg(T, 1.0e9, [0.0, -10.0 / 3600.0]))  # 10 kt blowing south: from heading 90 deg
time.sleep(0.5)
print("published", flush=True)
"""


def test_replay_to_paths_services_and_latched(backend_snippet, snippet, tmp_path: Path) -> None:  # noqa: F811
    """Replayed radar -> planner -> paths in a separate subscriber; both services; late subscriber; NaN input;
    parameters at run time; a failed plan keeps the last plan and the next trigger plans again."""
    planner = start_planner(backend_snippet, params_file(tmp_path), scenario=GEO_SCENARIO)
    with dump_on_failure(planner=planner):
        wait_for(planner, "planner ready", 30)
        listener = snippet(PATH_LISTENER)
        listener.wait_for_line("listening")
        start_replay(backend_snippet, 2.0)
        wait_for(planner, "plan #1", 150)
        result = json.loads(listener.wait_for_line("RESULT ", 30)[len("RESULT "):])

        assert result["diag_plans"] == "1"  # the first DiagnosticArray counts its own plan
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
            # the sequence (wake category, target, delay) and the path on the Earth, sample for sample
            wake, target, delay = result["sequence"][cs]
            assert wake == "M" and target > 0.0 and delay == pytest.approx(result["landing"][cs] - target)
            lat, lon, alt = result["lat_lon_alt"][cs]
            assert len(lat) == len(lon) == len(alt) == p["n"]
            # ends at the CDG 27R threshold (49.02667786 N, 2.56169447 E, 392 ft): 1e-4 deg is 7-11 m
            assert lat[-1] == pytest.approx(49.02667786, abs=1e-4) and lon[-1] == pytest.approx(2.56169447, abs=1e-4)
            assert alt[-1] == pytest.approx(392.0 * 0.3048, abs=5.0)
        assert result["geodetic"] is True
        assert result["origin"] == pytest.approx([49.02667786, 2.56169447, 392.0 * 0.3048, 265.43])

        # Services from a client process; radar callbacks keep running while the service waits for its plan.
        go = tmp_path / "go"
        bad = snippet(BAD_INPUT % {"repeat": 1, "go": str(go), "nfz": False, "issue10": False})
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
        assert landing["error_code"] == landing["ERROR_NONE"] == 0
        assert landing["plan_stamp"] == pytest.approx(BAG_T0 + 30.0)
        assert landing["first_pose_stamp"] == pytest.approx(BAG_T0 + 30.0)

        # A late subscriber still gets the latched radar plan and paths: the explicit-state (what-if) plan was
        # answered in the response only and did not clobber the plan other nodes follow.
        late = snippet(PATH_LISTENER)
        late_result = json.loads(late.wait_for_line("RESULT ", 30)[len("RESULT "):])
        assert late_result["plan_stamp"] < BAG_T0 + 25.0
        # The latched plan is the radar plan or the Trigger's (radar time ~20 s, by when A2 of the recording may be
        # leaving through the ceiling and left out, depending on how fast this machine reached it).
        assert {"A1", "A3"} <= set(late_result["order"]) <= {"A1", "A2", "A3"}
        assert all(late_result["paths"][cs]["n"] > 10 for cs in late_result["order"])
        assert late_result["paths"]["A1"]["stamps"][0] == pytest.approx(late_result["plan_stamp"])

        # Parameters at run time: a refused value keeps the old one; a failed plan keeps the last plan
        # published and reports FAILED; the next trigger plans again.
        params = json.loads(snippet(PARAMS_CLIENT).wait_for_line("PARAMS ", 300)[len("PARAMS "):])
        assert params["bad"] == [False, "Parameter replan_period_s out of range Min: 0.0, Max: inf, value: -1.0"]
        assert params["ranges"] == [[2, 16], [0.01, 60.0]]  # on both backends, as `ros2 param describe` shows
        assert params["after_bad"] == 0.0 and params["set_iter"] == [True, ""]
        assert params["failed"][0] is False and "keeping the last plan" in params["failed"][1]
        assert params["diag_failed"][0] == 2 and params["diag_failed"][1].startswith("FAILED: ")
        kept = params["diag_failed_values"]  # the kept plan says how old it is and why it was kept
        assert float(kept["kept_plan_stamp"]) == pytest.approx(params["stamp_before"], abs=1e-3)
        assert float(kept["kept_plan_age_s"]) >= 0.0 and kept["failure"]
        assert kept["kept_plan_aircraft"] and set(kept["kept_plan_aircraft"].split(",")) <= {"A1", "A2", "A3"}
        assert params["stamp_after_fail"] == params["stamp_before"]
        assert params["set_back"] == [True, ""]
        assert params["recovered"][0] is True, params
        assert params["diag_recovered"] in (0, 1)
        # landing_plan says that its plan is kept (why, since when) until a new plan replaces it
        assert "keeping the last plan" in params["kept"][0] and params["kept"][1] > params["stamp_before"]
        assert params["kept"][2] > 0 and params["fresh"][:2] == ["", 0.0] and params["fresh"][2] > 0
        assert params["expired"][0] is False and params["expired"][1] == 0, params["expired"]  # holds only (3)
        assert "kept plan expired" in params["expired"][2]
        assert planner.proc.poll() is None
        if os.environ.get("MAL_TEST_VERBOSE"):
            while not planner.lines.empty():
                planner.output.append(planner.lines.get_nowait())
            print("\n".join(line for line in planner.output if "plan #" in line or "requested" in line))


def test_restart_in_the_middle_of_a_replay(backend_snippet, snippet, tmp_path: Path) -> None:  # noqa: F811
    """Kill the planner while the bag plays; a new planner picks the radar up and publishes a new plan."""
    params = params_file(tmp_path)
    first = start_planner(backend_snippet, params)
    wait_for(first, "planner ready", 30)
    started = time.monotonic()
    start_replay(backend_snippet, 0.5)  # 40 s of wall time
    wait_for(first, "plan #1", 150)
    time.sleep(max(0.0, 14.0 - (time.monotonic() - started)))  # at least 7 s into the bag
    first.proc.kill()
    first.proc.wait()
    second = start_planner(backend_snippet, params)
    wait_for(second, "planner ready", 30)
    line = wait_for(second, "first radar message", 30)
    first_stamp = float(line.rsplit("t=", 1)[1].split(")")[0])
    assert first_stamp > BAG_T0 + 5.0  # joined in the middle of the replay
    wait_for(second, "plan #1", 150)
    listener = snippet(PATH_LISTENER)
    result = json.loads(listener.wait_for_line("RESULT ", 30)[len("RESULT "):])
    assert result["plan_stamp"] >= first_stamp
    assert sorted(result["paths"]) == ["A1", "A2", "A3"]


def test_bad_input_is_logged_and_ignored(backend_snippet, snippet, tmp_path: Path) -> None:  # noqa: F811
    """NaN, wrong frame, absurd speed, implausible/stale/future/below-ground tracks, invalid no-fly zone and a
    bad parameter: one log line each, node lives."""
    params = params_file(tmp_path, "    min_aircraft: 5\n    bogus: 1\n")
    planner = start_planner(backend_snippet, params)
    wait_for(planner, "planner ready", 30)
    text = "\n".join(planner.output)
    assert "unknown parameter 'bogus'" in text
    snippet(BAD_INPUT % {"repeat": 3, "go": "", "nfz": True, "issue10": True}).wait_for_line("published", 30)
    wait_for(planner, "added no-fly zone 'storm'", 20)
    text = "\n".join(planner.output)
    assert "'NAN1'" in text and "non-finite x" in text
    assert "'FRM1'" in text and "unknown frame 'map'" in text
    assert "'KTS1'" in text and "m/s (units?)" in text
    assert "bad NoFlyZone" in text and "p must be an even integer" in text
    wait_for(planner, "wind 10.0 kt from heading 90 deg", 20)
    assert "bad wind on wind: frame 'map', expected 'runway'" in "\n".join(planner.output)
    assert "'A1'" in text and "implausible for this aircraft" in text
    assert "'LOW1'" in text and "below the airspace floor" in text
    assert "'FUT1'" in text and "in the future" in text
    assert "'OLD1'" in text and "stale stamp" in text
    assert "'GOOD1'" not in text
    assert sum("'NAN1'" in line for line in planner.output) == 1  # rate-limited: one line, not a flood
    client = snippet("""
from mal_planner.ros.transport import create_node
node = create_node("client")
cli = node.create_client("std_srvs/srv/Trigger", "plan")
assert cli.wait_for_service(20)
res = cli.call(node.types.srv("std_srvs/srv/Trigger").Request(), timeout_sec=30)
print("TRIGGER", res.success, res.message, flush=True)
""")
    assert client.wait_for_line("TRIGGER", 40) == "TRIGGER False 1 aircraft tracked (min_aircraft 5): nothing to plan"
    assert planner.proc.poll() is None


def test_params_file_errors_are_one_line(tmp_path: Path) -> None:
    """A params file that cannot be read, is not YAML or holds a bad value: one line naming it (the node then
    exits 2 before anything starts)."""
    from mal_planner.ros.node_params import ParamsError, read_params_file

    log = logging.getLogger("test")
    bad = tmp_path / "bad.yaml"
    bad.write_text("planner:\n  ros__parameters: {seed: [1,\n", encoding="utf-8")
    value = tmp_path / "value.yaml"
    value.write_text("planner:\n  ros__parameters: {mesh_tol: -1.0}\n", encoding="utf-8")
    problems = []
    for path in (bad, tmp_path / "missing.yaml", value):
        with pytest.raises(ParamsError) as err:
            read_params_file(path, "planner", "", log)
        problems.append(str(err.value))
    assert all("\n" not in p and p.startswith(f"params file {tmp_path}") for p in problems)
    assert "invalid" in problems[0] and "cannot read" in problems[1]
    assert problems[2].endswith("parameter 'mesh_tol': must be > 0, got -1.0")


def test_plan_scenario_extrapolates_and_adds_unknown_aircraft() -> None:
    import numpy as np

    from mal_planner.scenario import load_scenario
    from mal_planner.service.inputs import build_plan_scenario
    from mal_planner.service.tracks import Track

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



def test_plan_scenario_uses_the_radars_wake_categories() -> None:
    """Issue 18: under a wake table the radar's categories count; one the table does not know (or none) is the
    worst case in each role; an unknown aircraft is slotted its pair's wake spacing behind the one before."""
    from dataclasses import replace

    import numpy as np

    from mal_planner.scenario import load_scenario
    from mal_planner.sequencing.schedule import landing_spacing
    from mal_planner.service.inputs import build_plan_scenario
    from mal_planner.service.tracks import Track
    from mal_planner.wake import wake_distance_nm

    sc = replace(load_scenario(SCENARIO), wake="icao")  # the file's aircraft are all M
    a1 = sc.aircraft_by_callsign("A1")
    heavy_behind = {"A1": Track("A1", 0.0, a1.state0.copy(), a1.speed),
                    "L9": Track("L9", 0.0, np.array([0.0, 5.0, 0.2, 0.0, -np.pi / 2]), 0.04, "L"),
                    "Q1": Track("Q1", 0.0, np.array([-2.0, 5.0, 0.2, 0.0, -np.pi / 2]), 0.04, "A"),  # RECAT's
                    "N0": Track("N0", 0.0, np.array([2.0, 5.0, 0.2, 0.0, -np.pi / 2]), 0.04)}
    inputs = build_plan_scenario(sc, heavy_behind, 0.0, landing_shift=0.0)
    got = {a.callsign: a for a in inputs.scenario.aircraft}
    assert (got["A1"].wake_category, got["L9"].wake_category) == ("M", "L")
    assert got["Q1"].wake_category is None and got["N0"].wake_category is None
    assert wake_distance_nm("icao", None, "L", 3.0) == 8.0 and wake_distance_nm("icao", "H", None, 3.0) == 6.0
    # slotted after A1's fixed 155 s in order of their earliest times, each its pair's spacing (wake included)
    order = sorted(got.values(), key=lambda a: a.landing_time)
    assert order[0].callsign == "A1" and order[0].landing_time == pytest.approx(155.0)
    for leader, follower in zip(order, order[1:], strict=False):
        assert follower.landing_time - leader.landing_time >= landing_spacing(inputs.scenario, leader, follower) - 1e-9
    behind_m = order[1]  # the first slotted follows A1 (M): 5 nm for an L or an unknown
    assert behind_m.landing_time - 155.0 >= 5.0 / 0.04 - 1e-9


def test_plan_scenario_leaves_out_an_aircraft_that_cannot_stay_inside_the_airspace() -> None:
    """The main job's replan: A2 (climbing at 5 deg) at the ceiling cannot stay inside; it is left out with the
    reason, like an aircraft outside the airspace, and the others are planned."""

    from mal_planner.scenario import load_scenario
    from mal_planner.service.inputs import build_plan_scenario
    from mal_planner.service.tracks import Track

    sc = load_scenario(SCENARIO)
    tracks = {a.callsign: Track(a.callsign, 0.0, a.state0.copy(), a.speed) for a in sc.aircraft}
    climbing = sc.aircraft_by_callsign("A2").state0.copy()
    climbing[2] = 0.305  # radar noise above the ceiling, within the node's tolerance: clipped onto it
    tracks["A2"] = Track("A2", 0.0, climbing, 0.04)
    inputs = build_plan_scenario(sc, tracks, 0.0, landing_shift=0.0)
    assert [a.callsign for a in inputs.scenario.aircraft] == ["A1", "A3"]
    assert inputs.left_out["A2"].startswith("leaving the airspace (at 0.3000 nm climbing at 5.0 deg")
    climbing[2] = 0.29  # 0.01 nm below: it can level off in time
    tracks["A2"] = Track("A2", 0.0, climbing, 0.04)
    assert "A2" not in build_plan_scenario(sc, tracks, 0.0, landing_shift=0.0).left_out


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-v"]))


def test_check_track_rejects_tracks_implausible_in_context() -> None:
    """Issue 10: plausible alone, but not for this aircraft (speed), below ground, stale or in the future."""
    import numpy as np

    from mal_planner.scenario import load_scenario
    from mal_planner.service.tracks import Track, check_track

    sc = load_scenario(SCENARIO)
    a1 = sc.aircraft_by_callsign("A1")

    def check(stamp: float = 100.0, z: float = 0.2, speed: float = a1.speed) -> str | None:
        track = Track("A1", stamp, np.array([0.5, 5.0, z, 0.0, -1.57]), speed)
        return check_track(track, "runway", "runway", sc.airspace, expected_speed=a1.speed, newest=120.0,
                           timeout_s=30.0, now=110.0)

    assert check() is None
    assert check(speed=a1.speed * 1.5) is None  # generous tolerance
    assert "implausible" in (check(speed=a1.speed * 3) or "") and "implausible" in (check(speed=a1.speed / 3) or "")
    assert "below the airspace floor" in (check(z=-0.3) or "")
    assert check(z=-0.02) is None  # radar noise near the runway
    assert "stale stamp" in (check(stamp=80.0) or "")
    assert "in the future" in (check(stamp=130.0) or "")
