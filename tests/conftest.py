"""Shared fixtures: the two ROS backends, the colcon-built mal_msgs; CI turns ROS 2 and extras skips into failures.

With CI=true, a test skipped because ROS 2 Jazzy or an optional extra (``adsb``, ``bluesky``: the test command
installs them) is missing fails: CI must run the interop tests and the tests of the extras.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
from dds_support import dds_env, snippet, snippet_factory  # noqa: F401  (fixtures for every module)
from ros2_env import SKIP_PREFIX, colcon_build_mal_msgs, ros2_env, skip_without_ros2

BACKENDS = ("cyclone", "rclpy")
OPTIONAL_EXTRA = "(optional extra '"
"""In the skip reason of a test that needs an optional extra (bluesky, adsb)."""


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> object:  # type: ignore[type-arg]
    outcome = yield
    report = outcome.get_result()
    if os.environ.get("CI", "").lower() in ("1", "true", "yes") and report.skipped:
        reason = str(report.longrepr[2] if isinstance(report.longrepr, tuple) else report.longrepr)
        if SKIP_PREFIX in reason or OPTIONAL_EXTRA in reason:
            report.outcome = "failed"
            report.longrepr = f"CI=true but the test was skipped: {reason}"


@pytest.fixture(scope="session")
def mal_msgs_install(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """``ros2_ws/src/mal_msgs`` built once per session with colcon against /opt/ros/jazzy (install path and
    build time); the rclpy backend and the ros2 CLI need it for our message types."""
    skip_without_ros2()
    t0 = time.monotonic()
    install = colcon_build_mal_msgs(tmp_path_factory.mktemp("ros2_ws"))
    return {"install": install, "seconds": time.monotonic() - t0}


@pytest.fixture
def ros2_overlay_env(dds_env: dict[str, str], mal_msgs_install: dict[str, object]) -> dict[str, str]:  # noqa: F811
    """Environment of a ROS-side subprocess for this test: ROS 2 Jazzy + built mal_msgs + the test's DDS."""
    install = mal_msgs_install["install"]
    assert isinstance(install, Path)
    return ros2_env(dds_env, install)


@pytest.fixture(params=BACKENDS)
def backend(request: pytest.FixtureRequest) -> str:
    """Each node-level integration test runs once per backend (rclpy: the real ROS 2 Jazzy)."""
    if request.param == "rclpy":
        skip_without_ros2()
    return str(request.param)


@pytest.fixture
def backend_env(backend: str, dds_env: dict[str, str], request: pytest.FixtureRequest) -> dict[str, str]:  # noqa: F811
    """Environment for processes of the backend under test (MAL_ROS_BACKEND set; rclpy: ROS 2 sourced)."""
    env = dict(dds_env) if backend == "cyclone" else dict(request.getfixturevalue("ros2_overlay_env"))
    env["MAL_ROS_BACKEND"] = backend
    return env


@pytest.fixture
def backend_snippet(backend_env: dict[str, str]):
    """Like ``snippet``, but the children run on the backend under test."""
    yield from snippet_factory(backend_env)

