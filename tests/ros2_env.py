"""A real ROS 2 Jazzy (/opt/ros/jazzy) for interop tests: its environment for subprocesses, skip markers.

The pytest process itself never imports rclpy: ROS-side processes (ros2 CLI, rclpy nodes, our nodes on the
rclpy backend, colcon) run as subprocesses with :func:`ros2_env`, i.e. the environment of
``source /opt/ros/jazzy/setup.bash`` on top of the test's DDS settings, with this venv's Python first on
PATH (it must hold ../shared/ros2-jazzy/requirements.txt). Where ROS 2 is missing the tests skip with
:data:`SKIP_PREFIX` in the reason; with ``CI=true`` conftest.py turns those skips into failures.
"""

from __future__ import annotations

import functools
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROS_SETUP = Path(os.environ.get("MAL_ROS2_SETUP", "/opt/ros/jazzy/setup.bash"))
SKIP_PREFIX = "needs ROS 2 Jazzy"
INSTALL_HINT = ("install it with `bash ../shared/ros2-jazzy/install.sh` and "
                "`.venv/bin/pip install -r ../shared/ros2-jazzy/requirements.txt`")
SRC = Path(__file__).resolve().parents[1] / "src"


@functools.cache
def _sourced(overlay: str = "") -> dict[str, str] | str:
    """The environment after sourcing ROS_SETUP (and an overlay's local_setup.bash), or the reason it is
    unusable."""
    if not ROS_SETUP.is_file():
        return f"{SKIP_PREFIX}: {ROS_SETUP} not found; {INSTALL_HINT}"
    venv_bin = str(Path(sys.executable).parent)
    extra = f" && source {overlay}/local_setup.bash >/dev/null" if overlay else ""
    cmd = f"set +u; source {ROS_SETUP} >/dev/null{extra} && env -0"
    base = {k: v for k, v in os.environ.items() if not k.startswith(("AMENT_", "COLCON_", "ROS_"))}
    base["PATH"] = venv_bin + os.pathsep + base.get("PATH", "")
    try:
        out = subprocess.run(["bash", "-c", cmd], env=base, capture_output=True, timeout=30, check=True).stdout
    except (OSError, subprocess.SubprocessError) as exc:
        return f"{SKIP_PREFIX}: sourcing {ROS_SETUP} failed ({exc})"
    env = dict(item.split("=", 1) for item in out.decode().split("\0") if "=" in item)
    env["PATH"] = venv_bin + os.pathsep + env.get("PATH", "")  # `ros2` runs with this venv's python3
    env["RMW_IMPLEMENTATION"] = "rmw_cyclonedds_cpp"
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    probe = subprocess.run([sys.executable, "-c", "import rclpy, yaml, psutil, catkin_pkg, lark, em"],
                           env=env, capture_output=True, text=True, timeout=60, check=False)
    if probe.returncode:
        last = (probe.stderr.strip().splitlines() or ["?"])[-1]
        return f"{SKIP_PREFIX}: rclpy does not import in this venv ({last}); {INSTALL_HINT}"
    return env


def ros2_missing() -> str | None:
    """None when ROS 2 Jazzy is usable, else the skip reason."""
    got = _sourced()
    return got if isinstance(got, str) else None


requires_ros2 = pytest.mark.skipif("ros2_missing() is not None", reason=f"{SKIP_PREFIX} at /opt/ros/jazzy")


def skip_without_ros2() -> None:
    """Skip the calling test (with the precise reason) where ROS 2 Jazzy is not usable."""
    reason = ros2_missing()
    if reason is not None:
        pytest.skip(reason)


def ros2_env(dds: dict[str, str] | None = None, overlay: Path | None = None) -> dict[str, str]:
    """Environment for a ROS-side subprocess: sourced ROS 2 (plus the colcon ``overlay`` install, e.g. the
    built mal_msgs), the DDS settings (domain id, loopback config) of ``dds`` (default: this process's) and
    our sources on PYTHONPATH."""
    skip_without_ros2()
    got = _sourced(str(overlay) if overlay else "")
    if isinstance(got, str):
        pytest.fail(got)
    env = dict(got)
    src = dds if dds is not None else os.environ
    for key in ("ROS_DOMAIN_ID", "CYCLONEDDS_URI", "MAL_ROS_BACKEND"):
        if key in src:
            env[key] = src[key]
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(SRC), env.get("PYTHONPATH", "")]))
    return env


def ros2(args: list[str], env: dict[str, str], timeout: float = 20.0) -> subprocess.CompletedProcess[str]:
    """Run ``ros2 <args>`` (``--no-daemon`` where the verb takes it is up to the caller) with a hard timeout."""
    return subprocess.run(["timeout", "-k", "2", str(timeout), "ros2", *args], env=env, capture_output=True,
                          text=True, timeout=timeout + 5, check=False)


def colcon_build_mal_msgs(workspace: Path) -> Path:
    """Build ros2_ws/src/mal_msgs with colcon against /opt/ros/jazzy in ``workspace``; its install folder."""
    shutil.copytree(SRC.parent / "ros2_ws" / "src" / "mal_msgs", workspace / "src" / "mal_msgs", symlinks=False)
    env = ros2_env()
    env["MAKEFLAGS"] = "-j2"
    proc = subprocess.run(["timeout", "-k", "5", "600", "colcon", "build", "--cmake-args", "-DBUILD_TESTING=OFF"],
                          cwd=workspace, env=env, capture_output=True, text=True, check=False)
    if proc.returncode:
        pytest.fail(f"colcon build of mal_msgs failed ({proc.returncode}):\n{proc.stdout[-3000:]}{proc.stderr[-3000:]}")
    return workspace / "install"
