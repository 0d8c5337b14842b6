"""The mal-plan command: outputs, JSON schema, error handling."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from mal_planner.cli import main


def test_initial_only_writes_json_and_figures(tmp_path: Path, capsys) -> None:
    assert main(["scenarios/thesis.yaml", "--initial-only", "--seed", "3", "--out", str(tmp_path), "-q"]) == 0
    out = capsys.readouterr().out
    assert "landing order A1 -> A2 -> A3" in out and "initial trajectories only" in out
    doc = json.loads((tmp_path / "plan.json").read_text())
    assert doc["schema"] == "mal-planner/plan" and doc["version"] == 1 and doc["status"] == "initial_guess"
    assert doc["units"] == {"length": "nm", "time": "s", "angle": "rad", "speed": "nm/s"}
    assert [a["callsign"] for a in doc["aircraft"]] == doc["landing_order"] == ["A1", "A2", "A3"]
    first = doc["aircraft"][0]
    assert first["initial"]["waypoint"] is None and first["order"] == 1
    assert any(a["initial"]["waypoint_index"] is not None for a in doc["aircraft"][1:])  # a later one is stretched
    assert set(first["trajectory"]) >= {"t", "x", "y", "z", "gamma", "heading"}
    for name in ("initial_paths_3d", "initial_x", "initial_y", "initial_z"):
        assert (tmp_path / f"{name}.png").stat().st_size > 10_000


def test_full_run_reproduces_the_thesis(tmp_path: Path, capsys) -> None:
    assert main(["scenarios/thesis.yaml", "--out", str(tmp_path), "-q"]) == 0
    out = capsys.readouterr().out
    assert "verified" in out and "NOT verified" not in out
    doc = json.loads((tmp_path / "plan.json").read_text())
    assert doc["status"] == "optimal" and doc["verified"] is True
    assert doc["outcome"] == {"name": "success", "reason": "", "error_code": 0, "exit_code": 0}
    assert doc["optimizer"]["mesh_iterations"][-1]["max_error"] <= 1e-5  # the default mesh tolerance
    traj = doc["aircraft"][0]["trajectory"]
    assert {"n_h", "n_v", "phase"} <= set(traj) and len(traj["t"]) == len(traj["n_h"])
    assert doc["verification"]["pairs"] and doc["verification"]["verified"] is True
    report = (tmp_path / "report.md").read_text()
    assert "Table 6-1" in report and "**verified: true**" in report
    for name in ("overview.png", "paths_3d.png", "yz_view.png", "states.png", "controls.png", "separation.png",
                 "plan.html"):
        assert (tmp_path / name).exists(), name


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["missing.yaml"], "missing.yaml: cannot read file"),
        (["scenarios/thesis.yaml", "--initializer", "ompl:Nope"], "--initializer: no such planner (known: "),
    ],
)
def test_errors_are_one_line_with_exit_code_2(args, message) -> None:
    proc = subprocess.run([sys.executable, "-m", "mal_planner.cli", *args], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in proc.stderr


def test_invalid_scenario_field(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    text = Path("scenarios/thesis.yaml").read_text().replace("speed: 0.04, model: point_mass, wake_category: M, "
                                                            "landing_time: 170.0", "speed: -1, model: point_mass, "
                                                            "wake_category: M, landing_time: 170.0")
    bad.write_text(text)
    proc = subprocess.run([sys.executable, "-m", "mal_planner.cli", str(bad)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip() == f"mal-plan: error: {bad}: aircraft[1].speed: must be > 0 nm/s, got -1"


def test_unverified_plan_exits_3(tmp_path: Path, capsys) -> None:
    """A coarse mesh (no refinement) solves, but the flown trajectory drifts: the verification says so."""
    code = main(["scenarios/thesis.yaml", "--no-refine", "--no-figures", "--out", str(tmp_path), "-q"])
    out = capsys.readouterr().out
    assert code == 3 and "NOT verified" in out
    doc = json.loads((tmp_path / "plan.json").read_text())
    assert doc["status"] == "optimal" and doc["verified"] is False and doc["verification"]["reasons"]
