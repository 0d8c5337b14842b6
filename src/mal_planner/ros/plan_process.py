"""Planning in a child process, off the node's interpreter.

The initializer, the sequencing, the NLP construction and the verification are Python that holds the GIL; in the
node's own process they starve its radar callbacks, services and parameter answers while a plan runs (20 aircraft
at 100 Hz: the first plan 1.3x slower than at 2 Hz). :class:`PlanProcess` keeps a
:class:`~mal_planner.pipeline.Planner` (and its warm-start state) in a child process started with ``spawn`` (the
node's DDS threads must not be forked) and hands it scenarios and options over a pipe; results and exceptions come
back pickled (a thesis plan is ~0.35 MB). A what-if plan gets a fresh Planner there, so the radar plan's warm
start stays intact. A child that dies (a crash in C code, out of memory) is reported as a failed plan and started
again for the next one; the child ends when the node's end of the pipe closes and, on Linux, is killed with the
node (PR_SET_PDEATHSIG; the node starts it from its main thread, or from its plan thread after a death: both live
as long as the node).
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import sys
import threading
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from multiprocessing.connection import Connection

    from mal_planner.options import PlanOptions
    from mal_planner.pipeline import PlanResult
    from mal_planner.scenario import Scenario
    from mal_planner.scenario.traffic import Traffic

LOG_FORMAT = "[%(levelname)s] [%(asctime)s] [%(name)s]: %(message)s"
"""The node's log line format (the child logs to the same stderr in the same form)."""

log = logging.getLogger("mal_planner.ros.plan_process")


class PlanningProcessDied(RuntimeError):
    """The planning process ended during a plan (its exit code in the message)."""


def _serve(conn: Connection, log_level: int) -> None:
    """The child: plan what arrives until the pipe closes (or the node dies: SIGKILL, also in the middle of a
    plan, so that no planning process outlives its node)."""
    from mal_planner.campaign.child import die_with_parent

    die_with_parent()
    logging.basicConfig(level=log_level, stream=sys.stderr, format=LOG_FORMAT)
    from mal_planner.pipeline import Planner
    from mal_planner.pipeline.among import plan_or_replan

    planner: Planner | None = None
    given: PlanOptions | None = None
    while True:
        try:
            op, payload = conn.recv()
        except (EOFError, OSError):
            return
        if op == "stop":
            return
        if op == "reset":
            planner = None
            continue
        options, scenario, reuse, start_time, what_if, traffic = payload
        try:
            if what_if:
                result = Planner(options).plan(scenario, reuse=False, start_time=start_time)
            else:
                if planner is None or given is None or _but_time_limit(given) != _but_time_limit(options):
                    planner = Planner(options)  # other options: the next plan starts from scratch
                planner.options, given = options, options  # a replan's own time limit keeps the warm start
                result = plan_or_replan(planner, scenario, start_time, traffic, reuse=reuse)
            conn.send(("ok", result))
        except Exception as exc:  # sent back and raised in the node, as if planned there
            try:
                conn.send(("error", exc))
            except Exception:  # an exception that does not pickle: its text
                conn.send(("error", RuntimeError(f"{type(exc).__name__}: {exc}")))


def _but_time_limit(options: PlanOptions) -> PlanOptions:
    from dataclasses import replace

    return replace(options, time_limit_s=None)


class PlanProcess:
    """A Planner in a child process (see the module docstring); one caller at a time (the node's plan thread)."""

    def __init__(self) -> None:
        self._ctx = multiprocessing.get_context("spawn")
        self._lock = threading.Lock()
        self._conn: Connection | None = None
        self._proc: Any = None
        self._start()

    def _start(self) -> None:
        parent, child = self._ctx.Pipe()
        self._proc = self._ctx.Process(target=_serve, args=(child, logging.getLogger().getEffectiveLevel()),
                                       name="mal-planner-plan", daemon=True)
        self._proc.start()
        child.close()
        self._conn = parent
        log.info("planning process started (pid %d)", self._proc.pid)

    @property
    def pid(self) -> int | None:
        return None if self._proc is None else self._proc.pid

    def plan(self, scenario: Scenario, options: PlanOptions, *, reuse: bool, start_time: float,
             what_if: bool = False, traffic: Traffic | None = None) -> PlanResult:
        """Plan in the child (a replan of what changed among ``traffic``, if given); its exception is raised here. A
        dead child raises :class:`PlanningProcessDied` and is started again for the next plan."""
        with self._lock:
            if self._proc is None or not self._proc.is_alive():
                self._start()
            assert self._conn is not None
            try:
                self._conn.send(("plan", (options, scenario, reuse, start_time, what_if, traffic)))
                status, value = self._conn.recv()
            except (EOFError, OSError):
                self._proc.join(timeout=1.0)
                code = self._proc.exitcode
                self._proc = None
                raise PlanningProcessDied(f"the planning process died (exit {code})") from None
        if status == "error":
            raise value
        return value

    def reset(self) -> None:
        """Forget the warm-start state: the next plan starts from scratch."""
        with self._lock:
            if self._conn is not None and self._proc is not None and self._proc.is_alive():
                self._conn.send(("reset", None))

    def close(self) -> None:
        """End the child (it also ends by itself when this process dies: its pipe closes)."""
        proc, conn = self._proc, self._conn
        if proc is None or conn is None:
            return
        with contextlib.suppress(OSError):
            conn.send(("stop", None))
        proc.join(timeout=2.0)
        if proc.is_alive():
            proc.terminate()
            proc.join(timeout=1.0)
        conn.close()
        self._proc = None
