"""Backend-independent pieces of the node API: QoS profiles, parameters, names, params files."""

from __future__ import annotations

import logging
import math
import re
import threading
from collections.abc import Callable, Mapping
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
    lifespan_s: float = 0.0
    """Samples older than this are dropped [s]; 0 = infinite."""


#: rmw_qos_profile_default: RELIABLE, VOLATILE, KEEP_LAST 10 (also used for services).
QOS_DEFAULT = QoSProfile()
#: rmw_qos_profile_sensor_data: BEST_EFFORT, VOLATILE, KEEP_LAST 5.
QOS_SENSOR_DATA = QoSProfile(depth=5, reliable=False)
#: Latched topic: RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1 (subscribers must use it too to get the last sample).
QOS_LATCHED = QoSProfile(depth=1, transient_local=True)
QOS_SERVICES = QOS_DEFAULT
#: rmw_qos_profile_parameters (parameter services) and rmw_qos_profile_parameter_events: RELIABLE, VOLATILE,
#: KEEP_LAST 1000.
QOS_PARAMETERS = QoSProfile(depth=1000)
QOS_PARAMETER_EVENTS = QoSProfile(depth=1000)
#: rcl_qos_profile_rosout_default: RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1000, lifespan 10 s.
QOS_ROSOUT = QoSProfile(depth=1000, transient_local=True, lifespan_s=10.0)


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


#: rcl_interfaces/msg/ParameterType values and the ParameterValue field holding each.
NOT_SET, BOOL, INTEGER, DOUBLE, STRING = 0, 1, 2, 3, 4
RCLPY_PARAM_REL_TOL = 1e-6
"""rclpy's Node.PARAM_REL_TOL: a double at a range's bound within this relative tolerance is in range."""
BYTE_ARRAY, BOOL_ARRAY, INTEGER_ARRAY, DOUBLE_ARRAY, STRING_ARRAY = 5, 6, 7, 8, 9
VALUE_FIELDS = {BOOL: "bool_value", INTEGER: "integer_value", DOUBLE: "double_value", STRING: "string_value",
                BYTE_ARRAY: "byte_array_value", BOOL_ARRAY: "bool_array_value",
                INTEGER_ARRAY: "integer_array_value", DOUBLE_ARRAY: "double_array_value",
                STRING_ARRAY: "string_array_value"}
TYPE_NAMES = {NOT_SET: "not set", BOOL: "bool", INTEGER: "integer", DOUBLE: "double", STRING: "string",
              BYTE_ARRAY: "byte_array", BOOL_ARRAY: "bool_array", INTEGER_ARRAY: "integer_array",
              DOUBLE_ARRAY: "double_array", STRING_ARRAY: "string_array"}


def parameter_type(value: Any) -> int:
    """ParameterType of a Python value (like ``rclpy.Parameter.Type.from_parameter_value``)."""
    if value is None:
        return NOT_SET
    for py, kind in ((bool, BOOL), (int, INTEGER), (float, DOUBLE), (str, STRING)):
        if isinstance(value, py):
            return kind
    if isinstance(value, bytes | bytearray):
        return BYTE_ARRAY
    if isinstance(value, list | tuple):
        for py, kind in ((bool, BOOL_ARRAY), (int, INTEGER_ARRAY), (float, DOUBLE_ARRAY), (str, STRING_ARRAY)):
            if all(isinstance(v, py) and (py is bool or not isinstance(v, bool)) for v in value):
                return kind
    msg = f"unsupported parameter value {value!r}"
    raise TypeError(msg)


def value_to_msg(cls: type, value: Any) -> Any:
    """rcl_interfaces/msg/ParameterValue (class ``cls``) holding ``value``."""
    kind = parameter_type(value)
    msg = cls(type=kind)
    if kind != NOT_SET:
        setattr(msg, VALUE_FIELDS[kind], bytes(value) if kind == BYTE_ARRAY else
                list(value) if kind >= BOOL_ARRAY else value)
    return msg


def value_from_msg(msg: Any) -> Any:
    """The Python value of an rcl_interfaces/msg/ParameterValue; ValueError for an unknown type."""
    kind = int(msg.type)
    if kind == NOT_SET:
        return None
    if kind not in VALUE_FIELDS:
        msg_ = f"unknown parameter type {kind}"
        raise ValueError(msg_)
    value = getattr(msg, VALUE_FIELDS[kind])
    return bytes(value) if kind == BYTE_ARRAY else list(value) if kind >= BOOL_ARRAY else value


#: ``callback(parameters) -> (successful, reason)`` run before parameters are set (both backends).
SetParametersCallback = Callable[[list[Parameter]], tuple[bool, str]]


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
    """Declared parameters with overrides (params file first, explicit overrides win), their types and
    descriptions, and rclpy's rules for setting them at run time (:meth:`set_atomically`)."""

    def __init__(self, overrides: Mapping[str, Any] | None) -> None:
        self._overrides = dict(overrides or {})
        self._params: dict[str, Parameter] = {}
        self.types: dict[str, int] = {}
        self.descriptions: dict[str, str] = {}
        self.ranges: dict[str, tuple[float, float]] = {}
        self.callbacks: list[SetParametersCallback] = []
        self.lock = threading.RLock()

    def declare(self, name: str, default: Any = None, description: str = "",
                value_range: tuple[float, float] | None = None) -> Parameter:
        """Declare ``name``; ``value_range`` (inclusive, of an integer or double parameter) is described and
        enforced on sets, as rclpy does with a descriptor's integer/floating-point range (an override outside it
        is kept here: the node's own check replaces it, as with rclpy's backend)."""
        with self.lock:
            if name in self._params:
                msg = f"parameter {name!r} already declared"
                raise ValueError(msg)
            param = Parameter(name, self._overrides.get(name, default))
            self._params[name] = param
            self.types[name] = parameter_type(default if default is not None else param.value)
            self.descriptions[name] = description
            if value_range is not None:
                self.ranges[name] = value_range
            return param

    def range_problem(self, param: Parameter) -> str | None:
        """rclpy's refusal (same words) of a value outside the parameter's range, or None."""
        bounds = self.ranges.get(param.name)
        if bounds is None or isinstance(param.value, bool) or not isinstance(param.value, int | float):
            return None
        lo, hi = bounds
        if param.value in (lo, hi) or (self.types[param.name] == DOUBLE and any(
                math.isclose(param.value, b, rel_tol=RCLPY_PARAM_REL_TOL) for b in bounds)):
            return None
        if lo < param.value < hi:
            return None
        gap = " " if self.types[param.name] == DOUBLE else ". "  # rclpy's two messages differ so
        return f"Parameter {param.name} out of range{gap}Min: {lo}, Max: {hi}, value: {param.value}"

    def names(self) -> list[str]:
        with self.lock:
            return list(self._params)

    def set_atomically(self, params: list[Parameter]) -> tuple[bool, str]:
        """Set all or none, like ``rclpy.Node.set_parameters_atomically``: declared, same type, accepted by
        every on-set callback; returns (successful, reason)."""
        with self.lock:
            for p in params:
                if p.name not in self._params:
                    return False, f"parameter {p.name!r} is not declared"
                declared, kind = self.types[p.name], parameter_type(p.value)
                if declared != NOT_SET and kind != declared:
                    return False, (f"Wrong parameter type, parameter {{{p.name}}} is of type "
                                   f"{{{TYPE_NAMES[declared]}}}, setting it to {{{TYPE_NAMES[kind]}}} is not allowed.")
                if (problem := self.range_problem(p)) is not None:
                    return False, problem
            for callback in self.callbacks:
                ok, reason = callback(list(params))
                if not ok:
                    return False, reason
            for p in params:
                self._params[p.name].value = p.value
                if self.types[p.name] == NOT_SET:
                    self.types[p.name] = parameter_type(p.value)
            return True, ""

    def get(self, name: str) -> Parameter:
        if name not in self._params:
            msg = f"parameter {name!r} not declared"
            raise KeyError(msg)
        return self._params[name]

    def has(self, name: str) -> bool:
        return name in self._params

    def set(self, name: str, value: Any) -> None:
        """Set without callbacks or type checks (the node's own code, e.g. replacing an invalid override)."""
        with self.lock:
            self.get(name).value = value
            self.types[name] = parameter_type(value)


_LOG_LEVELS = (50, 40, 30, 20)  # rcl_interfaces/msg/Log FATAL, ERROR, WARN, INFO (else DEBUG = 10)


class RosoutHandler(logging.Handler):
    """Forwards Python log records to ``/rosout`` as rcl_interfaces/msg/Log (both backends).

    ``publish`` is the node's /rosout publisher (thread-safe); records logged while publishing are dropped.
    """

    def __init__(self, name: str, log_cls: type, time_msg: Callable[[float], Any], publish: Callable[[Any], None]):
        super().__init__(logging.INFO)
        self.node_logger_name = name
        self._cls, self._time_msg, self._publish = log_cls, time_msg, publish
        self._local = threading.local()
        self.closed = False

    def emit(self, record: logging.LogRecord) -> None:
        if self.closed or getattr(self._local, "busy", False):
            return
        self._local.busy = True
        try:
            level = next((lv for lv in _LOG_LEVELS if record.levelno >= lv), 10)
            self._publish(self._cls(stamp=self._time_msg(record.created), level=level, name=self.node_logger_name,
                                    msg=record.getMessage(), file=record.pathname, function=record.funcName,
                                    line=record.lineno))
        except Exception:  # never let logging break the node (e.g. a publisher already destroyed)
            pass
        finally:
            self._local.busy = False

    def close(self) -> None:
        self.closed = True
        super().close()
