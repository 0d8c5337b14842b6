"""What the standard node interfaces need of a node (so that they do not depend on a backend's node class)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from ._common import QoSProfile


class MessageTypeSource(Protocol):
    """Message classes by ROS type name (``node.types``)."""

    def msg(self, name: str) -> type: ...


class InterfaceHost(Protocol):
    """The part of a node's API that :class:`._node_interfaces.NodeInterfaces` uses."""

    types: MessageTypeSource

    def get_name(self) -> str: ...

    def get_namespace(self) -> str: ...

    def time_msg(self, stamp: float | None = None) -> Any: ...

    def create_publisher(self, msg_type: str | type, topic: str, qos: QoSProfile | int | None = None) -> Any: ...

    def create_service(self, srv_type: Any, name: str, callback: Callable[[Any, Any], Any],
                       reentrant: bool = False, qos: QoSProfile | None = None) -> Any: ...
