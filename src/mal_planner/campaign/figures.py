"""The campaign's PNG figures, in the team's figure style (:mod:`mal_planner.figures.style`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from mal_planner.campaign.aggregates import STAGES, failure_counts, fit_growth, stage_medians, success_by_n
from mal_planner.campaign.results import as_float


def _pyplot():
    from mal_planner.figures.style import apply_style

    apply_style()
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    from mal_planner.figures.style import save

    fig.tight_layout()
    return save(fig, path)


def figure_success(rows: Sequence[dict[str, str]], path: Path) -> Path:
    plt = _pyplot()
    by_n = success_by_n(rows)
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ns = list(by_n)
    rates = [100.0 * ok / total for ok, total in by_n.values()]
    bars = ax.bar([str(n) for n in ns], rates, color="tab:green")
    for bar, (ok, total) in zip(bars, by_n.values(), strict=True):
        ax.annotate(f"{ok}/{total}", (bar.get_x() + bar.get_width() / 2, bar.get_height()), ha="center",
                    va="bottom", fontsize=8)
    ax.set(xlabel="aircraft N", ylabel="verified plans (%)", ylim=(0, 110), title="Success rate per N")
    return _save(fig, path)


def figure_stage_times(rows: Sequence[dict[str, str]], path: Path) -> Path:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    for stage, marker in zip(STAGES, "osv*", strict=True):
        medians = stage_medians(rows, stage)
        if not medians:
            continue
        ns, ts = np.array(list(medians)), np.array(list(medians.values()))
        keep = ts > 0
        growth = fit_growth(list(ns), list(ts))
        label = stage.removesuffix("_s") + (f" (~N^{growth.exponent:.2f})" if growth else "")
        line, = ax.loglog(ns[keep], ts[keep], marker=marker, label=label)
        if growth:
            grid = np.linspace(ns.min(), ns.max(), 50)
            ax.loglog(grid, growth.coefficient * grid ** growth.exponent, "--", color=line.get_color(), lw=0.8)
    from matplotlib.ticker import FormatStrFormatter, NullFormatter

    ns_all = sorted({n for stage in STAGES for n in stage_medians(rows, stage)})
    if ns_all:
        ax.set_xticks(ns_all)
    ax.xaxis.set_major_formatter(FormatStrFormatter("%d"))
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.set(xlabel="aircraft N", ylabel="median time (s)", title="Time per stage (dashed: fitted c N^k)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)


def figure_solve_times(rows: Sequence[dict[str, str]], path: Path) -> Path:
    plt = _pyplot()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.5))
    groups = {"verified": [r for r in rows if r["status"] == "ok"], "failed": [r for r in rows if r["status"] != "ok"]}
    every = [t for r in rows if (t := as_float(r["process_s"])) is not None]
    bins = np.histogram_bin_edges(every, bins=20) if every else 20
    for label, sel in groups.items():
        times = np.sort([t for r in sel if (t := as_float(r["process_s"])) is not None])
        if times.size == 0:
            continue
        ax1.hist(times, bins=bins, alpha=0.6, label=f"{label} ({times.size})")
        ax2.step(np.concatenate([[times[0]], times]), np.arange(times.size + 1) / times.size, where="post",
                 label=label)
    ax1.set(xlabel="wall time per scenario (s)", ylabel="scenarios", title="Histogram")
    ax2.set(xlabel="wall time per scenario (s)", ylabel="fraction", title="ECDF", xscale="log")
    for ax in (ax1, ax2):
        ax.legend(fontsize=8)
        ax.grid(True, alpha=0.3)
    return _save(fig, path)


def figure_failures(rows: Sequence[dict[str, str]], path: Path) -> Path:
    plt = _pyplot()
    counts = failure_counts(rows)
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.barh(list(counts), list(counts.values()), color="tab:red")
    ax.invert_yaxis()
    ax.set(xlabel="scenarios", title="Failure classes")
    return _save(fig, path)


def figure_closed_loop(rows: Sequence[dict[str, str]], path: Path) -> Path:
    """Closed-loop runs: the smallest separation flown per run against N, the largest deviation from the plans, and
    every replan's planning time (ECDF)."""
    plt = _pyplot()
    flown = [r for r in rows if r.get("cl_landed")]
    fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(12, 3.6))
    rng = np.random.default_rng(0)
    for ok, color, label in ((True, "tab:green", "success"), (False, "tab:red", "failed")):
        sel = [r for r in flown if (r["status"] == "ok") == ok]
        pts = [(n, v) for r in sel if (n := as_float(r["n_aircraft"])) is not None
               and (v := as_float(r.get("cl_separation_ratio", ""))) is not None]
        if pts:
            n, v = np.array(pts).T
            ax1.scatter(n + rng.uniform(-0.2, 0.2, n.size), v, s=10, color=color, label=f"{label} ({len(sel)})")
        devs = [v for r in sel if (v := as_float(r.get("cl_max_deviation_nm", ""))) is not None]
        if devs:
            ax2.hist(devs, bins=np.linspace(0.0, max(0.2, max(devs)), 30), alpha=0.6, color=color, label=label)
    ax1.axhline(1.0, color="k", lw=0.8, ls="--")
    ax1.set(xlabel="aircraft N", ylabel="smallest separation flown (minima)", title="Closest pair per run")
    ax2.set(xlabel="largest deviation from the plan flown (nm)", ylabel="runs", title="Deviation per run")
    times = np.sort([float(x) for r in flown for x in r.get("cl_replan_times_s", "").split(";") if x])
    if times.size:
        ax3.step(np.concatenate([[times[0]], times]), np.arange(times.size + 1) / times.size, where="post")
        ax3.set_xscale("log")
    ax3.set(xlabel="replan planning time, charged (s)", ylabel="fraction of replans",
            title=f"Replans ({times.size})")
    for ax in (ax1, ax2, ax3):
        ax.grid(True, alpha=0.3)
    for ax in (ax1, ax2):
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    return _save(fig, path)


def figure_delay(rows: Sequence[dict[str, str]], path: Path) -> Path:
    """Verified plans: each scenario's total delay (planned landings) against first come, first served's on the
    same problem (left; below the diagonal: the sequence saved delay), and the saving per N (right)."""
    plt = _pyplot()
    pts = [(n, f, d) for r in rows if r["status"] == "ok" and (n := as_float(r["n_aircraft"])) is not None
           and (f := as_float(r.get("fcfs_delay_s") or "")) is not None
           and (d := as_float(r.get("total_delay_s") or "")) is not None]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    if pts:
        n, fcfs, ours = np.array(pts).T
        top = max(float(fcfs.max()), float(ours.max()), 1.0) * 1.05
        ax1.plot([0.0, top], [0.0, top], "k--", lw=0.8, label="equal")
        dots = ax1.scatter(fcfs, ours, s=12, c=n, cmap="viridis", label=f"scenarios ({n.size})")
        fig.colorbar(dots, ax=ax1, label="aircraft N")
        ax1.set(xlim=(0.0, top), ylim=(0.0, top))
        sizes = sorted(set(n.tolist()))
        ax2.boxplot([fcfs[n == k] - ours[n == k] for k in sizes], positions=sizes, widths=0.6)
        ax2.set_xticks(sizes, [f"{k:g}" for k in sizes])
        ax1.legend(fontsize=8)
    ax1.set(xlabel="first come, first served: total delay (s)", ylabel="optimal sequence, planned: total delay (s)",
            title="Total delay per scenario")
    ax2.set(xlabel="aircraft N", ylabel="delay saved (s)", title="Saving against first come, first served")
    for ax in (ax1, ax2):
        ax.grid(True, alpha=0.3)
    return _save(fig, path)


def write_figures(rows: Sequence[dict[str, str]], out_dir: Path) -> list[Path]:
    out_dir = Path(out_dir)
    paths = [figure_success(rows, out_dir / "success_rate.png"),
             figure_stage_times(rows, out_dir / "stage_times.png"),
             figure_solve_times(rows, out_dir / "solve_times.png"),
             figure_failures(rows, out_dir / "failure_classes.png")]
    if any(r.get("fcfs_delay_s") and r.get("total_delay_s") for r in rows):
        paths.append(figure_delay(rows, out_dir / "delay_vs_fcfs.png"))
    if any(r.get("cl_landed") for r in rows):
        paths.append(figure_closed_loop(rows, out_dir / "closed_loop.png"))
    return paths
