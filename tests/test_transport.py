"""Transport on real DDS (loopback) between processes: the node under test in a child process runs on each
backend (``backend_snippet``: built-in Cyclone, or rclpy on the real ROS 2 Jazzy); the test side is always
the built-in backend, so the rclpy runs are interop checks as well."""

import time
from dataclasses import dataclass
from pathlib import Path

import pytest
from cyclonedds.idl import IdlStruct

from mal_planner.ros.transport import QOS_LATCHED, create_node, load_params_file, resolve_name

pytestmark = pytest.mark.usefixtures("dds_env")


@dataclass
class String(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    """std_msgs/msg/String written by hand, independently of mal_msgs_py (as a plain DDS app would)."""

    data: str


TALKER = """
from mal_planner.ros.transport import create_node
node = create_node("talker", "atc", backend="auto")
String = node.types.msg("std_msgs/msg/String")
pub = node.create_publisher("std_msgs/msg/String", "chatter", 10)
count = [0]
def tick():
    count[0] += 1
    pub.publish(String(data=f"hello {count[0]}"))
node.create_timer(0.05, tick)
print("ready", flush=True)
node.spin()
"""


def spin_until(node, predicate, timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while not predicate() and time.monotonic() < deadline:
        node.spin_once(0.05)
    return predicate()


def test_pub_sub_between_processes(backend_snippet) -> None:
    backend_snippet(TALKER).wait_for_line("ready")
    with create_node("listener", "atc", backend="cyclone") as node:
        got: list[str] = []
        sub = node.create_subscription(
            "std_msgs/msg/String", "/atc/chatter", lambda m: got.append(m.data), 10
        )
        assert sub.topic_name == "/atc/chatter"
        assert spin_until(node, lambda: len(got) >= 3)
        assert got[0].startswith("hello ")


def test_raw_cyclonedds_reader_sees_ros_topic(backend_snippet) -> None:
    """A plain DDS reader (hand-written IdlStruct) receives our rt/ topic, like a ROS 2 node would."""
    from cyclonedds.core import Policy, Qos
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    backend_snippet(TALKER).wait_for_line("ready")
    dp = DomainParticipant(int(__import__("os").environ["ROS_DOMAIN_ID"]))
    reader = DataReader(dp, Topic(dp, "rt/atc/chatter", String), qos=Qos(Policy.Reliability.Reliable(0)))
    samples = []
    deadline = time.monotonic() + 10
    while not samples and time.monotonic() < deadline:
        samples = [s for s in reader.take(N=10) if isinstance(s, String)]
        time.sleep(0.05)
    assert samples and samples[0].data.startswith("hello ")
    [handle] = reader.get_matched_publications()
    qos = reader.get_matched_publication_data(handle).qos
    user_data = qos[Policy.Userdata].data.decode()
    assert "typehash=RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18;" in user_data


TRIGGER_SERVER = """
from mal_planner.ros.transport import create_node
node = create_node("server", backend="auto")
def handle(request, response):
    response.success = True
    response.message = "triggered"
    return response
node.create_service("std_srvs/srv/Trigger", "/trigger", handle)
print("ready", flush=True)
node.spin()
"""


def test_trigger_service_between_processes(backend_snippet) -> None:
    backend_snippet(TRIGGER_SERVER).wait_for_line("ready")
    with create_node("caller", backend="cyclone") as node:
        client = node.create_client("std_srvs/srv/Trigger", "trigger")
        assert client.wait_for_service(10.0)
        for _ in range(3):
            response = client.call(node.types.srv("std_srvs/srv/Trigger").Request(), timeout_sec=5.0)
            assert response.success and response.message == "triggered"


PLAN_SERVER = """
from mal_planner.ros.transport import create_node
node = create_node("planner", "atc", backend="auto")
T = node.types
def handle(request, response):
    plan_cls = T.msg("mal_msgs/msg/AircraftPlan")
    response.plan.header.frame_id = "runway"
    for i, ac in enumerate(request.aircraft):
        response.plan.aircraft.append(plan_cls(callsign=ac.callsign, order=i + 1,
            landing_time=100.0 * (i + 1), status=plan_cls.STATUS_OPTIMAL, verified=True))
        pose = T.msg("geometry_msgs/msg/PoseStamped")()
        pose.pose.position = ac.position
        response.paths.append(T.msg("nav_msgs/msg/Path")(poses=[pose]))
    response.success = True
    response.message = f"planned {len(request.aircraft)}"
    return response
node.create_service("mal_msgs/srv/PlanLanding", "plan_landing", handle)
print("ready", flush=True)
node.spin()
"""


def test_plan_landing_service_between_processes(backend_snippet) -> None:
    backend_snippet(PLAN_SERVER).wait_for_line("ready")
    with create_node("atc_client", backend="cyclone") as node:
        srv = node.types.srv("mal_msgs/srv/PlanLanding")
        state = node.types.msg("mal_msgs/msg/AircraftState")
        client = node.create_client(srv, "/atc/plan_landing")
        assert client.wait_for_service(10.0)
        request = srv.Request(aircraft=[state(callsign="AF1"), state(callsign="BA2", wake_category="H")])
        request.aircraft[1].position.x = -15000.0
        future = client.call_async(request)
        node.spin_until_future_complete(future, 10.0)
        response = future.result(timeout=0)
        assert response.success and response.message == "planned 2"
        assert [a.callsign for a in response.plan.aircraft] == ["AF1", "BA2"]
        assert response.plan.aircraft[1].order == 2 and response.plan.aircraft[0].verified
        assert response.paths[1].poses[0].pose.position.x == -15000.0


def test_call_from_other_thread_while_spinning(backend_snippet) -> None:
    import threading

    backend_snippet(TRIGGER_SERVER).wait_for_line("ready")
    with create_node("threaded", backend="cyclone") as node:
        client = node.create_client("std_srvs/srv/Trigger", "/trigger")
        spinner = threading.Thread(target=node.spin, daemon=True)
        spinner.start()
        assert client.wait_for_service(10.0)
        assert client.call(node.types.srv("std_srvs/srv/Trigger").Request(), timeout_sec=5.0).success
        node.shutdown()
        spinner.join(5)
        assert not spinner.is_alive()


LATCHED = """
from mal_planner.ros.transport import QOS_LATCHED, create_node
node = create_node("radar", backend="auto")
pub = node.create_publisher("std_msgs/msg/String", "/latched", QOS_LATCHED)
for i in range(3):
    pub.publish(node.types.msg("std_msgs/msg/String")(data=f"state {i}"))
print("published", flush=True)
node.spin()
"""


def test_late_joiner_gets_last_latched_sample(backend_snippet) -> None:
    backend_snippet(LATCHED).wait_for_line("published")
    time.sleep(0.3)
    with create_node("late", backend="cyclone") as node:
        got: list[str] = []
        node.create_subscription("std_msgs/msg/String", "/latched", lambda m: got.append(m.data), QOS_LATCHED)
        assert spin_until(node, lambda: bool(got))
        node.spin_once(0.2)
        assert got == ["state 2"]


def test_ros_discovery_info_lists_node_and_gids() -> None:
    import os

    from cyclonedds.core import Policy, Qos
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    import mal_msgs_py

    with create_node("graph_node", "atc", backend="cyclone") as node:
        pub = node.create_publisher("std_msgs/msg/String", "out")
        sub = node.create_subscription("std_msgs/msg/String", "in", lambda m: None)
        srv = node.create_service("std_srvs/srv/Trigger", "trig", lambda q, r: r)
        pei = mal_msgs_py.get_type("rmw_dds_common/msg/ParticipantEntitiesInfo")
        dp = DomainParticipant(int(os.environ["ROS_DOMAIN_ID"]))
        qos = Qos(
            Policy.Reliability.Reliable(0), Policy.Durability.TransientLocal, Policy.History.KeepLast(1)
        )
        reader = DataReader(dp, Topic(dp, "ros_discovery_info", pei), qos=qos)
        infos = []
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            infos = [s for s in reader.take(N=10) if isinstance(s, pei)] or infos
            if infos and infos[-1].node_entities_info_seq:
                break
            time.sleep(0.05)
        assert infos, "no ros_discovery_info sample"
        info = infos[-1]
        assert info.gid.data == node.context.participant.guid.bytes
        [entry] = info.node_entities_info_seq
        assert (entry.node_namespace, entry.node_name) == ("/atc", "graph_node")
        writers = {g.data for g in entry.writer_gid_seq}
        readers = {g.data for g in entry.reader_gid_seq}
        assert pub.gid in writers and srv.writer_gid in writers
        assert sub.gid in readers and srv.reader_gid in readers
        # The gids are the DDS endpoint GUIDs that ROS tools match against DCPSPublication keys.
        assert pub.gid == pub._writer.guid.bytes


def test_timer_and_parameters(tmp_path: Path) -> None:
    params = tmp_path / "params.yaml"
    params.write_text(
        "/**:\n  ros__parameters:\n    rate: 1.0\n    shared: a\n"
        "/atc/timer_node:\n  ros__parameters:\n    rate: 20.0\n    solver: {tol: 1.0e-6}\n",
        encoding="utf-8",
    )
    with create_node(
        "timer_node", "atc", backend="cyclone", params_file=params, parameter_overrides={"shared": "b"}
    ) as node:
        assert node.declare_parameter("rate", 5.0).value == 20.0
        assert node.declare_parameter("solver.tol", 0.1).value == 1e-6
        assert node.declare_parameter("shared", "x").value == "b"
        assert node.declare_parameter("unset", 3).value == 3
        assert node.get_parameter("rate").value == 20.0
        ticks: list[float] = []
        timer = node.create_timer(0.02, lambda: ticks.append(time.monotonic()))
        assert spin_until(node, lambda: len(ticks) >= 5, timeout=5.0)
        timer.cancel()
        n = len(ticks)
        node.spin_once(0.1)
        assert len(ticks) == n
    assert load_params_file(params, "other", "/x") == {"rate": 1.0, "shared": "a"}


def test_name_resolution() -> None:
    assert resolve_name("chatter", "/atc", "n") == "/atc/chatter"
    assert resolve_name("/abs", "/atc", "n") == "/abs"
    assert resolve_name("~/private", "atc", "n") == "/atc/n/private"
    assert resolve_name("chatter", "", "n") == "/chatter"
    with pytest.raises(ValueError):
        resolve_name("bad name", "", "n")


REENTRANT_SERVER = """
import threading
from mal_planner.ros.transport import create_node
node = create_node("waiter", backend="auto")
released = threading.Event()
node.create_subscription("std_msgs/msg/String", "release", lambda msg: released.set(), 10)
def handle(request, response):
    # Blocks until a message arrives on a topic of the SAME node: only possible if the service does not
    # hold the node's executor.
    response.success = released.wait(10.0)
    response.message = "released" if response.success else "timed out"
    return response
node.create_service("std_srvs/srv/Trigger", "wait", handle, reentrant=True)
print("ready", flush=True)
node.spin()
"""


def test_reentrant_service_does_not_block_the_node(backend_snippet) -> None:
    backend_snippet(REENTRANT_SERVER).wait_for_line("ready")
    with create_node("releaser", backend="cyclone") as node:
        srv = node.types.srv("std_srvs/srv/Trigger")
        client = node.create_client(srv, "wait")
        pub = node.create_publisher("std_msgs/msg/String", "release", 10)
        assert client.wait_for_service(10.0)
        future = client.call_async(srv.Request())
        node.spin_until_future_complete(future, 1.0)
        assert not future.done()  # the service is waiting for the release message
        deadline = time.monotonic() + 10.0
        while not future.done() and time.monotonic() < deadline:
            pub.publish(node.types.msg("std_msgs/msg/String")(data="go"))
            node.spin_until_future_complete(future, 0.2)
        response = future.result(timeout=0)
        assert response.success and response.message == "released"


def test_parameter_services_follow_rclpy() -> None:
    """Built-in backend, no ROS needed: the rcl_interfaces parameter services answer like rclpy's, a callback
    can refuse a value (nothing changes), and /parameter_events reports declared and changed parameters."""
    import threading

    from mal_planner.ros.transport._common import value_from_msg, value_to_msg
    from mal_planner.ros.transport._node_interfaces import list_parameters

    assert list_parameters(["a", "b.c", "b.d.e"], [], 0) == (["a", "b.c", "b.d.e"], ["b", "b.d"])
    assert list_parameters(["a", "b.c", "b.d.e"], [], 1) == (["a"], [])
    assert list_parameters(["a", "b.c", "b.d.e"], ["b"], 1) == (["b.c"], ["b"])
    with create_node("params_node", "atc", backend="cyclone") as server, \
            create_node("param_caller", backend="cyclone", start_parameter_services=False) as caller:
        server.declare_parameter("rate", 5.0, "update rate [Hz]")
        server.declare_parameter("solver.tol", 1e-6)
        server.add_on_set_parameters_callback(
            lambda ps: next(((False, f"{p.name} must be > 0") for p in ps if p.value <= 0), (True, "")))
        T = caller.types
        events: list = []
        caller.create_subscription("rcl_interfaces/msg/ParameterEvent", "/parameter_events", events.append, 100)
        spinner = threading.Thread(target=server.spin, daemon=True)
        spinner.start()

        def call(srv: str, **fields):
            cli = caller.create_client(f"rcl_interfaces/srv/{srv}", f"/atc/params_node/{srv_name(srv)}")
            assert cli.wait_for_service(10.0)
            return cli.call(T.srv(f"rcl_interfaces/srv/{srv}").Request(**fields), timeout_sec=10.0)

        def param(name, value):
            return T.msg("rcl_interfaces/msg/Parameter")(
                name=name, value=value_to_msg(T.msg("rcl_interfaces/msg/ParameterValue"), value))

        # every node has use_sim_time (rclpy declares it too): the node's clock follows /clock when it is true
        assert list(call("ListParameters").result.names) == ["use_sim_time", "rate", "solver.tol"]
        assert [value_from_msg(v) for v in call("GetParameters", names=["rate", "solver.tol"]).values] == [5.0, 1e-6]
        assert call("GetParameters", names=["rate", "nope"]).values == []  # rclpy: nothing if one is undeclared
        assert list(call("GetParameterTypes", names=["rate", "nope"]).types) == [3, 0]
        assert call("DescribeParameters", names=["rate"]).descriptors[0].description == "update rate [Hz]"
        results = call("SetParameters", parameters=[param("rate", 10.0), param("rate", -1.0), param("rate", 1)]).results
        assert [(r.successful, r.reason) for r in results] == [
            (True, ""), (False, "rate must be > 0"),
            (False, "Wrong parameter type, parameter {rate} is of type {double}, setting it to {integer} is not "
                    "allowed.")]
        atomic = call("SetParametersAtomically", parameters=[param("solver.tol", 1e-3), param("rate", 0.0)]).result
        assert not atomic.successful and server.get_parameter("solver.tol").value == 1e-6  # all or nothing
        assert server.get_parameter("rate").value == 10.0
        assert spin_until(caller, lambda: any(p.name == "rate" for e in events for p in e.changed_parameters))
        changed = [(p.name, value_from_msg(p.value)) for e in events for p in e.changed_parameters]
        assert changed == [("rate", 10.0)] and all(e.node == "/atc/params_node" for e in events)
        server.shutdown()
        spinner.join(5)


def srv_name(srv: str) -> str:
    """``SetParametersAtomically`` -> ``set_parameters_atomically``."""
    return "".join("_" + c.lower() if c.isupper() else c for c in srv).lstrip("_")
