"""The campaign table ``results.csv``: one row per scenario, appended and flushed as each result arrives."""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable
from pathlib import Path

COLUMNS: tuple[str, ...] = (
    "file",                        # the scenario file, relative to the campaign folder (absolute in tables
                                   # written before); the key --resume uses
    "name",                        # the scenario's name
    "n_aircraft",
    "layout",                      # wall | no-fly-zones | open (from the obstacles and gates of the file)
    "landing_times",               # fixed | free | partial: landing times given in the file
    "status",                      # ok (optimal and verified) | failed
    "verified",                    # true | false
    "failure_class",               # empty when ok, else one of mal_planner.errors.FAILURE_CLASSES
    "reason",                      # one line
    "optimizer_status",            # IPOPT's return status of the last solve
    "initializer_s", "optimizer_s", "verification_s",
    "total_s",                     # planning time (initializer + optimizer + verification)
    "process_s",                   # wall time of the child process (Python start and imports included)
    "ipopt_iterations", "mesh_iterations",
    "min_separation_nm",           # smallest distance of any pair in the verification's re-integrated flight
    "min_obstacle_clearance_nm",   # smallest ray distance of the planned trajectories to any obstacle
    "landing_times_s",             # planned landing time per aircraft, "CS=t;CS=t" in landing order
    "initializer_landing_times_s", # the initializer's (sequencer's) landing times, same format
    "mean_delay_s", "max_delay_s", # planned minus initializer landing times
    "peak_memory_mb",              # peak resident memory of the planning process
    "seed",
    "worker",                      # host:pid of the engine worker that ran it
)
REQUIRED_COLUMNS = COLUMNS
"""Every table has these; the closed-loop columns below are empty in an open-loop campaign (and may be missing
from tables written before they existed)."""
CLOSED_LOOP_COLUMNS: tuple[str, ...] = (
    "cl_wind_kt", "cl_wind_from_deg",  # the mean wind flown (drawn per scenario), local heading it blows from
    "cl_landed",                   # aircraft that landed inside the touchdown window
    "cl_separation_ratio",         # smallest distance flown in separation minima (< 1: a loss of separation)
    "cl_losses_of_separation", "cl_infringements",
    "cl_max_deviation_nm",         # largest distance of an aircraft from the plan it flew
    "cl_replans", "cl_failed_replans", "cl_replan_reasons",
    "cl_replans_what_changed",     # replans of some aircraft among the others' instructions
    "cl_replan_median_s", "cl_replan_p95_s", "cl_replan_max_s",
    "cl_order_changes", "cl_min_landing_spacing_s",
    "cl_replan_times_s",           # every replan's planning time as charged (CPU), ';'-separated
    "cl_simulator",                # who flew: ours (FlightSimulator) or bluesky
    "cl_fallback_share",           # share of the flight time on a hold, a vector or nothing
    "cl_holds", "cl_net_alerts", "cl_net_uses", "cl_vectors",  # the service's holds, the safety net's alerts and uses
    "cl_simulator_losses_of_separation",  # the simulator's own count (BlueSky's conflict detection); empty: ours
)
SEQUENCE_COLUMNS: tuple[str, ...] = (
    "wake_mix",                    # wake table and aircraft per category, "icao:H=1;M=3;L=3"; empty: no table
    "sequencing_strategy", "sequencing_status",  # the schedule's strategy (fcfs | optimal) and its status
    "total_delay_s",               # plan.json sequence.total_delay_s: planned landings minus targets, summed (s)
    "scheduled_delay_s",           # the same for the schedule's times (what the sequencing strategy chose)
    "fcfs_delay_s",                # first come, first served's total delay on the same sequencing problem
    "min_landing_gap_ratio",       # smallest consecutive landing gap / the time it needs (verification.landings)
    "landing_pairs_below",         # consecutive landings closer than they need (wake minimum or spacing)
)
"""Sequencing and wake columns (empty for runs without a plan; missing from tables written before them)."""
COLUMNS = COLUMNS + CLOSED_LOOP_COLUMNS + SEQUENCE_COLUMNS
FLOWN_RECORD = "flown_record"
"""A failed closed-loop run's record (:func:`mal_planner.closedloop.record.run_record`) in its row on the way from
the worker: the runner writes it to ``logs/<name>.closed_loop.json``, not into the table."""


def format_row(row: dict) -> dict[str, str]:
    """Every column as text: floats to 4 significant decimals, None as empty, bools lower case."""
    out: dict[str, str] = {}
    for key in COLUMNS:
        value = row.get(key)
        if value is None:
            out[key] = ""
        elif isinstance(value, bool):
            out[key] = str(value).lower()
        elif isinstance(value, float):
            out[key] = f"{value:.6g}"
        else:
            out[key] = str(value)
    return out


class ResultsTable:
    """Appends rows to ``path`` (header first when new) and flushes each one to disk."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        new = not self.path.exists() or self.path.stat().st_size == 0
        if not new:
            _drop_partial_line(self.path)
            _add_missing_columns(self.path)
        self._file = self.path.open("a", encoding="utf-8", newline="")
        self._writer = csv.DictWriter(self._file, fieldnames=COLUMNS)
        if new:
            self._writer.writeheader()
            self._file.flush()

    def append(self, row: dict) -> None:
        self._writer.writerow(format_row(row))
        self._file.flush()

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> ResultsTable:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _drop_partial_line(path: Path) -> None:
    """Cut a last line without its newline (a write interrupted half way), so the next row starts clean."""
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        path.write_bytes(data[: data.rfind(b"\n") + 1])


def _add_missing_columns(path: Path) -> None:
    """Rewrite a table written before some of :data:`COLUMNS` existed with today's header, those columns empty
    (their default), so that resumed rows line up with the header. A table with today's header is not touched."""
    text = path.read_text(encoding="utf-8")
    reader = csv.DictReader(io.StringIO(text))
    if reader.fieldnames is None or list(reader.fieldnames) == list(COLUMNS):
        return
    extra = [c for c in reader.fieldnames if c not in COLUMNS]
    rows = list(reader)
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=[*COLUMNS, *extra], restval="")
    writer.writeheader()
    writer.writerows(rows)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(out.getvalue(), encoding="utf-8")
    tmp.replace(path)


class ResultsFormatError(ValueError):
    """results.csv that this version cannot read (wrong header)."""


def read_rows(path: Path) -> list[dict[str, str]]:
    """All complete rows of ``path`` (a row cut short by an interruption is dropped)."""
    text = Path(path).read_text(encoding="utf-8")
    reader = csv.DictReader(io.StringIO(text))
    if reader.fieldnames is None:
        return []
    missing = [c for c in REQUIRED_COLUMNS if c not in reader.fieldnames]
    if missing:
        raise ResultsFormatError(f"{path}: not a campaign table (missing columns: {', '.join(missing)})")
    return [r for r in reader if r.get("worker") is not None and r.get("file")]


def done_files(rows: Iterable[dict[str, str]]) -> set[str]:
    return {r["file"] for r in rows}


def as_float(value: str) -> float | None:
    try:
        return float(value) if value not in ("", None) else None
    except ValueError:
        return None
