"""Scaling benchmark (issue "Scale: twenty aircraft in seconds"): whole-process planning time against N.

Run (takes long for large N; about 2 cores are assumed, nothing else heavy should run meanwhile):

    .venv/bin/python benchmarks/bench_scaling.py --sizes 2,4,6,8,10,15,20 --repeats 3

Quick smoke test:

    .venv/bin/python benchmarks/bench_scaling.py --sizes 2,4 --repeats 1 --time-limit 120 --node-replan 4 \
        --out /tmp/bs_smoke

What it measures, each in a SEPARATE PROCESS so that imports, start-up and memory are those of a real run:

* Per N (``--sizes``): one arrival stream made by the project's traffic generator
  (:func:`mal_planner.campaign.traffic.generate_one`, as ``mal-traffic --aircraft N --seed S --layout wall
  --landing-times free`` writes it; the files are kept in ``<out>/scenarios``), planned ``--repeats`` times by
  the real CLI ``mal-plan <scenario> --figures none --out <tmp> -q --time-limit S`` of this venv. The per-stage
  times, IPOPT iterations, mesh iterations and the verified flag come from the ``plan.json`` it writes.
* The NLP size of the initial mesh (variables, constraints, Jacobian and upper-triangle Hessian non-zeros),
  which ``plan.json`` does not hold: a child process builds that NLP once for the same scenario
  (initializer multi-rrt seed 0, ``make_guesses``, ``LandingOptimizer``, ``OCPSolver.transcription``) and
  reads the sparsity patterns of CasADi's ``nlp_jac_g`` and ``nlp_hess_l``.
* The thesis scenario (``scenarios/thesis.yaml``) through ``mal-plan`` the same way, and the naive reference
  of ``benchmarks/naive_reference.py`` (one fixed trapezoidal mesh in CasADi Opti) on the same problem.
* Warm replans the way the ROS node makes them (``--node-replan``): one :class:`Planner` in a child process
  plans cold, then the aircraft are moved along the plan being followed by ``--replan-dt`` seconds, their
  states become radar tracks, the node's own ``build_plan_scenario`` makes the new scenario (landing times
  shifted) and ``planner.plan(new, start_time=t)`` replans with the node's default plan options; three times.
* Optionally (``--node-sim``) the real node under the radar simulator (``mal-launch --simulate``) with periodic
  replanning; the plan times are read from ``<out>/logs/planner.log`` ("plan #k: ... planned in X s").

Wall time and peak memory of a child: the child is started with ``subprocess.Popen`` and reaped with
``os.wait4(pid)`` in a helper thread. ``wait4`` returns the resource usage of exactly that child (and of the
descendants it waited for), so ``ru_maxrss`` is its own peak resident set size and ``ru_utime + ru_stime``
its CPU time, whatever else this process started before; ``getrusage(RUSAGE_CHILDREN)`` instead holds the
maximum over all children ever reaped, and ``/usr/bin/time`` is not installed everywhere. One catch: Linux
starts a child's ``maxrss`` at the resident size of the process it was forked from (the old memory map's high
water mark is kept at ``exec``), so this process imports nothing heavy (no NumPy, CasADi or the planner; the
scenarios are generated in a child too) until the last child has ended; its own peak, the floor of every
child's figure, is reported (about 20 MB, against 150-400 MB of a planning process). The wall time runs
from just before ``Popen`` to the moment ``wait4`` returns. A child still running after its hard timeout
(the planning time limit x 1.25 + 60 s) is killed with its process group and recorded as a timeout row; any
failure is a row with its reason, never a crash of the benchmark.

Outputs in ``--out`` (default ``benchmarks/scaling``): ``results.md`` (tables, fitted exponent), ``results.json``
(every raw row) and ``scaling.png`` (log-log, fitted line, N^2 reference). Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import json
import math
import os
import platform
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from mal_planner import jsonio
from mal_planner.errors import OUTCOMES

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
THESIS = REPO / "scenarios" / "thesis.yaml"
NAIVE = Path(__file__).resolve().parent / "naive_reference.py"
EXIT_MEANING = {code: " / ".join(o.name for o in OUTCOMES if o.exit_code == code)
                for code in {o.exit_code for o in OUTCOMES}}
"""mal-plan's exit codes (mal_planner.errors.OUTCOMES)."""


# ---------------------------------------------------------------------------------------------- processes
@dataclass
class Measured:
    wall_s: float
    returncode: int | None
    timed_out: bool
    peak_rss_mb: float | None
    cpu_s: float | None
    stderr_tail: str


def run_measured(cmd: list[str], timeout_s: float, log_dir: Path) -> Measured:
    """Run ``cmd`` in its own session; wall time, exit code, peak RSS and CPU time of exactly this child."""
    log_dir.mkdir(parents=True, exist_ok=True)
    box: dict[str, Any] = {}
    with (log_dir / "stdout.txt").open("wb") as out, (log_dir / "stderr.txt").open("wb") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, stdin=subprocess.DEVNULL, cwd=REPO,
                                start_new_session=True)

        def reap() -> None:
            _pid, status, usage = os.wait4(proc.pid, 0)
            box.update(end=time.perf_counter(), status=status, usage=usage)

        reaper = threading.Thread(target=reap, daemon=True)
        reaper.start()
        try:
            reaper.join(timeout_s)
        finally:
            timed_out = reaper.is_alive()
            if timed_out:  # our own child and its process group (start_new_session), by id
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)
                reaper.join()
    proc.returncode = os.waitstatus_to_exitcode(box["status"])  # Popen must not wait for it again
    usage = box["usage"]
    scale = 1024.0 * 1024.0 if sys.platform == "darwin" else 1024.0  # ru_maxrss: bytes on macOS, KiB on Linux
    tail = (log_dir / "stderr.txt").read_text(encoding="utf-8", errors="replace")[-600:]
    return Measured(box["end"] - t0, None if timed_out else proc.returncode, timed_out, usage.ru_maxrss / scale,
                    usage.ru_utime + usage.ru_stime, tail)


def _failure(m: Measured, what: str = "") -> str | None:
    if m.timed_out:
        return f"killed after the hard timeout ({m.wall_s:.0f} s)"
    if m.returncode not in (0, None):
        last = [ln for ln in m.stderr_tail.strip().splitlines() if ln.strip()]
        return f"exit {m.returncode}{' (' + what + ')' if what else ''}: {last[-1][:200] if last else 'no message'}"
    return None


def _progress(text: str) -> None:
    print(f"[bench] {text}", file=sys.stderr, flush=True)


def _hard_timeout(limit: float) -> float:
    return 1.25 * limit + 60.0


# ---------------------------------------------------------------------------------------------- runs
def child_generate(folder: str, sizes: list[int], seed: int, layout: str, landing_times: str,
                   profile: str = "thesis") -> dict[str, Any]:
    """Scenario 0 of ``mal-traffic --aircraft N --seed S --layout L --landing-times T --profile P`` per N: path or
    error."""
    from mal_planner.campaign.traffic import TrafficError, TrafficSpec, generate_one

    out: dict[str, Any] = {}
    for n in sizes:
        try:
            generated = generate_one(TrafficSpec(aircraft=(n, n), seed=seed, layout=layout,
                                                 landing_times=landing_times, profile=profile), 0)
        except TrafficError as exc:
            out[str(n)] = {"error": str(exc)}
            continue
        Path(folder).mkdir(parents=True, exist_ok=True)
        path = Path(folder) / f"n{n:02d}-seed{seed}-{layout}-{landing_times}-{profile}.yaml"
        path.write_text(generated.text, encoding="utf-8")
        out[str(n)] = {"path": str(path.resolve())}
    return out


def run_plan(scenario: Path, label: str, n: int, repeat: int, time_limit: float, work: Path) -> dict[str, Any]:
    """One ``mal-plan`` process; its row (process measurements and what plan.json says)."""
    out = work / f"{label}-r{repeat}"
    cmd = [str(BIN / "mal-plan"), str(scenario), "--figures", "none", "--out", str(out / "plan"), "-q",
           "--time-limit", f"{time_limit:g}"]
    m = run_measured(cmd, _hard_timeout(time_limit), out)
    row: dict[str, Any] = {"kind": "plan", "label": label, "n": n, "repeat": repeat, "scenario": str(scenario),
                           **asdict(m), "exit_meaning": EXIT_MEANING.get(m.returncode, "?") if m.returncode is not None
                           else "killed", "failure": None if m.returncode == 0 else _failure(m) or "?"}
    del row["stderr_tail"]
    plan_json = out / "plan" / "plan.json"
    if plan_json.is_file():
        try:
            doc = json.loads(plan_json.read_text(encoding="utf-8"))
        except ValueError as exc:
            row["failure"] = f"unreadable plan.json: {exc}"
            return row
        opt = doc.get("optimizer") or {}
        meshes = opt.get("mesh_iterations") or []
        timings = doc.get("timings_s") or {}
        row.update({
            "plan_json": True, "status": doc.get("status"), "verified": bool(doc.get("verified")),
            "initializer_s": timings.get("initializer_s"), "optimizer_s": timings.get("optimizer_s"),
            "verification_s": timings.get("verification_s"),
            "initializer_paths_s": (doc.get("initializer") or {}).get("timings_s", {}).get("total"),
            "nlp_iterations": opt.get("nlp_iterations"), "mesh_iterations": len(meshes),
            "nlp_build_s": opt.get("build_time_s"), "nlp_solve_s": opt.get("solve_time_s"),
            "optimizer_status": opt.get("status"), "objective": opt.get("objective"),
            "phases": len(opt.get("phases") or []),
            "final_segments": sum(meshes[-1]["segments"]) if meshes else None,
            "final_nodes": sum(sum(d) for d in meshes[-1]["degrees"]) if meshes else None,
        })
        if m.returncode not in (0, None) and not row.get("verified"):
            row["failure"] = _failure(m, row["exit_meaning"])
    else:
        row.update(plan_json=False, verified=False)
    return row


def run_child(kind: str, scenario: Path, label: str, n: int, work: Path, timeout: float, extra: list[str]
              ) -> dict[str, Any]:
    """A measurement in a child process of this script (or the naive reference); its JSON plus the process data."""
    folder = work / f"{label}-{kind}"
    folder.mkdir(parents=True, exist_ok=True)
    result = folder / "result.json"
    if kind == "naive":
        cmd = [sys.executable, str(NAIVE), str(scenario), "--json", str(result), *extra]
    else:
        cmd = [sys.executable, str(Path(__file__).resolve()), "--child", kind, str(scenario), "--child-json",
               str(result), *extra]
    m = run_measured(cmd, timeout, folder)
    row: dict[str, Any] = {"kind": kind, "label": label, "n": n, "scenario": str(scenario), **asdict(m)}
    del row["stderr_tail"]
    if result.is_file():
        row.update(json.loads(result.read_text(encoding="utf-8")))
        row.setdefault("failure", None)
    else:
        row["failure"] = _failure(m) or "no result written"
    return row


# ---------------------------------------------------------------------------------------------- child modes
def child_nlp_size(scenario_path: str) -> dict[str, Any]:
    """Size of the NLP of the initial mesh, built the way the Planner's first solve builds it."""
    from mal_planner.initializer import plan_initial
    from mal_planner.landing.base import LandingOptions
    from mal_planner.landing.solve import LandingOptimizer, make_guesses
    from mal_planner.scenario import load_scenario

    sc = load_scenario(scenario_path)
    initial = plan_initial(sc, "multi-rrt", seed=0)
    options = LandingOptions()
    optimizer = LandingOptimizer(sc, make_guesses(sc, initial, options), options)
    meshes = tuple(ph.mesh for ph in optimizer.problem.problem.phases)
    t0 = time.perf_counter()
    tr, _built = optimizer.solver.transcription(meshes)
    out: dict[str, Any] = {"variables": int(tr.n_w), "constraints": int(tr.lbg.size), "phases": len(meshes),
                           "segments": sum(m.n_segments for m in meshes),
                           "problem_setup_s": optimizer.setup_time, "nlp_build_s": time.perf_counter() - t0}
    try:
        jac = tr.solver.get_function("nlp_jac_g")
        out["jac_nnz"] = int(jac.sparsity_out(jac.n_out() - 1).nnz())
        hess = tr.solver.get_function("nlp_hess_l")
        out["hess_nnz"] = int(hess.sparsity_out(0).nnz())
        out["hess_note"] = hess.name_out(0)
    except Exception as exc:  # older/newer CasADi without these names: sizes only
        out["nnz_error"] = str(exc)
    # What the planner solves from LandingOptions.sequential_from aircraft on: one NLP per aircraft.
    from dataclasses import replace

    from mal_planner.landing.solve import uses_sequential

    out["strategy"] = "sequential" if uses_sequential(options, len(sc.aircraft)) else "joint"
    per_aircraft = []
    for guess in make_guesses(sc, initial, options):
        sub = replace(sc, aircraft=(sc.aircraft_by_callsign(guess.callsign),))
        one = LandingOptimizer(sub, [guess], options)
        one_tr, _ = one.solver.transcription(tuple(ph.mesh for ph in one.problem.problem.phases))
        per_aircraft.append(int(one_tr.n_w))
    out["per_aircraft_variables_max"] = max(per_aircraft)
    out["per_aircraft_variables_sum"] = sum(per_aircraft)
    return out


def node_plan_options():
    """The planner node's default plan options (config/planner.params.yaml has the same defaults)."""
    from mal_planner.ros.node_params import PARAMETERS, NodeParams

    return NodeParams(**{name: spec[0] for name, spec in PARAMETERS.items()}).plan_options()


class _Capture:
    """Collects the pipeline's log records of one plan (warm start, fallbacks)."""

    def __init__(self) -> None:
        import logging

        self.records: list[logging.LogRecord] = []
        handler = logging.Handler(logging.INFO)
        handler.emit = self.records.append  # type: ignore[method-assign]
        logger = logging.getLogger("mal_planner")
        logger.setLevel(logging.INFO)
        logger.addHandler(handler)
        logger.propagate = False

    def messages(self, min_level: int = 0) -> list[str]:
        return [r.getMessage() for r in self.records if r.levelno >= min_level]


def child_replan(scenario_path: str, time_limit: float, step: float, count: int) -> dict[str, Any]:
    """Cold plan, then ``count`` replans every ``step`` seconds the way the node makes them (see the docstring)."""
    import logging
    from dataclasses import replace

    import numpy as np

    from mal_planner.pipeline import Planner
    from mal_planner.scenario import load_scenario
    from mal_planner.service.inputs import build_plan_scenario
    from mal_planner.service.tracks import Track

    capture = _Capture()
    base = load_scenario(scenario_path)
    options = node_plan_options()
    planner = Planner(replace(options, time_limit_s=time_limit))  # the cold plan may need more than the node's
    t0 = time.perf_counter()
    cold = planner.plan(base, start_time=0.0)
    out: dict[str, Any] = {
        "node_time_limit_s": options.time_limit_s, "cold_time_limit_s": time_limit, "step_s": step,
        "cold": {"wall_s": time.perf_counter() - t0, "verified": cold.verified, "timings": cold.timings,
                 "failure": None if cold.failure is None else ": ".join(cold.failure)},
        "replans": [],
    }
    planner.options = options  # replans: the node's own options, time limit included
    followed = cold if cold.verified else None
    for k in range(1, count + 1):
        t_abs = k * step
        if followed is None:
            out["replans"].append({"t": t_abs, "failure": "no verified plan to follow"})
            continue
        capture.records.clear()
        t1 = time.perf_counter()
        tracks = {}
        for tr in followed.trajectories():  # the radar sees the aircraft where the followed plan put them
            state = np.asarray(tr.state_at(t_abs - followed.start_time), float)
            state[4] = (state[4] + math.pi) % (2 * math.pi) - math.pi
            tracks[tr.callsign] = Track(tr.callsign, t_abs, state, base.aircraft_by_callsign(tr.callsign).speed)
        inputs = build_plan_scenario(base, tracks, t_abs, t_abs)  # the node: landing times shifted by t - epoch
        try:
            result = planner.plan(inputs.scenario, start_time=t_abs)
        except Exception as exc:
            out["replans"].append({"t": t_abs, "wall_s": time.perf_counter() - t1, "failure": str(exc)})
            planner = Planner(options)
            continue
        wall = time.perf_counter() - t1
        messages = capture.messages()
        warnings = capture.messages(logging.WARNING)
        warm = any("(warm start)" in msg for msg in messages)
        landing = result.landing
        out["replans"].append({
            "t": t_abs, "wall_s": wall, "aircraft": len(inputs.scenario.aircraft), "warm": warm,
            "warm_solve_kept": warm and not any(w.startswith("warm replan") for w in warnings),
            "new_nlp": any("new NLP" in msg for msg in messages) or bool(landing and landing.build_time > 0),
            "verified": result.verified, "timings": result.timings,
            "nlp_iterations": landing.nlp_iterations if landing else None,
            "nlp_build_s": landing.build_time if landing else None, "fallbacks": warnings[:5],
            "failure": None if result.failure is None else ": ".join(result.failure),
        })
        if result.verified:  # after a failed replan the planner starts over by itself, as in the node
            followed = result
    return out


def child_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="bench_scaling.py --child")
    p.add_argument("--child", choices=["generate", "nlp-size", "replan"], required=True)
    p.add_argument("scenario", help="scenario file (generate: the output folder)")
    p.add_argument("--sizes", type=_int_list, default=[])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--layout", default="wall")
    p.add_argument("--profile", default="thesis")
    p.add_argument("--landing-times", default="free")
    p.add_argument("--child-json", type=Path, required=True)
    p.add_argument("--time-limit", type=float, default=300.0)
    p.add_argument("--replan-dt", type=float, default=5.0)
    p.add_argument("--replans", type=int, default=3)
    a = p.parse_args(argv)
    if a.child == "generate":
        result = child_generate(a.scenario, a.sizes, a.seed, a.layout, a.landing_times, a.profile)
    elif a.child == "nlp-size":
        result = child_nlp_size(a.scenario)
    else:
        result = child_replan(a.scenario, a.time_limit, a.replan_dt, a.replans)
    jsonio.write(a.child_json, result, indent=1, default=str)
    return 0


# ---------------------------------------------------------------------------------------------- node under the sim
PLAN_LINE = re.compile(r"plan #(\d+): [^;]*; (.*); planned in ([0-9.]+) s \((initializer [^)]*)\)")


def parse_planner_log(text: str) -> list[dict[str, Any]]:
    """The plans in a planner node log: number, reason, warm start, planned-in time and stage times."""
    plans: list[dict[str, Any]] = []
    current: dict[str, Any] = {}
    for line in text.splitlines():
        if "]: planning (" in line:
            current = {"reason": line.split("]: planning (", 1)[1].split("):", 1)[0], "warm": False}
        elif "(warm start)" in line:
            current["warm"] = True
        elif (match := PLAN_LINE.search(line)) is not None:
            stages = dict(re.findall(r"(\w+) ([0-9.]+) s", match.group(4)))
            status = match.group(2)
            plans.append({**current, "plan": int(match.group(1)), "status": status,
                          "verified": status.endswith(", verified"), "planned_in_s": float(match.group(3)),
                          **{f"{k}_s": float(v) for k, v in stages.items()}})
            current = {}
        elif "[ERROR]" in line and current:
            plans.append({**current, "failure": line.split("]: ", 2)[-1][:200]})
            current = {}
    return plans


def run_node_sim(scenario: Path, label: str, n: int, work: Path, duration: float, step: float,
                 time_limit: float) -> dict[str, Any]:
    import yaml

    folder = work / f"{label}-node-sim"
    folder.mkdir(parents=True, exist_ok=True)
    params = yaml.safe_load((REPO / "config" / "planner.params.yaml").read_text(encoding="utf-8"))
    values = params["planner"]["ros__parameters"]
    values.update(replan_period_s=float(step), figures="none")
    (folder / "params.yaml").write_text(yaml.safe_dump(params), encoding="utf-8")
    cmd = [str(BIN / "mal-launch"), "--simulate", "--scenario", str(scenario), "--duration", f"{duration:g}",
           "--params", str(folder / "params.yaml"), "--out", str(folder / "out"), "--no-record",
           "--timeout", f"{time_limit:g}"]
    m = run_measured(cmd, duration + _hard_timeout(time_limit) + 60.0, folder)
    row: dict[str, Any] = {"kind": "node_sim", "label": label, "n": n, "scenario": str(scenario),
                           "duration_s": duration, "replan_period_s": step, **asdict(m)}
    del row["stderr_tail"]
    log = folder / "out" / "logs" / "planner.log"
    row["plans"] = parse_planner_log(log.read_text(encoding="utf-8", errors="replace")) if log.is_file() else []
    row["failure"] = _failure(m) if not row["plans"] else None
    return row


# ---------------------------------------------------------------------------------------------- summary
def _median(values: list[float | None]) -> float | None:
    vals = [v for v in values if v is not None]
    return statistics.median(vals) if vals else None


def _f(value: float | None, digits: int = 2) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def _i(value: float | None) -> str:
    return "–" if value is None else f"{value:,.0f}"


def size_summary(rows: list[dict[str, Any]], label: str) -> dict[str, Any]:
    runs = [r for r in rows if r["kind"] == "plan" and r["label"] == label]
    done = [r for r in runs if r.get("plan_json")]
    verified = [r for r in runs if r.get("verified")]
    out: dict[str, Any] = {"runs": len(runs), "finished": len(done), "verified": len(verified),
                           "hit_limit": sum(r.get("returncode") == 4 or r.get("timed_out", False) for r in runs)}
    out["total_s"] = _median([r["wall_s"] for r in done])
    out["total_verified_s"] = _median([r["wall_s"] for r in verified])
    for key in ("initializer_s", "optimizer_s", "verification_s", "nlp_iterations", "mesh_iterations",
                "peak_rss_mb", "cpu_s", "objective"):
        out[key] = _median([r.get(key) for r in done])
    # Start-up, imports and output: the median over the runs of the process time minus its stage times.
    out["other_s"] = _median([r["wall_s"] - sum(r.get(k) or 0.0 for k in ("initializer_s", "optimizer_s",
                                                                         "verification_s")) for r in done])
    return out


def fit_exponent(points: list[tuple[int, float]]) -> tuple[float, float] | None:
    """Least squares of log t = log c + k log N; (k, c) or None with fewer than two sizes."""
    pts = [(n, t) for n, t in points if n > 0 and t and t > 0]
    if len({n for n, _ in pts}) < 2:
        return None
    xs, ys = [math.log(n) for n, _ in pts], [math.log(t) for _, t in pts]
    mx, my = statistics.fmean(xs), statistics.fmean(ys)
    k = sum((x - mx) * (y - my) for x, y in zip(xs, ys, strict=True)) / sum((x - mx) ** 2 for x in xs)
    return k, math.exp(my - k * mx)


def write_plot(path: Path, sizes: list[tuple[int, dict[str, Any]]], fit: tuple[float, float] | None,
               thesis: dict[str, Any] | None) -> None:
    from mal_planner.figures.style import apply_style, save

    apply_style()
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter, LogLocator, NullLocator

    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    pts = [(n, s["total_verified_s"]) for n, s in sizes if s["total_verified_s"]]
    if pts:
        ax.plot(*zip(*pts, strict=True), "o-", color="#1f77b4", label="whole process (median, verified runs)")
    opt = [(n, s["optimizer_s"]) for n, s in sizes if s["optimizer_s"]]
    if opt:
        ax.plot(*zip(*opt, strict=True), "s--", color="#ff7f0e", ms=4, lw=1.0, label="optimizer stage (median)")
    failed = [(n, s["total_s"]) for n, s in sizes if not s["total_verified_s"] and s["total_s"]]
    if failed:
        ax.plot(*zip(*failed, strict=True), "x", color="#d62728", ms=8, label="no verified run (median time)")
    ns = [n for n, _ in sizes] or [2, 20]
    grid = [min(ns) * (max(ns) / min(ns)) ** (i / 50) for i in range(51)] if max(ns) > min(ns) else ns
    if fit is not None:
        k, c = fit
        ax.plot(grid, [c * n**k for n in grid], color="#2ca02c", lw=1.2, label=f"fit {c:.3g}$\\cdot N^{{{k:.2f}}}$ s")
    if pts:
        n0, t0 = pts[0]
        ax.plot(grid, [t0 * (n / n0) ** 2 for n in grid], ":", color="#7f7f7f", label="$N^2$ reference")
    if thesis and thesis.get("total_verified_s"):
        ax.plot([3], [thesis["total_verified_s"]], "*", color="#9467bd", ms=11, label="thesis scenario (N = 3)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xticks(sorted(set(ns) | ({3} if thesis else set())))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_locator(NullLocator())
    ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_locator(NullLocator())
    ax.set(xlabel="aircraft N", ylabel="time (s)", title="Planning time against the number of aircraft")
    ax.legend(loc="upper left")
    fig.tight_layout()
    save(fig, path)


def _self_peak_mb() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / (1024.0 * 1024.0 if sys.platform == "darwin"
                                                                 else 1024.0)


def _version(package: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(package)
    except PackageNotFoundError:
        return "?"


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "?"


def _section(title: str, intro: str, columns: list[str]) -> list[str]:
    """The lines opening a results section: its heading, an explanatory paragraph, a table's header."""
    return [f"## {title}", "", intro, "", f"| {' | '.join(columns)} |", "|" + "---|" * len(columns)]


def write_markdown(path: Path, meta: dict[str, Any], rows: list[dict[str, Any]], sizes: list[int],
                   fit: tuple[float, float] | None, fit_sizes: list[int]) -> None:
    a = meta["args"]
    lines = [
        "# Scaling benchmark: planning time against the number of aircraft", "",
        f"Generated {meta['date']} on {meta['machine']} ({meta['cpus']} CPUs), mal-planner commit {meta['commit']}, "
        f"Python {meta['python']}, CasADi {meta['casadi']}.", "",
        f"Command: `{meta['command']}`", "",
        f"Scenarios: the traffic generator (`mal-traffic --aircraft N --seed {a['seed']} --layout {a['layout']} "
        f"--landing-times {a['landing_times']} --profile {a.get('profile', 'thesis')}`, scenario 0; the files are in "
        "`scenarios/` of the output folder). "
        "Each run is its own process: `mal-plan <scenario> --figures none --out <tmp> -q --time-limit "
        f"{a['time_limit']:g}`; median of {a['repeats']} repeat(s). *Total* is the wall time of that process "
        "(Python start-up, imports, planning, writing plan.json); the stage times come from its plan.json "
        "(`timings_s`), *other* is the rest (start-up, imports, output). Peak RSS and CPU time: `ru_maxrss` and "
        "`ru_utime + ru_stime` of that very child (`os.wait4`; its floor is the benchmark process's own "
        f"{_f(meta.get('bench_process_peak_rss_mb'), 0)} MB at the spawn). IPOPT iterations include every mesh "
        "iteration and the verification-driven re-solves. NLP size: the initial mesh, built once in a separate process "
        "(Hessian: upper triangle, as IPOPT takes it).", "",
        "## Whole process per N", "",
        "| N | verified/runs | total s | initializer s | optimizer s | verification s | other s | IPOPT it | "
        "mesh it | strategy | joint NLP vars | constraints | Jac nnz | Hess nnz | per-aircraft NLP vars (max / sum) | "
        "peak RSS MB | CPU s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for n in sizes:
        s = size_summary(rows, f"n{n}")
        nlp = next((r for r in rows if r["kind"] == "nlp-size" and r["label"] == f"n{n}"), {})
        note = "" if not s["hit_limit"] else f" ({s['hit_limit']} at the limit)"
        lines.append(f"| {n} | {s['verified']}/{s['runs']}{note} | {_f(s['total_s'])} | {_f(s['initializer_s'])} | "
                     f"{_f(s['optimizer_s'])} | {_f(s['verification_s'])} | {_f(s['other_s'])} | "
                     f"{_i(s['nlp_iterations'])} | {_i(s['mesh_iterations'])} | {nlp.get('strategy', '-')} | "
                     f"{_i(nlp.get('variables'))} | {_i(nlp.get('constraints'))} | {_i(nlp.get('jac_nnz'))} | "
                     f"{_i(nlp.get('hess_nnz'))} | {_i(nlp.get('per_aircraft_variables_max'))} / "
                     f"{_i(nlp.get('per_aircraft_variables_sum'))} | {_f(s['peak_rss_mb'], 0)} | {_f(s['cpu_s'], 1)} |")
    lines.append("")
    if fit is not None:
        k, c = fit
        lines.append(f"**Fitted growth:** total ≈ {c:.3g} · N^**{k:.2f}** s (least squares on log-log of the median "
                     f"whole-process time of the verified runs, over N = {', '.join(map(str, fit_sizes))}).")
    else:
        lines.append("**Fitted growth:** not enough sizes with a verified run for a fit.")
    lines.append("")

    thesis = size_summary(rows, "thesis")
    naive = [r for r in rows if r["kind"] == "naive"]
    if thesis["runs"] or naive:
        nlp = next((r for r in rows if r["kind"] == "nlp-size" and r["label"] == "thesis"), {})
        ok = [r for r in naive if r.get("success")]
        nv_total = _median([r["wall_s"] for r in naive if not r.get("timed_out")])
        nv_opt = _median([r.get("optimizer_s") for r in naive])
        lines += [
            "## Thesis scenario: ours against a naive fixed-mesh transcription", "",
            "Naive reference (`benchmarks/naive_reference.py`): the same multi-phase problem (same dynamics, "
            "obstacles, gate, separation, safety margins, fixed landing times, guess from the same initializer), "
            f"one uniform trapezoidal mesh of {a['naive_intervals']} intervals built with CasADi `Opti`, IPOPT "
            "defaults, no mesh refinement; its *optimizer* time is building plus solving the NLP. Its solution "
            "is checked by the project's verification too.", "",
            "| method | verified/runs | total s (process) | optimizer s | IPOPT it | NLP vars | constraints | "
            "Jac nnz | objective | peak RSS MB |", "|---|---|---|---|---|---|---|---|---|---|",
            f"| mal-plan (hp Radau, refinement to 1e-6, verification) | {thesis['verified']}/{thesis['runs']} | "
            f"{_f(thesis['total_s'])} | {_f(thesis['optimizer_s'])} | {_i(thesis['nlp_iterations'])} | "
            f"{_i(nlp.get('variables'))} (initial mesh) | {_i(nlp.get('constraints'))} | {_i(nlp.get('jac_nnz'))} | "
            f"{_f(thesis['objective'], 3)} | {_f(thesis['peak_rss_mb'], 0)} |",
        ]
        if naive:
            first = naive[0]
            lines.append(
                f"| naive (Opti, trapezoid, {first.get('intervals', a['naive_intervals'])} intervals) | "
                f"{sum(bool(r.get('verified')) for r in naive)}/{len(naive)} (IPOPT success {len(ok)}/{len(naive)})"
                f" | {_f(nv_total)} | {_f(nv_opt)} | {_i(_median([r.get('iterations') for r in naive]))} | "
                f"{_i(first.get('variables'))} | {_i(first.get('constraints'))} | {_i(first.get('jac_nnz'))} | "
                f"{_f(_median([r.get('objective') for r in naive]), 3)} | "
                f"{_f(_median([r.get('peak_rss_mb') for r in naive]), 0)} |")
            lines.append("")
            if thesis["total_s"] and nv_total:
                ratio_opt = nv_opt / thesis["optimizer_s"] if nv_opt and thesis["optimizer_s"] else None
                lines.append(f"**Ratio naive / ours:** whole process {nv_total / thesis['total_s']:.2f}×, optimizer "
                             f"stage {_f(ratio_opt)}× (ours includes hp refinement and the re-solves; the naive "
                             "one solves one fixed mesh).")
            reasons = sorted({"; ".join(r.get("verification_reasons") or []) for r in naive if not r.get("verified")})
            if reasons:
                lines.append(f"Naive solution not verified: {' | '.join(x or '?' for x in reasons)[:400]}.")
            statuses = sorted({str(r.get("status") or r.get("failure")) for r in naive})
            lines.append(f"Naive IPOPT status: {', '.join(statuses)}.")
        lines.append("")

    replans = [r for r in rows if r["kind"] == "replan"]
    if replans:
        lines += _section(
            "Warm replans as the node makes them",
            "One `Planner` in a child process with the node's default plan options: a cold plan (time limit "
            f"{a['time_limit']:g} s), then every {a['replan_dt']:g} s the aircraft are where the followed plan "
            "puts them, the node's `build_plan_scenario` turns those radar tracks into the new scenario, "
            "and `planner.plan(new, start_time=t)` replans (node time limit "
            f"{_f(replans[0].get('node_time_limit_s'), 0)} s). Replan time = building the scenario + the "
            "plan, like the node's \"planned in\". *warm*: the replan started warm (no initializer) and kept "
            "the warm solve (no fallback).",
            ["N", "cold plan s", "replans s", "median replan s", "optimizer s", "verification s", "warm", "verified",
             "IPOPT it", "peak RSS MB"])
        for r in replans:
            reps = r.get("replans") or []
            cold = r.get("cold") or {}
            if r.get("failure") and not reps:
                lines.append(f"| {r['n']} | failed: {r['failure'][:120]} | | | | | | | | |")
                continue
            lines.append(
                f"| {r['n']} | {_f(cold.get('wall_s'))}{'' if cold.get('verified') else ' (not verified)'} | "
                f"{', '.join(_f(x.get('wall_s')) for x in reps)} | {_f(_median([x.get('wall_s') for x in reps]))} | "
                f"{_f(_median([(x.get('timings') or {}).get('optimizer_s') for x in reps]))} | "
                f"{_f(_median([(x.get('timings') or {}).get('verification_s') for x in reps]))} | "
                f"{sum(bool(x.get('warm_solve_kept')) for x in reps)}/{len(reps)} | "
                f"{sum(bool(x.get('verified')) for x in reps)}/{len(reps)} | "
                f"{', '.join(_i(x.get('nlp_iterations')) for x in reps)} | {_f(r.get('peak_rss_mb'), 0)} |")
        lines.append("")

    sims = [r for r in rows if r["kind"] == "node_sim"]
    if sims:
        lines += _section(
            "The node under the radar simulator",
            f"`mal-launch --simulate --duration {a['node_sim_duration']:g}` with `replan_period_s` = "
            f"{a['replan_dt']:g} (the node replans that long after the previous plan ended) and no figures; "
            "the times are the node's own, from `logs/planner.log` (\"plan #k: ... planned in X s\").",
            ["scenario", "N", "plan", "reason", "warm", "planned in s", "initializer s", "optimizer s",
             "verification s", "verified"])
        for r in sims:
            if not r["plans"]:
                lines.append(f"| {r['label']} | {r['n']} | – | {r.get('failure')} | | | | | | |")
            for p in r["plans"]:
                verdict = p.get("failure") or ("yes" if p.get("verified") else "no")
                lines.append(f"| {r['label']} | {r['n']} | {p.get('plan', '–')} | {p.get('reason', '')} | "
                             f"{'yes' if p.get('warm') else 'no'} | {_f(p.get('planned_in_s'))} | "
                             f"{_f(p.get('initializer_s'))} | {_f(p.get('optimizer_s'))} | "
                             f"{_f(p.get('verification_s'))} | {verdict} |")
        for r in sims:
            warm = [p["planned_in_s"] for p in r["plans"] if p.get("warm") and "planned_in_s" in p]
            if warm:
                lines.append(f"{r['label']}: median warm replan {_f(_median(warm))} s over {len(warm)} replans.")
        lines.append("")

    failures = [r for r in rows if r.get("failure")]
    lines += ["## Failures", ""]
    lines += [f"- {r['kind']} {r['label']}{' repeat ' + str(r['repeat']) if 'repeat' in r else ''}: {r['failure']}"
              for r in failures] or ["None."]
    lines.append("")
    path.write_text("\n".join(lines), encoding="utf-8")


# ---------------------------------------------------------------------------------------------- main
def _int_list(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}") from None
    if any(v < 1 for v in values):
        raise argparse.ArgumentTypeError("sizes must be >= 1")
    return values


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", type=_int_list, default=[2, 4, 6, 8, 10, 15, 20], help="aircraft counts N")
    p.add_argument("--repeats", type=int, default=3, help="runs per size for the medians (default 3)")
    p.add_argument("--time-limit", type=float, default=300.0, help="mal-plan --time-limit per run, s (default 300)")
    p.add_argument("--layout", choices=["wall", "no-fly-zones"], default="wall", help="traffic layout")
    p.add_argument("--profile", choices=["thesis", "tma"], default="thesis",
                   help="traffic numbers: the thesis's box or a real terminal area (mal-traffic --profile)")
    p.add_argument("--landing-times", choices=["free", "fixed"], default="free",
                   help="free: no times in the files (the sequencer's schedule); fixed: the generator's")
    p.add_argument("--seed", type=int, default=0, help="traffic generator seed (default 0)")
    p.add_argument("--out", type=Path, default=REPO / "benchmarks" / "scaling", help="output folder")
    p.add_argument("--nlp-size", action=argparse.BooleanOptionalAction, default=True,
                   help="measure the initial NLP's size per N in a child process (default on)")
    p.add_argument("--nlp-size-max", type=int, default=20, help="skip the NLP size above this N (default 20)")
    p.add_argument("--thesis", action=argparse.BooleanOptionalAction, default=True,
                   help="the thesis scenario and the naive reference (default on)")
    p.add_argument("--naive-intervals", type=int, default=100, help="naive reference: intervals (default 100)")
    p.add_argument("--node-replan", type=_int_list, default=[10, 20], help="sizes for the warm replans (10,20)")
    p.add_argument("--no-node-replan", action="store_true", help="skip the warm replans")
    p.add_argument("--replan-dt", type=float, default=5.0, help="seconds between replans (default 5)")
    p.add_argument("--replans", type=int, default=3, help="replans after the cold plan (default 3)")
    p.add_argument("--node-sim", action="store_true",
                   help="also run the real node under the radar simulator (thesis and the --node-replan sizes)")
    p.add_argument("--node-sim-duration", type=float, default=30.0, help="simulated radar duration, s (default 30)")
    p.add_argument("--keep-work", action="store_true", help="keep the runs' folders (plan.json, logs) in <out>/work")
    return p


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if "--child" in argv:
        return child_main(argv)
    args = build_parser().parse_args(argv)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    # Nothing heavy is imported here before the last child has ended: a child's ru_maxrss starts from this
    # process's resident size at the spawn (see the module docstring).
    meta = {"date": dt.datetime.now().isoformat(timespec="seconds"), "machine": platform.platform(),
            "cpus": os.cpu_count(), "python": platform.python_version(), "casadi": _version("casadi"),
            "commit": _git("rev-parse", "--short", "HEAD") + (" (dirty)" if _git("status", "--porcelain", "-uno")
                                                             else ""),
            "command": " ".join(["benchmarks/bench_scaling.py", *argv]),
            "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()}}
    rows: list[dict[str, Any]] = []
    replan_sizes = [] if args.no_node_replan else args.node_replan
    all_sizes = sorted(set(args.sizes) | set(replan_sizes))
    scenario_dir = out / "scenarios"
    keep = tempfile.mkdtemp(prefix="work-", dir=out) if args.keep_work else None
    with tempfile.TemporaryDirectory(prefix="bench-scaling-") as tmp:
        work = Path(keep or tmp)
        scenarios: dict[int, Path] = {}
        gen = run_child("generate", scenario_dir, "traffic", 0, work, 600.0,
                        ["--sizes", ",".join(map(str, all_sizes)), "--seed", str(args.seed), "--layout", args.layout,
                         "--landing-times", args.landing_times, "--profile", args.profile])
        for n in all_sizes:
            entry = gen.get(str(n)) or {"error": gen.get("failure") or "not generated"}
            if "path" in entry:
                scenarios[n] = Path(entry["path"])
            else:
                rows.append({"kind": "generate", "label": f"n{n}", "n": n, "failure": entry["error"]})
                _progress(f"N={n}: no scenario: {entry['error']}")
        jobs: list[tuple[str, int, Path]] = [(f"n{n}", n, scenarios[n]) for n in args.sizes if n in scenarios]
        if args.thesis:
            jobs.append(("thesis", 3, THESIS))
        for label, n, path in jobs:
            for r in range(1, args.repeats + 1):
                row = run_plan(path, label, n, r, args.time_limit, work)
                rows.append(row)
                _progress(f"{label} (N={n}) repeat {r}/{args.repeats}: {row['wall_s']:.2f} s, "
                          f"{'verified' if row.get('verified') else row.get('failure')}, "
                          f"optimizer {_f(row.get('optimizer_s'))} s, {_i(row.get('nlp_iterations'))} IPOPT it, "
                          f"peak {_f(row.get('peak_rss_mb'), 0)} MB")
            if args.nlp_size and (label == "thesis" or n <= args.nlp_size_max):
                row = run_child("nlp-size", path, label, n, work, _hard_timeout(args.time_limit), [])
                rows.append(row)
                _progress(f"{label} (N={n}) NLP size: {row.get('variables')} variables, {row.get('constraints')} "
                          f"constraints, Jacobian nnz {row.get('jac_nnz')}, Hessian nnz {row.get('hess_nnz')}"
                          f"{'; ' + row['failure'] if row.get('failure') else ''}")
            if label == "thesis":
                for r in range(1, args.repeats + 1):
                    row = run_child("naive", path, "thesis", 3, work, _hard_timeout(args.time_limit),
                                    ["--intervals", str(args.naive_intervals)])
                    row["repeat"] = r
                    rows.append(row)
                    _progress(f"naive reference repeat {r}/{args.repeats}: {row['wall_s']:.2f} s, "
                              f"{row.get('status') or row.get('failure')}, optimizer {_f(row.get('optimizer_s'))} s, "
                              f"{row.get('iterations')} IPOPT it, verified {row.get('verified')}")
        replan_timeout = _hard_timeout(args.time_limit) + args.replans * _hard_timeout(60.0)
        for n in replan_sizes:
            if n not in scenarios:
                continue
            row = run_child("replan", scenarios[n], f"n{n}", n, work, replan_timeout,
                            ["--time-limit", f"{args.time_limit:g}", "--replan-dt", f"{args.replan_dt:g}",
                             "--replans", str(args.replans)])
            rows.append(row)
            reps = row.get("replans") or []
            _progress(f"warm replans N={n}: cold {_f((row.get('cold') or {}).get('wall_s'))} s, replans "
                      f"{', '.join(_f(x.get('wall_s')) for x in reps)} s, warm "
                      f"{[bool(x.get('warm_solve_kept')) for x in reps]}, verified "
                      f"{[bool(x.get('verified')) for x in reps]}{'; ' + row['failure'] if row.get('failure') else ''}")
        if args.node_sim:
            sims = ([("thesis", 3, THESIS)] if args.thesis else []) + [(f"n{n}", n, scenarios[n])
                                                                        for n in replan_sizes if n in scenarios]
            for label, n, path in sims:
                row = run_node_sim(path, label, n, work, args.node_sim_duration, args.replan_dt, args.time_limit)
                rows.append(row)
                _progress(f"node under the simulator {label}: "
                          f"{[(p.get('plan'), p.get('planned_in_s'), p.get('warm')) for p in row['plans']]}"
                          f"{'; ' + row['failure'] if row.get('failure') else ''}")

    meta["bench_process_peak_rss_mb"] = _self_peak_mb()
    fit_pts, fit_sizes = [], []
    sizes_summary = []
    for n in args.sizes:
        s = size_summary(rows, f"n{n}")
        sizes_summary.append((n, s))
        if s["total_verified_s"]:
            fit_pts.append((n, s["total_verified_s"]))
            fit_sizes.append(n)
    fit = fit_exponent(fit_pts)
    thesis = size_summary(rows, "thesis") if args.thesis else None
    summary = {"sizes": {str(n): s for n, s in sizes_summary}, "thesis": thesis,
               "fit": None if fit is None else {"exponent": fit[0], "coefficient_s": fit[1], "sizes": fit_sizes}}
    jsonio.write(out / "results.json", {"meta": meta, "summary": summary, "rows": rows}, indent=1, default=str)
    write_markdown(out / "results.md", meta, rows, args.sizes, fit, fit_sizes)
    try:
        write_plot(out / "scaling.png", sizes_summary, fit, thesis)
    except Exception as exc:  # the tables matter more than the picture
        _progress(f"plot failed: {exc}")
    _progress(f"wrote {out / 'results.md'}, {out / 'results.json'}, {out / 'scaling.png'}"
              + (f"; fitted exponent {fit[0]:.2f}" if fit else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
