"""One small node API for the MAL planner's ROS 2 nodes, with two backends chosen at start-up.

* ``rclpy`` when it imports (a sourced ROS 2 installation): a thin adapter over rclpy;
* ``cyclone`` otherwise: a built-in backend speaking ROS 2 Jazzy's wire protocol on plain Cyclone DDS
  (rmw_cyclonedds_cpp conventions, ros_discovery_info, RIHS01 type hashes), messages from ``mal_msgs_py``.

The API mirrors rclpy: ``create_publisher``, ``create_subscription``, ``create_service``,
``create_client`` (``wait_for_service``, ``call``, ``call_async`` returning a concurrent.futures.Future),
``create_timer``, parameters (``declare_parameter``, ``add_on_set_parameters_callback``; the standard
parameter services on both backends), ``get_logger``/``forward_logs`` (/rosout),
``spin``/``spin_once``/``shutdown``, and ``node.types`` for message classes.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path
from typing import Any

from ._common import (
    QOS_DEFAULT,
    QOS_LATCHED,
    QOS_SENSOR_DATA,
    QOS_SERVICES,
    Parameter,
    QoSProfile,
    load_params_file,
    resolve_name,
)

__all__ = [
    "QOS_DEFAULT",
    "QOS_LATCHED",
    "QOS_SENSOR_DATA",
    "QOS_SERVICES",
    "Parameter",
    "QoSProfile",
    "available_backends",
    "create_node",
    "load_params_file",
    "resolve_name",
]


def available_backends() -> list[str]:
    """Backends usable in this process, preferred first."""
    out = ["rclpy"] if importlib.util.find_spec("rclpy") is not None else []
    return [*out, "cyclone"]


def create_node(
    name: str,
    namespace: str = "",
    *,
    backend: str = "auto",
    parameter_overrides: dict[str, Any] | None = None,
    params_file: str | Path | None = None,
    start_parameter_services: bool = True,
) -> Any:
    """Create a node.

    ``backend``: ``"auto"`` (``$MAL_ROS_BACKEND`` if set, else rclpy when importable, else cyclone),
    ``"rclpy"`` or ``"cyclone"``. ``params_file``: ROS 2 params YAML; ``parameter_overrides`` win over it.
    ``start_parameter_services``: offer the parameter and type-description services, /parameter_events and
    /rosout like every ROS 2 node (as rclpy's option of that name).
    """
    if backend == "auto":
        backend = os.environ.get("MAL_ROS_BACKEND", "") or available_backends()[0]
    kwargs: dict[str, Any] = {"parameter_overrides": parameter_overrides, "params_file": params_file,
                              "start_parameter_services": start_parameter_services}
    if backend == "rclpy":
        from .rclpy_backend import RclpyNode

        return RclpyNode(name, namespace, **kwargs)
    if backend == "cyclone":
        from .cyclone import CycloneNode

        return CycloneNode(name, namespace, **kwargs)
    msg = f"unknown backend {backend!r} (expected auto, rclpy or cyclone)"
    raise ValueError(msg)
