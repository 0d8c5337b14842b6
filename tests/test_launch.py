"""mal-launch end to end: replay the thesis bag through the planner, record, write outputs, exit 0."""

from __future__ import annotations

import contextlib
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import IO

import pytest
from dds_support import coarse_params, dds_env  # noqa: F401  (fixture)

from mal_planner.ros.launch import STOP_TIMEOUT_S

REPO = Path(__file__).resolve().parents[1]


def test_launch_replay_end_to_end(backend_env: dict[str, str], tmp_path: Path) -> None:
    """On each backend: mal-launch's children (replay, planner, recorder) run on the backend under test. Recorded
    radar does not follow the plans: the deviation threshold is 0, as for any replay (no replans for deviations, no
    holds or vectors for aircraft that cannot fly them; on a loaded machine the safety net held every recorded
    aircraft once the first plan came late, and no plan was left to show)."""
    params = tmp_path / "params.yaml"
    params.write_text(coarse_params("    deviation_threshold_m: 0.0\n"), encoding="utf-8")
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "mal_planner.ros.launch", "--replay", str(REPO / "data" / "thesis_radar.mcap"),
         "--rate", "2", "--params", str(params), "--out", str(out), "--timeout", "150"],
        env=backend_env, cwd=tmp_path, capture_output=True, text=True, timeout=240, check=False)
    assert proc.returncode == 0, proc.stdout[-5000:] + proc.stderr[-2000:]
    assert "order  callsign" in proc.stdout and "A1" in proc.stdout
    assert (out / "plan.json").is_file() and (out / "report.md").is_file()
    assert list(out.glob("*.png"))

    from mal_planner.ros.bagio import open_reader

    reader = open_reader(out / "bag")
    try:
        counts: dict[str, int] = {}
        for conn, _t, raw in reader.messages():
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
            if conn.topic == "/aircraft/A1/path":
                path = reader.deserialize(raw, conn.msgtype)
                assert path.header.frame_id == "runway" and len(path.poses) > 10
    finally:
        reader.close()
    assert counts.get("/radar/tracks", 0) > 50
    assert all(counts.get(f"/aircraft/{cs}/path", 0) >= 1 for cs in ("A1", "A2", "A3"))
    assert counts.get("/landing_plan", 0) >= 1


def test_launch_closed_loop_lands_everyone(backend_env: dict[str, str], tmp_path: Path) -> None:
    """The main job's closed loop on each backend: the simulator flies the planner's paths on /clock (the planner on
    use_sim_time) until all three have landed, with every minimum kept on the flown tracks."""
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "mal_planner.ros.launch", "--closed-loop", "--scenario",
         str(REPO / "scenarios" / "thesis_wind.yaml"), "--sim-speed", "8", "--out", str(out), "--timeout", "150",
         "--no-record"],
        env=backend_env, cwd=tmp_path, capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 0, _story(proc.stdout) + proc.stderr[-2000:]
    assert "everyone landed, every minimum kept" in proc.stdout and "landed               3/3" in proc.stdout
    assert "in the future" not in proc.stdout  # the planner's clock is the simulator's
    import json

    metrics = json.loads((out / "closed_loop.json").read_text(encoding="utf-8"))
    assert metrics["success"] and metrics["separation_ratio"] > 1.0 and set(metrics["landing_times_s"]) == {
        "A1", "A2", "A3"}
    assert (out / "closed_loop.png").is_file()


def _story(stdout: str) -> str:
    """What a failed closed loop did, without the optimizer's lines (the end of a long log loses its start)."""
    noise = ("mal_planner.ocp]", "mal_planner.optimizer]", "mal_planner.initializer]")
    return "\n".join(line for line in stdout.splitlines() if not any(n in line for n in noise))[-12000:]


def test_loopback_config_only_when_unset(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from mal_planner.ros.launch import child_env, parse_args

    monkeypatch.delenv("CYCLONEDDS_URI", raising=False)
    env = child_env(tmp_path)
    assert env["CYCLONEDDS_URI"] == (tmp_path / "cyclonedds.xml").resolve().as_uri()
    assert "127.0.0.1" in (tmp_path / "cyclonedds.xml").read_text(encoding="utf-8")
    monkeypatch.setenv("CYCLONEDDS_URI", "file:///elsewhere.xml")
    assert child_env(tmp_path)["CYCLONEDDS_URI"] == "file:///elsewhere.xml"
    args = parse_args(["--replay", "x.mcap"])
    assert args.out == "out/main" and not args.no_record and args.record is None
    with pytest.raises(SystemExit):
        parse_args([])  # a radar source is required
    assert os.environ.get("CYCLONEDDS_URI") == "file:///elsewhere.xml"


def test_help_documents_the_network_default() -> None:
    proc = subprocess.run([sys.executable, "-m", "mal_planner.ros.launch", "--help"], capture_output=True, text=True,
                          timeout=60, check=True)
    assert "CYCLONEDDS_URI" in proc.stdout and "loopback" in proc.stdout


def _launch(env: dict[str, str], tmp_path: Path, *args: str) -> subprocess.Popen[str]:
    params = tmp_path / "params.yaml"
    params.write_text(coarse_params(), encoding="utf-8")
    return subprocess.Popen([sys.executable, "-u", "-m", "mal_planner.ros.launch", "--params", str(params), *args],
                            env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


_OUTPUT: dict[int, queue.Queue[str | None]] = {}


def _output(proc: subprocess.Popen[str]) -> queue.Queue[str | None]:
    """The launcher's output lines, read by a thread (select() on a buffered pipe misses lines already read into
    the buffer); None at end of output."""
    if proc.pid not in _OUTPUT:
        lines: queue.Queue[str | None] = queue.Queue()
        assert proc.stdout is not None

        def pump(stream: IO[str]) -> None:
            for line in stream:
                lines.put(line.rstrip("\n"))
            lines.put(None)

        threading.Thread(target=pump, args=(proc.stdout,), daemon=True).start()
        _OUTPUT[proc.pid] = lines
    return _OUTPUT[proc.pid]


def _wait_lines(proc: subprocess.Popen[str], *texts: str, timeout: float = 60.0) -> list[str]:
    """Lines of the launcher's output up to the one where every text has been seen."""
    lines: list[str] = []
    missing = set(texts)
    deadline = time.monotonic() + timeout
    output = _output(proc)
    while missing and time.monotonic() < deadline:
        try:
            line = output.get(timeout=max(0.0, min(0.2, deadline - time.monotonic())))
        except queue.Empty:
            continue
        if line is None:
            output.put(None)
            break
        lines.append(line)
        missing = {t for t in missing if t not in line}
    assert not missing, f"missing {missing} in:\n" + "\n".join(lines[-60:])
    return lines


def _rest_lines(proc: subprocess.Popen[str], timeout: float = 30.0) -> list[str]:
    """The launcher's remaining output lines, once it has exited."""
    lines: list[str] = []
    output = _output(proc)
    while (line := output.get(timeout=timeout)) is not None:
        lines.append(line)
    output.put(None)
    return lines


def _children(pid: int) -> list[int]:
    """Processes whose parent is ``pid`` (from /proc)."""
    out = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(entry.name))
    return out


def _alive(pid: int) -> bool:
    """Running (a zombie waiting for a reaper counts as dead)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_launch_sigkill_leaves_no_orphans(dds_env: dict[str, str], tmp_path: Path) -> None:  # noqa: F811
    """SIGKILL of mal-launch: within the launcher's own stop bound (STOP_TIMEOUT_S) none of its children
    (recorder, planner, simulator) is alive, and the recorder, stopped by SIGTERM on its parent's death, left a
    readable bag. Most end within 2 s; a planner inside a CasADi call holds the interpreter, so its SIGTERM
    handler runs only when that call returns (seen in CI: one child still alive after 2 s)."""
    out = tmp_path / "out"
    proc = _launch(dds_env, tmp_path, "--simulate", "--out", str(out))
    try:
        _wait_lines(proc, "[planner]", "planner ready", "[radar_sim]")
        children = _children(proc.pid)
        assert len(children) == 3, children
        proc.kill()
        proc.wait()
        deadline = time.monotonic() + STOP_TIMEOUT_S
        alive = [pid for pid in children if _alive(pid)]
        while alive and time.monotonic() < deadline:
            time.sleep(0.2)
            alive = [pid for pid in alive if _alive(pid)]
    finally:
        for pid in _children(proc.pid) + (alive if "alive" in locals() else []):
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
    assert alive == [], f"orphans left running: {alive}"
    from mal_planner.ros.bagio import open_reader

    open_reader(out / "bag").close()


def _planners(launcher: int) -> list[int]:
    """The launcher's planner children."""
    return [pid for pid in _children(launcher) if "planner_node" in Path(f"/proc/{pid}/cmdline").read_text()]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["SIGTERM", "SIGKILL"])
def test_launch_reports_a_child_killed_by_a_signal(dds_env: dict[str, str], tmp_path: Path,  # noqa: F811
                                                   sig: signal.Signals) -> None:
    """The planner stopped by a signal from outside, without --respawn: the launcher says so (signal by name),
    does not start it again and exits non-zero."""
    proc = _launch(dds_env, tmp_path, "--simulate", "--out", str(tmp_path / "out"))
    try:
        _wait_lines(proc, "planner ready", "[radar_sim]")
        planner = _planners(proc.pid)
        assert len(planner) == 1
        os.kill(planner[0], sig)
        lines = _wait_lines(proc, "launch: FAILED", timeout=30)
        assert proc.wait(timeout=60) == 1
        lines += _rest_lines(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert f"launch: FAILED: planner killed by {sig.name} (exit -{sig.value})" in lines
    assert not any("respawn" in line or "planner ready" in line for line in lines)


def test_launch_respawns_a_killed_planner(backend_env: dict[str, str], tmp_path: Path) -> None:
    """On each backend, --respawn: the planner SIGKILLed after its first plan comes back as another process (its
    duplicate probe not fooled by the dead one) and plans again from the radar; killed again with no respawn left,
    the launch ends reporting it. The recorder's one bag holds radar and plans from before and after the kill."""
    out = tmp_path / "out"
    proc = _launch(backend_env, tmp_path, "--simulate", "--respawn", "--respawn-delay", "0.5", "--respawn-max", "1",
                   "--out", str(out))
    try:
        _wait_lines(proc, "]: plan #1:", timeout=120)
        old = _planners(proc.pid)
        assert len(old) == 1
        os.kill(old[0], signal.SIGKILL)
        lines = _wait_lines(proc, "launch: planner killed by SIGKILL (exit -9): respawned as pid", timeout=30)
        respawned_ns = time.time_ns()
        assert lines[-1].endswith("after 0.5 s (attempt 1 of 1)")
        new = int(lines[-1].split("respawned as pid ")[1].split()[0])
        assert new != old[0] and _planners(proc.pid) == [new]
        lines += _wait_lines(proc, "]: plan #1:", timeout=120)  # the new planner's first plan
        replanned_ns = time.time_ns()
        os.kill(new, signal.SIGKILL)
        lines += _wait_lines(proc, "launch: FAILED", timeout=30)
        assert proc.wait(timeout=60) == 1
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert "launch: FAILED: planner killed by SIGKILL (exit -9) (respawned 1 time(s))" in lines
    from mal_planner.ros.bagio import open_reader

    assert sorted(p.name for p in out.iterdir() if p.name.startswith("bag")) == ["bag"]
    reader = open_reader(out / "bag")
    try:
        stamps: dict[str, list[int]] = {}
        for conn, t, _raw in reader.messages():
            stamps.setdefault(conn.topic, []).append(t)
    finally:
        reader.close()
    for topic in ("/radar/tracks", "/landing_plan"):
        assert min(stamps[topic]) < respawned_ns < max(stamps[topic]) < replanned_ns + 10**9, topic


@pytest.mark.parametrize("bad", [["--respawn-max", "0"], ["--respawn-delay", "-1"]])
def test_launch_bad_respawn_fails_before_starting(dds_env: dict[str, str], tmp_path: Path,  # noqa: F811
                                                  bad: list[str]) -> None:
    """--respawn-max below 1 or a negative --respawn-delay: exit 2, one line naming it, nothing started."""
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "mal_planner.ros.launch", "--simulate", "--respawn", *bad, "--out",
                           str(out)], env=dds_env, cwd=tmp_path, capture_output=True, text=True, timeout=60,
                          check=False)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"launch: {bad[0]}: must be"), proc.stderr
    assert "[planner]" not in proc.stdout and not out.exists()


@pytest.mark.parametrize("bad", ["replay", "scenario", "params"])
def test_launch_bad_input_fails_before_starting(dds_env: dict[str, str], tmp_path: Path, bad: str) -> None:  # noqa: F811
    """A bad bag, scenario or params file: exit 2, one line naming the file, no child started, no folder made."""
    garbage = tmp_path / ("garbage.mcap" if bad == "replay" else "garbage.yaml")
    garbage.write_text("not a bag: [\n", encoding="utf-8")
    args = ["--replay", str(garbage) if bad == "replay" else str(REPO / "data" / "thesis_radar.mcap")]
    if bad == "scenario":
        args += ["--scenario", str(garbage)]
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "mal_planner.ros.launch", *args, "--out", str(out)]
    if bad == "params":
        cmd += ["--params", str(garbage)]
    proc = subprocess.run(cmd, env=dds_env, cwd=tmp_path, capture_output=True, text=True, timeout=60, check=False)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"launch: --{bad}") and str(garbage) in lines[0], proc.stderr
    assert "[planner]" not in proc.stdout and "[recorder]" not in proc.stdout
    assert not out.exists()
