"""Built-in backend: ROS 2 nodes on plain Cyclone DDS, following rmw_cyclonedds_cpp conventions.

Topics ``/x`` are DDS topics ``rt/x``; services use ``rq/<name>Request`` and ``rr/<name>Reply`` with the
``{uint64 guid; int64 seq}`` request header. Every user callback of a node runs on the thread that spins it.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

from cyclonedds.core import GuardCondition, InstanceState, ReadCondition, SampleState, ViewState, WaitSet
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.util import duration

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
from ._cyclone_context import (
    CycloneContext,
    NodeEntities,
    csid_to_string,
    dds_qos,
    delete_entity,
    parse_user_data,
)
from ._node_interfaces import NodeInterfaces

_ANY = SampleState.Any | ViewState.Any | InstanceState.Any
_TAKE_BATCH = 64
_request_seq = itertools.count(1)  # process-wide, like rmw_cyclonedds' next_request_id


def _fields(obj: Any) -> dict[str, Any]:
    return {name: getattr(obj, name) for name in obj.__dataclass_fields__}


def _take_all(reader: DataReader[Any]) -> list[Any]:
    out: list[Any] = []
    while True:
        batch = reader.take(N=_TAKE_BATCH)
        out.extend(
            s for s in batch if getattr(s, "sample_info", None) is not None and s.sample_info.valid_data
        )
        if len(batch) < _TAKE_BATCH:
            return out


class MessageTypes:
    """Message/service classes by ROS type name for this backend (``mal_msgs_py``)."""

    def msg(self, name: str) -> type:
        return mal_msgs_py.get_type(name)

    def srv(self, name: str) -> mal_msgs_py.ServiceType:
        return mal_msgs_py.get_srv(name)

    def __getitem__(self, name: str) -> Any:
        return self.srv(name) if "/srv/" in name else self.msg(name)


class Publisher:
    """Writer on ``rt/<topic>``; ``publish`` is thread-safe."""

    def __init__(self, node: CycloneNode, cls: type, topic: str, qos: QoSProfile) -> None:
        self.topic_name = topic
        self.msg_type = cls
        ctx = node.context
        self._writer = DataWriter(
            ctx.participant, ctx.topic("rt" + topic, cls), qos=dds_qos(qos, f"typehash={cls.__typehash__};")
        )
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
        self, node: CycloneNode, cls: type, topic: str, callback: Callable[[Any], None], qos: QoSProfile
    ):
        self.topic_name = topic
        self.msg_type = cls
        self.callback = callback
        ctx = node.context
        self._reader = DataReader(
            ctx.participant, ctx.topic("rt" + topic, cls), qos=dds_qos(qos, f"typehash={cls.__typehash__};")
        )
        self.condition = ReadCondition(self._reader, _ANY)
        self.gid = self._reader.guid.bytes

    def get_publisher_count(self) -> int:
        return len(self._reader.get_matched_publications())

    def _execute(self, node: CycloneNode) -> None:
        for sample in _take_all(self._reader):
            node._run_callback(self.callback, sample)

    def destroy(self) -> None:
        delete_entity(self.condition)
        delete_entity(self._reader)


class _ServiceEndpoints:
    """Request/reply reader+writer pair of a service or a client, with the rmw_cyclonedds USER_DATA."""

    def __init__(self, node: CycloneNode, srv: mal_msgs_py.ServiceType, name: str, is_service: bool,
                 profile: QoSProfile = QOS_SERVICES) -> None:
        ctx = node.context
        self.srv = srv
        self.service_name = name
        self.csid = ctx.next_client_service_id()
        key = "serviceid" if is_service else "clientid"
        qos = dds_qos(profile, f"{key}={csid_to_string(self.csid)};typehash={srv.type_hash};")
        req_topic = ctx.topic(f"rq{name}Request", srv.WireRequest)
        rep_topic = ctx.topic(f"rr{name}Reply", srv.WireResponse)
        if is_service:
            self.reader = DataReader(ctx.participant, req_topic, qos=qos)
            self.writer = DataWriter(ctx.participant, rep_topic, qos=qos)
        else:
            self.writer = DataWriter(ctx.participant, req_topic, qos=qos)
            self.reader = DataReader(ctx.participant, rep_topic, qos=qos)
        self.condition = ReadCondition(self.reader, _ANY)
        self.reader_gid = self.reader.guid.bytes
        self.writer_gid = self.writer.guid.bytes

    def destroy(self) -> None:
        delete_entity(self.condition)
        delete_entity(self.reader)
        delete_entity(self.writer)


class Service(_ServiceEndpoints):
    """Service server; ``callback(request, response) -> response`` runs on the node's executor."""

    def __init__(
        self, node: CycloneNode, srv: mal_msgs_py.ServiceType, name: str, callback: Callable[..., Any],
        reentrant: bool = False, qos: QoSProfile = QOS_SERVICES,
    ):
        super().__init__(node, srv, name, is_service=True, profile=qos)
        self.callback = callback
        self.reentrant = reentrant

    def _client_reader_matched(self, publication_handle: int) -> bool | None:
        """rmw_send_response's check: True/None (send) once the client's reply reader is matched."""
        endpoint = self.reader.get_matched_publication_data(publication_handle)
        if endpoint is None:
            return None  # client gone
        clientid = parse_user_data(_user_data(endpoint)).get("clientid")
        if clientid is None:
            return True  # backwards compatibility: no client id, assume all is well
        for handle in self.writer.get_matched_subscriptions():
            sub = self.writer.get_matched_subscription_data(handle)
            if sub is not None and parse_user_data(_user_data(sub)).get("clientid") == clientid:
                return True
        return False

    def _execute(self, node: CycloneNode) -> None:
        for wire in _take_all(self.reader):
            if self.reentrant:  # may block (e.g. wait for a long computation): off the executor thread
                node._service_pool().submit(self._handle, node, wire)
            else:
                self._handle(node, wire)

    def _handle(self, node: CycloneNode, wire: Any) -> None:
        body = _fields(wire)
        guid, seq = body.pop(mal_msgs_py.WIRE_HEADER[0]), body.pop(mal_msgs_py.WIRE_HEADER[1])
        request = self.srv.Request(**body)
        response = node._run_callback(self.callback, request, self.srv.Response())
        if response is None:
            node.get_logger().error("service %s: callback returned no response", self.service_name)
            return
        deadline = time.monotonic() + 0.1
        state = self._client_reader_matched(wire.sample_info.publication_handle)
        while state is False and time.monotonic() < deadline:
            time.sleep(0.005)
            state = self._client_reader_matched(wire.sample_info.publication_handle)
        if state is None or node._destroyed:
            return
        header = dict(zip(mal_msgs_py.WIRE_HEADER, (guid, seq), strict=True))
        self.writer.write(self.srv.WireResponse(**header, **_fields(response)))


def _user_data(endpoint: Any) -> bytes | None:
    from cyclonedds.core import Policy

    policy = endpoint.qos[Policy.Userdata] if endpoint.qos is not None else None
    return policy.data if policy is not None else None


class Client(_ServiceEndpoints):
    """Service client; replies are matched on the request writer's instance handle and sequence number."""

    def __init__(self, node: CycloneNode, srv: mal_msgs_py.ServiceType, name: str) -> None:
        super().__init__(node, srv, name, is_service=False)
        self._node = node
        self._guid = self.writer.instance_handle & 0xFFFFFFFFFFFFFFFF  # uint64 on the wire
        self._pending: dict[int, Future[Any]] = {}
        self._lock = threading.Lock()

    def service_is_ready(self) -> bool:
        """Request writer and reply reader are both matched (nothing is kept for late joiners)."""
        return bool(self.writer.get_matched_subscriptions()) and bool(self.reader.get_matched_publications())

    def wait_for_service(self, timeout_sec: float | None = None) -> bool:
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not self.service_is_ready():
            if deadline is not None and time.monotonic() >= deadline:
                return False
            time.sleep(0.01)
        return True

    def call_async(self, request: Any) -> Future[Any]:
        """Send a request; the future completes when the executor takes the reply."""
        seq = next(_request_seq)
        future: Future[Any] = Future()
        with self._lock:
            self._pending[seq] = future
        header = dict(zip(mal_msgs_py.WIRE_HEADER, (self._guid, seq), strict=True))
        self.writer.write(self.srv.WireRequest(**header, **_fields(request)))
        self._node._wake()
        return future

    def call(self, request: Any, timeout_sec: float | None = None) -> Any:
        """Blocking call. Spins the node itself when no other thread does; raises TimeoutError."""
        if self._node._executor_thread == threading.get_ident():
            msg = "Client.call() from a callback would deadlock; use call_async()"
            raise RuntimeError(msg)
        future = self.call_async(request)
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not future.done():
            left = 0.05 if deadline is None else min(0.05, deadline - time.monotonic())
            if left <= 0:
                self._cancel(future)
                msg = f"service {self.service_name} did not answer within {timeout_sec} s"
                raise TimeoutError(msg)
            if not self._node._spin_some(left):
                with contextlib.suppress(TimeoutError):
                    future.result(timeout=left)
        return future.result()

    def _cancel(self, future: Future[Any]) -> None:
        with self._lock:
            for seq, fut in list(self._pending.items()):
                if fut is future:
                    del self._pending[seq]
        future.cancel()

    def _execute(self, node: CycloneNode) -> None:
        for wire in _take_all(self.reader):
            body = _fields(wire)
            guid, seq = body.pop(mal_msgs_py.WIRE_HEADER[0]), body.pop(mal_msgs_py.WIRE_HEADER[1])
            if guid != self._guid:
                continue
            with self._lock:
                future = self._pending.pop(seq, None)
            if future is not None and future.set_running_or_notify_cancel():
                node._run_callback(future.set_result, self.srv.Response(**body))


class Timer:
    """Periodic timer run by the node's executor."""

    def __init__(self, period_sec: float, callback: Callable[[], Any]) -> None:
        self.timer_period_ns = int(period_sec * 1e9)
        self.period = period_sec
        self.callback = callback
        self.next_due = time.monotonic() + period_sec
        self._canceled = False

    def cancel(self) -> None:
        self._canceled = True

    def is_canceled(self) -> bool:
        return self._canceled

    def reset(self) -> None:
        self._canceled = False
        self.next_due = time.monotonic() + self.period


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
        self._waitset = WaitSet(self.context.participant)
        self._guard = GuardCondition(self.context.participant)
        self._waitset.attach(self._guard)
        self._lock = threading.RLock()
        self._spin_lock = threading.Lock()
        self._executor_thread: int | None = None
        self._executables: list[Subscription | Service | Client] = []
        self._publishers: list[Publisher] = []
        self._timers: list[Timer] = []
        self._reentrant_pool: ThreadPoolExecutor | None = None
        self._destroyed = False
        self._finalized = False
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
        pub = Publisher(self, self._msg_cls(msg_type), self.resolve(topic), as_qos(qos))
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
        sub = Subscription(self, self._msg_cls(msg_type), self.resolve(topic), callback, as_qos(qos))
        self._add_executable(sub, readers=[sub.gid], writers=[])
        return sub

    def create_service(
        self, srv_type: str | mal_msgs_py.ServiceType, name: str, callback: Callable[[Any, Any], Any],
        reentrant: bool = False, qos: QoSProfile | None = None,
    ) -> Service:
        """A service server. ``reentrant`` callbacks run on a worker thread of their own and may block
        (e.g. wait for a result computed elsewhere) without holding up the node's other callbacks."""
        srv = Service(self, self._srv(srv_type), self.resolve(name), callback, reentrant, qos or QOS_SERVICES)
        self._add_executable(srv, readers=[srv.reader_gid], writers=[srv.writer_gid])
        return srv

    def create_client(self, srv_type: str | mal_msgs_py.ServiceType, name: str) -> Client:
        cli = Client(self, self._srv(srv_type), self.resolve(name))
        self._add_executable(cli, readers=[cli.reader_gid], writers=[cli.writer_gid])
        return cli

    def create_timer(self, period_sec: float, callback: Callable[[], Any]) -> Timer:
        timer = Timer(period_sec, callback)
        with self._lock:
            self._timers.append(timer)
        self._wake()
        return timer

    def _add_executable(
        self, ent: Subscription | Service | Client, readers: list[bytes], writers: list[bytes]
    ):
        with self._lock:
            self._executables.append(ent)
            self._entities.readers.extend(readers)
            self._entities.writers.extend(writers)
            self._waitset.attach(ent.condition)
        self.context.publish_graph()
        self._wake()

    def destroy_entity(self, ent: Publisher | Subscription | Service | Client | Timer) -> None:
        """Destroy one publisher/subscription/service/client/timer of this node."""
        with self._lock:
            if isinstance(ent, Timer):
                ent.cancel()
                if ent in self._timers:
                    self._timers.remove(ent)
                return
            if isinstance(ent, Publisher):
                self._publishers.remove(ent)
                self._entities.writers.remove(ent.gid)
            else:
                self._executables.remove(ent)
                self._waitset.detach(ent.condition)
                gids = [ent.gid] if isinstance(ent, Subscription) else [ent.reader_gid]
                self._entities.readers[:] = [g for g in self._entities.readers if g not in gids]
                if not isinstance(ent, Subscription):
                    self._entities.writers.remove(ent.writer_gid)
        self.context.publish_graph()
        ent.destroy()

    # -- executor ------------------------------------------------------------------------------------
    def _wake(self) -> None:
        self._guard.set(True)

    def _service_pool(self) -> ThreadPoolExecutor:
        with self._lock:
            if self._reentrant_pool is None:
                self._reentrant_pool = ThreadPoolExecutor(max_workers=4, thread_name_prefix=f"{self._name}-srv")
            return self._reentrant_pool

    def _run_callback(self, fn: Callable[..., Any], *args: Any) -> Any:
        try:
            return fn(*args)
        except Exception:  # keep the node alive, like a service that must not die on one bad request
            self._logger.exception("exception in callback %r", getattr(fn, "__qualname__", fn))
            return None

    def _spin_some(self, timeout_sec: float) -> bool:
        """One executor step if no other thread is spinning; False when another thread owns the executor."""
        if not self._spin_lock.acquire(blocking=False):
            return False
        try:
            if self._destroyed:
                self._finalize()
                return True
            self._executor_thread = threading.get_ident()
            self._step(timeout_sec)
            if self._destroyed:  # shutdown() was called from a callback
                self._finalize()
        finally:
            self._executor_thread = None
            self._spin_lock.release()
        return True

    def _step(self, timeout_sec: float | None) -> None:
        with self._lock:
            timers = [t for t in self._timers if not t.is_canceled()]
            executables = list(self._executables)
        now = time.monotonic()
        wait = 3600.0 if timeout_sec is None else max(0.0, timeout_sec)
        if timers:
            wait = min(wait, max(0.0, min(t.next_due for t in timers) - now))
        if wait > 0:
            self._waitset.wait(duration(seconds=wait))
        self._guard.take()
        for ent in executables:
            if not self._destroyed:
                ent._execute(self)
        now = time.monotonic()
        for timer in timers:
            if not timer.is_canceled() and timer.next_due <= now and not self._destroyed:
                # Skip missed periods instead of bursting.
                timer.next_due += max(1, int((now - timer.next_due) / timer.period) + 1) * timer.period
                self._run_callback(timer.callback)

    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Wait up to ``timeout_sec`` for work, then run every ready callback."""
        if self._destroyed:
            return
        if not self._spin_some(
            0.0 if timeout_sec == 0 else (timeout_sec if timeout_sec is not None else 3600.0)
        ):
            msg = "node is already spinning in another thread"
            raise RuntimeError(msg)

    def spin(self) -> None:
        """Run callbacks until :meth:`shutdown` (from another thread or a callback)."""
        while not self._destroyed:
            self.spin_once(0.5)

    def spin_until_future_complete(self, future: Future[Any], timeout_sec: float | None = None) -> None:
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not future.done() and not self._destroyed:
            left = 0.1 if deadline is None else min(0.1, deadline - time.monotonic())
            if left <= 0:
                return
            self.spin_once(left)

    def shutdown(self) -> None:
        """Destroy the node: stop spinning, delete its entities and update ros_discovery_info.

        Safe from a callback: the clean-up then runs when the current executor step ends.
        """
        with self._lock:
            if self._destroyed:
                return
            self._destroyed = True
            for timer in self._timers:
                timer.cancel()
        if self._interfaces is not None:
            self._interfaces.rosout.close()
            for logger in self._log_targets:
                logger.removeHandler(self._interfaces.rosout)
        self._wake()
        if self._executor_thread == threading.get_ident():
            return
        with self._spin_lock:  # waits for a running executor step to finish
            self._finalize()

    def _finalize(self) -> None:
        with self._lock:
            if self._finalized:
                return
            self._finalized = True
            pool, self._reentrant_pool = self._reentrant_pool, None
        if pool is not None:
            pool.shutdown(wait=False, cancel_futures=True)
        with self._lock:
            ents, self._executables = self._executables, []
            pubs, self._publishers = self._publishers, []
            self._timers = []
        for ent in ents:
            self._waitset.detach(ent.condition)
            ent.destroy()
        for pub in pubs:
            pub.destroy()
        self.context.remove_node(self._entities)
        delete_entity(self._guard)
        delete_entity(self._waitset)
        self.context.release()

    destroy_node = shutdown
    destroy = shutdown

    def __enter__(self) -> CycloneNode:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()
