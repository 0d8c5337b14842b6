"""Figures: the style, the PNGs, plan.html (opened in headless Chromium where installed), mal-figures."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest
from figure_support import CHROMIUM, browser_probe, screenshot, synthetic_plan

from mal_planner.figures import render, static, style, want
from mal_planner.figures.cli import main as figures_main
from mal_planner.figures.data import plan_view
from mal_planner.figures.interactive import figure as html_figure
from mal_planner.figures.interactive import write_html
from mal_planner.pipeline import plan
from mal_planner.report import result_to_dict, start_figures, validation_report, write_outputs
from mal_planner.ros.node_params import PARAMETERS
from mal_planner.scenario import load_scenario


@pytest.fixture(scope="module")
def thesis_result():
    """The thesis scenario, verified (about 5 s)."""
    return plan(load_scenario("scenarios/thesis.yaml"))


@pytest.fixture(scope="module")
def thesis_doc(thesis_result) -> dict:
    return json.loads(json.dumps(result_to_dict(thesis_result)))


def _hex(rgb: np.ndarray) -> str:
    return "#" + "".join(f"{int(round(c * 255)):02x}" for c in rgb[:3])


# -- style -------------------------------------------------------------------------------------------------
def test_want_parses_the_figures_option() -> None:
    assert want("all") == {"png", "html"} and want("PNG") == {"png"} and want("none") == set()
    assert want(True) == {"png"} and want(False) == set()
    with pytest.raises(ValueError, match="none, png, html, all"):
        want("pdf")


@pytest.mark.parametrize("n", [1, 2, 10, 20, 30, 45])
def test_aircraft_colors_are_distinct_and_stable(n: int) -> None:
    colors = style.aircraft_colors(n)
    assert len(colors) == n == len(set(colors))
    assert style.aircraft_colors(n + 5)[:n] == colors  # adding aircraft keeps the others' colours
    assert not set(style.pair_colors(8)) & set(style.aircraft_colors(30))


def test_stagger_rows_separate_overlapping_labels() -> None:
    rng = np.random.default_rng(1)
    pos, width = rng.uniform(0, 100, 40), rng.uniform(2, 12, 40)
    rows = static.stagger_rows(pos.tolist(), width.tolist())
    for i, j in itertools.combinations(range(40), 2):
        if rows[i] == rows[j]:
            assert abs(pos[i] - pos[j]) >= (width[i] + width[j]) / 2
    assert static.stagger_rows([0.0, 10.0, 0.5], [2.0, 2.0, 2.0]) == [0, 0, 1]


# -- plan.json: what the figures need ------------------------------------------------------------------------
def test_plan_json_carries_geometry_limits_and_a_global_sample_grid(thesis_result, thesis_doc) -> None:
    sc = thesis_doc["scenario"]
    assert len(sc["obstacles"]) == len(thesis_result.scenario.obstacles) == 4 and sc["gates"][0]["axis"] == 1
    assert thesis_doc["aircraft"][0]["limits"]["bank_angle_max"] == pytest.approx(np.radians(45.0))
    view = plan_view(thesis_doc)
    assert view.obstacles == thesis_result.scenario.obstacles and view.gates == thesis_result.scenario.gates
    t = np.asarray(thesis_doc["aircraft"][0]["trajectory"]["t"])
    k = np.round(t / 0.25)
    on_grid = np.abs(t - 0.25 * k) < 1e-9
    # Every multiple of 0.25 s of the flight is a sample; the other samples are nodes and phase ends.
    assert set(range(1, int(t[-1] / 0.25))) <= set(k[on_grid].astype(int))


def test_pair_separation_agrees_with_the_verification(thesis_result, thesis_doc) -> None:
    seps = plan_view(thesis_doc).separations()
    assert [s.pair for s in seps] == [p.pair for p in thesis_result.verification.pairs]
    for s, p in zip(seps, thesis_result.verification.pairs, strict=True):
        assert float(np.min(s.distance)) == pytest.approx(p.min_distance_nm, abs=0.01)
        assert s.verified_min == p.min_distance_nm


# -- PNGs ----------------------------------------------------------------------------------------------------
def test_real_plan_writes_every_png_with_one_colour_per_aircraft(thesis_doc, tmp_path: Path) -> None:
    written = render(thesis_doc, tmp_path, want("png"))
    names = {p.stem for p in written}
    assert names == {"initial_paths_3d", "initial_x", "initial_y", "initial_z", "overview", "plan_view", "yz_view",
                     "separation", "sequence", "paths_3d", "states", "controls"}
    for path in written:
        img = matplotlib.image.imread(path)
        assert img.shape[0] > 300 and img[..., :3].std() > 0.05, path.name
    view = plan_view(thesis_doc)
    colors = style.color_map(view.callsigns)
    fig = static.figure_series(view, colors, "z")
    ax = fig.axes[0]
    drawn = {_hex(np.array(matplotlib.colors.to_rgb(line.get_color()))) for line in ax.get_lines()
             if len(line.get_xdata()) > 2}
    assert drawn == set(colors.values()) and len(drawn) == 3
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend[:3] == view.callsigns and "landing" in legend


def test_twenty_aircraft_labels_do_not_overlap(tmp_path: Path) -> None:
    view = plan_view(synthetic_plan(20))
    colors = style.color_map(view.callsigns)
    fig = static.figure_states(view, colors)
    fig.canvas.draw()
    boxes = [t.get_window_extent() for t in fig.axes[0].texts]
    assert len(boxes) == 40  # a gate and a landing label per aircraft
    assert not any(a.overlaps(b) for a, b in itertools.combinations(boxes, 2))
    assert len([t for t in fig.legends[0].get_texts() if t.get_text().startswith("C")]) == 20
    fig = static.figure_plan(view, colors)
    fig.canvas.draw()
    starts = [t.get_window_extent() for t in fig.axes[0].texts]
    assert len(starts) == 20 and not any(a.overlaps(b) for a, b in itertools.combinations(starts, 2))
    frame = fig.axes[0].get_window_extent()
    assert all(frame.x0 <= b.x0 and b.x1 <= frame.x1 and frame.y0 <= b.y0 and b.y1 <= frame.y1 for b in starts)


def test_initializer_only_plan_has_no_control_figures(tmp_path: Path) -> None:
    names = {p.stem for p in render(synthetic_plan(3, optimal=False), tmp_path, want("png"))}
    assert {"overview", "initial_paths_3d", "plan_view"} <= names and not {"states", "controls"} & names


def test_plan_json_without_geometry_still_renders() -> None:
    doc = synthetic_plan(2)
    doc["scenario"] = {"name": "old", "source": "<test>"}  # written before plan.json carried the geometry
    for a in doc["aircraft"]:
        del a["limits"]
    view = plan_view(doc)
    assert view.obstacles == () and view.gates == () and view.airspace[2].tolist() == [0.0, 0.25]
    fig = static.figure_overview(view, style.color_map(view.callsigns), view.separations())
    assert len(fig.axes) == 6  # with the landing-sequence panel


def test_real_plan_timeline_is_the_sequence_and_the_verified_spacing(thesis_result, thesis_doc) -> None:
    tl = plan_view(thesis_doc).timeline
    assert [s.callsign for s in tl.slots] == thesis_result.order == ["A1", "A2", "A3"]
    landed = thesis_result.landing_times()
    assert [s.landing_time for s in tl.slots] == pytest.approx([landed[cs] for cs in thesis_result.order])
    assert all(s.fixed and s.delay == pytest.approx(0.0) for s in tl.slots) and tl.wake_table is None
    assert [(g.pair, g.needed, g.wake, g.short) for g in tl.gaps] == [("A1->A2", 15.0, None, False),
                                                                      ("A2->A3", 15.0, None, False)]
    assert [g.gap for g in tl.gaps] == pytest.approx([g.gap_s for g in thesis_result.verification.landings])


def test_report_embeds_the_sequence_figure(thesis_result) -> None:
    text = validation_report(thesis_result)
    section = text[text.index("## Landing sequence"):text.index("## Landing spacing")]
    assert "![landing sequence" in section and "](sequence.png)" in section


# -- plan.html -----------------------------------------------------------------------------------------------
def test_html_is_self_contained_with_a_time_slider(thesis_doc, tmp_path: Path) -> None:
    view = plan_view(thesis_doc)
    fig = html_figure(view)
    t_end = max(a.trajectory.t[-1] for a in view.aircraft)
    assert len(fig["frames"]) == int(np.ceil(t_end)) + 1
    assert len(fig["layout"]["sliders"][0]["steps"]) == len(fig["frames"])
    first = view.aircraft[0]
    late = next(f for f in fig["frames"] if float(f["name"]) > first.landing_time + 1)
    moved = [f["data"][0]["x"] for f in fig["frames"][:2]]
    assert len(late["data"][0]["x"]) == 0 and moved[0][0] != moved[1][0]  # A1 moves, then disappears on landing
    html = write_html(view, tmp_path / "plan.html").read_text(encoding="utf-8")
    assert "<script src=" not in html and "Plotly.newPlot" in html and len(html) < 8_000_000
    assert "t = %{customdata[0]:.1f} s" in html and "bank %{customdata[2]:.1f}" in html


@pytest.mark.skipif(not Path(CHROMIUM).exists(), reason="headless browser test needs /usr/bin/chromium "
                    "(Debian: apt-get install chromium)")
def test_html_opens_in_chromium_without_errors(thesis_doc, tmp_path: Path) -> None:
    view = plan_view(thesis_doc)
    page = write_html(view, tmp_path / "plan.html")
    report = browser_probe(page, tmp_path)
    assert report["errors"] == [] and report["svg"] and report["canvas"]
    assert report["frames"] == int(np.ceil(max(a.trajectory.t[-1] for a in view.aircraft))) + 1
    t = float(report["frame"])
    for a, (x, y, z) in zip(view.aircraft, report["markers"], strict=True):
        expected = [np.interp(t, a.trajectory.t, a.trajectory.positions[:, k]) for k in range(3)]
        assert [x[0], y[0], z[0]] == pytest.approx(expected, abs=1e-3)  # the slider moved the markers
    img = screenshot(page, tmp_path / "shot.png", tmp_path)[:, :-30, :3]  # without the scroll bar
    for color in style.aircraft_colors(len(view.aircraft)):
        rgb = np.array(matplotlib.colors.to_rgb(color))
        assert np.sum(np.all(np.abs(img - rgb) < 0.08, axis=-1)) > 30, f"no path drawn in {color}"


@pytest.mark.skipif(not Path(CHROMIUM).exists(), reason="headless browser test needs /usr/bin/chromium")
def test_browser_probe_reports_a_broken_page(thesis_doc, tmp_path: Path) -> None:
    page = write_html(plan_view(thesis_doc), tmp_path / "plan.html")
    page.write_text(page.read_text(encoding="utf-8").replace("Plotly.newPlot(", "Plotly.newPlott("), encoding="utf-8")
    assert any("newPlott is not a function" in e for e in browser_probe(page, tmp_path)["errors"])


# -- commands and the node ------------------------------------------------------------------------------------
def test_mal_figures_renders_a_saved_plan(thesis_result, tmp_path: Path, capsys) -> None:
    write_outputs(thesis_result, tmp_path, figures="none")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.json", "report.md"]
    assert figures_main([str(tmp_path / "plan.json"), "--figures", "html"]) == 0
    assert (tmp_path / "plan.html").exists() and not list(tmp_path.glob("*.png"))
    assert figures_main([str(tmp_path / "plan.json"), "--out", str(tmp_path / "copy"), "--figures", "html"]) == 0
    assert (tmp_path / "copy" / "plan.html").exists() and "wrote 1 figures" in capsys.readouterr().out
    (tmp_path / "bad.json").write_text('{"schema": "other"}', encoding="utf-8")
    assert figures_main([str(tmp_path / "bad.json")]) == 2
    assert "not a usable plan.json" in capsys.readouterr().err


def test_node_renders_in_one_background_process(thesis_result, tmp_path: Path) -> None:
    write_outputs(thesis_result, tmp_path, figures="none")
    proc = start_figures(tmp_path, "html")
    assert start_figures(tmp_path, "html", proc) is proc  # busy: no second renderer
    assert proc.wait(timeout=120) == 0 and (tmp_path / "plan.html").stat().st_size > 1_000_000
    again = start_figures(tmp_path, "html", proc)
    assert again is not proc
    again.wait(timeout=120)


def test_node_parameter_figures_accepts_choices_and_former_booleans() -> None:
    option = PARAMETERS["figures"]
    check, default = option.check_ros, option.ros_default()
    assert check(default) == "png" and check(True) == "png" and check(False) == "none" and check("All") == "all"
    with pytest.raises(ValueError, match="none, png, html, all"):
        check("yes")
