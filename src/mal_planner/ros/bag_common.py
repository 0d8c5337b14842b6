"""The rosbag2 conventions of our bags shared by writing, recording, recovery and reading: topic types, QoS,
storages, and the one error type."""

from __future__ import annotations

import fnmatch
from typing import Any

from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer

import mal_msgs_py
from mal_planner.ros.transport import QOS_DEFAULT, QOS_LATCHED, QoSProfile

STATE_TYPE = "mal_msgs/msg/AircraftState"

#: Topic name patterns (relative, fnmatch) -> message type; first match wins.
TOPIC_TYPES: tuple[tuple[str, str], ...] = (
    ("aircraft/*/state", STATE_TYPE),
    ("aircraft/*/path", "nav_msgs/msg/Path"),
    ("radar/tracks", STATE_TYPE),
    ("landing_plan", "mal_msgs/msg/LandingPlan"),
    ("planner/markers", "visualization_msgs/msg/MarkerArray"),
    ("diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),
    ("airspace/no_fly_zones", "mal_msgs/msg/NoFlyZone"),
)
#: Types published latched (TRANSIENT_LOCAL) by our nodes; subscribe to them with QOS_LATCHED.
LATCHED_TYPES = frozenset({"nav_msgs/msg/Path", "mal_msgs/msg/LandingPlan", "visualization_msgs/msg/MarkerArray"})
STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
SUFFIX = {"mcap": ".mcap", "sqlite3": ".db3"}


class MsgTypes:
    """``node.types`` stand-in without a node: the ``mal_msgs_py`` classes (for writing bags directly)."""

    @staticmethod
    def msg(name: str) -> type:
        return mal_msgs_py.get_type(name)


class BagError(Exception):
    """A bag that cannot be written or read (the message names the file)."""


def topic_type(topic: str) -> str | None:
    """Message type of one of our topics (absolute or relative name, any namespace), or None."""
    name = topic.strip("/")
    for pattern, msgtype in TOPIC_TYPES:
        if fnmatch.fnmatchcase(name, pattern) or fnmatch.fnmatchcase(name, "*/" + pattern):
            return msgtype
    return None


def qos_for_type(msgtype: str) -> QoSProfile:
    """QoS our nodes use for a topic of this type (latched for plans, paths and markers)."""
    return QOS_LATCHED if msgtype in LATCHED_TYPES else QOS_DEFAULT


def bag_qos(profile: QoSProfile) -> list[Qos]:
    """rosbags ``offered_qos_profiles`` entry for one of our QoS profiles."""
    zero = QosTime(0, 0)
    return [
        Qos(
            QosHistory.KEEP_ALL if profile.keep_all else QosHistory.KEEP_LAST,
            profile.depth,
            QosReliability.RELIABLE if profile.reliable else QosReliability.BEST_EFFORT,
            QosDurability.TRANSIENT_LOCAL if profile.transient_local else QosDurability.VOLATILE,
            zero,
            zero,
            QosLiveliness.AUTOMATIC,
            zero,
            False,
        )
    ]


def add_topic(writer: Writer, topic: str, msgtype: str, qos: QoSProfile | None = None) -> Any:
    """Add a connection with the type's definition from our typestore; returns the rosbags Connection."""
    return writer.add_connection(
        topic, msgtype, typestore=mal_msgs_py.typestore(), offered_qos_profiles=bag_qos(qos or qos_for_type(msgtype))
    )
