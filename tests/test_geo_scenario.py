"""Geodetic scenarios: the thesis placed at a real runway is the thesis, and plans the same; bad input fails clearly."""

from __future__ import annotations

import copy
import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest
import yaml
from pymap3d.vincenty import vdist

from mal_planner.geo import GeoFrame
from mal_planner.geo.convert import geodetic_copy, main
from mal_planner.scenario import ScenarioError, load_scenario, parse_scenario
from mal_planner.units import ft_to_m, m_to_nm

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


@pytest.fixture(scope="module")
def plans(scenarios):
    from mal_planner.options import PlanOptions
    from mal_planner.pipeline import plan

    return tuple(plan(sc, PlanOptions(seed=0)) for sc in scenarios)


def test_thesis_geodetic_plans_the_same(plans) -> None:
    a, b = plans
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
    ("lat-range", lambda: _geo(lambda d: d["aircraft"][0].update(lat=91.0)), "aircraft[0].lat",
     "must be <= 90 deg, got 91"),
    ("no-speed", lambda: _geo(lambda d: d["aircraft"][1].pop("speed_kt")), "aircraft[1].speed_kt", "Field required"),
    ("mixed", lambda: _geo(lambda d: d["aircraft"][1].update(position=[0, 5, 0.2])), "aircraft[1].position",
     "Extra inputs"),
    ("course", lambda: _geo(lambda d: d["runway"].update(course_deg=360.0)), "runway.course_deg",
     "must be < 360 deg, got 360"),
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


def test_plan_json_carries_lat_lon_alt(plans) -> None:
    from mal_planner.report import result_to_dict

    local, geo = (json.loads(json.dumps(result_to_dict(p), allow_nan=False)) for p in plans)
    assert local["scenario"]["geo_frame"] is None
    assert "lat_deg" not in local["aircraft"][0]["trajectory"]
    frame = geo["scenario"]["geo_frame"]
    assert frame["datum"] == "WGS84" and frame["course_deg"] == 265.43
    assert frame["origin"] == {"lat_deg": 49.02667786, "lon_deg": 2.56169447, "elevation_ft": 392.0}
    given = {ac["callsign"]: ac for ac in yaml.safe_load(GEODETIC.read_text())["aircraft"]}
    for ac in geo["aircraft"]:
        tr = ac["trajectory"]
        assert len(tr["lat_deg"]) == len(tr["lon_deg"]) == len(tr["alt_ft"]) == len(tr["t"])
        # the first sample is where the file put the aircraft; the last is the threshold (touchdown)
        first = given[ac["callsign"]]
        assert (tr["lat_deg"][0], tr["lon_deg"][0], m_to_nm(ft_to_m(tr["alt_ft"][0]))) == pytest.approx(
            (first["lat"], first["lon"], m_to_nm(ft_to_m(first["alt_ft"]))), abs=1e-11)  # 1e-11 deg: 6e-10 nm
        # geodesic distance and azimuth from the threshold (Vincenty, not the ENU path) match the local position:
        # the last sample is at the threshold (crossed at the airspace margin, 0.001 nm, above and behind it)
        for k in (0, -1):
            dist_m, az = vdist(49.02667786, 2.56169447, tr["lat_deg"][k], tr["lon_deg"][k])
            x, y = tr["x"][k], tr["y"][k]
            assert m_to_nm(dist_m) == pytest.approx(math.hypot(x, y), abs=1e-3)
            assert az == pytest.approx((90.0 - math.degrees(math.atan2(y, x)) + 265.43 - 180.0) % 360.0, abs=1e-3)
        assert m_to_nm(ft_to_m(tr["alt_ft"][-1] - 392.0)) == pytest.approx(tr["z"][-1], abs=1e-6)
        # and every sample maps back onto the local one
        back = GeoFrame(49.02667786, 2.56169447, 392.0, 265.43).to_local(tr["lat_deg"], tr["lon_deg"], tr["alt_ft"])
        np.testing.assert_allclose(back, np.column_stack([tr["x"], tr["y"], tr["z"]]), rtol=0, atol=1e-9)
