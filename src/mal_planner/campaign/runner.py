"""Spread scenarios over a Dask cluster (a local one by default) and collect the rows as they arrive.

Every scenario is one Dask task that runs :func:`mal_planner.campaign.isolation.run_isolated`: the
planning happens in a child process of the worker, so the worker survives hangs, crashes and memory
exhaustion. Rows are appended to the table the moment their task finishes.
"""

from __future__ import annotations

import logging
import os
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mal_planner import jsonio
from mal_planner.campaign.isolation import run_isolated
from mal_planner.campaign.results import FLOWN_RECORD, ResultsTable
from mal_planner.errors import one_line

if TYPE_CHECKING:
    from distributed import Client

log = logging.getLogger("mal_planner.campaign")


@dataclass(frozen=True)
class ScenarioJob:
    source: str
    """The scenario file's path relative to the campaign folder (the row's key; it names the file in messages)."""
    text: str
    """The file's YAML text (sent to the worker)."""
    known: dict[str, Any]
    """Columns known before planning (name, n_aircraft, layout, landing_times), used if the child dies."""


@dataclass(frozen=True)
class EngineSettings:
    workers: int = 2
    address: str | None = None
    """Scheduler address of an existing Dask cluster; None: start a local cluster of ``workers`` processes."""
    timeout_s: float = 600.0
    memory_limit_bytes: int | None = 4 * 2**30


def open_client(settings: EngineSettings) -> Client:
    """A Dask client on the given scheduler, or on a new local cluster of single-threaded worker processes."""
    from distributed import Client, LocalCluster

    logging.getLogger("distributed").setLevel(max(logging.WARNING, log.getEffectiveLevel()))
    if settings.address:
        return Client(settings.address, timeout="30s")
    # memory_limit=0: the worker's memory is small; the planning child has its own RLIMIT_AS. Any free port for
    # the scheduler's HTTP server, so that several campaigns can run on one machine.
    cluster = LocalCluster(n_workers=settings.workers, threads_per_worker=1, processes=True, memory_limit=0,
                           dashboard_address=":0", silence_logs=logging.ERROR)
    return Client(cluster)


def close_client(client: Client) -> None:
    cluster = getattr(client, "cluster", None)
    client.close()
    if cluster is not None:
        cluster.close()


def engine_failure_row(job: ScenarioJob, error: BaseException, seed: Any) -> dict[str, Any]:
    """A row for a task the engine itself lost (e.g. its worker died): class crash."""
    return {"file": job.source, "status": "failed", "verified": False, "failure_class": "crash", "seed": seed,
            "reason": one_line(f"engine: {type(error).__name__}: {error}")}


def run_campaign(jobs: Sequence[ScenarioJob], options: dict[str, Any], settings: EngineSettings,
                 table: ResultsTable, logs_dir: Path | None = None, progress: bool = True,
                 on_row: Callable[[dict[str, Any]], None] | None = None) -> list[dict[str, Any]]:
    """Plan every job on the cluster; append each row to ``table`` as it arrives; return the rows."""
    from distributed import as_completed
    from tqdm import tqdm
    from tqdm.contrib.logging import logging_redirect_tqdm

    if not jobs:
        return []
    rows: list[dict[str, Any]] = []
    client = open_client(settings)
    log.info("engine: %s (%d workers)", client.scheduler.address if settings.address else "local Dask cluster",
             len(client.scheduler_info().get("workers", {})))
    try:
        futures = {}
        token = uuid.uuid4().hex[:8]  # task keys unique to this campaign: a shared cluster must not reuse results
        for i, job in enumerate(jobs):
            future = client.submit(run_isolated, job.source, job.text, options, settings.timeout_s,
                                   settings.memory_limit_bytes, key=f"plan-{token}-{i:05d}-{Path(job.source).stem}",
                                   pure=False, retries=0)
            futures[future] = job
        failed = 0
        bar = tqdm(total=len(jobs), unit="scenario", desc="campaign", disable=not progress or None, dynamic_ncols=True)
        with bar, logging_redirect_tqdm():
            for future in as_completed(futures):
                job = futures[future]
                try:
                    row = future.result()
                except Exception as exc:  # the engine lost the task: still a row
                    row = engine_failure_row(job, exc, options.get("seed"))
                row = {**job.known, **row}
                log_tail, flown = row.pop("log_tail", ""), row.pop(FLOWN_RECORD, None)
                if logs_dir is not None and log_tail:
                    (logs_dir / f"{Path(job.source).stem}.log").write_text(log_tail, encoding="utf-8")
                if logs_dir is not None and flown is not None:
                    jsonio.write(logs_dir / f"{Path(job.source).stem}.closed_loop.json", flown, indent=None)
                table.append(row)
                rows.append(row)
                failed += row.get("status") != "ok"
                log.info("%s: %s%s (%.1f s)", Path(job.source).name, row.get("status"),
                         f" [{row.get('failure_class')}] {row.get('reason')}" if row.get("status") != "ok" else "",
                         float(row.get("process_s") or 0.0))
                bar.set_postfix(ok=len(rows) - failed, failed=failed)
                bar.update(1)
    finally:
        close_client(client)
    return rows


def default_workers() -> int:
    return max(1, min(len(os.sched_getaffinity(0)), 8))
