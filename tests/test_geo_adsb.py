"""Real arrivals from ADS-B: the runway table, the converter on synthetic and (with the adsb extra) real flights,
the bundled CDG scenario and its radar bag."""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from pymap3d.vincenty import vdist

from mal_planner.geo import adsb, adsb_tracks
from mal_planner.geo.runways import UnknownRunwayError, runway, runways
from mal_planner.ros.bagio import STATE_TYPE, open_reader
from mal_planner.ros.convert import aircraft_state_to_planner
from mal_planner.scenario import load_scenario
from mal_planner.service.tracks import Track as RadarTrack
from mal_planner.service.tracks import check_track
from mal_planner.units import ft_to_nm, kt_to_nm_per_s

SCENARIO = "scenarios/cdg_1443.yaml"
BAG = "data/cdg_1443_radar.mcap"
MOMENT = adsb_tracks.utc_seconds("2021-10-07T14:43Z")
PRESSURE_OFFSET_FT = 489.0


def test_runway_table_matches_apt_dat():
    table = runways("LFPG")
    assert sorted(table) == ["08L", "08R", "09L", "09R", "26L", "26R", "27L", "27R"]
    r27 = table["27R"].frame  # no displaced threshold: the runway end, as in scenarios/thesis_geodetic.yaml
    assert (r27.lat_deg, r27.lon_deg, round(r27.course_deg, 2)) == (49.02667786, 2.56169447, 265.43)
    r26 = table["26R"]  # threshold displaced 576.99 m along the runway from its end
    moved, _ = vdist(48.99875734, 2.61060285, r26.frame.lat_deg, r26.frame.lon_deg)
    assert moved == pytest.approx(576.99, abs=1e-3)
    assert r26.length_m == pytest.approx(vdist(48.99875734, 2.61060285, 48.99566392, 2.55215505)[0] - 576.99,
                                         abs=0.01)
    for a, b in (("08R", "26L"), ("09L", "27R")):  # opposite directions
        assert (table[a].frame.course_deg - table[b].frame.course_deg) % 360.0 == pytest.approx(180.0, abs=0.05)
    with pytest.raises(UnknownRunwayError, match="known: 08L"):
        runway("LFPG", "28")
    with pytest.raises(UnknownRunwayError, match="LFPG"):
        runway("EGLL", "27R")


def _approach(name: str, rw_name: str, y0_nm: float, speed_kt: float, t0: float, height_ft: float | None = None,
              x_nm: float = 0.0) -> adsb_tracks.Track:
    """A synthetic track flying straight along -y of ``rw_name``'s frame at 1 Hz: on a 3-deg glide path to 50 ft
    over the threshold (or level at ``height_ft``), to 1 nm past it, its altitudes recorded barometric (the day's
    pressure offset taken off)."""
    frame = runway("LFPG", rw_name).frame
    v = kt_to_nm_per_s(speed_kt)
    t = np.arange(0.0, (y0_nm + 1.0) / v, 1.0)
    y = y0_nm - v * t
    if height_ft is None:
        z = np.maximum(y, 0.0) * math.tan(math.radians(3.0)) + ft_to_nm(adsb_tracks.THRESHOLD_CROSSING_HEIGHT_FT)
    else:
        z = np.full_like(y, ft_to_nm(height_ft))
    lat, lon, alt = frame.to_geodetic(np.stack([np.full_like(y, x_nm), y, z], axis=-1))
    track = np.array([frame.direction_to_geodetic(p, -math.pi / 2, 0.0)[0]
                      for p in np.stack([np.full_like(y, x_nm), y, z], axis=-1)])
    return adsb_tracks.Track(name, name, t0 + t, lat, lon, alt - PRESSURE_OFFSET_FT, np.full_like(t, speed_kt), track)


def test_converter_on_synthetic_tracks():
    t0 = MOMENT - 300.0
    first = _approach("FIRST", "08R", 20.0, 150.0, t0)           # lands first (about 500 s after t0)
    second = _approach("SECOND", "09R", 30.0, 180.0, t0)         # the parallel runway, same direction
    close = _approach("CLOSE", "08R", 21.0, 150.0, t0 + 6.0)    # 1.3 nm behind FIRST at the moment
    high = _approach("HIGH", "08R", 40.0, 250.0, t0 - 60.0, height_ft=30000.0)  # overflight, aligned: no landing
    far = _approach("FAR", "08R", 120.0, 250.0, t0)             # lands much later, outside the area at the moment
    tracks = [first, second, close, high, far]
    landings = {tr.callsign: adsb_tracks.detect_landing(tr, runways("LFPG").values()) for tr in tracks}
    assert landings["HIGH"] is None
    assert {c: lnd.runway.name for c, lnd in landings.items() if lnd} == {
        "FIRST": "08R", "SECOND": "09R", "CLOSE": "08R", "FAR": "08R"}
    expected = t0 + 20.0 / kt_to_nm_per_s(150.0)
    assert landings["FIRST"].time_s == pytest.approx(expected, abs=0.5)
    for tr in tracks:
        tr.landing = landings[tr.callsign]
    # to the Earth's curvature: the straight glide path rises 14 ft above the line fitted in altitude at 4 nm
    assert adsb_tracks.altimeter_offset_ft(tracks) == pytest.approx(PRESSURE_OFFSET_FT, abs=5.0)

    rw = runway("LFPG", "08R")
    only_runway = adsb.select_arrivals(tracks, rw, MOMENT, adsb.Area.square(25.0, 1.2))
    assert [a.callsign for a in only_runway.kept] == ["FIRST"]
    assert dict(only_runway.skipped)["CLOSE"].endswith("closer than the separation")
    assert "outside the terminal area" in dict(only_runway.skipped)["FAR"]
    airport = adsb.select_arrivals(tracks, rw, MOMENT, adsb.Area.square(25.0, 1.2), arrivals="airport")
    assert [a.callsign for a in airport.kept] == ["FIRST", "SECOND"]
    state = airport.kept[0]
    y_now = 20.0 - kt_to_nm_per_s(150.0) * 300.0
    assert state.local == pytest.approx([0.0, y_now, y_now * math.tan(math.radians(3.0)) + ft_to_nm(50.0)],
                                        abs=ft_to_nm(5.0))  # the calibration's few ft
    # at the aircraft: -3 deg in the runway frame less the tangent plane's tilt there (y / R, 0.1 deg at 7.5 nm)
    _, gamma = rw.frame.direction_to_local(state.lat, state.lon, state.track_deg, state.flight_path_angle_deg)
    assert math.degrees(gamma) == pytest.approx(-3.0, abs=0.02)
    assert state.speed_kt == 150.0
    low_ceiling = adsb.select_arrivals(tracks, rw, MOMENT, adsb.Area.square(25.0, ft_to_nm(800.0)))
    assert "outside the terminal area's 0-800 ft" in dict(low_ceiling.skipped)["FIRST"]

    data = adsb.scenario_data(airport, "synthetic")
    assert data["separation"] == {"distance_nm": 3.0, "landing_spacing_s": 90.0, "max_landing_spacing_s": 180.0}
    assert data["runway"]["flight_path_angle_deg"] == -3.0
    assert data["limits"] == {"bank_angle_deg": 30.0, "n_h": [-1.0, 1.0], "n_v": [0.7, 1.3]}
    assert "procedures" not in data and "model" not in data["aircraft"][0]
    flyable = adsb.scenario_data(airport, "synthetic", flyable=True)  # airliners under the default procedures
    assert flyable["procedures"] == {"aircraft_type": "A320"}
    assert {a["model"] for a in flyable["aircraft"]} == {"point_mass_airspeed"}


def test_flyable_airspeed_is_kept_inside_the_envelope_and_the_speed_limit():
    """Ground speeds taken as airspeeds: a slow one on final (headwind) starts at the type's slowest final approach
    speed, a fast one below 10,000 ft (tailwind) at the speed limit, both less the optimizer's share; others keep
    their ground speed."""
    from mal_planner.landing.margins import SafetyMargins
    from mal_planner.performance import cas_of_tas, performance_of

    keep = 1.0 - SafetyMargins().speed
    slowest = performance_of("A320").final_approach_cas.low / keep

    def start(speed_kt: float, alt_ft: float) -> tuple[float, float, str | None]:
        a = adsb.Arrival(None, "T", 49.0, 2.5, alt_ft, 90.0, -3.0, speed_kt, np.zeros(3))
        tas_kt, note = adsb.airspeed_estimate(a)
        return tas_kt, float(cas_of_tas(kt_to_nm_per_s(tas_kt), ft_to_nm(alt_ft))), note

    tas, cas, note = start(120.0, 700.0)
    assert cas == pytest.approx(slowest, rel=1e-6) and tas > 120.0
    assert "below the type's slowest final approach" in note
    tas, cas, note = start(270.0, 4500.0)
    assert cas == pytest.approx(keep * kt_to_nm_per_s(250.0), rel=1e-6) and tas < 270.0
    assert note.startswith("T: ground speed 270 kt") and "the rest is wind" in note
    assert start(200.0, 4500.0)[::2] == (200.0, None)
    assert start(330.0, 15000.0)[::2] == (330.0, None)  # above 10,000 ft the limit does not hold


def test_cdg_scenario_loads_inside_its_airspace():
    sc = load_scenario(SCENARIO)
    assert sc.geo_frame == runway("LFPG", "08R").frame
    assert len(sc.aircraft) >= 8
    assert (sc.separation_nm, sc.landing_spacing_s) == (3.0, 90.0)
    assert math.degrees(sc.runway_state[3]) == pytest.approx(-3.0)
    states = np.array([a.state0[:3] for a in sc.aircraft])
    assert np.all(sc.in_airspace(states))
    for a, b in itertools.combinations(states, 2):  # a separated start
        assert np.linalg.norm(a - b) >= sc.separation_nm
    for ac in sc.aircraft:
        assert 140.0 <= ac.speed / kt_to_nm_per_s(1.0) <= 400.0  # ground speeds of arrivals


def test_cdg_radar_bag_replays_the_scenario_states():
    sc = load_scenario(SCENARIO)
    reader = open_reader(BAG)
    try:
        topics = {c.topic for c in reader.connections}
        assert topics == {"/radar/tracks"} | {f"/aircraft/{a.callsign}/state" for a in sc.aircraft}
        last: dict[str, tuple[float, np.ndarray, float]] = {}
        stamps = set()
        conns = [c for c in reader.connections if c.topic == "/radar/tracks"]
        for conn, stamp_ns, raw in reader.messages(connections=conns):
            assert conn.msgtype == STATE_TYPE
            msg = reader.deserialize(raw, STATE_TYPE)
            assert msg.header.frame_id == "runway"
            callsign, t, state, speed, _wake = aircraft_state_to_planner(msg)
            assert check_track(RadarTrack(callsign, t, state, speed), msg.header.frame_id, "runway", sc.airspace,
                               expected_speed=sc.aircraft_by_callsign(callsign).speed) is None
            last[callsign] = (t, state, speed)
            stamps.add(stamp_ns)
    finally:
        reader.close()
    assert max(stamps) == round(MOMENT * 1e9) and min(stamps) == round((MOMENT - 30.0) * 1e9)
    for ac in sc.aircraft:  # at the moment, the radar and the scenario agree (to the file's rounding)
        t, state, speed = last[ac.callsign]
        assert t == pytest.approx(MOMENT)
        assert state[:3] == pytest.approx(ac.state0[:3], abs=1e-4)
        assert state[4] == pytest.approx(ac.state0[4], abs=1e-3)
        assert state[3] == pytest.approx(ac.state0[3], abs=1e-4)
        assert speed == pytest.approx(ac.speed, rel=1e-3)


@pytest.fixture(scope="module")
def sample_flights():
    """A few real flights of traffic's sample quickstart (needs the adsb extra)."""
    pytest.importorskip("traffic", reason="the traffic library is not installed (optional extra 'adsb': "
                                          "pip install -e '.[adsb]')")
    from traffic.data.samples import quickstart

    df = quickstart.data
    return adsb_tracks.tracks_from_frame(df[df["callsign"].isin(["AFR4145", "AFR71ZP", "AFR429", "AFL2461"])])


def test_stale_positions_are_dropped(sample_flights):
    """The receiver repeats a position until it decodes a new one: AFR71ZP's sample holds its last position 0.83 nm
    before 08R for minutes after it landed, which made its landing (time over the threshold, fitted on its final)
    204 s late. Every kept sample has a new position, and the landing is within seconds of its last live sample
    (flying on at 129 kt, 0.83 nm take 23 s)."""
    from traffic.data.samples import quickstart

    raw = quickstart.data.query("callsign == 'AFR71ZP'").dropna(subset=["latitude", "longitude"])
    afr = next(tr for tr in sample_flights if tr.callsign == "AFR71ZP")
    assert len(afr.t) < len(raw) and np.all((np.diff(afr.lat) != 0.0) | (np.diff(afr.lon) != 0.0))
    landing = adsb_tracks.detect_landing(afr, runways("LFPG").values())
    assert 0.0 < landing.time_s - afr.t[-1] < 40.0
    assert raw["timestamp"].max().timestamp() - landing.time_s > 200.0  # the stale repeats went on past it


def test_converter_on_sample_flights(sample_flights):
    by = {tr.callsign: tr for tr in sample_flights}
    table = runways("LFPG").values()
    lands = {c: adsb_tracks.detect_landing(tr, table) for c, tr in by.items()}
    assert lands["AFL2461"] is None  # a departure
    assert {c: (lnd.runway.name, adsb_tracks.utc_text(lnd.time_s)[11:16]) for c, lnd in lands.items() if lnd} == {
        "AFR4145": ("08R", "14:48"), "AFR71ZP": ("08R", "14:46"), "AFR429": ("09R", "14:54")}
    sc = load_scenario(SCENARIO)
    # the bundled file's offset (its header: calibrated on all the recording's landings, not on these three)
    offset = float(re.search(r"barometric altitude ([+-]\d+\.\d) ft", Path(SCENARIO).read_text("utf-8")).group(1))
    sel = adsb.select_arrivals(sample_flights, runway("LFPG", "08R"), MOMENT, adsb.Area.square(40.0, 3.0),
                               arrivals="airport", altitude_offset_ft=offset)
    assert [a.callsign for a in sel.kept] == ["AFR71ZP", "AFR4145", "AFR429"]
    bundled = {a.callsign: a.state0 for a in sc.aircraft}
    written = {a["callsign"]: a for a in yaml.safe_load(Path(SCENARIO).read_text("utf-8"))["aircraft"]}
    for a in sel.kept:  # the bundled scenario's states, to its rounding (1e-7 deg, 0.1 ft)
        assert a.local == pytest.approx(bundled[a.callsign][:3], abs=ft_to_nm(0.2))
        assert a.flight_path_angle_deg == pytest.approx(written[a.callsign]["flight_path_angle_deg"], abs=1e-3)
        assert a.speed_kt == written[a.callsign]["speed_kt"]
