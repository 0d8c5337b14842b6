"""Plan one scenario in this process and write its result row: ``python -m mal_planner.campaign.child JOB OUT``.

JOB is a JSON file ``{source, text, options, memory_limit_bytes}`` (the scenario's YAML text travels with
the job, so engine workers need no shared file system); OUT receives the row as JSON. The address-space
limit is set first, so that exhausting it makes allocations fail in this process only.

Test hook (used by the test suite through the real runner path): ``MAL_CAMPAIGN_TEST_FAULTS`` =
``"file-name=fault,..."`` makes the run of that file ``exit`` (os._exit(3)), ``segfault`` (SIGSEGV), ``raise``
(RuntimeError), ``hang`` (sleep) or ``oom`` (allocate beyond the memory limit) before planning.
"""

from __future__ import annotations

import json
import logging
import os
import resource
import signal
import sys
import time
from pathlib import Path
from typing import Any

from mal_planner import jsonio

FAULTS_ENV = "MAL_CAMPAIGN_TEST_FAULTS"


def die_with_parent() -> None:
    """Linux: get SIGKILL when the engine worker that started this process dies (e.g. the campaign is
    interrupted), so no planning process outlives its campaign."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, int(signal.SIGKILL))  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() == 1:  # the parent died before the call
        os._exit(1)


def limit_memory(limit_bytes: int | None) -> None:
    if limit_bytes:
        resource.setrlimit(resource.RLIMIT_AS, (limit_bytes, limit_bytes))


def injected_fault(source: str) -> str | None:
    name = Path(source).name
    for item in os.environ.get(FAULTS_ENV, "").split(","):
        target, _, fault = item.partition("=")
        if target.strip() == name:
            return fault.strip()
    return None


def apply_fault(fault: str, limit_bytes: int | None) -> None:
    if fault == "exit":
        os._exit(3)
    if fault == "segfault":
        os.kill(os.getpid(), signal.SIGSEGV)
    if fault == "raise":
        raise RuntimeError("injected fault")
    if fault == "hang":
        time.sleep(1e6)
    if fault == "oom":
        import numpy as np

        hoard = [np.ones(2**27) for _ in range(int((limit_bytes or 2**34) // 2**30) + 2)]  # 1 GiB each
        raise AssertionError(f"allocated {len(hoard)} GiB beyond the memory limit")


def plan_row(job: dict[str, Any]) -> dict[str, Any]:
    """Load, plan with the normal pipeline (no figures), classify; the row's columns this process knows."""
    from mal_planner.campaign.metrics import plan_columns, scenario_columns
    from mal_planner.campaign.plan_options import to_plan_options
    from mal_planner.errors import classify
    from mal_planner.pipeline import Planner
    from mal_planner.scenario import scenario_from_text

    row: dict[str, Any] = {"seed": job["options"]["seed"]}
    fault = injected_fault(job["source"])
    t0: float | None = None
    try:
        if fault:
            apply_fault(fault, job.get("memory_limit_bytes"))
        scenario = scenario_from_text(job["text"], job["source"])
        row.update(scenario_columns(scenario))
        t0 = time.perf_counter()
        if job["options"].get("closed_loop"):
            from mal_planner.campaign.closed_loop import closed_loop_row

            row.update(closed_loop_row(scenario, job["source"], job["options"]))
            return row
        result = Planner(to_plan_options(job["options"])).plan(scenario, reuse=False)
    except (Exception, MemoryError) as exc:  # every failure becomes a row; the campaign goes on
        outcome = classify(error=exc)
        if t0 is not None:  # the pipeline ran until it raised
            row["total_s"] = time.perf_counter() - t0
            if outcome.failure_class == "initializer_failed":
                row["initializer_s"] = row["total_s"]
        logging.getLogger("mal_planner.campaign").warning("%s: %s", job["source"], outcome.reason)
    else:
        row.update(plan_columns(scenario, result))
        outcome = classify(result=result)
    row.update(failure_class=outcome.failure_class, reason=outcome.reason, status="ok" if outcome.ok else "failed")
    row.setdefault("verified", False)
    return row


def main(argv: list[str] | None = None) -> int:
    job_path, out_path = (argv if argv is not None else sys.argv[1:])[:2]
    die_with_parent()
    job = json.loads(Path(job_path).read_text(encoding="utf-8"))
    limit_memory(job.get("memory_limit_bytes"))
    logging.basicConfig(level=logging.INFO, stream=sys.stderr,
                        format="%(asctime)s %(levelname).1s %(name)s: %(message)s", datefmt="%H:%M:%S")
    row = plan_row(job)
    jsonio.write(out_path, row, indent=None)  # atomically: the parent reads a whole row or none
    return 0


if __name__ == "__main__":
    sys.exit(main())
