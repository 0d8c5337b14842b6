"""Our built-in-backend planner driven by the real ROS 2 Jazzy tools: ros2 CLI, plain rclpy, colcon.

One planner (built-in backend, no ROS in its environment) is started per module, fed by the bundled radar
bag until its first plan, and shared by the tests below (they run in file order; each needs the one before
only for speed, never for its assertions). ROS-side processes get the sourced environment of
/opt/ros/jazzy plus the colcon-built mal_msgs (tests/ros2_env.py).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import time
from pathlib import Path

import pytest
from dds_support import SRC, Snippet, coarse_params, unique_domain_id
from ros2_env import ros2, ros2_env, skip_without_ros2

import mal_msgs_py
from mal_planner.ros.transport.loopback import write_loopback_config

REPO = SRC.parent
BAG_T0 = 1_700_000_000.0
LATCHED = ["--qos-durability", "transient_local", "--qos-reliability", "reliable"]


class Planner:
    """The shared planner process and the environments to talk to it."""

    def __init__(self, proc: Snippet, env: dict[str, str], ros: dict[str, str]) -> None:
        self.proc, self.env, self.ros = proc, env, ros

    def wait_for(self, text: str, timeout: float = 60.0) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if any(text in line for line in self.proc.output):
                return next(line for line in self.proc.output if text in line)
            try:
                self.proc.output.append(self.proc.lines.get(timeout=0.1))
            except Exception:  # queue.Empty
                if self.proc.proc.poll() is not None:
                    break
        pytest.fail(f"planner did not log {text!r}; output:\n" + "\n".join(self.proc.output[-60:]))

    def log(self) -> str:
        while not self.proc.lines.empty():
            self.proc.output.append(self.proc.lines.get_nowait())
        return "\n".join(self.proc.output)


@pytest.fixture(scope="module")
def planner(tmp_path_factory: pytest.TempPathFactory, mal_msgs_install: dict[str, object]):
    skip_without_ros2()
    tmp = tmp_path_factory.mktemp("interop")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("AMENT_", "ROS_", "COLCON_"))}
    env.update(CYCLONEDDS_URI=write_loopback_config(tmp / "cyclonedds.xml"), ROS_DOMAIN_ID=str(unique_domain_id()),
               MAL_ROS_BACKEND="cyclone", PYTHONPATH=str(SRC))
    install = mal_msgs_install["install"]
    assert isinstance(install, Path)
    ros = ros2_env(env, install)
    params = tmp / "planner.params.yaml"
    params.write_text(coarse_params("    deviation_threshold_m: 0.0\n    figures: none\n"), encoding="utf-8")
    args = ["--scenario", str(REPO / "scenarios" / "thesis.yaml"), "--params", str(params)]
    proc = Snippet(f"import sys\nfrom mal_planner.ros.planner_node import main\nsys.exit(main({args!r}))\n", env)
    shared = Planner(proc, env, ros)
    try:
        shared.wait_for("planner ready", 30)
        replay = Snippet("import sys\nfrom mal_planner.ros.replay import main\n"
                         f"sys.exit(main({[str(REPO / 'data' / 'thesis_radar.mcap'), '--rate', '4']!r}))\n", env)
        shared.wait_for("plan #1", 150)
        replay.stop()
        yield shared
    finally:
        proc.stop()


def test_ros2_node_list_and_info(planner: Planner) -> None:
    out = ros2(["node", "list", "--no-daemon"], planner.ros)
    assert "/planner" in out.stdout.split(), out
    info = ros2(["node", "info", "/planner", "--no-daemon"], planner.ros).stdout
    for line in ("/aircraft/A1/path: nav_msgs/msg/Path", "/rosout: rcl_interfaces/msg/Log",
                 "/parameter_events: rcl_interfaces/msg/ParameterEvent", "/plan: std_srvs/srv/Trigger",
                 "/plan_landing: mal_msgs/srv/PlanLanding", "/radar/tracks: mal_msgs/msg/AircraftState",
                 "/planner/get_parameters: rcl_interfaces/srv/GetParameters",
                 "/planner/set_parameters: rcl_interfaces/srv/SetParameters",
                 "/planner/get_type_description: type_description_interfaces/srv/GetTypeDescription"):
        assert line in info, info


def test_ros2_topic_echo_latched_path_and_first_diagnostics(planner: Planner) -> None:
    out = ros2(["topic", "echo", "/aircraft/A1/path", "nav_msgs/msg/Path", *LATCHED, "--once", "--no-daemon"],
               planner.ros, timeout=30)
    assert "frame_id: runway" in out.stdout and out.stdout.count("pose:") > 10, out
    diag = ros2(["topic", "echo", "/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", *LATCHED, "--once",
                 "--no-daemon"], planner.ros, timeout=30).stdout
    assert re.search(r"key: plans\n\s+value: '1'", diag), diag  # the first array counts its own plan


def test_ros2_service_call_plan_and_type_description(planner: Planner) -> None:
    # Early in the module (after the first diagnostics are read): the plan starts from the last radar tracks
    # predicted to the node's clock, which runs on after the replay stops (on a loaded machine the calls before it
    # took 114 s, past the thesis's landings).
    out = ros2(["service", "call", "/plan", "std_srvs/srv/Trigger"], planner.ros, timeout=120).stdout
    assert "success=True" in out and "lands at" in out, out
    request = json.dumps({"type_name": "mal_msgs/msg/LandingPlan", "type_hash": mal_msgs_py.type_hash(
        "mal_msgs/msg/LandingPlan"), "include_type_sources": False})
    out = ros2(["service", "call", "/planner/get_type_description",
                "type_description_interfaces/srv/GetTypeDescription", request], planner.ros, timeout=30).stdout
    assert "successful=True" in out and "type_name='mal_msgs/msg/AircraftPlan'" in out, out


def test_ros2_param_list_get_set_dump(planner: Planner) -> None:
    names = ros2(["param", "list", "/planner", "--no-daemon"], planner.ros).stdout.split()
    assert {"replan_period_s", "mesh_tol", "radar_qos", "output_dir"} <= set(names), names
    get = ros2(["param", "get", "/planner", "replan_period_s", "--no-daemon"], planner.ros).stdout
    assert get.strip() == "Double value is: 0.0"
    ok = ros2(["param", "set", "/planner", "replan_period_s", "5.0", "--no-daemon"], planner.ros).stdout
    assert ok.strip() == "Set parameter successful"
    planner.wait_for("plan requested: periodic replan", 30)  # it takes effect
    ros2(["param", "set", "/planner", "replan_period_s", "0.0", "--no-daemon"], planner.ros)
    bad = ros2(["param", "set", "/planner", "replan_period_s", "-1.0", "--no-daemon"], planner.ros)
    assert bad.stderr.strip() == ("Setting parameter failed: Parameter replan_period_s out of range Min: 0.0, "
                                  "Max: inf, value: -1.0"), bad  # the descriptor's range, in rclpy's words
    wrong_type = ros2(["param", "set", "/planner", "replan_period_s", "5", "--no-daemon"], planner.ros).stderr
    assert "Setting parameter failed: Wrong parameter type" in wrong_type
    assert ros2(["param", "get", "/planner", "replan_period_s", "--no-daemon"], planner.ros).stdout.strip() == (
        "Double value is: 0.0")
    dump = ros2(["param", "dump", "/planner", "--no-daemon"], planner.ros).stdout
    assert dump.startswith("/planner:\n  ros__parameters:\n") and "    mesh_tol: 0.001\n" in dump, dump
    describe = ros2(["param", "describe", "/planner", "radar_qos", "--no-daemon"], planner.ros).stdout
    assert "Type: string" in describe and "read-only at run time" in describe
    degree = ros2(["param", "describe", "/planner", "degree", "--no-daemon"], planner.ros).stdout
    assert "Type: integer" in degree and "Min value: 2" in degree and "Max value: 16" in degree, degree
    too_big = ros2(["param", "set", "/planner", "degree", "1000", "--no-daemon"], planner.ros).stderr
    assert too_big.strip() == "Setting parameter failed: Parameter degree out of range. Min: 2, Max: 16, value: 1000"


def test_ros2_topic_echo_rosout(planner: Planner) -> None:
    """/rosout keeps a line 10 s (its lifespan, as rclpy's): the planner logs a line (a parameter set) while the
    echo listens, not only before it (a loaded machine starts the echo later than that)."""
    echo = subprocess.Popen(["timeout", "-k", "2", "60", "ros2", "topic", "echo", "/rosout", "rcl_interfaces/msg/Log",
                             *LATCHED, "--once", "--no-daemon"], env=planner.ros, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while echo.poll() is None and time.monotonic() < deadline:
            ros2(["param", "set", "/planner", "replan_period_s", "0.0", "--no-daemon"], planner.ros)
        out, err = echo.communicate(timeout=10)
    finally:
        echo.kill()
    assert "name: planner" in out and "msg:" in out, (out, err)


RCLPY_CLIENT = """
import json, time
import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from mal_msgs.msg import AircraftState, LandingPlan
from mal_msgs.srv import PlanLanding
rclpy.init()
node = rclpy.create_node("rclpy_interop")
latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
plans = []
node.create_subscription(LandingPlan, "/landing_plan", plans.append, latched)
client = node.create_client(PlanLanding, "/plan_landing")
assert client.wait_for_service(timeout_sec=20)
end = time.monotonic() + 20
while not plans and time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.1)
ours = node.get_publishers_info_by_topic("/landing_plan")
mine = node.get_subscriptions_info_by_topic("/landing_plan")
out = {"n_plans": len(plans), "order": [a.callsign for a in plans[0].aircraft],
       "publisher_node": [i.node_name for i in ours], "hash_ours": [str(i.topic_type_hash) for i in ours],
       "hash_rclpy": [str(i.topic_type_hash) for i in mine]}
request = PlanLanding.Request()
for cs, (x, y, z, gamma, heading), speed in %(states)r:
    state = AircraftState(callsign=cs, speed=speed, flight_path_angle=gamma, heading=heading)
    state.header.frame_id = "runway"
    state.header.stamp.sec = %(stamp)d
    state.position.x, state.position.y, state.position.z = x, y, z
    request.aircraft.append(state)
future = client.call_async(request)
rclpy.spin_until_future_complete(node, future, timeout_sec=150)
res = future.result()
end = time.monotonic() + 1.0
while time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.1)
out.update(success=res.success, message=res.message, n_paths=len(res.paths),
           what_if=sorted(a.callsign for a in res.plan.aircraft), n_plans_after=len(plans))
print("RCLPY " + json.dumps(out), flush=True)
"""


def test_rclpy_subscriber_and_client(planner: Planner) -> None:
    """Plain rclpy: the latched plan arrives with rosidl's type hash; a what-if PlanLanding call is answered
    and does not republish the radar plan."""
    from mal_planner.scenario import load_scenario
    from mal_planner.service.tracks import extrapolate

    states = []  # A1 and A3 of the scenario flown 30 s straight on, SI units (as the radar would see them)
    for a in load_scenario(REPO / "scenarios" / "thesis.yaml").aircraft:
        if a.callsign != "A2":
            s = extrapolate(a.state0, a.speed, 30.0)
            si = [float(v) * f for v, f in zip(s, (1852.0, 1852.0, 1852.0, 1.0, 1.0), strict=True)]
            states.append((a.callsign, si, float(a.speed) * 1852.0))
    snip = Snippet(RCLPY_CLIENT % {"stamp": int(BAG_T0) + 30, "states": states}, planner.ros)
    try:
        out = json.loads(snip.wait_for_line("RCLPY ", 240)[len("RCLPY "):])
    finally:
        snip.stop()
    # The latched plan is the latest: the first (A1, A2, A3) or, after the bag's 16.5 s, the replan without A2
    # (it is leaving the airspace through its ceiling).
    assert out["n_plans"] == 1 and sorted(out["order"]) in (["A1", "A2", "A3"], ["A1", "A3"])
    assert out["publisher_node"] == ["planner"]
    assert out["hash_ours"] == out["hash_rclpy"] and out["hash_ours"][0].startswith("RIHS01_")
    assert out["success"] and out["n_paths"] == 2 and out["what_if"] == ["A1", "A3"], out
    assert out["n_plans_after"] == 1  # the what-if plan was not published


def test_ros2_topic_pub_aircraft_state(planner: Planner) -> None:
    msg = (f"{{header: {{stamp: {{sec: {int(BAG_T0) + 22}}}, frame_id: runway}}, callsign: Z9, "
           "position: {x: 0.0, y: 9000.0, z: 300.0}, flight_path_angle: 0.0, heading: -1.5708, speed: 80.0}")
    out = ros2(["topic", "pub", "--once", "-w", "1", "/radar/tracks", "mal_msgs/msg/AircraftState", msg],
               planner.ros, timeout=30)
    assert out.returncode == 0, out
    planner.wait_for("new aircraft Z9 on radar/tracks", 20)


def test_colcon_built_mal_msgs_hashes_equal_ours(mal_msgs_install: dict[str, object]) -> None:
    """ros2_ws/src/mal_msgs builds with colcon against /opt/ros/jazzy; rosidl's hashes equal mal_msgs_py's."""
    install = mal_msgs_install["install"]
    assert isinstance(install, Path)
    share = install / "mal_msgs" / "share" / "mal_msgs"
    compared = 0
    for path in sorted(share.glob("*/*.json")):
        for entry in json.loads(path.read_text(encoding="utf-8"))["type_hashes"]:
            assert mal_msgs_py.type_hash(entry["type_name"]) == entry["hash_string"], entry["type_name"]
            compared += 1
    assert compared >= 8  # 4 messages, the service with its request/response/event, and nested types
    print(f"colcon build of mal_msgs: {mal_msgs_install['seconds']:.1f} s")
