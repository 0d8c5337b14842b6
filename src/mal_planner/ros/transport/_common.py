"""Backend-independent pieces of the node API: QoS profiles, parameters, names, params files."""

from __future__ import annotations

import logging
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml


@dataclass(frozen=True)
class QoSProfile:
    """The subset of ROS 2 QoS our nodes use (history depth, reliability, durability)."""

    depth: int = 10
    reliable: bool = True
    transient_local: bool = False
    keep_all: bool = False


#: rmw_qos_profile_default: RELIABLE, VOLATILE, KEEP_LAST 10 (also used for services).
QOS_DEFAULT = QoSProfile()
#: rmw_qos_profile_sensor_data: BEST_EFFORT, VOLATILE, KEEP_LAST 5.
QOS_SENSOR_DATA = QoSProfile(depth=5, reliable=False)
#: Latched topic: RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1 (subscribers must use it too to get the last sample).
QOS_LATCHED = QoSProfile(depth=1, transient_local=True)
QOS_SERVICES = QOS_DEFAULT


def as_qos(qos: QoSProfile | int | None) -> QoSProfile:
    """Accept a profile, a history depth (like rclpy) or None (default profile)."""
    if qos is None:
        return QOS_DEFAULT
    if isinstance(qos, int):
        return QoSProfile(depth=qos)
    return qos


@dataclass
class Parameter:
    """A node parameter (``.name``, ``.value``) like ``rclpy.parameter.Parameter``."""

    name: str
    value: Any = None


_NAME_RE = re.compile(r"^(/[A-Za-z_][A-Za-z0-9_]*)+$|^/$")


def node_fqn(name: str, namespace: str) -> str:
    """Fully qualified node name, e.g. ``/atc/planner``."""
    ns = normalize_namespace(namespace)
    return f"{ns.rstrip('/')}/{name}"


def normalize_namespace(namespace: str) -> str:
    """``""``/``"atc"``/``"/atc/"`` -> ``"/"``/``"/atc"``/``"/atc"``."""
    ns = "/" + namespace.strip("/")
    if not _NAME_RE.match(ns):
        msg = f"invalid namespace {namespace!r}"
        raise ValueError(msg)
    return ns


def resolve_name(name: str, namespace: str, node_name: str) -> str:
    """Resolve a topic/service name like ROS: absolute, ``~``-private or relative to the namespace."""
    if name.startswith("/"):
        out = name
    elif name == "~" or name.startswith("~/"):
        out = node_fqn(node_name, namespace) + name[1:]
    else:
        out = normalize_namespace(namespace).rstrip("/") + "/" + name
    out = out.rstrip("/") or "/"
    if not _NAME_RE.match(out) or out == "/":
        msg = f"invalid topic or service name {name!r}"
        raise ValueError(msg)
    return out


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, Mapping):
        for key, sub in value.items():
            _flatten(f"{prefix}.{key}" if prefix else str(key), sub, out)
    else:
        out[prefix] = value


def _pattern_matches(pattern: str, fqn: str) -> bool:
    pat = pattern.strip("/")
    if "/" not in pat and "*" not in pat:  # bare node name: any namespace (lenient)
        return fqn.rsplit("/", 1)[-1] == pat
    regex = "".join(".*" if tok == "**" else "[^/]*" if tok == "*" else re.escape(tok)
                    for tok in re.split(r"(\*\*|\*)", pat))  # fmt: skip
    return re.fullmatch(regex, fqn.strip("/")) is not None


def _collect(tree: Any, path: list[str], found: list[tuple[str, dict[str, Any]]]) -> None:
    if not isinstance(tree, Mapping):
        return
    for key, sub in tree.items():
        if key == "ros__parameters":
            params: dict[str, Any] = {}
            _flatten("", sub or {}, params)
            found.append(("/".join(path), params))
        else:
            _collect(sub, [*path, str(key).strip("/")], found)


def load_params_file(path: str | Path, node_name: str, namespace: str = "") -> dict[str, Any]:
    """Parameters for one node from a ROS 2 params YAML (``node: ros__parameters: {...}``).

    Keys may be node names, fully qualified names, nested namespaces, or wildcards (``/**``, ``*``).
    Nested dictionaries become dotted parameter names. Wildcard entries apply first, exact ones override.
    """
    data = yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
    found: list[tuple[str, dict[str, Any]]] = []
    _collect(data, [], found)
    fqn = node_fqn(node_name, namespace)
    result: dict[str, Any] = {}
    for wildcard in (True, False):
        for pattern, params in found:
            if ("*" in pattern) == wildcard and _pattern_matches(pattern, fqn):
                result.update(params)
    return result


class NodeLogger(logging.LoggerAdapter):  # type: ignore[type-arg]
    """Python logger named after the node with rclpy-style ``warn``/``fatal`` aliases."""

    def warn(self, msg: object, *args: Any, **kwargs: Any) -> None:
        self.warning(msg, *args, **kwargs)

    def fatal(self, msg: object, *args: Any, **kwargs: Any) -> None:
        self.critical(msg, *args, **kwargs)


def make_logger(name: str, namespace: str) -> NodeLogger:
    """Logger ``<namespace dots>.<node>`` (``/atc/planner`` -> ``atc.planner``)."""
    return NodeLogger(logging.getLogger(node_fqn(name, namespace).strip("/").replace("/", ".")), {})


class ParameterStore:
    """Declared parameters with overrides (params file first, explicit overrides win)."""

    def __init__(self, overrides: Mapping[str, Any] | None) -> None:
        self._overrides = dict(overrides or {})
        self._params: dict[str, Parameter] = {}

    def declare(self, name: str, default: Any = None) -> Parameter:
        if name in self._params:
            msg = f"parameter {name!r} already declared"
            raise ValueError(msg)
        param = Parameter(name, self._overrides.get(name, default))
        self._params[name] = param
        return param

    def get(self, name: str) -> Parameter:
        if name not in self._params:
            msg = f"parameter {name!r} not declared"
            raise KeyError(msg)
        return self._params[name]

    def has(self, name: str) -> bool:
        return name in self._params

    def set(self, name: str, value: Any) -> None:
        self.get(name).value = value
