"""``mal-campaign``: plan many scenario files in parallel on a Dask cluster; write results.csv and summary.md."""

from __future__ import annotations

import argparse
import json
import logging
import platform
import sys
import time
from pathlib import Path
from typing import Any

from mal_planner import jsonio
from mal_planner.campaign.paths import campaign_key, scenario_path
from mal_planner.campaign.plan_options import DEFAULTS, add_plan_arguments, check_options, options_from_args
from mal_planner.campaign.results import ResultsFormatError, ResultsTable, done_files, read_rows
from mal_planner.campaign.runner import EngineSettings, ScenarioJob, default_workers, run_campaign

log = logging.getLogger("mal_planner.campaign")
PROG = "mal-campaign"


class UsageError(ValueError):
    """Bad input found before any planning: one line naming what, where and why (exit 2)."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Plan every scenario with the normal pipeline (initializer, optimizer, verification), each in "
                    "its own process with a time and memory limit, in parallel on a Dask cluster (a local one "
                    "unless --address). Writes OUT/results.csv row by row, OUT/summary.md and figures.")
    parser.add_argument("scenarios", nargs="*", type=Path, help="scenario YAML files or folders of them")
    parser.add_argument("--out", type=Path, required=True, help="campaign folder (results.csv, summary.md, logs/)")
    parser.add_argument("--workers", type=int, default=None,
                        help="worker processes of the local cluster (default: the number of cores, at most 8)")
    parser.add_argument("--address", default=None, help="scheduler address of an existing Dask cluster")
    parser.add_argument("--timeout-s", type=float, default=600.0,
                        help="time limit per scenario, seconds (default: %(default)s)")
    parser.add_argument("--memory-limit-gb", type=float, default=4.0,
                        help="address-space limit of each planning process, GiB; 0: none (default: %(default)s)")
    parser.add_argument("--resume", action="store_true", help="skip the scenarios already in OUT/results.csv")
    parser.add_argument("--summary-only", action="store_true",
                        help="only rewrite OUT/summary.md and the figures from OUT/results.csv")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("-q", "--quiet", action="store_true", help="warnings only")
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    add_plan_arguments(parser)
    return parser


def scenario_files(paths: list[Path]) -> list[Path]:
    """Files given, folders expanded to their *.yaml / *.yml (sorted), duplicates dropped; UsageError if missing."""
    files: list[Path] = []
    for path in paths:
        if path.is_dir():
            found = sorted([*path.glob("*.yaml"), *path.glob("*.yml")])
            if not found:
                raise UsageError(f"{path}: folder holds no *.yaml scenario files")
            files.extend(found)
        elif path.is_file():
            files.append(path)
        else:
            raise UsageError(f"{path}: no such scenario file")
    unique = dict.fromkeys(p.resolve() for p in files)
    return list(unique)


def make_job(path: Path, out: Path) -> ScenarioJob:
    """The job of one file (keyed by its path relative to the campaign folder ``out``): its text, and the columns
    a cheap validation gives (none if it does not validate)."""
    from mal_planner.campaign.metrics import scenario_columns
    from mal_planner.scenario import ScenarioError, load_scenario

    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"{path}: cannot read the scenario file ({exc})") from None
    try:
        known = scenario_columns(load_scenario(path))
    except ScenarioError:
        known = {}  # planned anyway: the worker records it as invalid_input
    return ScenarioJob(campaign_key(path, out), text, known)


def check_settings(args: argparse.Namespace) -> EngineSettings:
    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers: must be >= 1, got {args.workers}")
    if args.address and args.workers is not None:
        raise UsageError("--workers: the size of an existing cluster (--address) is set where it was started")
    if not args.timeout_s > 0:
        raise UsageError(f"--timeout-s: must be > 0, got {args.timeout_s}")
    if args.memory_limit_gb < 0 or (0 < args.memory_limit_gb < 0.5):
        raise UsageError(f"--memory-limit-gb: must be 0 (no limit) or >= 0.5, got {args.memory_limit_gb}")
    memory = int(args.memory_limit_gb * 2**30) or None
    return EngineSettings(workers=args.workers or default_workers(), address=args.address, timeout_s=args.timeout_s,
                          memory_limit_bytes=memory)


def campaign_record(options: dict[str, Any], settings: EngineSettings, files: list[Path], out: Path) -> dict[str, Any]:
    from importlib.metadata import version

    return {"schema": "mal-planner/campaign", "version": 1, "plan_options": options,
            "engine": {"kind": "dask", "address": settings.address, "workers": settings.workers,
                       "timeout_s": settings.timeout_s, "memory_limit_bytes": settings.memory_limit_bytes},
            "scenarios": [campaign_key(f, out) for f in files],
            "software": {"mal-planner": version("mal-planner"), "distributed": version("distributed"),
                         "python": platform.python_version()},
            "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}


def check_resume(out: Path, resume: bool, options: dict[str, Any]) -> set[Path]:
    """Files already done (with --resume; their keys relative or, in older tables, absolute); UsageError when the
    folder holds another campaign."""
    table, record = out / "results.csv", out / "campaign.json"
    if not table.exists():
        return set()
    if not resume:
        raise UsageError(f"{table}: exists; use --resume to continue that campaign or another --out")
    if record.exists():
        previous = {**DEFAULTS, **(json.loads(record.read_text(encoding="utf-8")).get("plan_options") or {})}
        if previous != options:  # options added since that campaign count with their defaults
            raise UsageError(f"{record}: plan options {previous} differ from this run's {options}; "
                             "resume with the same options")
    try:
        return {scenario_path(key, out) for key in done_files(read_rows(table))}
    except ResultsFormatError as exc:
        raise UsageError(str(exc)) from None


def write_summary(out: Path) -> Path:
    """summary.md and the figures from results.csv (the rows' files as paths on this machine, either form)."""
    from mal_planner.campaign.summary import write_summary as write

    rows = [{**row, "file": str(scenario_path(row["file"], out))} for row in read_rows(out / "results.csv")]
    return write(rows, out)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_intermixed_args(argv)
    level = logging.WARNING if args.quiet else (logging.DEBUG if args.verbose else logging.INFO)
    logging.basicConfig(level=level, format="%(asctime)s %(levelname).1s %(name)s: %(message)s", datefmt="%H:%M:%S")
    for noisy in ("distributed", "matplotlib"):
        logging.getLogger(noisy).setLevel(max(level, logging.WARNING))
    out: Path = args.out
    try:
        if args.summary_only:
            if not (out / "results.csv").is_file():
                raise UsageError(f"{out / 'results.csv'}: no such campaign table")
            print(f"{PROG}: wrote {write_summary(out)}")
            return 0
        if not args.scenarios:
            raise UsageError("SCENARIOS: give at least one scenario file or folder")
        settings = check_settings(args)
        options = options_from_args(args)
        problem = check_options(options)
        if problem:
            raise UsageError(problem)
        files = scenario_files(args.scenarios)
        if out.exists() and not out.is_dir():
            raise UsageError(f"--out: {out} is not a folder")
        done = check_resume(out, args.resume, options)
        todo = [f for f in files if f not in done]
        jobs = [make_job(f, out) for f in todo]
    except (UsageError, ResultsFormatError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    logs_dir = out / "logs"
    logs_dir.mkdir(parents=True, exist_ok=True)
    jsonio.write(out / "campaign.json", campaign_record(options, settings, files, out))
    log.info("%d scenarios, %d already in %s, %d to plan", len(files), len(files) - len(todo), out / "results.csv",
             len(jobs))
    t0 = time.perf_counter()
    interrupted = False
    with ResultsTable(out / "results.csv") as table:
        try:
            run_campaign(jobs, options, settings, table, logs_dir, progress=not args.no_progress)
        except KeyboardInterrupt:
            interrupted = True
            print(f"{PROG}: interrupted; the rows so far are in {out / 'results.csv'} (continue with --resume)",
                  file=sys.stderr)
    summary = write_summary(out)
    rows = read_rows(out / "results.csv")
    ok = sum(r["status"] == "ok" for r in rows)
    print(f"{PROG}: {len(rows) - len(done)} of {len(jobs)} planned in {time.perf_counter() - t0:.0f} s; "
          f"{ok}/{len(rows)} verified in the table; wrote {out / 'results.csv'}, {summary}")
    return 130 if interrupted else 0


if __name__ == "__main__":
    sys.exit(main())
