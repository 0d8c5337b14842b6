"""Process-wide Cyclone DDS state shared by the built-in backend's nodes (like an rmw context).

One DomainParticipant per domain id with USER_DATA ``enclave=/;`` and a ``ros_discovery_info`` writer
(rmw_dds_common ParticipantEntitiesInfo, RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1) that lists our nodes
with the GIDs of their readers and writers, so that ROS 2 tools see them under their names.
"""

from __future__ import annotations

import os
import threading
from typing import Any

from cyclonedds.core import Entity, Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.topic import Topic
from cyclonedds.util import duration

import mal_msgs_py

from ._common import QoSProfile

DISCOVERY_TOPIC = "ros_discovery_info"
DISCOVERY_TYPE = "rmw_dds_common/msg/ParticipantEntitiesInfo"


def dds_qos(profile: QoSProfile, user_data: str) -> Qos:
    """DDS QoS for a ROS profile, XCDR1 data representation and the given USER_DATA."""
    lifespan = [Policy.Lifespan(duration(seconds=profile.lifespan_s))] if profile.lifespan_s > 0 else []
    return Qos(
        *lifespan,
        Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100))
        if profile.reliable
        else Policy.Reliability.BestEffort,
        Policy.Durability.TransientLocal if profile.transient_local else Policy.Durability.Volatile,
        Policy.History.KeepAll if profile.keep_all else Policy.History.KeepLast(depth=profile.depth),
        Policy.DataRepresentation(use_cdrv0_representation=True),
        Policy.Userdata(data=user_data.encode()),
    )


def delete_entity(entity: Entity | None) -> None:
    """Delete a cyclonedds entity now instead of at garbage collection."""
    if entity is not None:
        entity.__del__()


class NodeEntities:
    """Reader/writer GIDs of one node for ros_discovery_info."""

    def __init__(self, name: str, namespace: str) -> None:
        self.name = name
        self.namespace = namespace
        self.readers: list[bytes] = []
        self.writers: list[bytes] = []


class CycloneContext:
    """Participant, topic cache and graph publication of one domain."""

    _lock = threading.Lock()
    _instances: dict[int, CycloneContext] = {}

    def __init__(self, domain_id: int) -> None:
        self.domain_id = domain_id
        self.participant = DomainParticipant(domain_id, qos=Qos(Policy.Userdata(data=b"enclave=/;")))
        self.gid = self.participant.guid.bytes
        self.lock = threading.RLock()
        self._topics: dict[str, Topic[Any]] = {}
        self._nodes: list[NodeEntities] = []
        self._refs = 0
        self._csid = 0
        pei = mal_msgs_py.get_type(DISCOVERY_TYPE)
        self._pei_cls = pei
        self._gid_cls = mal_msgs_py.get_type("rmw_dds_common/msg/Gid")
        self._nei_cls = mal_msgs_py.get_type("rmw_dds_common/msg/NodeEntitiesInfo")
        from cyclonedds.pub import DataWriter

        qos = dds_qos(QoSProfile(depth=1, transient_local=True), f"typehash={pei.__typehash__};")
        self._discovery_writer = DataWriter(self.participant, self.topic(DISCOVERY_TOPIC, pei), qos=qos)

    @classmethod
    def acquire(cls) -> CycloneContext:
        """Context of ``$ROS_DOMAIN_ID`` (default 0); reference counted by nodes."""
        domain_id = int(os.environ.get("ROS_DOMAIN_ID", "0") or 0)
        with cls._lock:
            ctx = cls._instances.get(domain_id)
            if ctx is None:
                ctx = cls._instances[domain_id] = CycloneContext(domain_id)
            ctx._refs += 1
            return ctx

    def release(self) -> None:
        """Drop one reference; the last one deletes the participant and everything in it."""
        with CycloneContext._lock:
            self._refs -= 1
            if self._refs > 0:
                return
            CycloneContext._instances.pop(self.domain_id, None)
        self._topics.clear()
        delete_entity(self._discovery_writer)
        delete_entity(self.participant)

    def topic(self, name: str, cls: type) -> Topic[Any]:
        """Topic ``name`` of type ``cls``, created once per participant."""
        with self.lock:
            topic = self._topics.get(name)
            if topic is None:
                topic = self._topics[name] = Topic(self.participant, name, cls)
            elif topic.data_type is not cls:
                msg = f"topic {name!r} already exists with type {topic.data_type.__name__}"
                raise TypeError(msg)
            return topic

    def next_client_service_id(self) -> bytes:
        """Unique 16-byte client/service id: participant GUID prefix + big-endian counter (rmw_cyclonedds)."""
        with self.lock:
            self._csid += 1
            return self.gid[:12] + self._csid.to_bytes(4, "big")

    def add_node(self, node: NodeEntities) -> None:
        with self.lock:
            self._nodes.append(node)
        self.publish_graph()

    def remove_node(self, node: NodeEntities) -> None:
        with self.lock:
            if node in self._nodes:
                self._nodes.remove(node)
        self.publish_graph()

    def publish_graph(self) -> None:
        """Write the ParticipantEntitiesInfo sample describing all our nodes."""
        with self.lock:
            infos = [
                self._nei_cls(
                    node_namespace=n.namespace,
                    node_name=n.name,
                    reader_gid_seq=[self._gid_cls(data=g) for g in n.readers],
                    writer_gid_seq=[self._gid_cls(data=g) for g in n.writers],
                )
                for n in self._nodes
            ]
            self._discovery_writer.write(
                self._pei_cls(gid=self._gid_cls(data=self.gid), node_entities_info_seq=infos)
            )


def csid_to_string(csid: bytes) -> str:
    """Client/service id as rmw_cyclonedds writes it into USER_DATA (hex bytes joined by '.')."""
    return f"{csid[0]:2x}" + "".join(f".{b:x}" for b in csid[1:])


def parse_user_data(data: bytes | None) -> dict[str, str]:
    """``key=value;`` pairs of an endpoint's USER_DATA."""
    out: dict[str, str] = {}
    for item in (data or b"").decode(errors="replace").split(";"):
        key, sep, value = item.partition("=")
        if sep:
            out[key.strip()] = value
    return out
