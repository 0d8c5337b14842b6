"""The landing-sequence time line (sequence.png, the overview's panel) from plan.json-like documents: what it
draws (slots, gaps got against spacings needed, short gaps) with and without ``sequence`` and a wake table."""

from __future__ import annotations

import copy
from pathlib import Path

import matplotlib.colors
import pytest
from figure_support import synthetic_plan

from mal_planner.figures import render, static, style, want
from mal_planner.figures.data import landing_timeline, plan_view

WAKE = ["L", "L", "M", "H"]
TARGETS = [130.0, 140.0, 150.0, 120.0]
"""synthetic_plan(4) lands C01-C04 at 135, 147, 159, 171 s."""


def _sequenced(short: bool = False) -> dict:
    """synthetic_plan(4) with a ``sequence`` and the verification's landings under the ICAO table; ``short``: the
    medium-ahead-of-heavy gap C03->C04 (12 s) needs 30 s and the verification failed it."""
    doc = synthetic_plan(4)
    rows = []
    for k, a in enumerate(doc["aircraft"]):
        t = a["landing_time_s"]
        rows.append({"callsign": a["callsign"], "slot": k + 1, "wake_category": WAKE[k], "fixed": k == 0,
                     "earliest_s": TARGETS[k] - 5.0, "target_s": TARGETS[k], "scheduled_s": t, "landing_time_s": t,
                     "delay_s": t - TARGETS[k]})
    doc["sequence"] = {"strategy": "optimal", "status": "optimal", "gap": 0.0, "wake": "icao",
                       "total_delay_s": sum(r["delay_s"] for r in rows), "aircraft": rows}
    landings = [{"pair": f"{a['callsign']}->{b['callsign']}", "gap_s": 12.0, "needed_s": 12.0,
                 "wake": f"{WAKE[k]}->{WAKE[k + 1]}", "wake_nm": 0.25}
                for k, (a, b) in enumerate(zip(doc["aircraft"], doc["aircraft"][1:], strict=False))]
    reasons = []
    if short:
        landings[2] |= {"needed_s": 30.0, "wake_nm": 5.0}
        reasons.append("C03->C04: landings 12.00 s apart, the icao wake minimum M->H of 5 nm needs 30.0 s")
    doc["verification"] = {"verified": not short, "reasons": reasons, "aircraft": [], "pairs": [],
                           "tolerances": {"landing_time_s": 1e-3}, "landings": landings}
    return doc


def test_timeline_reads_the_sequence_and_the_spacings() -> None:
    tl = landing_timeline(_sequenced())
    assert [s.callsign for s in tl.slots] == ["C01", "C02", "C03", "C04"]
    assert [s.wake_category for s in tl.slots] == WAKE and [s.target for s in tl.slots] == TARGETS
    assert [s.landing_time for s in tl.slots] == [135.0, 147.0, 159.0, 171.0]
    assert [s.delay for s in tl.slots] == [5.0, 7.0, 9.0, 51.0] and tl.slots[0].fixed
    assert tl.strategy == "optimal" and tl.wake_table == "icao" and tl.total_delay == pytest.approx(72.0)
    assert [(g.pair, g.gap, g.needed, g.wake, g.short) for g in tl.gaps] == [
        ("C01->C02", 12.0, 12.0, "L->L", False), ("C02->C03", 12.0, 12.0, "L->M", False),
        ("C03->C04", 12.0, 12.0, "M->H", False)]


def test_a_gap_is_short_where_the_verification_failed_its_spacing() -> None:
    tl = landing_timeline(_sequenced(short=True))
    assert [g.short for g in tl.gaps] == [False, False, True]
    assert (tl.gaps[2].gap, tl.gaps[2].needed, tl.gaps[2].wake_nm) == (12.0, 30.0, 5.0)
    assert static.gap_label(tl.gaps[2]) == "C03→C04  12.0 < 30.0 s  M→H 5 nm  SHORT"
    assert static.gap_label(tl.gaps[0], pair=False) == "12.0 ≥ 12.0 s  L→L 0.25 nm"
    doc = _sequenced()
    del doc["verification"]["reasons"]  # no reasons: the gap against the need, within the landing-time tolerance
    doc["verification"]["landings"][0]["gap_s"] = 12.0 - 5e-4
    doc["verification"]["landings"][1]["gap_s"] = 11.9
    assert [g.short for g in landing_timeline(doc).gaps] == [False, True, False]


def test_timeline_without_sequence_or_wake_table_uses_the_landing_times() -> None:
    doc = synthetic_plan(3)
    doc["aircraft"][0]["landing_time_s"] = 200.0  # lands last although first in the file's order
    tl = landing_timeline(doc)  # sequence absent, verification None
    assert [s.callsign for s in tl.slots] == ["C02", "C03", "C01"] and [s.slot for s in tl.slots] == [1, 2, 3]
    assert all(s.target is None and s.earliest is None and s.wake_category is None for s in tl.slots)
    assert [(g.pair, g.gap, g.needed, g.short) for g in tl.gaps] == [("C02->C03", 12.0, None, False),
                                                                     ("C03->C01", 41.0, None, False)]
    assert tl.strategy is None and tl.wake_table is None and tl.total_delay is None
    assert static.gap_label(tl.gaps[1]) == "C03→C01  41.0 s"


def test_without_sequence_the_verification_gives_gaps_and_wake_categories() -> None:
    doc = _sequenced(short=True)
    doc["sequence"] = None
    tl = landing_timeline(doc)
    assert [s.callsign for s in tl.slots] == ["C01", "C02", "C03", "C04"]
    assert [s.wake_category for s in tl.slots] == WAKE and all(s.target is None for s in tl.slots)
    assert [(g.needed, g.short) for g in tl.gaps] == [(12.0, False), (12.0, False), (30.0, True)]
    doc["sequence"] = {"strategy": "fcfs", "wake": "none", "total_delay_s": 0.0, "aircraft": []}
    assert landing_timeline(doc).wake_table is None  # "none": no wake table


@pytest.mark.parametrize("case", ["sequenced", "short", "no sequence", "bare"])
def test_sequence_png_is_written_and_labels_every_gap(case: str, tmp_path: Path) -> None:
    doc = {"sequenced": _sequenced(), "short": _sequenced(short=True), "no sequence": _sequenced(),
           "bare": synthetic_plan(4)}[case]
    if case == "no sequence":
        doc = copy.deepcopy(doc)
        doc["sequence"] = None
    view = plan_view(doc)
    fig = static.figure_sequence(view, style.color_map(view.callsigns))
    ax = fig.axes[0]
    labels = {t.get_text(): t for t in ax.texts if "→" in t.get_text()}
    assert set(labels) == {static.gap_label(g) for g in view.timeline.gaps} and len(labels) == 3
    red = {text for text, t in labels.items() if matplotlib.colors.same_color(t.get_color(), style.REQUIRED_COLOR)}
    assert red == ({"C03→C04  12.0 < 30.0 s  M→H 5 nm  SHORT"} if case == "short" else set())
    ticks = [t.get_text() for t in ax.get_yticklabels()]
    assert ticks == (["C01", "C02", "C03", "C04"] if case == "bare" else
                     ["C01 (L, fixed)" if case != "no sequence" else "C01 (L)", "C02 (L)", "C03 (M)", "C04 (H)"])
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert ("target" in legend) == (case in ("sequenced", "short")) and ("gap short" in legend) == (case == "short")
    assert style.save(fig, tmp_path / "sequence.png").stat().st_size > 10_000


def test_render_writes_sequence_png_beside_the_other_figures(tmp_path: Path) -> None:
    written = render(_sequenced(short=True), tmp_path, want("png"))
    assert tmp_path / "sequence.png" in written and tmp_path / "overview.png" in written


def test_overview_has_the_sequence_panel() -> None:
    view = plan_view(_sequenced(short=True))
    fig = static.figure_overview(view, style.color_map(view.callsigns), view.separations())
    panel = next(ax for ax in fig.axes if ax.get_title().startswith("Landing sequence"))
    assert [t.get_text() for t in panel.get_yticklabels()] == ["C01 (L, fixed)", "C02 (L)", "C03 (M)", "C04 (H)"]
    assert "12.0 < 30.0 s  M→H 5 nm  SHORT" in [t.get_text() for t in panel.texts]
