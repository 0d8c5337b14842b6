"""With CI=true, a test skipped because ROS 2 Jazzy is missing fails: CI must run the interop tests."""

from __future__ import annotations

import os

import pytest
from ros2_env import SKIP_PREFIX


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> object:  # type: ignore[type-arg]
    outcome = yield
    report = outcome.get_result()
    if os.environ.get("CI", "").lower() in ("1", "true", "yes") and report.skipped:
        reason = str(report.longrepr[2] if isinstance(report.longrepr, tuple) else report.longrepr)
        if SKIP_PREFIX in reason:
            report.outcome = "failed"
            report.longrepr = f"CI=true but the ROS 2 interop test was skipped: {reason}"
