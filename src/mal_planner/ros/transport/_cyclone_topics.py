"""Topics on the built-in backend: ROS topic ``/x`` is DDS topic ``rt/x``, with the type hash in USER_DATA."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader

from ._common import QoSProfile
from ._cyclone_context import CycloneContext, dds_qos, delete_entity
from ._cyclone_executor import Executor

ANY_SAMPLE = SampleState.Any | ViewState.Any | InstanceState.Any
_TAKE_BATCH = 64


def take_all(reader: DataReader[Any]) -> list[Any]:
    """Every valid sample waiting in ``reader`` (disposal notices and the like left out)."""
    out: list[Any] = []
    while True:
        batch = reader.take(N=_TAKE_BATCH)
        out.extend(
            s for s in batch if getattr(s, "sample_info", None) is not None and s.sample_info.valid_data
        )
        if len(batch) < _TAKE_BATCH:
            return out


def _topic_qos(cls: type, qos: QoSProfile) -> Any:
    return dds_qos(qos, f"typehash={cls.__typehash__};")  # type: ignore[attr-defined]


class Publisher:
    """Writer on ``rt/<topic>``; ``publish`` is thread-safe."""

    def __init__(self, ctx: CycloneContext, cls: type, topic: str, qos: QoSProfile) -> None:
        self.topic_name = topic
        self.msg_type = cls
        self._writer = DataWriter(ctx.participant, ctx.topic("rt" + topic, cls), qos=_topic_qos(cls, qos))
        self.gid = self._writer.guid.bytes

    def publish(self, msg: Any) -> None:
        self._writer.write(msg)

    def get_subscription_count(self) -> int:
        return len(self._writer.get_matched_subscriptions())

    def destroy(self) -> None:
        delete_entity(self._writer)


class Subscription:
    """Reader on ``rt/<topic>``; the callback runs on the node's executor."""

    def __init__(
        self, ctx: CycloneContext, cls: type, topic: str, callback: Callable[[Any], None], qos: QoSProfile
    ):
        self.topic_name = topic
        self.msg_type = cls
        self.callback = callback
        self._reader = DataReader(ctx.participant, ctx.topic("rt" + topic, cls), qos=_topic_qos(cls, qos))
        self.condition = ReadCondition(self._reader, ANY_SAMPLE)
        self.gid = self._reader.guid.bytes

    def get_publisher_count(self) -> int:
        return len(self._reader.get_matched_publications())

    def execute(self, executor: Executor) -> None:
        for sample in take_all(self._reader):
            executor.run_callback(self.callback, sample)

    def destroy(self) -> None:
        delete_entity(self.condition)
        delete_entity(self._reader)
