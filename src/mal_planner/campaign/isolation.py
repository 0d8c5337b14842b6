"""Run one scenario in its own child process with a time limit and an address-space limit.

The engine's task calls :func:`run_isolated`; it never imports the planner itself, so a hang, a crash or
memory exhaustion of the planning process ends as a row (timeout, crash, out_of_memory) and the worker
stays healthy. The peak resident memory is that child's own (``os.wait4``'s rusage).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from mal_planner import jsonio
from mal_planner.errors import classify

POLL_S = 0.05
SINGLE_THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
"""Each planning process uses one core: W workers on W cores do not oversubscribe them."""


def _wait(pid: int, timeout_s: float) -> tuple[int | None, Any, bool]:
    """Wait for ``pid`` up to ``timeout_s``; kill its process group when late. (exit code, rusage, timed out)."""
    deadline = time.monotonic() + timeout_s
    timed_out = False
    while True:
        done, status, usage = os.wait4(pid, os.WNOHANG)
        if done:
            return os.waitstatus_to_exitcode(status), usage, timed_out
        if not timed_out and time.monotonic() > deadline:
            timed_out = True
            with contextlib.suppress(ProcessLookupError):
                os.killpg(pid, signal.SIGKILL)
        time.sleep(POLL_S)


def run_isolated(source: str, text: str, options: dict[str, Any], timeout_s: float,
                 memory_limit_bytes: int | None) -> dict[str, Any]:
    """Plan one scenario (its file name and YAML text) in a child process; the result row plus its log tail.

    Always returns a row: the child's own, or one made here when it timed out or died without one.
    """
    row: dict[str, Any] = {"file": source, "worker": f"{socket.gethostname()}:{os.getpid()}"}
    with tempfile.TemporaryDirectory(prefix="mal-campaign-") as tmp:
        job_path, out_path, log_path = Path(tmp, "job.json"), Path(tmp, "row.json"), Path(tmp, "log.txt")
        job = {"source": source, "text": text, "options": options, "memory_limit_bytes": memory_limit_bytes}
        jsonio.write(job_path, job, indent=None)
        env = {**os.environ, **SINGLE_THREAD_ENV, "PYTHONUNBUFFERED": "1"}
        t0 = time.perf_counter()
        with log_path.open("wb") as log:
            proc = subprocess.Popen([sys.executable, "-m", "mal_planner.campaign.child", str(job_path), str(out_path)],
                                    stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, env=env,
                                    start_new_session=True)
            exit_code, usage, timed_out = _wait(proc.pid, timeout_s)
            proc.returncode = exit_code  # reaped by wait4: tell Popen
        row["process_s"] = time.perf_counter() - t0
        row["peak_memory_mb"] = usage.ru_maxrss / 1024.0  # kB on Linux
        log_text = log_path.read_text(encoding="utf-8", errors="replace")
        if out_path.exists() and not timed_out:
            row.update(json.loads(out_path.read_text(encoding="utf-8")))
        else:
            outcome = classify(timed_out=timeout_s if timed_out else None, exit_code=exit_code,
                               output_tail=log_text[-4000:])
            row.update(status="failed", verified=False, failure_class=outcome.failure_class, reason=outcome.reason,
                       seed=options.get("seed"))
    row["log_tail"] = kept_log(log_text)
    return row


LOG_KEPT_CHARS = 200_000
"""How much of a scenario's log the campaign keeps (its end), after the optimizer's per-iteration lines."""


def kept_log(text: str) -> str:
    """A scenario's log without the transcription's progress lines (mesh and IPOPT iterations: most of a closed
    loop's log), its last :data:`LOG_KEPT_CHARS` characters: a closed loop's story from the start."""
    lines = [line for line in text.splitlines(keepends=True) if " mal_planner.ocp: " not in line]
    return "".join(lines)[-LOG_KEPT_CHARS:]
