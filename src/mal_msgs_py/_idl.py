"""Generate cyclonedds ``IdlStruct`` classes (ROS 2 DDS names, XCDR1, final) from rosbags field defs."""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Callable
from typing import Any

from cyclonedds.idl import IdlMeta, IdlStruct
from cyclonedds.idl import types as t
from rosbags.interfaces import Nodetype

from ._names import WIRE_HEADER, dds_type_name
from ._store import type_hash, typestore

_BASE: dict[str, Any] = {
    "bool": bool, "byte": t.byte, "char": t.uint8, "int8": t.int8, "uint8": t.uint8, "int16": t.int16,
    "uint16": t.uint16, "int32": t.int32, "uint32": t.uint32, "int64": t.int64, "uint64": t.uint64,
    "float32": t.float32, "float64": t.float64,
}  # fmt: skip
_OCTETS = ("uint8", "byte", "char")
_ZERO: dict[str, Any] = {"bool": False, "float32": 0.0, "float64": 0.0, "string": ""}

#: Non-zero defaults from the .msg files that rosbags' field definitions do not carry.
_DEFAULTS: dict[str, dict[str, Any]] = {"geometry_msgs/msg/Quaternion": {"w": 1.0}}


_lock = threading.RLock()
_classes: dict[str, type[IdlStruct]] = {}


def _annotation(desc: Any) -> tuple[Any, Callable[[], Any]]:
    """IDL annotation and default factory of one field descriptor."""
    kind, rest = desc
    if kind == Nodetype.BASE:
        base, bound = rest
        if base == "string":
            return (t.bounded_str[bound] if bound else str), str
        if base not in _BASE:
            msg = f"unsupported ROS type {base!r}"
            raise TypeError(msg)
        zero = _ZERO.get(base, 0)
        return _BASE[base], lambda: zero
    if kind == Nodetype.NAME:
        cls = get_class(rest)
        return cls, cls
    sub, size = rest
    sub_ann, sub_default = _annotation(sub)
    if sub[0] == Nodetype.BASE and sub[1][0] in _OCTETS:
        # cyclonedds deserializes 8-bit arrays/sequences as bytes; default to bytes as well.
        if kind == Nodetype.ARRAY:
            return t.array[sub_ann, size], lambda: bytes(size)
        return (t.sequence[sub_ann, size] if size else t.sequence[sub_ann]), bytes
    if kind == Nodetype.ARRAY:
        return t.array[sub_ann, size], lambda: [sub_default() for _ in range(size)]
    return (t.sequence[sub_ann, size] if size else t.sequence[sub_ann]), list


def make_struct(
    class_name: str, dds_name: str, fields: list[tuple[str, Any]], defaults: dict[str, Any] | None = None
) -> type[IdlStruct]:
    """Create a final IdlStruct dataclass; every field gets a default like rclpy messages have."""
    namespace = IdlMeta.__prepare__(class_name, (IdlStruct,), typename=dds_name)
    annotations = namespace.setdefault("__annotations__", {})
    for name, desc in fields or [("structure_needs_at_least_one_member", (Nodetype.BASE, ("uint8", 0)))]:
        ann, factory = _annotation(desc)
        if defaults and name in defaults:
            value = defaults[name]
            factory = lambda value=value: value  # noqa: E731
        annotations[name] = ann
        namespace[name] = dataclasses.field(default_factory=factory)
    namespace["__module__"] = __name__
    cls = IdlMeta(class_name, (IdlStruct,), namespace)
    return dataclasses.dataclass(cls)


def get_class(ros_name: str) -> type[IdlStruct]:
    """IdlStruct class for a message type ``pkg/msg/Name`` (or a service part ``pkg/srv/Name_Request``)."""
    with _lock:
        if ros_name in _classes:
            return _classes[ros_name]
        store = typestore()
        if ros_name not in store.fielddefs:
            msg = f"unknown ROS type {ros_name!r}"
            raise KeyError(msg)
        consts, fields = store.fielddefs[ros_name]
        pkg, kind, name = ros_name.split("/")
        # Service parts are never on the wire alone (the wire type adds the request header), so they keep
        # a distinct DDS name; the wire type uses the canonical one.
        dds_name = dds_type_name(ros_name) if kind == "msg" else f"{pkg}::{kind}::{name}"
        cls = make_struct(name, dds_name, list(fields), _DEFAULTS.get(ros_name))
        for cname, _ctype, value in consts:
            setattr(cls, cname, value)
        cls.__msgtype__ = ros_name  # type: ignore[attr-defined]
        cls.__typehash__ = type_hash(ros_name)  # type: ignore[attr-defined]
        _classes[ros_name] = cls
        return cls


def get_wire_class(ros_part: str) -> type[IdlStruct]:
    """Wire type of a request/reply: request header, then the fields (``pkg::srv::dds_::X_Request_``)."""
    key = "wire:" + ros_part
    with _lock:
        if key in _classes:
            return _classes[key]
        get_class(ros_part)  # make sure nested types exist and the name is known
        _consts, fields = typestore().fielddefs[ros_part]
        header = [
            (WIRE_HEADER[0], (Nodetype.BASE, ("uint64", 0))),
            (WIRE_HEADER[1], (Nodetype.BASE, ("int64", 0))),
        ]
        body = list(fields) or [("structure_needs_at_least_one_member", (Nodetype.BASE, ("uint8", 0)))]
        cls = make_struct(ros_part.split("/")[2] + "Wire", dds_type_name(ros_part), header + body)
        _classes[key] = cls
        return cls
