"""Names on the wire that the message classes and the package API share (rmw_cyclonedds_cpp conventions)."""

from __future__ import annotations

#: Leading request-header fields of rmw_cyclonedds service samples ({uint64 guid; int64 seq;}).
WIRE_HEADER = ("rmw_guid", "rmw_seq")


def dds_type_name(ros_name: str) -> str:
    """``pkg/msg/Name`` -> ``pkg::msg::dds_::Name_`` (the DDS type name rmw_cyclonedds_cpp uses)."""
    pkg, kind, name = ros_name.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"
