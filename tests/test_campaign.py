"""mal-campaign end to end on a real local Dask cluster with real IPOPT solves, plus its parts.

One small campaign (three generated 2-aircraft scenarios, a corrupt file, a run that dies, a run that exhausts
its memory limit) runs once per module; the faults go through the real runner path: the child process
reads ``MAL_CAMPAIGN_TEST_FAULTS`` (inherited through the Dask workers) and dies or allocates for real.
"""

from __future__ import annotations

import csv
import json
import signal
from pathlib import Path

import pytest

from mal_planner.campaign.child import FAULTS_ENV
from mal_planner.campaign.cli import main
from mal_planner.campaign.metrics import ray_clearance_nm
from mal_planner.campaign.results import COLUMNS, ResultsTable, read_rows
from mal_planner.campaign.traffic import TrafficSpec, generate_one
from mal_planner.errors import FAILURE_CLASSES, InfeasibleRequest, InvalidInput, classify
from mal_planner.initializer import PlanningFailed
from mal_planner.obstacles import Superquadric
from mal_planner.scenario import ScenarioError

REAL = [f"real-{i}.yaml" for i in range(3)]
FAULTS = {"dies.yaml": "exit", "segfaults.yaml": "segfault", "raises.yaml": "raise", "hog.yaml": "oom"}


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> dict:
    root = tmp_path_factory.mktemp("campaign")
    scenarios = root / "scenarios"
    scenarios.mkdir()
    for i, name in enumerate(REAL):
        (scenarios / name).write_text(generate_one(TrafficSpec((2, 2), seed=4, layout="wall"), i).text)
    for name in FAULTS:
        (scenarios / name).write_text((scenarios / REAL[0]).read_text())
    (scenarios / "corrupt.yaml").write_text("name: corrupt\naircraft: [\n")
    out = root / "out"
    args = [str(scenarios), "--out", str(out), "--workers", "2", "--timeout-s", "150", "--memory-limit-gb", "1",
            "--no-progress"]
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(FAULTS_ENV, ",".join(f"{k}={v}" for k, v in FAULTS.items()))
        code = main(args)
    rows = {Path(r["file"]).name: r for r in read_rows(out / "results.csv")}
    return {"code": code, "out": out, "scenarios": scenarios, "rows": rows, "args": args}


def test_every_scenario_gets_one_row_with_its_class(campaign: dict) -> None:
    assert campaign["code"] == 0
    rows = campaign["rows"]
    assert sorted(rows) == sorted([*REAL, *FAULTS, "corrupt.yaml"])
    header = (campaign["out"] / "results.csv").read_text().splitlines()[0]
    assert header.split(",") == list(COLUMNS)
    assert rows["corrupt.yaml"]["failure_class"] == "invalid_input" and "invalid YAML" in rows["corrupt.yaml"]["reason"]
    assert rows["dies.yaml"]["failure_class"] == "crash" and "exited with code 3" in rows["dies.yaml"]["reason"]
    assert rows["segfaults.yaml"]["failure_class"] == "crash" and "SIGSEGV" in rows["segfaults.yaml"]["reason"]
    assert rows["raises.yaml"]["failure_class"] == "crash"
    assert rows["raises.yaml"]["reason"] == "RuntimeError: injected fault"
    assert rows["hog.yaml"]["failure_class"] == "out_of_memory" and "MemoryError" in rows["hog.yaml"]["reason"]
    for row in rows.values():
        assert row["failure_class"] in ("", *FAILURE_CLASSES) and row["reason"] and "\n" not in row["reason"]
        assert (row["status"] == "ok") == (row["failure_class"] == "") == (row["verified"] == "true")
        assert float(row["peak_memory_mb"]) > 10 and row["seed"] == "0"


def test_real_runs_report_timings_iterations_and_plan_metrics(campaign: dict) -> None:
    real = [campaign["rows"][name] for name in REAL]
    assert all(r["n_aircraft"] == "2" and r["layout"] == "wall" and r["landing_times"] == "free" for r in real)
    verified = [r for r in real if r["status"] == "ok"]
    assert verified, [r["reason"] for r in real]
    for r in verified:
        stages = [float(r[k]) for k in ("initializer_s", "optimizer_s", "verification_s")]
        assert min(stages) > 0 and float(r["total_s"]) == pytest.approx(sum(stages), rel=1e-3)
        assert float(r["process_s"]) > float(r["total_s"])
        assert int(r["ipopt_iterations"]) > 0 and int(r["mesh_iterations"]) >= 1
        assert float(r["min_separation_nm"]) >= 0.25 - 1e-3
        assert 0.0 <= float(r["min_obstacle_clearance_nm"]) < 3.0
        assert r["landing_times_s"].count("=") == 2 and r["initializer_landing_times_s"].count("=") == 2
        assert float(r["max_delay_s"]) >= float(r["mean_delay_s"])
        # no wake table: first come, first served is the strategy, so its delay is the schedule's
        assert r["wake_mix"] == "" and r["sequencing_strategy"] == "fcfs" and r["sequencing_status"] == "heuristic"
        assert float(r["fcfs_delay_s"]) == pytest.approx(float(r["scheduled_delay_s"]), abs=1e-6)
        assert float(r["total_delay_s"]) >= 0.0
        assert float(r["min_landing_gap_ratio"]) >= 1.0 - 1e-4 and r["landing_pairs_below"] == "0"
    assert (campaign["out"] / "logs" / "real-0.log").read_text()


def test_summary_figures_and_record(campaign: dict) -> None:
    out = campaign["out"]
    summary = (out / "summary.md").read_text()
    assert "8 scenarios" in summary and "| 2 | 7 |" in summary  # N = 2: seven scenarios (the corrupt one has no N)
    assert "| crash | 3 |" in summary
    for cls in ("invalid_input", "out_of_memory"):
        assert f"| {cls} | 1 |" in summary
    for name in ("success_rate", "stage_times", "solve_times", "failure_classes"):
        assert (out / f"{name}.png").stat().st_size > 5_000 and f"({name}.png)" in summary
    record = json.loads((out / "campaign.json").read_text())
    assert record["plan_options"]["seed"] == 0 and record["engine"]["timeout_s"] == 150
    assert len(record["scenarios"]) == 8
    (out / "summary.md").unlink()
    assert main(["--out", str(out), "--summary-only"]) == 0
    assert (out / "summary.md").read_text() == summary


def test_resume_redoes_nothing_and_a_hang_times_out(campaign: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    out, scenarios = campaign["out"], campaign["scenarios"]
    before = (out / "results.csv").read_bytes()
    # were anything re-planned, it would die (exit) and change its row
    monkeypatch.setenv(FAULTS_ENV, ",".join(f"{name}=exit" for name in REAL) + ",hangs.yaml=hang")
    assert main([*campaign["args"], "--resume"]) == 0
    assert (out / "results.csv").read_bytes() == before
    (scenarios / "hangs.yaml").write_text((scenarios / REAL[0]).read_text())
    args = [*campaign["args"], "--resume"]
    args[args.index("--timeout-s") + 1] = "3"
    assert main(args) == 0
    after = (out / "results.csv").read_bytes()
    assert after.startswith(before)  # only the new scenario ran
    new = list(csv.DictReader(after[len(before):].decode().splitlines(), fieldnames=COLUMNS))
    assert len(new) == 1 and Path(new[0]["file"]).name == "hangs.yaml"
    assert new[0]["failure_class"] == "timeout" and 3.0 <= float(new[0]["process_s"]) < 20.0
    assert new[0]["n_aircraft"] == "2"  # known from the file although the run died


@pytest.mark.parametrize("extra, message", [
    (["--workers", "0"], "--workers: must be >= 1"),
    (["--initializer", "nope"], "--initializer: no such planner (known: multi-rrt"),
    (["--mesh-tol", "2"], "--mesh-tol: must be < 1, got 2.0"),
    (["--plan-time-limit-s", "0"], "--plan-time-limit-s: must be > 0, got 0.0"),
    (["--timeout-s", "0"], "--timeout-s: must be > 0"),
    (["missing.yaml"], "missing.yaml: no such scenario file"),
])
def test_bad_options_exit_2_before_planning(tmp_path: Path, capsys, extra: list[str], message: str) -> None:
    scenario = tmp_path / "one.yaml"
    scenario.write_text(generate_one(TrafficSpec((2, 2)), 0).text)
    assert main([str(scenario), "--out", str(tmp_path / "out"), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and not (tmp_path / "out" / "results.csv").exists()


def test_an_existing_table_needs_resume_and_the_same_options(campaign: dict, capsys) -> None:
    args = campaign["args"]
    assert main(args) == 2
    assert "exists; use --resume" in capsys.readouterr().err
    assert main([*args, "--resume", "--mesh-tol", "1e-3"]) == 2
    assert "plan options" in capsys.readouterr().err


def test_classify_maps_every_ending_to_one_class() -> None:
    assert classify(error=ScenarioError("f.yaml", "aircraft[0].speed", "bad")).failure_class == "invalid_input"
    assert classify(error=InvalidInput("x")).failure_class == "invalid_input"
    assert classify(error=InfeasibleRequest("too early")).failure_class == "infeasible_request"
    assert classify(error=PlanningFailed("no path")).failure_class == "initializer_failed"
    assert classify(error=MemoryError()).failure_class == "out_of_memory"
    assert classify(error=KeyError("k")).failure_class == "crash"
    assert classify(timed_out=5.0).failure_class == "timeout"
    dead = classify(exit_code=-signal.SIGSEGV, output_tail="last words\n")
    assert dead.failure_class == "crash" and "SIGSEGV" in dead.reason and "last words" in dead.reason
    assert classify(exit_code=-6, output_tail="std::bad_alloc").failure_class == "out_of_memory"


def test_ray_clearance_is_metric_for_spheres_and_box_faces() -> None:
    sphere = Superquadric("s", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), 2)
    box = Superquadric("b", (0.0, 3.0, 0.0), (1.0, 0.0005, 0.15), 50)
    assert ray_clearance_nm(sphere, [[3.0, 0.0, 0.0], [0.0, 0.5, 0.0]]) == pytest.approx([2.0, -0.5])
    assert ray_clearance_nm(box, [[0.0, 3.5, 0.0], [2.0, 3.0, 0.0]]) == pytest.approx([0.4995, 1.0], rel=1e-3)


def test_a_row_cut_short_by_an_interruption_is_dropped(tmp_path: Path) -> None:
    path = tmp_path / "results.csv"
    with ResultsTable(path) as table:
        table.append({"file": "/a.yaml", "status": "ok", "verified": True, "worker": "h:1"})
    with path.open("a") as f:
        f.write("/b.yaml,b,2,wall")  # the process died in the middle of a write
    with ResultsTable(path) as table:
        table.append({"file": "/c.yaml", "status": "failed", "failure_class": "timeout", "worker": "h:2"})
    rows = read_rows(path)
    assert [r["file"] for r in rows] == ["/a.yaml", "/c.yaml"] and rows[1]["failure_class"] == "timeout"


def test_summary_only_needs_a_table(tmp_path: Path, capsys) -> None:
    assert main(["--out", str(tmp_path), "--summary-only"]) == 2
    assert "no such campaign table" in capsys.readouterr().err


def test_plan_options_are_built_like_mal_plan() -> None:
    from mal_planner.campaign.cli import build_parser
    from mal_planner.campaign.plan_options import check_options, options_from_args, to_plan_options

    args = build_parser().parse_args(["x.yaml", "--out", "o", "--seed", "5", "--mesh-tol", "1e-4", "--no-refine",
                                      "--free-landing-times", "--plan-time-limit-s", "30"])
    options = options_from_args(args)
    plan = to_plan_options(options)
    assert check_options(options) is None
    assert (plan.seed, plan.landing.mesh_tol, plan.landing.refine, plan.landing.fixed_landing_times,
            plan.time_limit_s) == (5, 1e-4, False, False, 30.0)
    assert "--plan-time-limit-s" in check_options({**options, "time_limit_s": -1.0})


def _strict_json(path: Path) -> dict:
    def refuse(token: str) -> None:
        raise ValueError(f"{path}: {token} is not JSON")

    return json.loads(path.read_text(encoding="utf-8"), parse_constant=refuse)


def test_records_name_the_scenarios_relative_to_the_campaign_folder(campaign: dict) -> None:
    """No path of the machine in the committed files: results.csv, campaign.json, summary.md and the logs name the
    scenarios relative to the campaign folder; campaign.json is strict JSON."""
    out = campaign["out"]
    rows = read_rows(out / "results.csv")
    assert sorted(r["file"] for r in rows if "hangs" not in r["file"]) == sorted(
        f"../scenarios/{name}" for name in [*REAL, *FAULTS, "corrupt.yaml"])
    record = _strict_json(out / "campaign.json")
    assert all(s.startswith("../scenarios/") for s in record["scenarios"])
    machine = str(out.parent.resolve())
    for path in [out / "results.csv", out / "campaign.json", out / "summary.md", *(out / "logs").iterdir()]:
        assert machine not in path.read_text(encoding="utf-8"), path


def test_an_older_table_with_absolute_paths_resumes_and_summarizes(campaign: dict,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """A campaign folder written before (absolute paths): --resume plans nothing again, --summary-only reads it."""
    import shutil

    out = campaign["out"]
    old = out.parent / "old_out"
    shutil.copytree(out, old)
    with (old / "results.csv").open(encoding="utf-8", newline="") as fh:
        rows = list(csv.DictReader(fh))
    for row in rows:  # the key only: reasons name the files as they were given
        row["file"] = str((old / row["file"]).resolve())
    with (old / "results.csv").open("w", encoding="utf-8", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    absolute = (old / "results.csv").read_text(encoding="utf-8")
    assert str(out.parent.resolve()) in absolute
    monkeypatch.setenv(FAULTS_ENV, ",".join(f"{name}=exit" for name in [*REAL, "hangs.yaml"]))
    args = [*campaign["args"], "--resume"]
    args[args.index("--out") + 1] = str(old)
    assert main(args) == 0
    assert (old / "results.csv").read_text(encoding="utf-8").startswith(absolute)
    (old / "summary.md").unlink()
    assert main(["--out", str(old), "--summary-only"]) == 0
    assert (old / "summary.md").read_text(encoding="utf-8") == (out / "summary.md").read_text(encoding="utf-8")


def test_a_scenarios_log_keeps_its_story_without_the_optimizers_iterations() -> None:
    """A closed loop's log is mostly mesh and IPOPT iterations: the campaign keeps the rest, from the start."""
    from mal_planner.campaign.isolation import LOG_KEPT_CHARS, kept_log

    story = "12:00:00 I mal_planner.service: t=1.0 s: T07 holds (no plan)\n"
    chatter = "12:00:01 I mal_planner.ocp: mesh iter 0: segments=(2, 3) max_err=1e-3\n" * 5000
    kept = kept_log(story + chatter + "12:00:02 W mal_planner: partial plan\n")
    assert kept.startswith(story) and "mesh iter" not in kept and kept.endswith("partial plan\n")
    assert len(kept_log(story * (LOG_KEPT_CHARS // len(story) + 10))) == LOG_KEPT_CHARS


def test_a_summary_names_a_scenario_it_cannot_read(tmp_path: Path, caplog) -> None:
    """The closed-loop summary reads each scenario's separation from its file: a file moved away gives a warning
    naming it (its deviation is then not counted), not a silent gap; a readable one gives its minimum."""
    from mal_planner.campaign.summary import separation_of

    missing = tmp_path / "gone.yaml"
    with caplog.at_level("WARNING", logger="mal_planner.campaign"):
        assert separation_of({"file": str(missing)}) is None
    assert "gone.yaml" in caplog.text and "separation" in caplog.text
    assert separation_of({"file": "scenarios/thesis.yaml"}) == pytest.approx(0.25)
