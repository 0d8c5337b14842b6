"""rclpy backend: a thin adapter giving rclpy nodes the same API as the built-in Cyclone backend.

Only imported when rclpy is importable (a sourced ROS 2 installation). Each node has its own rclpy
context (initialised from the environment when the node is created, so ROS_DOMAIN_ID/CYCLONEDDS_URI
changes apply to the next node; shut down with the node) and its own executor; its callbacks run one at a
time, like the built-in backend, except services created with ``reentrant=True``, which may block.
``call_async`` returns a ``concurrent.futures.Future`` on both backends.
"""

from __future__ import annotations

import importlib
import logging
import threading
import time
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.duration import Duration
from rclpy.executors import MultiThreadedExecutor
from rclpy.parameter import Parameter as RclpyParameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy
from rclpy.qos import QoSProfile as RclpyQoSProfile

from ._common import (
    QOS_ROSOUT,
    QOS_SERVICES,
    Parameter,
    QoSProfile,
    RosoutHandler,
    SetParametersCallback,
    as_qos,
    make_logger,
    node_fqn,
    normalize_namespace,
)


def to_rclpy_qos(qos: QoSProfile | int | None) -> RclpyQoSProfile:
    """Convert our profile to an rclpy QoSProfile."""
    profile = as_qos(qos)
    return RclpyQoSProfile(
        history=HistoryPolicy.KEEP_ALL if profile.keep_all else HistoryPolicy.KEEP_LAST,
        depth=profile.depth,
        reliability=ReliabilityPolicy.RELIABLE if profile.reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if profile.transient_local else DurabilityPolicy.VOLATILE,
        **({"lifespan": Duration(nanoseconds=int(profile.lifespan_s * 1e9))} if profile.lifespan_s > 0 else {}),
    )


class RclpyTypes:
    """Message/service classes by ROS type name, imported from the generated Python packages."""

    bytes_for_byte = True  # a `byte` field takes bytes of length 1 (see ros/convert.py byte_field)

    def msg(self, name: str) -> type:
        pkg, _, cls = _split(name, "msg")
        return getattr(importlib.import_module(f"{pkg}.msg"), cls)

    def srv(self, name: str) -> Any:
        pkg, _, cls = _split(name, "srv")
        return getattr(importlib.import_module(f"{pkg}.srv"), cls)

    def __getitem__(self, name: str) -> Any:
        return self.srv(name) if "/srv/" in name else self.msg(name)


def _split(name: str, kind: str) -> tuple[str, str, str]:
    parts = name.strip("/").split("/")
    if len(parts) == 2:
        parts = [parts[0], kind, parts[1]]
    return parts[0], parts[1], parts[2]


class RclpyClient:
    """Client wrapper whose ``call`` works whether or not another thread spins the node."""

    def __init__(self, node: RclpyNode, client: Any) -> None:
        self._node = node
        self.client = client

    def service_is_ready(self) -> bool:
        return bool(self.client.service_is_ready())

    def wait_for_service(self, timeout_sec: float | None = None) -> bool:
        return bool(self.client.wait_for_service(timeout_sec=timeout_sec))

    def call_async(self, request: Any) -> Future[Any]:
        """Send a request; the ``concurrent.futures.Future`` completes when the node's executor takes the
        reply (as on the built-in backend: ``result(timeout=...)`` works; cancelling drops the request)."""
        future: Future[Any] = Future()
        inner = self.client.call_async(request)

        def done(f: Any) -> None:
            if f.cancelled():
                future.cancel()
            elif future.set_running_or_notify_cancel():
                exc = f.exception()
                future.set_exception(exc) if exc is not None else future.set_result(f.result())

        def cancelled(f: Future[Any]) -> None:
            if f.cancelled():
                self.client.remove_pending_request(inner)

        inner.add_done_callback(done)
        future.add_done_callback(cancelled)
        return future

    def call(self, request: Any, timeout_sec: float | None = None) -> Any:
        if self._node._executor_thread == threading.get_ident():
            msg = "Client.call() from a callback would deadlock; use call_async()"
            raise RuntimeError(msg)
        future = self.client.call_async(request)
        done = threading.Event()
        future.add_done_callback(lambda _f: done.set())
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not done.is_set():
            left = 0.05 if deadline is None else min(0.05, deadline - time.monotonic())
            if left <= 0:
                self.client.remove_pending_request(future)
                msg = f"service {self.client.srv_name} did not answer within {timeout_sec} s"
                raise TimeoutError(msg)
            if not self._node._spin_some(left):
                done.wait(left)
        return future.result()

    def destroy(self) -> None:
        self._node.node.destroy_client(self.client)


class RclpyNode:
    """An rclpy node behind the transport API (see :func:`..create_node`)."""

    backend = "rclpy"

    def __init__(
        self,
        name: str,
        namespace: str = "",
        *,
        parameter_overrides: dict[str, Any] | None = None,
        params_file: str | Path | None = None,
        start_parameter_services: bool = True,
    ) -> None:
        self._context = rclpy.Context()
        rclpy.init(context=self._context)  # reads ROS_DOMAIN_ID, CYCLONEDDS_URI now
        cli_args = ["--ros-args", "--params-file", str(params_file)] if params_file else None
        self.node = rclpy.create_node(
            name,
            namespace=normalize_namespace(namespace),
            context=self._context,
            parameter_overrides=[RclpyParameter(k, value=v) for k, v in (parameter_overrides or {}).items()],
            cli_args=cli_args,
            start_parameter_services=start_parameter_services,
        )
        self.types = RclpyTypes()
        self._logger = make_logger(name, namespace)
        # Callbacks of the node's default (mutually exclusive) group still run one at a time; only the
        # services created with reentrant=True run beside them on the executor's second thread.
        self._executor = MultiThreadedExecutor(num_threads=2, context=self._context)
        self._executor.add_node(self.node)
        rosout = self.node.create_publisher(self.types.msg("rcl_interfaces/msg/Log"), "/rosout",
                                            to_rclpy_qos(QOS_ROSOUT))
        self._rosout = RosoutHandler(node_fqn(name, namespace).strip("/").replace("/", "."),
                                     self.types.msg("rcl_interfaces/msg/Log"), self.time_msg, rosout.publish)
        self._log_targets: list[logging.Logger] = []
        self.forward_logs(self._logger.logger)
        self._reentrant_group = ReentrantCallbackGroup()
        self._spin_lock = threading.Lock()
        self._executor_thread: int | None = None
        self._destroyed = False

    def get_name(self) -> str:
        return str(self.node.get_name())

    def get_namespace(self) -> str:
        return str(self.node.get_namespace())

    def get_logger(self) -> Any:
        return self._logger

    def resolve(self, name: str) -> str:
        return str(self.node.resolve_topic_name(name))

    def declare_parameter(self, name: str, default: Any = None, description: str = "",
                          value_range: tuple[float, float] | None = None) -> Parameter:
        """Declare with a descriptor (``value_range``: an inclusive integer or floating-point range, which rclpy
        enforces on sets). An override that rclpy refuses (another type, out of range) does not stop the node:
        it is returned as given, for the node's own check to report and replace, as on the built-in backend."""
        from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException

        descriptor = ParameterDescriptor(description=description)
        if value_range is not None and isinstance(default, bool):
            pass
        elif value_range is not None and isinstance(default, int):
            descriptor.integer_range = [IntegerRange(from_value=int(value_range[0]), to_value=int(value_range[1]))]
        elif value_range is not None and isinstance(default, float):
            descriptor.floating_point_range = [FloatingPointRange(from_value=float(value_range[0]),
                                                                  to_value=float(value_range[1]))]
        try:
            param = self.node.declare_parameter(name, default, descriptor)
        except InvalidParameterTypeException:
            # A params file with another type than the default (e.g. the former `figures: false`): let the
            # node's own check (node_params) decide, as the built-in backend does.
            descriptor.dynamic_typing = True
            descriptor.integer_range, descriptor.floating_point_range = [], []
            param = self.node.declare_parameter(name, default, descriptor)
        except InvalidParameterValueException:  # outside the range: declared at the default, reported by the node
            override = self.node._parameter_overrides.get(name)  # rclpy keeps the file's values there
            self.node.declare_parameter(name, default, descriptor, ignore_override=True)
            return Parameter(name, default if override is None else override.value)
        return Parameter(name, param.value)

    def add_on_set_parameters_callback(self, callback: SetParametersCallback) -> None:
        """``callback(parameters) -> (successful, reason)`` before parameters are set (rclpy's on-set hook)."""

        def hook(params: list[RclpyParameter]) -> SetParametersResult:
            ok, reason = callback([Parameter(p.name, p.value) for p in params])
            return SetParametersResult(successful=ok, reason=reason)

        self.node.add_on_set_parameters_callback(hook)

    def forward_logs(self, logger: logging.Logger) -> None:
        """Publish the records of the Python ``logger`` on /rosout as this node's (until shutdown)."""
        if logger not in self._log_targets:
            logger.addHandler(self._rosout)
            self._log_targets.append(logger)

    def get_parameter(self, name: str) -> Parameter:
        return Parameter(name, self.node.get_parameter(name).value)

    def has_parameter(self, name: str) -> bool:
        return bool(self.node.has_parameter(name))

    def set_parameter(self, name: str, value: Any) -> None:
        self.node.set_parameters([RclpyParameter(name, value=value)])

    @property
    def uses_sim_time(self) -> bool:
        return bool(self.node.get_parameter("use_sim_time").value)

    def now(self) -> float:
        return float(self.node.get_clock().now().nanoseconds) * 1e-9

    def time_msg(self, stamp: float | None = None) -> Any:
        ns = self.node.get_clock().now().nanoseconds if stamp is None else int(round(stamp * 1e9))
        return self.types.msg("builtin_interfaces/msg/Time")(
            sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000
        )

    def _cls(self, t: str | type, kind: str) -> Any:
        return (self.types.srv(t) if kind == "srv" else self.types.msg(t)) if isinstance(t, str) else t

    def create_publisher(self, msg_type: str | type, topic: str, qos: QoSProfile | int | None = None) -> Any:
        return self.node.create_publisher(self._cls(msg_type, "msg"), topic, to_rclpy_qos(qos))

    def create_subscription(self, msg_type: str | type, topic: str, callback: Any, qos: Any = None) -> Any:
        return self.node.create_subscription(self._cls(msg_type, "msg"), topic, callback, to_rclpy_qos(qos))

    def create_service(self, srv_type: str | type, name: str, callback: Any, reentrant: bool = False,
                       qos: QoSProfile | None = None) -> Any:
        srv = self._cls(srv_type, "srv")
        group = self._reentrant_group if reentrant else None
        return self.node.create_service(srv, name, callback, qos_profile=to_rclpy_qos(qos or QOS_SERVICES),
                                        callback_group=group)

    def create_client(self, srv_type: str | type, name: str) -> RclpyClient:
        return RclpyClient(self, self.node.create_client(self._cls(srv_type, "srv"), name))

    def create_timer(self, period_sec: float, callback: Any) -> Any:
        """A timer on the steady (wall) clock, as on the built-in backend: our timers schedule housekeeping, which
        must go on while a simulator holds /clock (rclpy's default, the ROS clock, stops with use_sim_time)."""
        from rclpy.clock import Clock, ClockType

        return self.node.create_timer(period_sec, callback, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def destroy_entity(self, ent: Any) -> None:
        if isinstance(ent, RclpyClient):
            ent.destroy()
            return
        for fn in ("destroy_publisher", "destroy_subscription", "destroy_service", "destroy_timer"):
            if getattr(self.node, fn)(ent):
                return

    def _spin_some(self, timeout_sec: float) -> bool:
        if not self._spin_lock.acquire(blocking=False):
            return False
        try:
            if self._destroyed:
                self._finalize()
                return True
            self._executor_thread = threading.get_ident()
            self._executor.spin_once(timeout_sec=timeout_sec)
            if self._destroyed:
                self._finalize()
        finally:
            self._executor_thread = None
            self._spin_lock.release()
        return True

    def spin_once(self, timeout_sec: float | None = None) -> None:
        if self._destroyed:
            return
        if not self._spin_some(3600.0 if timeout_sec is None else timeout_sec):
            msg = "node is already spinning in another thread"
            raise RuntimeError(msg)

    def spin(self) -> None:
        while not self._destroyed and self._context.ok():
            self.spin_once(0.5)

    def spin_until_future_complete(self, future: Any, timeout_sec: float | None = None) -> None:
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not future.done() and not self._destroyed:
            left = 0.1 if deadline is None else min(0.1, deadline - time.monotonic())
            if left <= 0:
                return
            self.spin_once(left)

    def shutdown(self) -> None:
        """Destroy the node and shut its context down (safe from a callback: then at the end of the step)."""
        if self._destroyed:
            return
        self._destroyed = True
        self._rosout.close()
        for logger in self._log_targets:
            logger.removeHandler(self._rosout)
        if self._executor_thread == threading.get_ident():
            return  # _spin_some finishes the clean-up when the current callback returns
        with self._spin_lock:
            self._finalize()

    def _finalize(self) -> None:
        if self._context.ok():
            self._executor.remove_node(self.node)
            self.node.destroy_node()
            self._executor.shutdown(timeout_sec=1.0)
            self._context.try_shutdown()

    destroy_node = shutdown
    destroy = shutdown

    def __enter__(self) -> RclpyNode:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()
