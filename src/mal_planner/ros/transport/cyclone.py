"""Built-in backend: ROS 2 nodes on plain Cyclone DDS, following rmw_cyclonedds_cpp conventions.

Topics ``/x`` are DDS topics ``rt/x`` (:mod:`._cyclone_topics`); services use ``rq/<name>Request`` and
``rr/<name>Reply`` with the ``{uint64 guid; int64 seq}`` request header (:mod:`._cyclone_services`). Every user
callback of a node runs on the thread that spins it (:mod:`._cyclone_executor`).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import mal_msgs_py

from ._common import (
    QOS_SERVICES,
    Parameter,
    ParameterStore,
    QoSProfile,
    SetParametersCallback,
    as_qos,
    load_params_file,
    make_logger,
    normalize_namespace,
    resolve_name,
)
from ._cyclone_context import CycloneContext, NodeEntities
from ._cyclone_executor import Executor, Timer
from ._cyclone_services import Client, Service
from ._cyclone_topics import Publisher, Subscription
from ._node_interfaces import NodeInterfaces

__all__ = ["Client", "CycloneNode", "MessageTypes", "Publisher", "Service", "Subscription", "Timer"]


class MessageTypes:
    """Message/service classes by ROS type name for this backend (``mal_msgs_py``)."""

    def msg(self, name: str) -> type:
        return mal_msgs_py.get_type(name)

    def srv(self, name: str) -> mal_msgs_py.ServiceType:
        return mal_msgs_py.get_srv(name)

    def __getitem__(self, name: str) -> Any:
        return self.srv(name) if "/srv/" in name else self.msg(name)


class CycloneNode:
    """A ROS 2 node on the built-in Cyclone DDS backend (see :func:`..create_node`)."""

    backend = "cyclone"

    def __init__(
        self,
        name: str,
        namespace: str = "",
        *,
        parameter_overrides: dict[str, Any] | None = None,
        params_file: str | Path | None = None,
        start_parameter_services: bool = True,
    ) -> None:
        self._name = name
        self._namespace = normalize_namespace(namespace)
        overrides = load_params_file(params_file, name, self._namespace) if params_file else {}
        overrides.update(parameter_overrides or {})
        self._params = ParameterStore(overrides)
        self._logger = make_logger(name, self._namespace)
        self.types = MessageTypes()
        self.context = CycloneContext.acquire()
        self._entities = NodeEntities(name, self._namespace)
        self._executor = Executor(self.context.participant, name, self._logger, self._finalize)
        self._lock = threading.RLock()
        self._publishers: list[Publisher] = []
        self.context.add_node(self._entities)
        self._interfaces: NodeInterfaces | None = None
        self._log_targets: list[logging.Logger] = []
        if start_parameter_services:
            self._interfaces = NodeInterfaces(self, self._params)
            self.forward_logs(self._logger.logger)
        # use_sim_time, as every rclpy node has it: the node's time is the last one received on /clock.
        self._sim_now: float | None = None
        if bool(self.declare_parameter("use_sim_time", bool(overrides.get("use_sim_time", False))).value):
            self.create_subscription("rosgraph_msgs/msg/Clock", "/clock", self._on_clock, QoSProfile(depth=1))

    # -- names, logging, parameters, time ------------------------------------------------------------
    def get_name(self) -> str:
        return self._name

    def get_namespace(self) -> str:
        return self._namespace

    def get_logger(self) -> Any:
        return self._logger

    def resolve(self, name: str) -> str:
        return resolve_name(name, self._namespace, self._name)

    def declare_parameter(self, name: str, default: Any = None, description: str = "",
                          value_range: tuple[float, float] | None = None) -> Parameter:
        param = self._params.declare(name, default, description, value_range)
        if self._interfaces is not None:
            self._interfaces.parameter_event(new=[param])
        return param

    def add_on_set_parameters_callback(self, callback: SetParametersCallback) -> None:
        """``callback(parameters) -> (successful, reason)`` runs before a parameter service sets parameters;
        a refusal leaves every value as it was and returns the reason to the caller."""
        self._params.callbacks.append(callback)

    def forward_logs(self, logger: logging.Logger) -> None:
        """Publish the records of the Python ``logger`` on /rosout as this node's (until shutdown)."""
        if self._interfaces is not None and logger not in self._log_targets:
            logger.addHandler(self._interfaces.rosout)
            self._log_targets.append(logger)

    def get_parameter(self, name: str) -> Parameter:
        return self._params.get(name)

    def has_parameter(self, name: str) -> bool:
        return self._params.has(name)

    def set_parameter(self, name: str, value: Any) -> None:
        self._params.set(name, value)
        if self._interfaces is not None:
            self._interfaces.parameter_event(changed=[self._params.get(name)])

    def _on_clock(self, msg: Any) -> None:
        self._sim_now = float(msg.clock.sec) + 1e-9 * float(msg.clock.nanosec)

    @property
    def uses_sim_time(self) -> bool:
        return bool(self.get_parameter("use_sim_time").value)

    def now(self) -> float:
        """The node's time [s since the epoch]: the wall clock, or with use_sim_time the last /clock (0 before)."""
        if self.uses_sim_time:
            return self._sim_now or 0.0
        return time.time()

    def time_msg(self, stamp: float | None = None) -> Any:
        """``builtin_interfaces/msg/Time`` for ``stamp`` (default: now)."""
        ns = time.time_ns() if stamp is None else int(round(stamp * 1e9))
        return self.types.msg("builtin_interfaces/msg/Time")(
            sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000
        )

    # -- entities -----------------------------------------------------------------------------------
    def _msg_cls(self, msg_type: str | type) -> type:
        return self.types.msg(msg_type) if isinstance(msg_type, str) else msg_type

    def _srv(self, srv_type: str | mal_msgs_py.ServiceType) -> mal_msgs_py.ServiceType:
        return self.types.srv(srv_type) if isinstance(srv_type, str) else srv_type

    def create_publisher(
        self, msg_type: str | type, topic: str, qos: QoSProfile | int | None = None
    ) -> Publisher:
        pub = Publisher(self.context, self._msg_cls(msg_type), self.resolve(topic), as_qos(qos))
        with self._lock:
            self._publishers.append(pub)
            self._entities.writers.append(pub.gid)
        self.context.publish_graph()
        return pub

    def create_subscription(
        self,
        msg_type: str | type,
        topic: str,
        callback: Callable[[Any], None],
        qos: QoSProfile | int | None = None,
    ) -> Subscription:
        sub = Subscription(self.context, self._msg_cls(msg_type), self.resolve(topic), callback, as_qos(qos))
        self._add_executable(sub, readers=[sub.gid], writers=[])
        return sub

    def create_service(
        self, srv_type: str | mal_msgs_py.ServiceType, name: str, callback: Callable[[Any, Any], Any],
        reentrant: bool = False, qos: QoSProfile | None = None,
    ) -> Service:
        """A service server. ``reentrant`` callbacks run on a worker thread of their own and may block
        (e.g. wait for a result computed elsewhere) without holding up the node's other callbacks."""
        srv = Service(self.context, self._srv(srv_type), self.resolve(name), callback, reentrant,
                      qos or QOS_SERVICES)
        self._add_executable(srv, readers=[srv.reader_gid], writers=[srv.writer_gid])
        return srv

    def create_client(self, srv_type: str | mal_msgs_py.ServiceType, name: str) -> Client:
        cli = Client(self.context, self._executor, self._srv(srv_type), self.resolve(name))
        self._add_executable(cli, readers=[cli.reader_gid], writers=[cli.writer_gid])
        return cli

    def create_timer(self, period_sec: float, callback: Callable[[], Any]) -> Timer:
        timer = Timer(period_sec, callback)
        self._executor.add_timer(timer)
        return timer

    def _add_executable(
        self, ent: Subscription | Service | Client, readers: list[bytes], writers: list[bytes]
    ) -> None:
        with self._lock:
            self._entities.readers.extend(readers)
            self._entities.writers.extend(writers)
        self._executor.add(ent)
        self.context.publish_graph()

    def destroy_entity(self, ent: Publisher | Subscription | Service | Client | Timer) -> None:
        """Destroy one publisher/subscription/service/client/timer of this node."""
        if isinstance(ent, Timer):
            self._executor.remove_timer(ent)
            return
        with self._lock:
            if isinstance(ent, Publisher):
                self._publishers.remove(ent)
                self._entities.writers.remove(ent.gid)
            else:
                self._executor.remove(ent)
                gids = [ent.gid] if isinstance(ent, Subscription) else [ent.reader_gid]
                self._entities.readers[:] = [g for g in self._entities.readers if g not in gids]
                if not isinstance(ent, Subscription):
                    self._entities.writers.remove(ent.writer_gid)
        self.context.publish_graph()
        ent.destroy()

    # -- executor ------------------------------------------------------------------------------------
    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Wait up to ``timeout_sec`` for work, then run every ready callback."""
        self._executor.spin_once(timeout_sec)

    def spin(self) -> None:
        """Run callbacks until :meth:`shutdown` (from another thread or a callback)."""
        self._executor.spin()

    def spin_until_future_complete(self, future: Future[Any], timeout_sec: float | None = None) -> None:
        self._executor.spin_until_future_complete(future, timeout_sec)

    def shutdown(self) -> None:
        """Destroy the node: stop spinning, delete its entities and update ros_discovery_info.

        Safe from a callback: the clean-up then runs when the current executor step ends.
        """
        if not self._executor.begin_shutdown():
            return
        if self._interfaces is not None:
            self._interfaces.rosout.close()
            for logger in self._log_targets:
                logger.removeHandler(self._interfaces.rosout)
        self._executor.finish_shutdown()

    def _finalize(self) -> None:
        """The executor's last step (its own entities are gone): the publishers, the graph entry, the context."""
        with self._lock:
            pubs, self._publishers = self._publishers, []
        for pub in pubs:
            pub.destroy()
        self.context.remove_node(self._entities)
        self.context.release()

    destroy_node = shutdown
    destroy = shutdown

    def __enter__(self) -> CycloneNode:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()
