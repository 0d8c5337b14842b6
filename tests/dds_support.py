"""Helpers for tests that use real Cyclone DDS on loopback: config, per-test domain ids, subprocesses."""

from __future__ import annotations

import itertools
import os
import queue
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
if str(SRC) not in sys.path:  # run from a source checkout without installing
    sys.path.insert(0, str(SRC))

from mal_planner.ros.transport.loopback import write_loopback_config  # noqa: E402

_counter = itertools.count()


def unique_domain_id() -> int:
    """A domain id (1..200) unlikely to be used by a parallel test run (pid + counter based)."""
    return 1 + (os.getpid() * 13 + next(_counter) * 7) % 200


@pytest.fixture
def dds_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> dict[str, str]:
    """Loopback-only Cyclone config and a fresh ROS_DOMAIN_ID for this test; returns the env for children."""
    monkeypatch.setenv("CYCLONEDDS_URI", write_loopback_config(tmp_path / "cyclonedds.xml"))
    monkeypatch.setenv("ROS_DOMAIN_ID", str(unique_domain_id()))
    monkeypatch.setenv("MAL_ROS_BACKEND", "cyclone")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(SRC), env.get("PYTHONPATH", "")]))
    return env


class Snippet:
    """A Python snippet running in a child process (stdout and stderr collected line by line)."""

    def __init__(self, code: str, env: dict[str, str]) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-u", "-c", textwrap.dedent(code)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self.output: list[str] = []
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.put(line.rstrip("\n"))

    def wait_for_line(self, prefix: str, timeout: float = 15.0) -> str:
        """Block until the child prints a line starting with ``prefix``; fail with its output otherwise."""
        deadline = time.monotonic() + timeout
        while (left := deadline - time.monotonic()) > 0:
            try:
                line = self.lines.get(timeout=min(left, 0.1))
            except queue.Empty:
                if self.proc.poll() is not None and self.lines.empty():
                    break
                continue
            self.output.append(line)
            if line.startswith(prefix):
                return line
        self.stop()
        pytest.fail(f"child did not print {prefix!r}; output:\n" + "\n".join(self.output))

    def stop(self) -> int | None:
        """Terminate the child (if still running) and return its exit code."""
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode


@pytest.fixture
def snippet(dds_env: dict[str, str]):
    """Factory starting snippets with the test's DDS environment; all are stopped at teardown."""
    started: list[Snippet] = []

    def start(code: str) -> Snippet:
        snip = Snippet(code, dds_env)
        started.append(snip)
        return snip

    yield start
    for snip in started:
        snip.stop()


def coarse_params(extra: str = "") -> str:
    """A planner params file with coarse, fast optimizer settings (for integration tests); ``extra`` lines
    (indented by four spaces) are appended to ``ros__parameters``."""
    return (
        "planner:\n"
        "  ros__parameters:\n"
        "    refine: false\n"
        "    mesh_tol: 1.0e-3\n"
        "    nlp_tol: 1.0e-6\n"
        "    segments: 4\n"
        "    degree: 5\n"
        "    output_dt: 1.0\n"
        "    settle_time_s: 1.0\n"
        "    verify: false\n" + extra
    )


def snippet_factory(env: dict[str, str]):
    """Yield a function starting snippets in ``env``; stop them all afterwards (for fixtures)."""
    started: list[Snippet] = []

    def start(code: str) -> Snippet:
        started.append(Snippet(code, env))
        return started[-1]

    yield start
    for snip in started:
        snip.stop()
