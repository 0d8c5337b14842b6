"""Every JSON file the project writes is strict JSON (no NaN/Infinity tokens), read here with a parser that
refuses them: plan.json, closed_loop.json, the campaign's campaign.json and its child's job and row files."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from mal_planner import jsonio

THESIS = Path(__file__).resolve().parents[1] / "scenarios" / "thesis.yaml"


def strict_load(path: Path) -> object:
    def refuse(token: str) -> None:
        raise ValueError(f"{path}: {token} is not JSON")

    return json.loads(path.read_text(encoding="utf-8"), parse_constant=refuse)


def test_jsonio_writes_non_finite_numbers_as_null(tmp_path: Path) -> None:
    doc = {"nan": math.nan, "inf": math.inf, "neg": -np.inf, "np": np.float64("nan"), "ok": np.float32(1.5),
           "ints": np.arange(3), "nested": [(1.0, float("nan")), {"x": np.array([np.inf, 2.0])}],
           "flag": np.bool_(True)}
    path = jsonio.write(tmp_path / "doc.json", doc)
    assert strict_load(path) == {"nan": None, "inf": None, "neg": None, "np": None, "ok": 1.5, "ints": [0, 1, 2],
                                 "nested": [[1.0, None], {"x": [None, 2.0]}], "flag": True}
    assert path.read_text().endswith("\n") and [p.name for p in tmp_path.iterdir()] == ["doc.json"]
    assert json.loads(jsonio.dumps([math.nan])) == [None]
    with pytest.raises(TypeError):
        jsonio.dumps({"x": object()})


def test_plan_json_is_strict(tmp_path: Path) -> None:
    from mal_planner.cli import main

    assert main([str(THESIS), "--initial-only", "--seed", "3", "--figures", "none", "--out", str(tmp_path), "-q"]) == 0
    assert strict_load(tmp_path / "plan.json")["schema"] == "mal-planner/plan"


def test_closed_loop_json_is_strict_with_the_first_plans_time(tmp_path: Path) -> None:
    """mal-closed-loop on the thesis (no replans: their latencies are null, not NaN); the first plan's time is
    the measured one."""
    from mal_planner.closedloop.cli import main

    assert main([str(THESIS), "--out", str(tmp_path), "--no-figure", "-q"]) == 0
    record = strict_load(tmp_path / "closed_loop.json")
    metrics = record["metrics"]
    assert metrics["first_plan_s"] > 0 and metrics["all_landed"]
    told = {i["callsign"] for i in record["instructions"] if i["kind"] == "plan"}  # who was told what, and when
    assert told == set(record["flown"]) and len(told) == metrics["aircraft"]
    assert metrics["replans"] > 0 or metrics["replan_latency_s"] == {"median": None, "p95": None, "max": None}


def test_the_simulator_nodes_metrics_leave_the_first_plan_null_when_unmeasured() -> None:
    """measure_flight without the service's requests (the simulator node): no NaN but None, or the time its
    caller measured."""
    from mal_planner.closedloop.metrics import measure_flight
    from mal_planner.closedloop.simulator import FlightSimulator
    from mal_planner.scenario import load_scenario

    scenario = load_scenario(THESIS)
    sim = FlightSimulator(scenario)
    sim.advance(5.0)
    unmeasured = measure_flight(scenario, sim).to_dict()
    assert unmeasured["first_plan_s"] is None
    assert json.loads(jsonio.dumps(unmeasured), parse_constant=float)["min_landing_spacing_s"] is None
    assert measure_flight(scenario, sim, first_plan_s=2.5).first_plan_s == 2.5


def test_campaign_child_files_are_strict(tmp_path: Path) -> None:
    """The campaign's job file and the row its child writes (a scenario that does not validate: a row all the
    same, with timings that may be missing)."""
    from mal_planner.campaign.child import main

    job = tmp_path / "job.json"
    jsonio.write(job, {"source": "bad.yaml", "text": "name: bad\naircraft: [\n", "options": {"seed": 0},
                       "memory_limit_bytes": None})
    assert main([str(job), str(tmp_path / "row.json")]) == 0
    row = strict_load(tmp_path / "row.json")
    assert row["failure_class"] == "invalid_input" and "bad.yaml" in row["reason"]
    assert strict_load(job)["source"] == "bad.yaml"
