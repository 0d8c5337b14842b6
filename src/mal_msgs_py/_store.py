"""rosbags typestore holding ROS 2 Jazzy standard types plus ours, and RIHS01 type hashes."""

from __future__ import annotations

import json
from functools import cache, lru_cache
from hashlib import sha256
from typing import TYPE_CHECKING, Any

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore

from ._interfaces import package_typesdicts

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

# rosidl type ids (type_description_interfaces/msg/FieldType). The .msg `char` is an IDL uint8 and `byte`
# an IDL octet, which is what rosidl hashes (checked against published Jazzy hashes).
_TYPE_IDS = {
    "int8": 2, "uint8": 3, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7, "int64": 8, "uint64": 9,
    "float32": 10, "float64": 11, "float128": 12, "char": 3, "bool": 15, "byte": 16, "string": 17,
    "wstring": 18,
}  # fmt: skip
_NESTED, _BOUNDED_STRING, _BOUNDED_WSTRING = 1, 21, 22
_ARRAY, _BOUNDED_SEQ, _UNBOUNDED_SEQ = 48, 96, 144


@lru_cache(maxsize=1)
def _build() -> tuple[Typestore, tuple[str, ...]]:
    store = get_typestore(Stores.ROS2_JAZZY)
    types, services = package_typesdicts()
    store.register(types)
    return store, tuple(services)


def typestore() -> Typestore:
    """rosbags typestore (ROS 2 Jazzy) with all mal_msgs and std_srvs types registered (for MCAP bags)."""
    return _build()[0]


def service_names() -> tuple[str, ...]:
    """Names of the services known to :func:`typestore` (``pkg/srv/Name``)."""
    return _build()[1]


def _field(name: str, desc: Any, refs: dict[str, dict[str, Any]], fielddefs: Any) -> dict[str, Any]:
    offset, capacity, string_capacity, nested = 0, 0, 0, ""
    kind, rest = desc
    if kind == Nodetype.ARRAY:
        (kind, rest), capacity = rest
        offset = _ARRAY
    elif kind == Nodetype.SEQUENCE:
        (kind, rest), capacity = rest
        offset = _BOUNDED_SEQ if capacity else _UNBOUNDED_SEQ
    if kind == Nodetype.NAME:
        type_id = offset + _NESTED
        nested = rest
        _struct(rest, refs, fielddefs)
    else:
        base, bound = rest
        if base in ("string", "wstring") and bound:
            string_capacity = bound
            type_id = offset + (_BOUNDED_STRING if base == "string" else _BOUNDED_WSTRING)
        else:
            type_id = offset + _TYPE_IDS[base]
    return {
        "name": name,
        "type": {
            "type_id": type_id,
            "capacity": capacity,
            "string_capacity": string_capacity,
            "nested_type_name": nested,
        },
    }


def _struct(typename: str, refs: dict[str, dict[str, Any]], fielddefs: Any) -> dict[str, Any]:
    if typename not in refs:
        refs[typename] = {}  # cycle guard; filled below
        fields = fielddefs[typename][1] or [
            ("structure_needs_at_least_one_member", (Nodetype.BASE, ("uint8", 0)))
        ]
        refs[typename] = {
            "type_name": typename,
            "fields": [_field(n, d, refs, fielddefs) for n, d in fields],
        }
    return refs[typename]


@cache
def _description(typename: str) -> str:
    fielddefs = typestore().fielddefs
    refs: dict[str, dict[str, Any]] = {}
    top = _struct(typename, refs, fielddefs)
    desc = {
        "type_description": top,
        "referenced_type_descriptions": [v for k, v in sorted(refs.items()) if k != typename],
    }
    return json.dumps(desc)


def type_description(typename: str) -> dict[str, Any]:
    """rosidl's hashed type description (``type_description``, ``referenced_type_descriptions``; fields with
    name and type, no default values), as served by ``type_description_interfaces/srv/GetTypeDescription``."""
    return json.loads(_description(typename))  # a fresh copy each time


@cache
def type_hash(typename: str) -> str:
    """RIHS01 hash (``RIHS01_<64 hex>``) of a message or service type, as ROS 2 Jazzy computes it."""
    return "RIHS01_" + sha256(_description(typename).encode()).hexdigest()
