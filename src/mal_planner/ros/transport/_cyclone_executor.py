"""The built-in backend's executor: one node's callbacks run on the thread that spins it, one step at a time.

A step waits on a Cyclone DDS WaitSet (a read condition per subscription, service and client, plus a guard
condition that wakes it when something changes) or until the next timer is due, then runs every ready callback.
Only one thread may spin a node; another one gets ``False`` from :meth:`Executor.spin_some`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, Protocol

from cyclonedds.core import GuardCondition, ReadCondition, WaitSet
from cyclonedds.domain import DomainParticipant
from cyclonedds.util import duration

from ._cyclone_context import delete_entity

_NO_TIMEOUT_S = 3600.0
_REENTRANT_WORKERS = 4


class Executable(Protocol):
    """A subscription, service or client: a read condition and the callbacks to run when it triggers."""

    condition: ReadCondition

    def execute(self, executor: Executor) -> None: ...

    def destroy(self) -> None: ...


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


class Executor:
    """Waits for one node's work and runs its callbacks; ``on_finalize`` deletes the node's other entities."""

    def __init__(self, participant: DomainParticipant, name: str, logger: logging.LoggerAdapter[Any],
                 on_finalize: Callable[[], None]) -> None:
        self.name = name
        self.logger = logger
        self._on_finalize = on_finalize
        self._waitset = WaitSet(participant)
        self._guard = GuardCondition(participant)
        self._waitset.attach(self._guard)
        self._lock = threading.RLock()
        self._spin_lock = threading.Lock()
        self.thread: int | None = None
        """Identity of the thread running a step now, else None."""
        self._executables: list[Executable] = []
        self._timers: list[Timer] = []
        self._reentrant_pool: ThreadPoolExecutor | None = None
        self.destroyed = False
        self._finalized = False

    # -- what it waits for ----------------------------------------------------------------------------
    def wake(self) -> None:
        """End the current wait (something to run, or to wait for, changed)."""
        self._guard.set(True)

    def add(self, ent: Executable) -> None:
        with self._lock:
            self._executables.append(ent)
            self._waitset.attach(ent.condition)
        self.wake()

    def remove(self, ent: Executable) -> None:
        with self._lock:
            self._executables.remove(ent)
            self._waitset.detach(ent.condition)

    def add_timer(self, timer: Timer) -> None:
        with self._lock:
            self._timers.append(timer)
        self.wake()

    def remove_timer(self, timer: Timer) -> None:
        timer.cancel()
        with self._lock:
            if timer in self._timers:
                self._timers.remove(timer)

    # -- running callbacks ----------------------------------------------------------------------------
    def service_pool(self) -> ThreadPoolExecutor:
        """Worker threads for reentrant service callbacks (created on first use)."""
        with self._lock:
            if self._reentrant_pool is None:
                self._reentrant_pool = ThreadPoolExecutor(max_workers=_REENTRANT_WORKERS,
                                                          thread_name_prefix=f"{self.name}-srv")
            return self._reentrant_pool

    def run_callback(self, fn: Callable[..., Any], *args: Any) -> Any:
        try:
            return fn(*args)
        except Exception:  # keep the node alive, like a service that must not die on one bad request
            self.logger.exception("exception in callback %r", getattr(fn, "__qualname__", fn))
            return None

    def spin_some(self, timeout_sec: float) -> bool:
        """One executor step if no other thread is spinning; False when another thread owns the executor."""
        if not self._spin_lock.acquire(blocking=False):
            return False
        try:
            if self.destroyed:
                self._finalize()
                return True
            self.thread = threading.get_ident()
            self._step(timeout_sec)
            if self.destroyed:  # shutdown() was called from a callback
                self._finalize()
        finally:
            self.thread = None
            self._spin_lock.release()
        return True

    def _step(self, timeout_sec: float | None) -> None:
        with self._lock:
            timers = [t for t in self._timers if not t.is_canceled()]
            executables = list(self._executables)
        wait = _NO_TIMEOUT_S if timeout_sec is None else max(0.0, timeout_sec)
        if timers:
            wait = min(wait, max(0.0, min(t.next_due for t in timers) - time.monotonic()))
        if wait > 0:
            self._waitset.wait(duration(seconds=wait))
        self._guard.take()
        for ent in executables:
            if not self.destroyed:
                ent.execute(self)
        now = time.monotonic()
        for timer in timers:
            if not timer.is_canceled() and timer.next_due <= now and not self.destroyed:
                # Skip missed periods instead of bursting.
                timer.next_due += max(1, int((now - timer.next_due) / timer.period) + 1) * timer.period
                self.run_callback(timer.callback)

    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Wait up to ``timeout_sec`` for work, then run every ready callback."""
        if self.destroyed:
            return
        if not self.spin_some(0.0 if timeout_sec == 0 else (timeout_sec if timeout_sec is not None
                                                             else _NO_TIMEOUT_S)):
            msg = "node is already spinning in another thread"
            raise RuntimeError(msg)

    def spin(self) -> None:
        while not self.destroyed:
            self.spin_once(0.5)

    def spin_until_future_complete(self, future: Future[Any], timeout_sec: float | None = None) -> None:
        deadline = None if timeout_sec is None else time.monotonic() + timeout_sec
        while not future.done() and not self.destroyed:
            left = 0.1 if deadline is None else min(0.1, deadline - time.monotonic())
            if left <= 0:
                return
            self.spin_once(left)

    # -- shutting down --------------------------------------------------------------------------------
    def begin_shutdown(self) -> bool:
        """Stop running callbacks; False when it was already shut down."""
        with self._lock:
            if self.destroyed:
                return False
            self.destroyed = True
            for timer in self._timers:
                timer.cancel()
        return True

    def finish_shutdown(self) -> None:
        """Delete everything now, or (called from a callback) when the current step ends."""
        self.wake()
        if self.thread == threading.get_ident():
            return
        with self._spin_lock:  # waits for a running executor step to finish
            self._finalize()

    def _finalize(self) -> None:
        with self._lock:
            if self._finalized:
                return
            self._finalized = True
            pool, self._reentrant_pool = self._reentrant_pool, None
            ents, self._executables = self._executables, []
            self._timers = []
        if pool is not None:
            pool.shutdown(wait=False, cancel_futures=True)
        for ent in ents:
            self._waitset.detach(ent.condition)
            ent.destroy()
        delete_entity(self._guard)
        delete_entity(self._waitset)
        self._on_finalize()
