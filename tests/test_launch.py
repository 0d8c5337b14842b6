"""mal-launch end to end: replay the thesis bag through the planner, record, write outputs, exit 0."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from dds_support import coarse_params, dds_env  # noqa: F401  (fixture)

REPO = Path(__file__).resolve().parents[1]


def test_launch_replay_end_to_end(backend_env: dict[str, str], tmp_path: Path) -> None:
    """On each backend: mal-launch's children (replay, planner, recorder) run on the backend under test."""
    params = tmp_path / "params.yaml"
    params.write_text(coarse_params(), encoding="utf-8")
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
