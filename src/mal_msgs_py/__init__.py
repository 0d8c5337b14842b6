"""ROS 2 message types of the MAL planner for the built-in Cyclone DDS transport.

The ``mal_msgs`` .msg/.srv files (``ros2_ws/src/mal_msgs``) are parsed at run time with rosbags (the one
parser); standard types come from the rosbags ROS 2 Jazzy typestore. The generated classes are cyclonedds
``IdlStruct`` dataclasses with the DDS type names of rmw_cyclonedds_cpp (``pkg::msg::dds_::Name_``), XCDR1,
final, constructible with keyword arguments named like the rclpy message fields.

>>> State = get_type("mal_msgs/msg/AircraftState")
>>> Request, Response = get_service("mal_msgs/srv/PlanLanding")
>>> type_hash("std_msgs/msg/String")[:14]
'RIHS01_df668c7'
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from rosbags.interfaces import Nodetype

from ._interfaces import interface_dir
from ._names import WIRE_HEADER, dds_type_name
from ._store import service_names, type_description, type_hash, typestore

if TYPE_CHECKING:
    from cyclonedds.idl import IdlStruct


def get_class(ros_name: str) -> type[IdlStruct]:
    """IdlStruct class of a message or service part. The cyclonedds classes (and the Cyclone C library) load
    only here, so that the typestore, hashes and bag (de)serialization work without them (rclpy backend)."""
    from ._idl import get_class as _get_class

    return _get_class(ros_name)


def get_wire_class(ros_part: str) -> type[IdlStruct]:
    from ._idl import get_wire_class as _get_wire_class

    return _get_wire_class(ros_part)


__all__ = [
    "ServiceType",
    "WIRE_HEADER",
    "dds_type_name",
    "get_service",
    "get_srv",
    "get_type",
    "interface_dir",
    "service_names",
    "to_rosbags",
    "from_rosbags",
    "type_description",
    "type_hash",
    "typestore",
]


def get_type(name: str) -> type[IdlStruct]:
    """Message class for ``pkg/msg/Name`` (any ROS 2 Jazzy standard type, or ours)."""
    return get_class(_normalize(name))


@dataclass(frozen=True)
class ServiceType:
    """A service type: user-facing Request/Response classes plus their wire types (with request header)."""

    name: str
    Request: type[IdlStruct]
    Response: type[IdlStruct]
    WireRequest: type[IdlStruct]
    WireResponse: type[IdlStruct]
    type_hash: str


_services: dict[str, ServiceType] = {}


def get_srv(name: str) -> ServiceType:
    """Service type ``pkg/srv/Name`` (ours and std_srvs/srv/Trigger)."""
    name = _normalize(name)
    if name not in _services:
        if name not in service_names():
            msg = f"unknown service type {name!r}"
            raise KeyError(msg)
        _services[name] = ServiceType(
            name=name,
            Request=get_class(name + "_Request"),
            Response=get_class(name + "_Response"),
            WireRequest=get_wire_class(name + "_Request"),
            WireResponse=get_wire_class(name + "_Response"),
            type_hash=type_hash(name),
        )
    return _services[name]


def get_service(name: str) -> tuple[type[IdlStruct], type[IdlStruct]]:
    """``(Request, Response)`` classes of service ``pkg/srv/Name``."""
    srv = get_srv(name)
    return srv.Request, srv.Response


def _normalize(name: str) -> str:
    """Accept ``pkg/msg/Name`` and ``pkg/Name`` (message) spellings."""
    parts = name.strip("/").split("/")
    if len(parts) == 2:
        return f"{parts[0]}/msg/{parts[1]}"
    return "/".join(parts)


def to_rosbags(msg: Any) -> Any:
    """Convert one of our message objects to the rosbags class of the same type (for bag writing)."""
    store = typestore()
    ros_name = type(msg).__msgtype__
    cls = store.types[ros_name]
    kwargs = {}
    for fname, desc in store.fielddefs[ros_name][1]:
        value = _convert(getattr(msg, fname), to_rosbags)
        dtype = _primitive_array_dtype(desc)
        kwargs[fname] = value if dtype is None else np.asarray(value, dtype=dtype)
    return cls(**kwargs) if kwargs else cls()


def _primitive_array_dtype(desc: Any) -> str | None:
    """The numpy dtype rosbags wants for an array or sequence of numbers or bools (None for other fields)."""
    if desc[0] not in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return None
    element = desc[1][0]
    if element[0] != Nodetype.BASE or element[1][0] == "string":
        return None
    name = element[1][0]
    return {"byte": "uint8", "char": "uint8", "octet": "uint8", "bool": "bool"}.get(name, name)


def from_rosbags(msg: Any) -> Any:
    """Convert a rosbags message object to our class of the same type."""
    ros_name = msg.__msgtype__
    cls = get_class(ros_name)
    fields = typestore().fielddefs[ros_name][1]
    return cls(**{f: _convert(getattr(msg, f), from_rosbags) for f, _ in fields})


def _convert(value: Any, fn: Any) -> Any:
    if hasattr(value, "__msgtype__"):
        return fn(value)
    if isinstance(value, list | tuple):
        return [_convert(v, fn) for v in value]
    if hasattr(value, "tolist"):  # numpy arrays from rosbags
        return value.tolist()
    return value
