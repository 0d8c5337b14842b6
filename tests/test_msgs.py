"""mal_msgs_py: generated types, CDR layout against rosbags' serializer, RIHS01 hashes, typestore."""

from __future__ import annotations

from pathlib import Path

import pytest

import mal_msgs_py as m

# Published values: std_msgs/String (rmw_zenoh docs), builtin_interfaces/Time and service_msgs/
# ServiceEventInfo (rosidl-generated *_description.c), ParticipantEntitiesInfo (rmw_cyclonedds based
# projects), std_srvs/Trigger (an rmw_zenoh key expression).
KNOWN_HASHES = {
    "std_msgs/msg/String": "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
    "builtin_interfaces/msg/Time": "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197",
    "service_msgs/msg/ServiceEventInfo": (
        "RIHS01_41bcbbe07a75c9b52bc96bfd5c24d7f0fc0a08c0cb7921b3373c5732345a6f45"
    ),
    "rmw_dds_common/msg/ParticipantEntitiesInfo": (
        "RIHS01_91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e"
    ),
    "std_srvs/srv/Trigger": "RIHS01_eeff2cd6fa5ad9d27cdf4dec64818317839b62f212a91e6b5304b634b2062c5f",
}


@pytest.mark.parametrize("name", sorted(KNOWN_HASHES))
def test_known_rihs01_hashes(name: str) -> None:
    assert m.type_hash(name) == KNOWN_HASHES[name]


def test_all_used_types_have_hashes() -> None:
    names = [
        "mal_msgs/msg/AircraftState", "mal_msgs/msg/AircraftPlan", "mal_msgs/msg/LandingPlan",
        "mal_msgs/srv/PlanLanding", "std_msgs/msg/Header", "geometry_msgs/msg/PoseStamped",
        "nav_msgs/msg/Path", "visualization_msgs/msg/MarkerArray", "diagnostic_msgs/msg/DiagnosticArray",
        "rmw_dds_common/msg/Gid", "rmw_dds_common/msg/NodeEntitiesInfo",
    ]  # fmt: skip
    for name in names:
        assert m.type_hash(name).startswith("RIHS01_") and len(m.type_hash(name)) == 71


def test_dds_names_fields_and_constants() -> None:
    state = m.get_type("mal_msgs/msg/AircraftState")
    assert state.__idl_typename__ == "mal_msgs::msg::dds_::AircraftState_"
    assert list(state.__dataclass_fields__) == [
        "header", "callsign", "position", "flight_path_angle", "heading", "speed", "wake_category",
    ]  # fmt: skip
    plan = m.get_type("mal_msgs/msg/AircraftPlan")
    assert (plan.STATUS_OPTIMAL, plan.STATUS_INITIAL_GUESS, plan.STATUS_FAILED, plan.STATUS_HOLD) == (0, 1, 2, 3)
    assert m.get_type("std_msgs/msg/Header").__idl_typename__ == "std_msgs::msg::dds_::Header_"
    srv = m.get_srv("mal_msgs/srv/PlanLanding")
    assert srv.WireRequest.__idl_typename__ == "mal_msgs::srv::dds_::PlanLanding_Request_"
    assert srv.WireResponse.__idl_typename__ == "mal_msgs::srv::dds_::PlanLanding_Response_"
    assert list(srv.WireRequest.__dataclass_fields__) == ["rmw_guid", "rmw_seq", "aircraft"]
    assert list(srv.Response.__dataclass_fields__) == ["success", "error_code", "message", "plan", "paths"]
    assert (srv.Response.ERROR_NONE, srv.Response.ERROR_TIMEOUT) == (0, 6)
    gid = m.get_type("rmw_dds_common/msg/Gid")()
    assert gid.data == bytes(16)  # Jazzy: char[16]
    assert m.get_type("geometry_msgs/msg/Quaternion")().w == 1.0


def _rosbags_bytes(msg: object) -> bytes:
    return bytes(m.typestore().serialize_cdr(m.to_rosbags(msg), type(msg).__msgtype__))


def test_time_and_header_layout_matches_rosbags() -> None:
    time_cls = m.get_type("builtin_interfaces/msg/Time")
    stamp = time_cls(sec=1_700_000_000, nanosec=123_456_789)
    raw = stamp.serialize()
    # CDR little-endian encapsulation header, int32 sec, uint32 nanosec.
    assert raw == bytes([0, 1, 0, 0]) + (1_700_000_000).to_bytes(4, "little") + (123_456_789).to_bytes(
        4, "little"
    )
    assert raw == _rosbags_bytes(stamp)
    header = m.get_type("std_msgs/msg/Header")(stamp=stamp, frame_id="runway")
    assert header.serialize() == _rosbags_bytes(header)
    assert header.serialize()[12:16] == (len("runway") + 1).to_bytes(4, "little")


def _sample_plan_response() -> object:
    _req, res = m.get_service("mal_msgs/srv/PlanLanding")
    plan_cls = m.get_type("mal_msgs/msg/AircraftPlan")
    header = m.get_type("std_msgs/msg/Header")(frame_id="runway")
    pose = m.get_type("geometry_msgs/msg/PoseStamped")(header=header)
    pose.pose.position.x = -12000.5
    path = m.get_type("nav_msgs/msg/Path")(header=header, poses=[pose, pose])
    return res(
        success=True,
        message="ok",
        plan=m.get_type("mal_msgs/msg/LandingPlan")(
            header=header,
            aircraft=[
                plan_cls(
                    callsign="AF1", order=1, gate_time=10.0, landing_time=130.5, status=0, verified=True,
                    wake_category="H", target_time=120.0, delay=10.5, latitude=[49.1, 49.05],
                    longitude=[2.7, 2.6], altitude=[900.0, 119.5],
                ),
                plan_cls(callsign="BA2", order=2, gate_time=80.0, landing_time=210.0, status=1),
            ],
            geodetic=True, origin_latitude=49.02667786, origin_longitude=2.56169447, origin_altitude=119.48,
            course=265.43,
        ),
        paths=[path],
    )


def test_nested_messages_layout_matches_rosbags_and_round_trip() -> None:
    state = m.get_type("mal_msgs/msg/AircraftState")(
        callsign="AFR123", flight_path_angle=-0.052, heading=3.1, speed=72.5, wake_category="M"
    )
    state.position.z = 900.0
    for msg in (state, _sample_plan_response().plan, _sample_plan_response()):
        raw = msg.serialize()
        assert raw == _rosbags_bytes(msg)
        assert type(msg).deserialize(raw) == msg
        assert m.from_rosbags(m.typestore().deserialize_cdr(raw, type(msg).__msgtype__)) == msg


def test_service_wire_layout_is_request_header_then_fields() -> None:
    srv = m.get_srv("mal_msgs/srv/PlanLanding")
    res = _sample_plan_response()
    wire = srv.WireResponse(rmw_guid=0x1122334455667788, rmw_seq=7, **vars(res))
    raw = wire.serialize()
    assert raw[4:12] == (0x1122334455667788).to_bytes(8, "little")
    assert raw[12:20] == (7).to_bytes(8, "little")
    assert raw[20:] == _rosbags_bytes(res)[4:]  # same alignment: the header is 16 bytes
    trigger = m.get_srv("std_srvs/srv/Trigger")
    assert trigger.WireRequest(rmw_guid=1, rmw_seq=2).serialize()[20:] == b"\x00"  # dummy member


def test_typestore_writes_mcap_bag(tmp_path: Path) -> None:
    from rosbags.rosbag2 import Reader, StoragePlugin, Writer

    store = m.typestore()
    msg = _sample_plan_response().plan
    bag = tmp_path / "bag"
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection("/landing_plan", "mal_msgs/msg/LandingPlan", typestore=store)
        writer.write(conn, 42, bytes(store.serialize_cdr(m.to_rosbags(msg), "mal_msgs/msg/LandingPlan")))
    with Reader(bag) as reader:
        [(conn, stamp, raw)] = list(reader.messages())
        assert stamp == 42
        assert m.get_type("mal_msgs/msg/LandingPlan").deserialize(raw) == msg


def test_interface_files_are_found() -> None:
    root = m.interface_dir()
    assert (root / "msg" / "AircraftState.msg").is_file()
    assert (root / "srv" / "PlanLanding.srv").is_file()
    assert "mal_msgs/srv/PlanLanding" in m.service_names()


def test_hashes_equal_real_ros2_jazzy() -> None:
    """Every message/service we know that a real ROS 2 Jazzy also has: our RIHS01 hash equals rosidl's
    (the ``type_hashes`` of /opt/ros/jazzy/share/<pkg>/<msg|srv>/<Name>.json, compiled into the typesupport)."""
    import json

    from ros2_env import ROS_SETUP, skip_without_ros2

    skip_without_ros2()
    share = ROS_SETUP.parent / "share"
    compared: dict[str, str] = {}
    for path in sorted(share.glob("*/[ms][sr][gv]/*.json")):
        for entry in json.loads(path.read_text(encoding="utf-8"))["type_hashes"]:
            try:
                compared[entry["type_name"]] = m.type_hash(entry["type_name"])
            except KeyError:  # a type we never use (not in our typestore)
                continue
            assert compared[entry["type_name"]] == entry["hash_string"], entry["type_name"]
    vendored = ["rcl_interfaces/srv/SetParameters", "rcl_interfaces/msg/ParameterEvent", "rcl_interfaces/msg/Log",
                "type_description_interfaces/srv/GetTypeDescription", "rcl_interfaces/srv/ListParameters_Event"]
    assert set(vendored) <= set(compared) and len(compared) > 150


def test_vendored_interfaces_are_parsed_from_their_files() -> None:
    from mal_msgs_py._interfaces import package_roots

    roots = package_roots()
    assert {"rcl_interfaces", "type_description_interfaces", "builtin_interfaces", "mal_msgs"} <= set(roots)
    assert (roots["rcl_interfaces"] / "srv" / "SetParameters.srv").is_file()
    assert "rcl_interfaces/srv/GetParameters" in m.service_names()
    req, res = m.get_service("rcl_interfaces/srv/SetParameters")
    assert res().results == [] and req().parameters == []
    assert m.get_type("rcl_interfaces/msg/ParameterType").PARAMETER_DOUBLE == 3


def test_plan_landing_error_codes_are_the_outcome_table() -> None:
    """One table of outcomes (mal_planner.errors.OUTCOMES): the service's ERROR_* constants say the same."""
    import re

    from mal_planner.errors import OUTCOMES

    text = (m.interface_dir() / "srv" / "PlanLanding.srv").read_text()
    constants = {name.lower(): int(value) for name, value in re.findall(r"^uint16 ERROR_(\w+)=(\d+)$", text, re.M)}
    assert constants == {("none" if o.name == "success" else o.name): o.error_code for o in OUTCOMES}
    assert sorted(o.error_code for o in OUTCOMES) == list(range(len(OUTCOMES)))
