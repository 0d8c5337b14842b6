"""Services on the built-in backend, as rmw_cyclonedds_cpp does them.

A service ``/x`` is a request topic ``rq/xRequest`` and a reply topic ``rr/xReply`` whose samples start with
the ``{uint64 guid; int64 seq}`` request header; the client matches replies on its writer's instance handle
and its sequence number, and the server answers only once the client's reply reader is matched.
"""

from __future__ import annotations

import contextlib
import itertools
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any

from cyclonedds.core import Policy, ReadCondition
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader

import mal_msgs_py

from ._common import QOS_SERVICES, QoSProfile
from ._cyclone_context import CycloneContext, csid_to_string, dds_qos, delete_entity, parse_user_data
from ._cyclone_executor import Executor
from ._cyclone_topics import ANY_SAMPLE, take_all

_request_seq = itertools.count(1)  # process-wide, like rmw_cyclonedds' next_request_id
_REPLY_READER_WAIT_S = 0.1
"""How long a server waits for the client's reply reader to match before answering anyway (rmw_cyclonedds)."""


def _fields(obj: Any) -> dict[str, Any]:
    return {name: getattr(obj, name) for name in obj.__dataclass_fields__}


def _split_header(wire: Any) -> tuple[int, int, dict[str, Any]]:
    """(guid, seq, other fields) of a request or reply sample."""
    body = _fields(wire)
    return body.pop(mal_msgs_py.WIRE_HEADER[0]), body.pop(mal_msgs_py.WIRE_HEADER[1]), body


def _with_header(cls: type, guid: int, seq: int, msg: Any) -> Any:
    return cls(**dict(zip(mal_msgs_py.WIRE_HEADER, (guid, seq), strict=True)), **_fields(msg))


def _user_data(endpoint: Any) -> bytes | None:
    policy = endpoint.qos[Policy.Userdata] if endpoint.qos is not None else None
    return policy.data if policy is not None else None


class _ServiceEndpoints:
    """Request/reply reader+writer pair of a service or a client, with the rmw_cyclonedds USER_DATA."""

    def __init__(self, ctx: CycloneContext, srv: mal_msgs_py.ServiceType, name: str, is_service: bool,
                 profile: QoSProfile = QOS_SERVICES) -> None:
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
        self.condition = ReadCondition(self.reader, ANY_SAMPLE)
        self.reader_gid = self.reader.guid.bytes
        self.writer_gid = self.writer.guid.bytes

    def destroy(self) -> None:
        delete_entity(self.condition)
        delete_entity(self.reader)
        delete_entity(self.writer)


class Service(_ServiceEndpoints):
    """Service server; ``callback(request, response) -> response`` runs on the node's executor, or with
    ``reentrant`` on a worker thread of its own (it may then block without holding up other callbacks)."""

    def __init__(
        self, ctx: CycloneContext, srv: mal_msgs_py.ServiceType, name: str, callback: Callable[..., Any],
        reentrant: bool = False, qos: QoSProfile = QOS_SERVICES,
    ):
        super().__init__(ctx, srv, name, is_service=True, profile=qos)
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

    def execute(self, executor: Executor) -> None:
        for wire in take_all(self.reader):
            if self.reentrant:
                executor.service_pool().submit(self._handle, executor, wire)
            else:
                self._handle(executor, wire)

    def _handle(self, executor: Executor, wire: Any) -> None:
        guid, seq, body = _split_header(wire)
        response = executor.run_callback(self.callback, self.srv.Request(**body), self.srv.Response())
        if response is None:
            executor.logger.error("service %s: callback returned no response", self.service_name)
            return
        deadline = time.monotonic() + _REPLY_READER_WAIT_S
        state = self._client_reader_matched(wire.sample_info.publication_handle)
        while state is False and time.monotonic() < deadline:
            time.sleep(0.005)
            state = self._client_reader_matched(wire.sample_info.publication_handle)
        if state is None or executor.destroyed:
            return
        self.writer.write(_with_header(self.srv.WireResponse, guid, seq, response))


class Client(_ServiceEndpoints):
    """Service client; replies are matched on the request writer's instance handle and sequence number."""

    def __init__(self, ctx: CycloneContext, executor: Executor, srv: mal_msgs_py.ServiceType, name: str) -> None:
        super().__init__(ctx, srv, name, is_service=False)
        self._executor = executor
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
        self.writer.write(_with_header(self.srv.WireRequest, self._guid, seq, request))
        self._executor.wake()
        return future

    def call(self, request: Any, timeout_sec: float | None = None) -> Any:
        """Blocking call. Spins the node itself when no other thread does; raises TimeoutError."""
        if self._executor.thread == threading.get_ident():
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
            if not self._executor.spin_some(left):
                with contextlib.suppress(TimeoutError):
                    future.result(timeout=left)
        return future.result()

    def _cancel(self, future: Future[Any]) -> None:
        with self._lock:
            for seq, fut in list(self._pending.items()):
                if fut is future:
                    del self._pending[seq]
        future.cancel()

    def execute(self, executor: Executor) -> None:
        for wire in take_all(self.reader):
            guid, seq, body = _split_header(wire)
            if guid != self._guid:
                continue
            with self._lock:
                future = self._pending.pop(seq, None)
            if future is not None and future.set_running_or_notify_cancel():
                executor.run_callback(future.set_result, self.srv.Response(**body))
