"""``summary.md`` of a campaign: success per N, time per stage against N with growth exponents, solve-time
distribution, failure classes. Computed from the rows of results.csv only (:mod:`.aggregates`); the figures are
:mod:`.figures`."""

from __future__ import annotations

import logging
import re
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from mal_planner.campaign.aggregates import STAGES, failure_counts, fit_growth, n_of, stage_medians, success_by_n
from mal_planner.campaign.figures import write_figures
from mal_planner.campaign.results import as_float

log = logging.getLogger("mal_planner.campaign")


def typical_reasons(rows: Sequence[dict[str, str]], failure_class: str, k: int = 2) -> list[tuple[str, int]]:
    """The most common reasons of a class (numbers stripped so that similar reasons count together)."""
    def shape(reason: str) -> str:
        return re.sub(r"\d+(\.\d+)?", "#", reason)[:120]

    counter = Counter(shape(r["reason"]) for r in rows if r["failure_class"] == failure_class)
    return counter.most_common(k)


def quantiles(values: Sequence[float]) -> str:
    if not values:
        return "| - | - | - | - | - | - |"
    q = np.quantile(values, [0.0, 0.25, 0.5, 0.75, 0.9, 1.0])
    return "| " + " | ".join(f"{v:.1f}" for v in q) + " |"


def _fmt(value: float | None, digits: int = 2) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def summary_markdown(rows: Sequence[dict[str, str]], figures: Sequence[Path] = ()) -> str:
    ok = sum(r["status"] == "ok" for r in rows)
    lines = ["# Campaign summary", "",
             f"{len(rows)} scenarios, {ok} verified ({100.0 * ok / max(len(rows), 1):.1f} %).", "",
             "## Success rate per number of aircraft", "",
             "| N | scenarios | verified | success rate | failures (class: count) |", "|---|---|---|---|---|"]
    for n, (n_ok, total) in success_by_n(rows).items():
        classes = Counter(r["failure_class"] for r in rows if n_of(r) == n and r["failure_class"])
        detail = ", ".join(f"{c}: {k}" for c, k in sorted(classes.items())) or "-"
        lines.append(f"| {n} | {total} | {n_ok} | {100.0 * n_ok / total:.0f} % | {detail} |")
    layouts = sorted({r["layout"] for r in rows if r["layout"]})
    if len(layouts) > 1:
        lines += ["", "| layout | scenarios | verified | success rate |", "|---|---|---|---|"]
        for layout in layouts:
            sel = [r for r in rows if r["layout"] == layout]
            n_ok = sum(r["status"] == "ok" for r in sel)
            lines.append(f"| {layout} | {len(sel)} | {n_ok} | {100.0 * n_ok / len(sel):.0f} % |")
    lines += ["", "## Failure classes", "", "| class | count | typical reasons |", "|---|---|---|"]
    for cls, count in failure_counts(rows).items():
        reasons = "; ".join(f"{reason} ({k}x)" for reason, k in typical_reasons(rows, cls)) if count else ""
        lines.append(f"| {cls} | {count} | {reasons.replace('|', '/')} |")
    lines += ["", "## Time per stage against N (median seconds over the runs where the stage ran)", "",
              "| N | initializer | optimizer | verification | total | runs |", "|---|---|---|---|---|---|"]
    medians = {stage: stage_medians(rows, stage) for stage in STAGES}
    for n in sorted(success_by_n(rows)):
        runs = sum(1 for r in rows if n_of(r) == n and as_float(r["total_s"]) is not None)
        lines.append(f"| {n} | " + " | ".join(_fmt(medians[s].get(n)) for s in STAGES) + f" | {runs} |")
    lines += ["", "Fitted growth (least squares on log median against log N): median time ~ c N^k", "",
              "| stage | k | c (s) |", "|---|---|---|"]
    for stage in STAGES:
        growth = fit_growth(list(medians[stage]), list(medians[stage].values()))
        lines.append(f"| {stage.removesuffix('_s')} | {_fmt(growth and growth.exponent)} | "
                     f"{_fmt(growth and growth.coefficient, 3)} |")
    verified_times = [t for r in rows if r["status"] == "ok" and (t := as_float(r["total_s"])) is not None]
    all_times = [t for r in rows if (t := as_float(r["total_s"])) is not None]
    process = [t for r in rows if (t := as_float(r["process_s"])) is not None]
    lines += ["", "## Distribution of solve times (seconds)", "",
              "| runs | min | 25 % | median | 75 % | 90 % | max |", "|---|---|---|---|---|---|---|",
              f"| verified plans, planning time ({len(verified_times)}) " + quantiles(verified_times),
              f"| every finished run, planning time ({len(all_times)}) " + quantiles(all_times),
              f"| every run, process wall time incl. start-up and kills ({len(process)}) " + quantiles(process)]
    delays = [d for r in rows if r["status"] == "ok" and (d := as_float(r["mean_delay_s"])) is not None]
    memory = [m for r in rows if (m := as_float(r["peak_memory_mb"])) is not None]
    seps = [s for r in rows if r["status"] == "ok" and (s := as_float(r["min_separation_nm"])) is not None]
    lines += ["", "## Plans", "",
              "* mean landing delay against the initializer's times, verified plans: "
              f"median {_fmt(_median(delays), 1)} s ({len(delays)} plans)",
              f"* smallest separation in a verified plan: {_fmt(min(seps) if seps else None, 3)} nm",
              f"* peak memory of a planning process: median {_fmt(_median(memory), 0)} MB, "
              f"max {_fmt(max(memory) if memory else None, 0)} MB"]
    lines += sequence_section(rows)
    lines += closed_loop_section(rows)
    if figures:
        lines += ["", "## Figures", ""] + [f"![{f.stem}]({f.name})" for f in figures]
    return "\n".join(lines) + "\n"


DELAY_TIE_S = 0.1
"""Two total delays of one scenario within this many seconds count as equal: far above the round-off of summed
landing times, far below a delay anyone would notice."""


def _values(rows: Sequence[dict[str, str]], key: str) -> list[float]:
    return [v for r in rows if (v := as_float(r.get(key) or "")) is not None]


def _lower_by(ours: float, fcfs: float) -> str:
    """``"123.4 s (45.6 %)"``: how much ``ours`` is below ``fcfs`` (s, and in per cent of ``fcfs``)."""
    saved = round(fcfs - ours, 1) + 0.0  # + 0.0: no "-0.0" for equal delays
    share = f" ({round(100.0 * saved / fcfs, 1) + 0.0:.1f} %)" if fcfs > 0 else ""
    return f"{saved:.1f} s{share}"


def delay_lines(rows: Sequence[dict[str, str]], key: str, label: str) -> list[str]:
    """Total delay of ``key`` against first come, first served over the rows that have both: sums, medians per
    scenario, and how many scenarios were lower, equal (within 0.1 s) or higher."""
    pairs = [(a, b) for r in rows if (a := as_float(r.get(key) or "")) is not None
             and (b := as_float(r.get("fcfs_delay_s") or "")) is not None]
    if not pairs:
        return []
    ours, fcfs = np.array([a for a, _ in pairs]), np.array([b for _, b in pairs])
    diff = fcfs - ours
    return [f"* {label} ({len(pairs)} scenarios): total {ours.sum():.1f} s against first come, first served "
            f"{fcfs.sum():.1f} s, lower by {_lower_by(float(ours.sum()), float(fcfs.sum()))}; per scenario median "
            f"{np.median(ours):.1f} s against {np.median(fcfs):.1f} s (median saving {np.median(diff):.1f} s, "
            f"largest {diff.max():.1f} s); lower in {int(np.sum(diff > DELAY_TIE_S))}, equal in "
            f"{int(np.sum(np.abs(diff) <= DELAY_TIE_S))}, higher in {int(np.sum(diff < -DELAY_TIE_S))}"]


def sequence_section(rows: Sequence[dict[str, str]]) -> list[str]:
    """Wake minima kept when re-flown and total delay against first come, first served; none for a table without
    the sequencing columns (written before them) or without a plan in it."""
    if not any(r.get("fcfs_delay_s") or r.get("min_landing_gap_ratio") for r in rows):
        return []
    ok = [r for r in rows if r["status"] == "ok"]
    wake = [r for r in rows if r.get("wake_mix")]
    checked = [r for r in rows if r.get("landing_pairs_below")]
    below = int(sum(_values(checked, "landing_pairs_below")))
    below_ok = int(sum(_values(ok, "landing_pairs_below")))
    ratio = _values(ok, "min_landing_gap_ratio")
    pairs = int(sum(max(0, int(n) - 1) for r in checked if (n := n_of(r)) is not None))
    strategies = Counter(r["sequencing_strategy"] for r in rows if r.get("sequencing_strategy"))
    tables = "; ".join(sorted({r["wake_mix"].split(":")[0] for r in wake})) or "-"
    lines = ["", "## Sequence: wake minima and delay", "",
             f"* verified: {len(ok)} of {len(rows)} ({100.0 * len(ok) / max(len(rows), 1):.1f} %); "
             f"{len(wake)} scenarios with a wake table ({tables}); "
             f"strategies: {', '.join(f'{k} {v}' for k, v in sorted(strategies.items())) or '-'}",
             f"* consecutive landings re-flown (verification): {pairs} pairs in {len(checked)} runs, {below} below the "
             f"time they need (wake minimum or spacing), {below_ok} of them in verified plans; smallest gap / need "
             f"in a verified plan {_fmt(min(ratio) if ratio else None, 6)}"]
    lines += delay_lines(ok, "total_delay_s", "planned landings, verified plans")
    lines += delay_lines(rows, "scheduled_delay_s", "the sequencer's schedule, every run with one")
    by_n = sorted({n for r in ok if (n := n_of(r)) is not None and r.get("fcfs_delay_s")})
    if by_n:
        lines += ["", "| N | verified plans | total delay (s) | first come, first served (s) | lower by |",
                  "|---|---|---|---|---|"]
        for n in by_n:
            sel = [r for r in ok if n_of(r) == n and r.get("fcfs_delay_s") and r.get("total_delay_s")]
            ours, fcfs = sum(_values(sel, "total_delay_s")), sum(_values(sel, "fcfs_delay_s"))
            lines.append(f"| {n} | {len(sel)} | {ours:.1f} | {fcfs:.1f} | {_lower_by(ours, fcfs)} |")
    return lines


NO_REPLAN_DEVIATION = 0.2
"""How close (in separations) a flown path must stay to its plan to count as flown as planned (thesis: 0.05 nm)."""


def separation_of(row: dict[str, str]) -> float | None:
    """The scenario's separation minimum (nm), read from its file (None, with a warning, if it cannot be read: a
    campaign's results moved away from its scenarios)."""
    from mal_planner.errors import InvalidInput
    from mal_planner.scenario import load_scenario

    try:
        return float(load_scenario(row["file"]).separation_nm)
    except (OSError, KeyError, InvalidInput) as exc:
        log.warning("summary: the separation of %s is unknown (%s); its deviation is not counted",
                    row.get("file", "?"), " ".join(str(exc).split()))
        return None


def closed_loop_section(rows: Sequence[dict[str, str]]) -> list[str]:
    """The closed-loop table (rows of ``mal-campaign --closed-loop``); none for an open-loop campaign."""
    flown = [r for r in rows if r.get("cl_landed")]
    if not flown:
        return []

    def values(key: str, sel: Sequence[dict[str, str]] = flown) -> list[float]:
        return [v for r in sel if (v := as_float(r.get(key, ""))) is not None]

    ok = sum(r["status"] == "ok" for r in flown)
    lines = ["", "## Closed loop (flown tracks)", "",
             f"{ok} of {len(flown)} runs ({100.0 * ok / len(flown):.1f} %) landed everyone with no loss of "
             "separation and no airspace or obstacle infringement on the tracks flown.", ""]
    own = [r for r in flown if r.get("cl_simulator_losses_of_separation", "") != ""]
    if own:
        los = int(sum(values("cl_simulator_losses_of_separation", own)))
        lines += [f"The simulator's own conflict detection ({own[0].get('cl_simulator', '')}) counted {los} losses "
                  f"of separation in {sum(as_float(r['cl_simulator_losses_of_separation']) > 0 for r in own)} of "
                  f"{len(own)} runs.", ""]
    calm = [r for r in flown if as_float(r.get("cl_replans", "")) == 0]
    close = [r for r in calm if (d := as_float(r.get("cl_max_deviation_nm", ""))) is not None
             and (sep := separation_of(r)) is not None and d <= NO_REPLAN_DEVIATION * sep]
    lines += [f"{len(calm)} of {len(flown)} runs needed no replan; in {len(close)} of them every flown path stayed "
              f"within {NO_REPLAN_DEVIATION:g} separation of its plan (0.05 nm in the thesis box).", "",
              "| N | runs | success | losses of separation | infringements | smallest separation (minima) | "
             "largest deviation (nm, median / max) | replans (mean) | replan time median / p95 / max (s) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for n in sorted({n for r in flown if (n := n_of(r)) is not None}):
        sel = [r for r in flown if n_of(r) == n]
        ratio, dev, replans = values("cl_separation_ratio", sel), values("cl_max_deviation_nm", sel), \
            values("cl_replans", sel)
        lat = values("cl_replan_median_s", sel)
        p95, top = values("cl_replan_p95_s", sel), values("cl_replan_max_s", sel)
        lines.append(f"| {n} | {len(sel)} | {sum(r['status'] == 'ok' for r in sel)} | "
                     f"{int(sum(values('cl_losses_of_separation', sel)))} | {int(sum(values('cl_infringements', sel)))}"
                     f" | {_fmt(min(ratio) if ratio else None, 3)} | {_fmt(_median(dev), 4)} / "
                     f"{_fmt(max(dev) if dev else None, 4)} | {_fmt(float(np.mean(replans)) if replans else None, 1)}"
                     f" | {_fmt(_median(lat))} / {_fmt(_median(p95))} / {_fmt(max(top) if top else None)} |")
    sizes = sorted({n_of(r) for r in flown} - {None})
    pooled = [(n, [float(x) for r in flown if n_of(r) == n for x in r.get("cl_replan_times_s", "").split(";") if x])
              for n in sizes]
    if any(times for _, times in pooled):
        lines += ["", "Every replan's planning time as charged (CPU s), pooled over the runs:", "",
                  "| N | replans | median | p95 | max |", "|---|---|---|---|---|"]
        lines += [f"| {n} | {len(t)} | {_fmt(float(np.median(t)))} | {_fmt(float(np.percentile(t, 95)))} | "
                  f"{_fmt(max(t))} |" for n, t in pooled if t]
    lines += fallback_section(flown)
    failed = [r for r in flown if r["status"] != "ok"]
    if failed:
        lines += ["", "Runs that failed, and why:", ""]
        lines += [f"* {Path(r['file']).name}: {r['reason']}" for r in failed[:20]]
    return lines


def fallback_section(flown: Sequence[dict[str, str]]) -> list[str]:
    """Per size: who landed, the share of the flight time on holds and vectors, and the safety net's work."""
    lines = ["", "Fallbacks and the safety net per size (fallback share: the share of the aircraft's flight time on a "
             "hold, a vector or nothing, per run):", "",
             "| N | runs | everyone landed | aircraft landed | fallback share median / max | holds | net alerts | "
             "net uses | vectors |", "|---|---|---|---|---|---|---|---|---|"]
    for n in sorted({n for r in flown if (n := n_of(r)) is not None}):
        sel = [r for r in flown if n_of(r) == n]
        landed = [int(as_float(r["cl_landed"]) or 0) for r in sel]
        share = [v for r in sel if (v := as_float(r.get("cl_fallback_share", ""))) is not None]
        total = {key: int(sum(as_float(r.get(key, "")) or 0 for r in sel))
                 for key in ("cl_holds", "cl_net_alerts", "cl_net_uses", "cl_vectors")}
        lines.append(f"| {n} | {len(sel)} | {sum(k == n for k in landed)} | {sum(landed)}/{n * len(sel)} | "
                     f"{_fmt(_median([100.0 * v for v in share]), 1)} / "
                     f"{_fmt(100.0 * max(share) if share else None, 1)} % | {total['cl_holds']} | "
                     f"{total['cl_net_alerts']} | {total['cl_net_uses']} | {total['cl_vectors']} |")
    return lines


def _median(values: Sequence[float]) -> float | None:
    return float(np.median(values)) if values else None


def write_summary(rows: Sequence[dict[str, str]], out_dir: Path) -> Path:
    """Write the figures and ``summary.md`` into ``out_dir``; return the summary's path."""
    figures = write_figures(rows, out_dir) if rows else []
    path = Path(out_dir) / "summary.md"
    path.write_text(summary_markdown(rows, figures), encoding="utf-8")
    return path
