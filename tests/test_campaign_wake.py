"""The campaign's sequencing and wake columns: filled from one small real plan of mixed-wake traffic (a few
seconds), summarized, and absent from tables written before them (which still summarize and resume)."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from mal_planner.campaign.child import plan_row
from mal_planner.campaign.plan_options import DEFAULTS
from mal_planner.campaign.results import COLUMNS, SEQUENCE_COLUMNS, ResultsTable, format_row, read_rows
from mal_planner.campaign.summary import summary_markdown, write_summary
from mal_planner.campaign.traffic import TrafficSpec, generate_one

WAKE_SPEC = TrafficSpec((2, 8), seed=2026, layout="mixed", wake="mixed")
WAKE_INDEX = 4
"""Scenario 4 of the thesis-size wake campaign: three aircraft (H, M, L) around no-fly zones, planned in ~3 s;
first come, first served lands the heavy first and the two others 125-150 s behind it."""


@pytest.fixture(scope="module")
def wake_row() -> dict:
    generated = generate_one(WAKE_SPEC, WAKE_INDEX)
    return plan_row({"source": generated.file_name, "text": generated.text, "options": dict(DEFAULTS)})


def test_a_real_wake_plan_fills_the_sequence_columns(wake_row: dict) -> None:
    row = wake_row
    assert row["status"] == "ok", row["reason"]
    assert row["wake_mix"] == "icao:H=1;M=1;L=1"
    assert (row["sequencing_strategy"], row["sequencing_status"]) == ("optimal", "optimal")
    # the plan lands at the schedule's times; the optimal sequence is well below first come, first served
    assert row["total_delay_s"] == pytest.approx(row["scheduled_delay_s"], abs=0.01)
    assert row["fcfs_delay_s"] > row["scheduled_delay_s"] + 100.0
    # re-flown, every consecutive pair keeps its wake minimum (the schedule's round-off margin: just above 1)
    assert 1.0 <= row["min_landing_gap_ratio"] < 1.001 and row["landing_pairs_below"] == 0


def test_summary_reports_wake_pairs_and_delay_against_fcfs(wake_row: dict, tmp_path: Path) -> None:
    rows = [format_row({**wake_row, "file": "/w.yaml", "process_s": 5.0, "worker": "h:1"}),
            format_row({"file": "/x.yaml", "n_aircraft": 3, "status": "failed", "failure_class": "timeout",
                        "reason": "killed", "wake_mix": "icao:H=2;M=1", "process_s": 300.0, "worker": "h:2"})]
    text = summary_markdown(rows)
    assert "## Sequence: wake minima and delay" in text
    assert "* verified: 1 of 2 (50.0 %); 2 scenarios with a wake table (icao); strategies: optimal 1" in text
    assert "2 pairs in 1 runs, 0 below the time they need" in text
    ours, fcfs = wake_row["total_delay_s"], wake_row["fcfs_delay_s"]
    assert f"total {ours:.1f} s against first come, first served {fcfs:.1f} s, lower by {fcfs - ours:.1f} s" in text
    assert "lower in 1, equal in 0, higher in 0" in text
    assert f"| 3 | 1 | {ours:.1f} | {fcfs:.1f} |" in text
    written = write_summary(rows, tmp_path).read_text()
    assert "(delay_vs_fcfs.png)" in written and (tmp_path / "delay_vs_fcfs.png").stat().st_size > 5_000


def test_a_table_from_before_the_sequence_columns_summarizes_and_resumes(tmp_path: Path) -> None:
    path = tmp_path / "results.csv"
    old = [c for c in COLUMNS if c not in SEQUENCE_COLUMNS]
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=old)
        writer.writeheader()
        writer.writerow({c: "" for c in old} | {"file": "/a.yaml", "name": "a", "n_aircraft": "2", "status": "ok",
                                                "verified": "true", "reason": "verified", "worker": "h:1"})
    rows = read_rows(path)
    assert rows[0].get("fcfs_delay_s") is None
    text = summary_markdown(rows)
    assert "1 scenarios, 1 verified" in text and "## Sequence" not in text
    with ResultsTable(path) as table:  # --resume appends: the old rows get the new columns, empty
        table.append({"file": "/b.yaml", "status": "ok", "verified": True, "fcfs_delay_s": 12.5, "worker": "h:2"})
    assert path.read_text().splitlines()[0].split(",") == list(COLUMNS)
    rows = read_rows(path)
    assert [r["file"] for r in rows] == ["/a.yaml", "/b.yaml"]
    assert rows[0]["fcfs_delay_s"] == "" and rows[0]["status"] == "ok" and rows[1]["fcfs_delay_s"] == "12.5"
    summary_markdown(rows)
