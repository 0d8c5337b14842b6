"""The rclpy backend (real ROS 2 Jazzy, in subprocesses): per-node contexts, futures, parameters, /rosout."""

from __future__ import annotations

import time

import pytest
from dds_support import Snippet, dds_env, unique_domain_id  # noqa: F401  (fixture)
from ros2_env import ros2_env, skip_without_ros2

from mal_planner.ros.transport import create_node

pytestmark = [pytest.mark.usefixtures("dds_env")]


@pytest.fixture
def rclpy_snippet(dds_env: dict[str, str]):  # noqa: F811
    """Factory of snippets running with the sourced ROS 2 environment (stopped at teardown)."""
    skip_without_ros2()
    env = ros2_env(dds_env)
    started: list[Snippet] = []

    def start(code: str) -> Snippet:
        started.append(Snippet(code, env))
        return started[-1]

    yield start
    for snip in started:
        snip.stop()


def test_second_node_honours_a_changed_domain_id(rclpy_snippet, dds_env) -> None:  # noqa: F811
    """A node created after ROS_DOMAIN_ID changed talks on the new domain (rclpy is initialised per node)."""
    first_domain = unique_domain_id()
    snip = rclpy_snippet(f"""
import os, time
from mal_planner.ros.transport import create_node
os.environ["ROS_DOMAIN_ID"], ours = "{first_domain}", os.environ["ROS_DOMAIN_ID"]
create_node("first", backend="rclpy").shutdown()
os.environ["ROS_DOMAIN_ID"] = ours
node = create_node("second", backend="rclpy")
pub = node.create_publisher("std_msgs/msg/String", "/chatter", 10)
print("ready", flush=True)
deadline = time.monotonic() + 30
while time.monotonic() < deadline:
    pub.publish(node.types.msg("std_msgs/msg/String")(data="on the new domain"))
    node.spin_once(0.05)
""")
    snip.wait_for_line("ready", 30)
    with create_node("listener", backend="cyclone") as node:
        got: list[str] = []
        node.create_subscription("std_msgs/msg/String", "/chatter", lambda m: got.append(m.data), 10)
        deadline = time.monotonic() + 15
        while not got and time.monotonic() < deadline:
            node.spin_once(0.05)
    assert got and got[0] == "on the new domain"


def test_call_async_future_has_result_timeout(rclpy_snippet) -> None:
    """``call_async`` returns a concurrent.futures.Future on rclpy too: ``result(timeout=...)`` works while
    another thread spins, and a timeout raises TimeoutError."""
    snip = rclpy_snippet("""
import concurrent.futures, threading
from mal_planner.ros.transport import create_node
server = create_node("server", backend="rclpy")
server.create_service("std_srvs/srv/Trigger", "/trig",
                      lambda q, r: (setattr(r, "message", "ok"), setattr(r, "success", True), r)[-1])
threading.Thread(target=server.spin, daemon=True).start()
node = create_node("client", backend="rclpy")
cli = node.create_client("std_srvs/srv/Trigger", "/trig")
threading.Thread(target=node.spin, daemon=True).start()
assert cli.wait_for_service(20)
Trigger = node.types.srv("std_srvs/srv/Trigger")
fut = cli.call_async(Trigger.Request())
print("TYPE", isinstance(fut, concurrent.futures.Future), flush=True)
print("RESULT", fut.result(timeout=10).message, flush=True)
slow = create_node("nobody", backend="rclpy").create_client("std_srvs/srv/Trigger", "/nobody")
try:
    slow.call_async(Trigger.Request()).result(timeout=0.2)
except concurrent.futures.TimeoutError:
    print("TIMEOUT", flush=True)
node.shutdown(); server.shutdown()
""")
    assert snip.wait_for_line("TYPE", 40) == "TYPE True"
    assert snip.wait_for_line("RESULT", 20) == "RESULT ok"
    snip.wait_for_line("TIMEOUT", 20)


def test_rclpy_backend_logs_reach_rosout(rclpy_snippet) -> None:
    """The node's Python log lines go to /rosout on rclpy as on the built-in backend (read by a built-in
    subscriber with rcl's rosout QoS)."""
    from mal_planner.ros.transport._common import QOS_ROSOUT

    snip = rclpy_snippet("""
import logging
from mal_planner.ros.transport import create_node
logging.basicConfig(level=logging.INFO)
node = create_node("talker", "atc", backend="rclpy")
node.create_timer(0.1, lambda: node.get_logger().warning("hello rosout"))
print("ready", flush=True)
node.spin()
""")
    snip.wait_for_line("ready", 30)
    with create_node("rosout_listener", backend="cyclone", start_parameter_services=False) as node:
        got: list = []
        node.create_subscription("rcl_interfaces/msg/Log", "/rosout",
                                 lambda m: got.append(m) if m.msg == "hello rosout" else None, QOS_ROSOUT)
        deadline = time.monotonic() + 15
        while not got and time.monotonic() < deadline:
            node.spin_once(0.05)
    assert got and got[0].name == "atc.talker" and got[0].level == 30
