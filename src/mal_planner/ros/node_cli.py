"""The planner node's command line: its arguments, its logging, and the check for another planner of its name."""

from __future__ import annotations

import argparse
import logging
import os
import sys

from mal_planner.ros.transport import create_node

DUPLICATE_PROBE_S = 1.0
"""How long a starting planner looks for another under its name: discovery on one host takes tens of ms; across
a network a planner discovered later than this is not seen."""


def parse_args(argv: list[str] | None, description: str) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="mal-planner-node", description=description)
    p.add_argument("--scenario", default=None, help="scenario YAML (default scenarios/thesis.yaml)")
    p.add_argument("--params", default=None, help="ROS 2 params YAML (default config/planner.params.yaml); a bad "
                                                  "value stops the start (exit 2)")
    p.add_argument("--out", default=None, help="output folder (overrides the output_dir parameter)")
    p.add_argument("--namespace", default="", help="node namespace")
    p.add_argument("--backend", default="auto", choices=("auto", "rclpy", "cyclone"), help="ROS backend")
    p.add_argument("--log-level", default="INFO", help="Python log level (default INFO)")
    p.add_argument("--allow-duplicate", action="store_true",
                   help="start even when another planner answers under the same name (both will publish plans)")
    return p.parse_args(argv)


def setup_logging(level: str, fmt: str) -> None:
    logging.basicConfig(level=getattr(logging, level.upper(), logging.INFO), stream=sys.stderr, format=fmt)


def other_planner(node_name: str, namespace: str, backend: str) -> str | None:
    """The full name of another planner that answers under ours (``<namespace>/<node_name>``), or None.

    Its parameter service must answer, not only be discovered: a planner killed moments ago stays in the DDS
    graph until its lease expires (10 s), and a respawned planner must not refuse to start because of it."""
    from mal_planner.ros.transport._common import normalize_namespace

    full = f"{normalize_namespace(namespace).rstrip('/')}/{node_name}"
    probe = create_node(f"{node_name}_probe_{os.getpid()}", namespace, backend=backend,
                        start_parameter_services=False)
    try:
        client = probe.create_client("rcl_interfaces/srv/GetParameters", f"{full}/get_parameters")
        if not client.wait_for_service(DUPLICATE_PROBE_S):
            return None
        request = probe.types.srv("rcl_interfaces/srv/GetParameters").Request(names=["frame_id"])
        try:
            client.call(request, timeout_sec=2.0 * DUPLICATE_PROBE_S)
        except TimeoutError:
            return None
        return full
    finally:
        probe.shutdown()
