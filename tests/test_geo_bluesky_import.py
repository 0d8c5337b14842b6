"""BlueSky scenarios in: CRE lines -> a geodetic scenario's initial states; ISA CAS/Mach -> TAS; WIND out."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mal_planner.geo.bluesky import (
    cas_to_tas_kt,
    create_commands,
    mach_to_tas_kt,
    scn_lines,
    tas_to_cas_kt,
    wind_command,
)
from mal_planner.geo.bluesky_import import ScnError, initial_aircraft, read_creates
from mal_planner.options import PlanOptions
from mal_planner.pipeline import plan
from mal_planner.scenario import GeoAircraftConfig, load_scenario
from mal_planner.units import nm_per_s_to_kt

GEODETIC = Path("scenarios/thesis_geodetic.yaml")


@pytest.mark.parametrize("alt_ft", [0.0, 2000.0, 10000.0, 35000.0])
def test_cas_to_tas_inverts_tas_to_cas(alt_ft: float) -> None:
    for tas in (100.0, 144.0, 250.0, 480.0):
        assert cas_to_tas_kt(tas_to_cas_kt(tas, alt_ft), alt_ft) == pytest.approx(tas, rel=1e-12)


def test_mach_to_tas_is_the_speed_of_sound_at_altitude() -> None:
    assert mach_to_tas_kt(1.0, 0.0) == pytest.approx(661.47, abs=0.01)  # ISA sea level: 340.29 m/s
    assert mach_to_tas_kt(0.78, 35000.0) == pytest.approx(0.78 * 576.6, abs=0.5)  # -54.3 C just below the tropopause
    assert mach_to_tas_kt(0.78, 50000.0) == pytest.approx(0.78 * 573.6, abs=0.5)  # -56.5 C above it


def test_exported_creates_import_as_the_scenarios_initial_states() -> None:
    """The export's CRE lines of the geodetic thesis, read back: the same aircraft (to the export's digits)."""
    sc = load_scenario(GEODETIC)
    lines = [f"00:00:00.00>{c}" for a in sc.aircraft for c in create_commands(
        a.callsign, sc.geo_frame, np.asarray(a.state0), nm_per_s_to_kt(a.speed), a.limits.bank_angle_max)]
    aircraft = initial_aircraft(read_creates("\n".join(lines)), wake={"A320": "M"})
    for entry, want in zip(aircraft, sc.aircraft, strict=True):
        assert entry["flight_path_angle_deg"] == 0.0  # BlueSky creates aircraft level
        # with the climb given back, the same state (A2 starts on the airspace's edge: converted, not validated)
        _, climb_deg = sc.geo_frame.direction_to_geodetic(want.state0[:3], want.state0[4], want.state0[3])
        got = GeoAircraftConfig(**{**entry, "flight_path_angle_deg": climb_deg}).to_local(sc.geo_frame)
        assert got.callsign == want.callsign and got.wake_category == "M"
        # to the export's digits: 8 decimals of a degree (1 mm), 0.01 ft, 1e-4 deg of track, CAS to 0.001 kt
        assert got.position == pytest.approx(np.asarray(want.state0)[:3], abs=1e-5)
        assert math.radians(got.heading_deg) == pytest.approx(want.state0[4], abs=1e-5)
        assert math.radians(got.flight_path_angle_deg) == pytest.approx(want.state0[3], abs=1e-5)
        assert got.speed == pytest.approx(want.speed, rel=1e-5)


def test_creates_in_blueskys_other_forms() -> None:
    text = """# a comment
00:00:00.00>CRE KL204 B744 52.1 4.5 90 FL70 250   # flight level, CAS
00:00:00.00>CREATE af12,a320,52.2,4.6,270,3000,0.5
00:00:00.00>CRE BA1 A320 52.3 4.7 180 3000 M.5;LNAV BA1 ON
00:01:00.00>CRE LATE A320 52.4 4.8 0 3000 200
00:02:00.00>CRE KL204 B744 52.0 4.4 90 FL70 250
"""
    creates = read_creates(text)
    assert [c.callsign for c in creates] == ["KL204", "AF12", "BA1", "LATE", "KL204"]
    first = creates[0]
    assert first.alt_ft == 7000.0 and first.tas_kt == pytest.approx(cas_to_tas_kt(250.0, 7000.0))
    assert creates[1].tas_kt == pytest.approx(creates[2].tas_kt) == pytest.approx(mach_to_tas_kt(0.5, 3000.0))
    assert [a["callsign"] for a in initial_aircraft(creates)] == ["KL204", "AF12", "BA1"]  # the first time only
    later = initial_aircraft(creates, at_s=120.0)
    assert [a["callsign"] for a in later] == ["KL204", "AF12", "BA1", "LATE"]
    assert [a["aircraft_type"] for a in later] == ["B744", "A320", "A320", "A320"]  # types OpenAP knows
    unknown = initial_aircraft(read_creates("00:00:00.00>CRE X1 ZZ99 52.1 4.5 90 FL70 250"))
    assert "aircraft_type" not in unknown[0]  # no performance for it: the scenario's default type applies
    assert later[0]["lat"] == 52.0  # created again: BlueSky replaces it, so the last state counts


@pytest.mark.parametrize(("text", "message"), [
    ("CRE A1 A320 52 4 90 3000 250", "not a .scn line"),
    ("00:00:00.00>CRE A1 A320 SPY 4 90 3000 250", "latitude 'SPY' is not a number"),
    ("00:00:00.00>CRE A1 A320 52 4 90 3000", "CRE needs 7 arguments"),
    ("00:00:00.00>CRE A1 A320 52 4 90 3000 -5", "speed '-5' must be > 0"),
    ("00:00:00.00>CRE A1 A320 152 4 90 3000 250", "is not a latitude/longitude"),
])
def test_bad_creates_are_one_line_errors_naming_the_line(text: str, message: str) -> None:
    with pytest.raises(ScnError, match=message) as info:
        read_creates("00:00:00.00>ASAS ON\n" + text, "t.scn")
    assert str(info.value).startswith("t.scn:2:") and "\n" not in str(info.value)


def test_cli_writes_a_scenario_that_plans(tmp_path: Path) -> None:
    scn = tmp_path / "traffic.scn"
    sc = load_scenario(GEODETIC)
    inwards = np.array([0.99, 0.99, 1.0, 1.0, 1.0])  # A2 and A3 start on the airspace's edges: rounded, outside
    scn.write_text("\n".join(f"00:00:00.00>{c}" for a in sc.aircraft for c in create_commands(
        a.callsign, sc.geo_frame, np.asarray(a.state0) * inwards, nm_per_s_to_kt(a.speed), a.limits.bank_angle_max))
        + "\n")
    out = tmp_path / "imported.yaml"
    run = subprocess.run([sys.executable, "-m", "mal_planner.geo.bluesky_import", str(scn), "--template",
                          str(GEODETIC), "-o", str(out), "--wake", "A320=M"],
                         capture_output=True, text=True, check=False)
    assert run.returncode == 0, run.stderr
    imported = load_scenario(out)
    assert [a.callsign for a in imported.aircraft] == ["A1", "A2", "A3"] and imported.geo_frame == sc.geo_frame
    result = plan(imported, PlanOptions(seed=0, optimize=False))  # the imported states plan (initial guess)
    assert set(result.landing_times()) == {"A1", "A2", "A3"}
    # a local template cannot hold latitude/longitude aircraft: exit 2, one line, nothing written
    bad = subprocess.run([sys.executable, "-m", "mal_planner.geo.bluesky_import", str(scn), "--template",
                          "scenarios/thesis.yaml", "-o", str(tmp_path / "no.yaml")], capture_output=True, text=True,
                         check=False)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "not on the Earth" in bad.stderr
    assert not (tmp_path / "no.yaml").exists()


def test_export_sets_the_scenarios_wind() -> None:
    sc = load_scenario(GEODETIC)
    calm = plan(sc, PlanOptions(seed=0, optimize=False))
    assert not any(">WIND" in line for line in scn_lines(calm))
    wind = (0.0, -20.0 / 3600.0)  # 20 kt towards local -y: blowing from the runway's approach side
    windy = plan(sc.with_wind(wind), PlanOptions(seed=0, optimize=False))
    lines = [line for line in scn_lines(windy) if ">WIND" in line]
    assert lines == [f"00:00:00.00>{wind_command(sc.geo_frame, wind)}"]
    _, lat, lon, from_deg, speed_kt = lines[0].split(">")[1].split()
    # the runway's course is 265.43 deg (landing towards -y): a wind towards -y blows from 85.43 deg
    assert float(from_deg) == pytest.approx((265.43 + 180.0) % 360.0, abs=0.05) and float(speed_kt) == 20.0
    assert (float(lat), float(lon)) == pytest.approx((sc.geo_frame.lat_deg, sc.geo_frame.lon_deg))
