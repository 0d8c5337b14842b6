"""BlueSky export: the .scn file's contents; with bluesky-simulator installed, a headless replay of the thesis."""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mal_planner.geo import GeoFrame
from mal_planner.geo.bluesky import mach_to_tas_kt, scn_lines, tas_to_cas_kt, write_scn
from mal_planner.options import PlanOptions
from mal_planner.pipeline import plan
from mal_planner.scenario import load_scenario
from mal_planner.units import METRES_PER_NM, ft_to_m, nm_to_ft

HAVE_BLUESKY = importlib.util.find_spec("bluesky") is not None
NEEDS_BLUESKY = pytest.mark.skipif(not HAVE_BLUESKY, reason="bluesky-simulator is not installed (optional extra "
                                   "'bluesky': pip install -e '.[bluesky]')")
LINE = re.compile(r"^(\d\d):(\d\d):(\d\d\.\d\d)>([A-Z]+) (.*)$")


@pytest.fixture(scope="module")
def geodetic():
    return load_scenario("scenarios/thesis_geodetic.yaml")


@pytest.fixture(scope="module")
def initial_plan(geodetic):
    """The initializer's plan (no optimizer): enough for the file's form."""
    return plan(geodetic, PlanOptions(seed=0, optimize=False))


def _commands(lines: list[str]) -> list[tuple[float, str, str]]:
    out = []
    for line in lines:
        if line.startswith("#"):
            continue
        m = LINE.match(line)
        assert m, line
        h, mi, s, cmd, args = m.groups()
        out.append((3600 * int(h) + 60 * int(mi) + float(s), cmd, args))
    return out


def test_scn_creates_routes_and_deletes_each_aircraft(geodetic, initial_plan) -> None:
    cmds = _commands(scn_lines(initial_plan))
    names = [c for _, c, _ in cmds]
    # detection first, then the zone (the other order resets it): the scenario's 0.25 nm sphere as its cylinder
    assert names[:3] == ["ASAS", "ZONER", "ZONEDH"] and cmds[0][2] == "ON"
    assert float(cmds[1][2]) == 0.25 and float(cmds[2][2]) == pytest.approx(nm_to_ft(0.25), abs=0.01)
    landing = initial_plan.landing_times()
    frame = geodetic.geo_frame
    for ac in geodetic.aircraft:
        cs = ac.callsign
        mine = [(t, c, a) for t, c, a in cmds if a.split(",")[0].split(" ")[0] == cs]
        kinds = [c for _, c, _ in mine]
        assert kinds[0] == "CRE" and kinds[1] == "BANK" and kinds[-3:] == ["LNAV", "VNAV", "DEL"]
        assert set(kinds[2:-3]) == {"ADDWPT"} and len(kinds) - 5 >= 20
        _, lat, lon, hdg, alt, cas = mine[0][2].split(",")[1:]
        # CRE at the plan's first state: position, true track, altitude, and the speed as CAS
        tr = next(t for t in initial_plan.trajectories() if t.callsign == cs)
        assert frame.to_local(float(lat), float(lon), float(alt)) == pytest.approx(ac.position, abs=1e-5)
        track, _ = frame.direction_to_geodetic(tr.states[0, :3], tr.states[0, 4], tr.states[0, 3])
        assert float(hdg) == pytest.approx(track, abs=1e-4)
        assert float(cas) == pytest.approx(tas_to_cas_kt(ac.speed * 3600.0, float(alt)), abs=1e-3)
        assert float(cas) < ac.speed * 3600.0  # above sea level CAS < TAS
        assert float(mine[1][2].split()[1]) == pytest.approx(math.degrees(ac.limits.bank_angle_max))
        # waypoints follow the plan's path and end at its landing point; DEL at the landing time
        wpts = np.array([[float(v) for v in a.split()[1:4]] for _, c, a in mine if c == "ADDWPT"])
        local = frame.to_local(wpts[:, 0], wpts[:, 1], wpts[:, 2])
        assert local[-1] == pytest.approx(tr.states[-1, :3], abs=1e-5)
        gaps = np.linalg.norm(np.diff(local, axis=0), axis=1)
        assert gaps.max() < 0.5 * ac.speed**2 / (ac.dynamics.gravity * math.tan(ac.limits.bank_angle_max))
        assert mine[-1][0] == pytest.approx(landing[cs], abs=0.01)


def test_local_scenario_needs_a_frame(tmp_path: Path) -> None:
    local = plan(load_scenario("scenarios/thesis.yaml"), PlanOptions(seed=0, optimize=False))
    with pytest.raises(ValueError, match="give a frame"):
        scn_lines(local)
    path = write_scn(local, tmp_path / "t.scn", frame=GeoFrame(52.3, 4.76, -11.0, 180.0))
    assert "CRE A1,A320,52." in path.read_text()  # no type in the scenario: the default
    typed = dataclasses.replace(local, scenario=dataclasses.replace(local.scenario, aircraft=tuple(
        dataclasses.replace(a, type_code="B738" if a.callsign == "A2" else None) for a in local.scenario.aircraft)))
    text = "\n".join(scn_lines(typed, frame=GeoFrame(52.3, 4.76, -11.0, 180.0)))
    assert "CRE A1,A320," in text and "CRE A2,B738," in text


def test_isa_cas_at_sea_level_and_above() -> None:
    assert tas_to_cas_kt(144.0, 0.0) == pytest.approx(144.0, rel=1e-7)
    # the speed limit below FL100: 250 kt CAS at 10 000 ft is about 289 kt TAS (ISA); CAS is a little above
    # the equivalent airspeed TAS sqrt(sigma) (density ratio 0.7385) through compressibility
    assert tas_to_cas_kt(289.0, 10000.0) == pytest.approx(250.0, abs=0.5)
    assert 1.0 < tas_to_cas_kt(289.0, 10000.0) / (289.0 * math.sqrt(0.7385)) < 1.01
    # above the tropopause (36,089 ft) the temperature stays constant: Mach 0.78 is 447 kt TAS at FL350-FL400
    assert mach_to_tas_kt(0.78, 37000.0) == pytest.approx(mach_to_tas_kt(0.78, 40000.0), rel=1e-9)
    assert mach_to_tas_kt(0.78, 35000.0) == pytest.approx(449.6, abs=0.1)


@NEEDS_BLUESKY
def test_isa_cas_agrees_with_bluesky() -> None:
    from bluesky.tools import aero

    for tas_kt, alt_ft in ((144.0, 2000.0), (250.0, 10000.0), (450.0, 35000.0)):  # OpenAP's ISA: BlueSky's model
        expected = aero.tas2cas(tas_kt * METRES_PER_NM / 3600.0, ft_to_m(alt_ft)) * 3600.0 / METRES_PER_NM
        assert tas_to_cas_kt(tas_kt, alt_ft) == pytest.approx(expected, rel=2e-4)


@pytest.mark.slow
@NEEDS_BLUESKY
def test_bluesky_flies_the_thesis_plan(geodetic, tmp_path: Path) -> None:
    """BlueSky's autopilot flies the exported plan within 0.05 nm, and its detection sees no loss of separation."""
    result = plan(geodetic, PlanOptions(seed=0))
    assert result.verification.verified
    scn = write_scn(result, tmp_path / "thesis.scn")
    out = tmp_path / "flown.npz"
    until = max(result.landing_times().values()) + 1.0
    code = (f"import numpy as np; from mal_planner.geo.bluesky import replay; "
            f"f, p = replay({str(scn)!r}, {until}, {str(tmp_path / 'bluesky')!r}); "
            f"np.savez({str(out)!r}, pairs=np.array(p, dtype=str).reshape(-1, 2), **f)")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=tmp_path, capture_output=True, timeout=600)
    flown = np.load(out)
    assert flown["pairs"].size == 0, f"BlueSky losses of separation: {flown['pairs'].tolist()}"
    frame = geodetic.geo_frame
    for tr in result.trajectories():
        rows = flown[tr.callsign]
        assert rows[-1, 0] == pytest.approx(result.landing_times()[tr.callsign], abs=0.1)  # deleted at landing
        local = frame.to_local(rows[:, 1], rows[:, 2], rows[:, 3])
        planned = np.column_stack([np.interp(rows[:, 0], tr.t, tr.states[:, k]) for k in range(3)])
        deviation = np.linalg.norm(local - planned, axis=1)
        assert deviation.max() < 0.05, f"{tr.callsign}: {deviation.max():.4f} nm"


def test_outputs_of_a_geodetic_plan_include_the_scn(initial_plan, tmp_path: Path) -> None:
    from mal_planner.report import write_outputs

    written = write_outputs(initial_plan, tmp_path / "geo", figures="none")
    assert [p.name for p in written] == ["plan.json", "report.md", "plan.scn"]
    assert (tmp_path / "geo" / "plan.scn").read_text() == "\n".join(scn_lines(initial_plan)) + "\n"
    local = plan(load_scenario("scenarios/thesis.yaml"), PlanOptions(seed=0, optimize=False))
    assert [p.name for p in write_outputs(local, tmp_path / "local", figures="none")] == ["plan.json", "report.md"]
