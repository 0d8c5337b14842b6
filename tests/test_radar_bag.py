"""Message conversions, the radar bag script, and the replay/record/radar_sim nodes on real DDS (loopback)."""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from dds_support import SRC, dds_env  # noqa: F401  (fixture; the replay/record/radar-sim tests run on both backends)

from mal_planner.ros.bagio import MsgTypes, open_reader, serialize
from mal_planner.ros.convert import (
    aircraft_state_to_planner,
    msg_to_time,
    path_msg,
    path_to_planner,
    planner_to_aircraft_state,
    pose_from_state,
    time_to_msg,
)
from mal_planner.scenario import load_scenario
from mal_planner.units import METRES_PER_NM

ROOT = SRC.parent
SCENARIO = ROOT / "scenarios" / "thesis.yaml"
SCRIPT = ROOT / "scripts" / "make_radar_bag.py"
STATE = "mal_msgs/msg/AircraftState"
N_STEPS = 41  # 20 s at 2 Hz, both ends included


# -- conversions -----------------------------------------------------------------------------------------
def test_aircraft_state_round_trip() -> None:
    state = np.array([1.2, 5.8, 0.28, 0.05, -0.3])
    msg = planner_to_aircraft_state(MsgTypes, "A1", 1234.5, state, 0.04, "M")
    assert msg.position.x == pytest.approx(1.2 * METRES_PER_NM)
    assert msg.position.z == pytest.approx(0.28 * METRES_PER_NM)
    assert msg.speed == pytest.approx(0.04 * METRES_PER_NM)
    assert msg.header.frame_id == "runway" and msg.header.stamp.sec == 1234 and msg.header.stamp.nanosec == 5e8
    callsign, stamp, back, speed, wake = aircraft_state_to_planner(msg)
    assert (callsign, stamp, wake) == ("A1", 1234.5, "M")
    np.testing.assert_allclose(back, state, rtol=1e-12)
    assert speed == pytest.approx(0.04)
    assert aircraft_state_to_planner(planner_to_aircraft_state(MsgTypes, "B", 0.0, state, 0.04))[4] is None


def test_time_round_trip() -> None:
    t = 1_700_000_000.123456789
    msg = time_to_msg(MsgTypes, t)
    assert msg.sec == 1_700_000_000 and abs(msg.nanosec - 123456789) <= 256
    assert msg_to_time(msg) == pytest.approx(t, abs=1e-6)


def _rotate(q, v) -> np.ndarray:
    x, y, z, w = q
    r = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip
    return r @ np.asarray(v, float)


def test_pose_quaternion_by_hand() -> None:
    # heading north (yaw pi/2), climbing 0.1 rad: q = q_yaw(pi/2) * q_pitch(-0.1), worked out by hand.
    pose = pose_from_state(MsgTypes, 10.0, [1.0, 2.0, 0.1, 0.1, math.pi / 2])
    o = pose.pose.orientation
    s, sp, cp = math.sqrt(0.5), math.sin(0.05), math.cos(0.05)
    np.testing.assert_allclose([o.x, o.y, o.z, o.w], [s * sp, -s * sp, s * cp, s * cp], atol=1e-12)
    assert pose.pose.position.y == pytest.approx(2 * METRES_PER_NM) and msg_to_time(pose) == 10.0
    # The nose (body +x) points north and up by gamma.
    np.testing.assert_allclose(_rotate((o.x, o.y, o.z, o.w), [1, 0, 0]), [0, math.cos(0.1), math.sin(0.1)], atol=1e-12)
    # Planner bank mu > 0 is a left (counter-clockwise) turn: left wing (body +y) down, i.e. REP 103 roll < 0.
    o = pose_from_state(MsgTypes, 0.0, [0, 0, 0, 0, 0], bank=0.2).pose.orientation
    np.testing.assert_allclose([o.x, o.y, o.z, o.w], [-math.sin(0.1), 0, 0, math.cos(0.1)], atol=1e-12)
    assert _rotate((o.x, o.y, o.z, o.w), [0, 1, 0])[2] < 0


def test_path_round_trip() -> None:
    t = np.array([0.0, 1.0, 2.5])
    states = np.array([[1.0, 5.0, 0.2, 0.02, -1.5], [1.0, 4.96, 0.2, 0.0, -1.6], [1.0, 4.9, 0.19, -0.03, 3.1]])
    bank = np.array([0.0, 0.1, -0.2])
    msg = path_msg(MsgTypes, "A1", 100.0, t, states, bank)
    assert msg.header.frame_id == "runway" and len(msg.poses) == 3
    assert msg.poses[1].pose.position.y == pytest.approx(4.96 * METRES_PER_NM)
    stamps, back, bank_back = path_to_planner(msg)
    np.testing.assert_allclose(stamps, 100.0 + t)
    np.testing.assert_allclose(back, states, atol=1e-9)
    np.testing.assert_allclose(bank_back, bank, atol=1e-9)
    assert len(serialize(msg, "nav_msgs/msg/Path")) > 100


# -- the bag script ---------------------------------------------------------------------------------------
def _make_bag(out: Path, storage: str = "mcap") -> Path:
    res = subprocess.run([sys.executable, str(SCRIPT), "--out", str(out), "--storage", storage],
                         capture_output=True, text=True, timeout=60)  # fmt: skip
    assert res.returncode == 0, res.stderr
    return out


@pytest.mark.parametrize(("storage", "name"), [("mcap", "radar.mcap"), ("sqlite3", "radar.db3"), ("sqlite3", "dir")])
def test_make_radar_bag(tmp_path: Path, storage: str, name: str) -> None:
    bag = _make_bag(tmp_path / name, storage)
    scenario = load_scenario(SCENARIO)
    reader = open_reader(bag)
    try:
        topics = {c.topic: c.msgtype for c in reader.connections}
        assert topics == {"/radar/tracks": STATE, **{f"/aircraft/{a.callsign}/state": STATE for a in scenario.aircraft}}
        assert reader.message_count == 2 * 3 * N_STEPS
        last: dict[str, float] = {}
        for conn, ts, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
            assert stamp == pytest.approx(ts / 1e9)
            key = conn.topic + msg.callsign
            assert stamp > last.get(key, -1.0)
            last[key] = stamp
            if stamp == 1_700_000_000:  # first sample: the scenario's initial position, in metres (5 m noise)
                ac = scenario.aircraft_by_callsign(msg.callsign)
                pos = [msg.position.x, msg.position.y, msg.position.z]
                np.testing.assert_allclose(pos, ac.position * METRES_PER_NM, atol=30.0)
                assert msg.speed == pytest.approx(ac.speed * METRES_PER_NM)
    finally:
        reader.close()


def test_make_radar_bag_is_deterministic(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    a = _make_bag(tmp_path / "a" / "thesis_radar.mcap")
    assert a.read_bytes() == (ROOT / "data" / "thesis_radar.mcap").read_bytes()


# -- nodes on DDS -----------------------------------------------------------------------------------------
_started: list[subprocess.Popen[str]] = []


@pytest.fixture(autouse=True)
def _no_leftover_processes():
    """Kill any replay/record process a test left running (e.g. after a failed assertion)."""
    yield
    while _started:
        proc = _started.pop()
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def _start(env: dict[str, str], module: str, *args: str) -> subprocess.Popen[str]:
    proc = subprocess.Popen([sys.executable, "-m", f"mal_planner.ros.{module}", *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    _started.append(proc)
    return proc


def _finish(proc: subprocess.Popen[str], timeout: float = 30.0) -> tuple[int, str, str]:
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        pytest.fail(f"{proc.args} did not finish; stderr:\n{err}")
    return proc.returncode, out, err


def test_replay_publishes_bag(tmp_path: Path, backend_env: dict[str, str]) -> None:
    from mal_planner.ros.transport import create_node

    bag = _make_bag(tmp_path / "radar.db3", "sqlite3")
    with create_node("listener", backend="cyclone") as node:
        topics = ["/radar/tracks", *(f"/aircraft/{cs}/state" for cs in ("A1", "A2", "A3"))]
        got = {t: [] for t in topics}
        for topic in topics:
            # Depth for every message: a listener that falls behind on a loaded machine must not lose any.
            node.create_subscription(STATE, topic, got[topic].append, 3 * N_STEPS)
        proc = _start(backend_env, "replay", str(bag), "--rate", "10", "--wait-for-subscribers", "15")
        deadline = time.monotonic() + 30
        while proc.poll() is None and time.monotonic() < deadline:
            node.spin_once(0.05)
        for _ in range(10):
            node.spin_once(0.05)
        rc, out, err = _finish(proc)
    assert rc == 0, err
    assert out.strip().splitlines()[-1].startswith(f"replay: {2 * 3 * N_STEPS} messages")
    assert len(got["/radar/tracks"]) == 3 * N_STEPS
    assert [m.callsign for m in got["/aircraft/A2/state"]] == ["A2"] * N_STEPS
    assert {m.callsign for m in got["/radar/tracks"]} == {"A1", "A2", "A3"}
    first = got["/aircraft/A2/state"][0]
    assert first.position.x == pytest.approx(-1.8 * METRES_PER_NM, abs=30.0)  # metres
    assert msg_to_time(got["/aircraft/A2/state"][-1]) - msg_to_time(first) == pytest.approx(20.0)


def test_replay_restamp(tmp_path: Path, backend_env: dict[str, str]) -> None:
    from mal_planner.ros.transport import create_node

    bag = _make_bag(tmp_path / "radar.mcap")
    with create_node("listener", backend="cyclone") as node:
        got: list = []
        node.create_subscription(STATE, "/aircraft/A1/state", got.append, 100)
        proc = _start(backend_env, "replay", str(bag), "--rate", "0", "--restamp", "--topics", "aircraft/A1/state",
                      "--wait-for-subscribers", "15")  # fmt: skip
        deadline = time.monotonic() + 30
        while len(got) < N_STEPS and time.monotonic() < deadline:
            node.spin_once(0.05)
        rc, _, err = _finish(proc)
    assert rc == 0, err
    assert len(got) == N_STEPS and abs(msg_to_time(got[0]) - time.time()) < 30.0


@pytest.mark.parametrize("bad", ["missing.mcap", "garbage.mcap", "empty_dir"])
def test_replay_bad_bag(tmp_path: Path, dds_env: dict[str, str], bad: str) -> None:  # noqa: F811
    path = tmp_path / bad
    if bad == "garbage.mcap":
        path.write_bytes(b"not a bag\n")
    elif bad == "empty_dir":
        path.mkdir()
    rc, out, err = _finish(_start(dds_env, "replay", str(path)))
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0] and lines[0].startswith("replay: ")


def test_record_until_sigterm(tmp_path: Path, backend_env: dict[str, str]) -> None:
    from mal_planner.ros.transport import QOS_LATCHED, create_node

    out = tmp_path / "rec"
    with create_node("talker", backend="cyclone") as node:
        # A latched path published BEFORE the recorder starts: it must still be recorded (TRANSIENT_LOCAL).
        path_pub = node.create_publisher("nav_msgs/msg/Path", "aircraft/A1/path", QOS_LATCHED)
        path_pub.publish(path_msg(node.types, "A1", 5.0, [0.0, 1.0], np.zeros((2, 5))))
        pub = node.create_publisher(STATE, "radar/tracks", 10)
        proc = _start(backend_env, "record", str(out), "--topics", "radar/tracks", "--callsigns", "A1")
        deadline = time.monotonic() + 20
        while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert pub.get_subscription_count() > 0, "recorder did not subscribe"
        for k in range(20):
            pub.publish(planner_to_aircraft_state(node.types, "A1", 100.0 + k, [1.0, 5.0, 0.2, 0.0, -1.5], 0.04))
            time.sleep(0.02)
        time.sleep(1.0)
        proc.send_signal(signal.SIGTERM)
        rc, stdout, err = _finish(proc)
    assert rc == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["metadata.yaml", "rec_0.mcap"]  # one storage file
    reader = open_reader(out)
    try:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts["/radar/tracks"] == 20
        assert counts["/aircraft/A1/path"] == 1
        assert counts["/aircraft/A1/state"] == 0
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types["/aircraft/A1/path"] == "nav_msgs/msg/Path" and types["/radar/tracks"] == STATE
        stamps = [reader.deserialize(raw, c.msgtype).header.stamp.sec
                  for c, _, raw in reader.messages() if c.topic == "/radar/tracks"]  # fmt: skip
        assert stamps == list(range(100, 120))
    finally:
        reader.close()


def test_record_survives_sigkill(tmp_path: Path, backend_env: dict[str, str]) -> None:
    """SIGKILL of the recorder after 4 s of radar at 20 Hz: the bag (one storage file, without its MCAP summary)
    is recovered when read and holds every message but those of the last --flush-s (1 s) before the kill, in
    order and without gaps."""
    from mal_planner.ros.transport import create_node

    out = tmp_path / "rec"
    with create_node("talker", backend="cyclone") as node:
        pub = node.create_publisher(STATE, "radar/tracks", 10)
        proc = _start(backend_env, "record", str(out), "--topics", "radar/tracks", "--flush-s", "1")
        deadline = time.monotonic() + 20
        while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert pub.get_subscription_count() > 0, "recorder did not subscribe"
        sent = 80
        for k in range(sent):
            pub.publish(planner_to_aircraft_state(node.types, "A1", 100.0 + k, [1.0, 5.0, 0.2, 0.0, -1.5], 0.04))
            time.sleep(0.05)
        proc.kill()
        proc.communicate()
    assert proc.returncode == -signal.SIGKILL
    assert sorted(p.name for p in out.iterdir()) == [".writing", "metadata.yaml", "rec_0.mcap"]
    assert not (out / "rec_0.mcap").read_bytes().endswith(b"\x89MCAP0\r\n")  # killed: no summary, no footer
    reader = open_reader(out)
    try:
        stamps = [reader.deserialize(raw, c.msgtype).header.stamp.sec
                  for c, _, raw in reader.messages() if c.topic == "/radar/tracks"]  # fmt: skip
        assert reader.message_count == len(stamps)
    finally:
        reader.close()
    lost = sent - len(stamps)
    print(f"recorder SIGKILL: {len(stamps)} of {sent} messages kept, {lost * 0.05:.2f} s lost")
    assert stamps == list(range(100, 100 + len(stamps)))  # the first ones, in order, no gap
    assert lost * 0.05 <= 2.0  # at most one flush period (1 s) plus delivery delays
    assert sorted(p.name for p in out.iterdir()) == ["metadata.yaml", "rec_0.mcap"]  # recovered once for all


def test_record_bad_input(tmp_path: Path, dds_env: dict[str, str]) -> None:  # noqa: F811
    existing = tmp_path / "exists"
    existing.mkdir()
    for args in ([str(existing)], [str(tmp_path / "x"), "--topics", "some/topic"],
                 ["/proc/no/such/bag"]):  # fmt: skip
        rc, _, err = _finish(_start(dds_env, "record", *args))
        assert rc == 2 and len(err.strip().splitlines()) == 1 and err.startswith("record: "), err
    assert not (tmp_path / "x").exists()


def test_radar_sim_publishes_every_callsign(backend_env: dict[str, str]) -> None:
    from mal_planner.ros.transport import create_node

    with create_node("listener", backend="cyclone") as node:
        topics = ["/radar/tracks", "/aircraft/A1/state", "/aircraft/A3/state"]
        got = {t: [] for t in topics}
        for topic in topics:
            node.create_subscription(STATE, topic, got[topic].append, 10)
        proc = _start(backend_env, "radar_sim", "--scenario", str(SCENARIO), "--rate", "10", "--duration", "4",
                      "--noise-m", "2", "--seed", "3")  # fmt: skip
        deadline = time.monotonic() + 30
        while proc.poll() is None and time.monotonic() < deadline:
            node.spin_once(0.05)
        rc, _, err = _finish(proc)
    assert rc == 0, err
    assert {m.callsign for m in got["/radar/tracks"]} == {"A1", "A2", "A3"}
    a1 = got["/aircraft/A1/state"]
    assert len(a1) >= 3 and {m.callsign for m in a1} == {"A1"}
    assert {m.callsign for m in got["/aircraft/A3/state"]} == {"A3"}
    # A1 flies level at heading -15 deg, 0.04 nm/s: the track moves that way, in metres.
    dt = msg_to_time(a1[-1]) - msg_to_time(a1[0])
    dx, dy = a1[-1].position.x - a1[0].position.x, a1[-1].position.y - a1[0].position.y
    v = 0.04 * METRES_PER_NM
    assert dx == pytest.approx(v * dt * math.cos(math.radians(-15)), abs=15)
    assert dy == pytest.approx(v * dt * math.sin(math.radians(-15)), abs=15)
    assert a1[0].header.frame_id == "runway" and abs(msg_to_time(a1[0]) - time.time()) < 60


def test_radar_sim_stops_on_sigint(dds_env: dict[str, str]) -> None:  # noqa: F811
    proc = _start(dds_env, "radar_sim", "--scenario", str(SCENARIO), "--topics", "shared")
    assert proc.stdout is not None and proc.stdout.readline().startswith("radar_sim: 3 aircraft")
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    rc, _, err = _finish(proc, timeout=15)
    assert rc == 0, err


def test_radar_simulator_level_flight_and_plan() -> None:
    from mal_planner.ros.radar_sim import RadarSimulator

    scenario = load_scenario(SCENARIO)
    sim = RadarSimulator(scenario, t0=100.0)
    sim.step_to(110.0)
    # Without a plan an aircraft holds its heading (A1 flies level already: a straight line) ...
    a1 = scenario.aircraft_by_callsign("A1")
    heading = a1.state0[4]
    expect = a1.position + 10 * a1.speed * np.array([math.cos(heading), math.sin(heading), 0.0])
    np.testing.assert_allclose(sim.tracks[0].state[:3], expect, atol=1e-9)
    # A received plan (nav_msgs/Path) is flown by the guidance from the current time: a straight line along -y.
    t_now = sim.t
    p0 = sim.tracks[0].state.copy()
    states = np.array([[p0[0], p0[1], p0[2], 0.0, -math.pi / 2], [p0[0], p0[1] - 1.6, p0[2], 0.0, -math.pi / 2]])
    stamps, planned, _ = path_to_planner(path_msg(MsgTypes, "A1", t_now, [0.0, 40.0], states))
    assert sim.set_plan("A1", stamps, planned) and not sim.set_plan("ZZ", stamps, planned)
    sim.step_to(t_now + 40.0)
    # ... and A2, climbing at 5 deg without a plan, levels off on its heading.
    assert abs(sim.tracks[1].state[3]) < math.radians(0.1)
    assert abs(math.remainder(sim.tracks[1].state[4] - scenario.aircraft[1].state0[4], 2 * math.pi)) < 1e-9
    # It turns onto the line (75 deg at the 45-deg bank limit) and then flies along it, a little behind.
    assert abs(sim.tracks[0].state[0] - p0[0]) < 0.02 and abs(sim.tracks[0].state[4] + math.pi / 2) < 0.05


def test_bag_io_does_not_load_cyclonedds() -> None:
    """Replay and record on the rclpy backend must not load a second Cyclone library: reading, (de)serializing
    and typestore use of bagio/replay/record import no cyclonedds module."""
    code = (
        "import sys\n"
        "import mal_planner.ros.bagio as b, mal_planner.ros.replay, mal_planner.ros.record\n"
        f"r = b.open_reader({str(SRC.parent / 'data' / 'thesis_radar.mcap')!r})\n"
        "c, t, raw = next(iter(r.messages()))\n"
        "assert b.serialize(r.deserialize(raw, c.msgtype), c.msgtype) == bytes(raw)\n"
        "print(sorted(m for m in sys.modules if m.startswith('cyclonedds')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    assert out.stdout.strip() == "[]", out.stdout
