"""Geodetic scenarios: the thesis placed at a real runway is the thesis, and plans the same; bad input fails clearly."""

from __future__ import annotations

import copy
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest
import yaml

from mal_planner.geo import GeoFrame
from mal_planner.geo.convert import geodetic_copy, main
from mal_planner.scenario import ScenarioError, load_scenario, parse_scenario

LOCAL, GEODETIC = Path("scenarios/thesis.yaml"), Path("scenarios/thesis_geodetic.yaml")


def _assert_same_scenario(a, b, tol: float = 1e-9) -> None:
    assert [ac.callsign for ac in a.aircraft] == [ac.callsign for ac in b.aircraft]
    for x, y in zip(a.aircraft, b.aircraft, strict=True):
        np.testing.assert_allclose(y.state0, x.state0, rtol=0, atol=tol)
        assert (y.speed, y.limits, y.wake_category, y.landing_time) == pytest.approx(
            (x.speed, x.limits, x.wake_category, x.landing_time), rel=1e-12)
        assert type(y.dynamics) is type(x.dynamics)
    np.testing.assert_allclose(b.runway_state, a.runway_state, rtol=0, atol=tol)
    np.testing.assert_array_equal(b.airspace, a.airspace)
    assert [asdict(o) for o in b.obstacles] == [asdict(o) for o in a.obstacles]
    assert [asdict(g) for g in b.gates] == [asdict(g) for g in a.gates]
    assert (b.separation_nm, b.landing_spacing_s, b.max_landing_spacing_s, b.gravity) == (
        a.separation_nm, a.landing_spacing_s, a.max_landing_spacing_s, a.gravity)


@pytest.fixture(scope="module")
def scenarios():
    return load_scenario(LOCAL), load_scenario(GEODETIC)


def test_thesis_geodetic_is_the_thesis(scenarios) -> None:
    local, geo = scenarios
    assert local.geo_frame is None
    assert geo.geo_frame == GeoFrame(49.02667786, 2.56169447, 392.0, 265.43)
    assert geo.config.runway.heading_deg == -90.0  # the planner sees the local file
    _assert_same_scenario(local, geo)


def test_thesis_geodetic_plans_the_same(scenarios) -> None:
    from mal_planner.pipeline import PlanOptions, plan

    a, b = (plan(sc, PlanOptions(seed=0)) for sc in scenarios)
    assert a.verification.verified and b.verification.verified
    assert b.landing_times() == pytest.approx(a.landing_times(), abs=1e-9)
    for ta, tb in zip(a.trajectories(), b.trajectories(), strict=True):
        np.testing.assert_allclose(tb.t, ta.t, rtol=0, atol=1e-9)
        np.testing.assert_allclose(tb.states, ta.states, rtol=0, atol=1e-9)


def test_the_file_is_what_the_converter_writes(tmp_path: Path) -> None:
    out = tmp_path / "copy.yaml"
    assert main([str(LOCAL), "--threshold", "49.02667786", "2.56169447", "392", "--course", "265.43",
                 "-o", str(out)]) == 0
    written = yaml.safe_load(out.read_text())
    bundled = yaml.safe_load(GEODETIC.read_text())
    assert written == {**bundled, "name": "thesis"}


@pytest.mark.parametrize("course", [0.0, 91.5, 180.0, 359.9])
def test_any_runway_gives_the_same_local_scenario(course: float) -> None:
    data = yaml.safe_load(LOCAL.read_text())
    frame = GeoFrame(-33.95, 151.18, 21.0, course)
    _assert_same_scenario(parse_scenario(data), parse_scenario(geodetic_copy(data, frame)))


def _geo(edit) -> dict:
    data = copy.deepcopy(yaml.safe_load(GEODETIC.read_text()))
    edit(data)
    return data


def _local(edit) -> dict:
    data = copy.deepcopy(yaml.safe_load(LOCAL.read_text()))
    edit(data)
    return data


CASES = [
    ("lat-range", lambda: _geo(lambda d: d["aircraft"][0].update(lat=91.0)), "aircraft[0].lat", "less than or equal"),
    ("no-speed", lambda: _geo(lambda d: d["aircraft"][1].pop("speed_kt")), "aircraft[1].speed_kt", "Field required"),
    ("mixed", lambda: _geo(lambda d: d["aircraft"][1].update(position=[0, 5, 0.2])), "aircraft[1].position",
     "Extra inputs"),
    ("course", lambda: _geo(lambda d: d["runway"].update(course_deg=360.0)), "runway.course_deg", "less than 360"),
    ("threshold", lambda: _geo(lambda d: d["runway"]["threshold"].pop("lon")), "runway.threshold.lon",
     "Field required"),
    ("outside", lambda: _geo(lambda d: d["aircraft"][2].update(lat=48.9)), "aircraft[2].lat/lon/alt_ft",
     "is outside the airspace"),
    ("geo-on-local-runway", lambda: _local(lambda d: d["aircraft"][0].update(
        lat=49.0, lon=2.6, alt_ft=2000.0, track_deg=180.0, speed_kt=144.0, position=None, heading_deg=None,
        speed=None)), "", "needs the runway on the Earth"),
]


@pytest.mark.parametrize(("make", "field", "reason"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_geodetic_input_is_one_line(make, field, reason) -> None:
    data = make()
    for ac in data["aircraft"]:
        for key in [k for k, v in ac.items() if v is None]:
            ac.pop(key)
    with pytest.raises(ScenarioError) as err:
        parse_scenario(data, "geo.yaml")
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith("geo.yaml: ") and reason in msg
    assert err.value.field == field or (not field and "aircraft[0].lat" in msg), msg


def test_converter_refuses_a_runway_off_the_origin(tmp_path: Path, capsys) -> None:
    data = _local(lambda d: d["runway"].update(position=[0.0, 1.0, 0.0]))
    src = tmp_path / "moved.yaml"
    src.write_text(yaml.safe_dump(data))
    assert main([str(src), "--threshold", "49", "2.5", "300", "--course", "90", "-o", str(tmp_path / "o.yaml")]) == 2
    assert "only a runway at the origin" in capsys.readouterr().err
