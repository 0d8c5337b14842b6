"""The planner node's parameters, from the one option table: the plan options (``PLAN_OPTIONS`` rows with a ROS
name) and the node's own (``NODE_OPTIONS``). Checks, ranges and descriptions derive from the rows.

A bad value in the params file stops the start (:class:`ParamsError`, one line naming it); a bad ``ros2 param
set`` is refused with the reason and changes nothing.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from mal_planner.options import NODE_OPTIONS, PLAN_OPTIONS, Option, PlanOptions, build_plan_options
from mal_planner.ros.transport import load_params_file
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.service.rules import ServiceRules
from mal_planner.units import m_to_nm, nm_to_m

PARAMETERS: dict[str, Option] = {**{o.ros: o for o in PLAN_OPTIONS if o.ros is not None},
                                 **{o.ros: o for o in NODE_OPTIONS if o.ros is not None}}
"""Every parameter of the node by its ROS name: the plan options, then the node's own."""
ROS_STANDARD = frozenset({"use_sim_time"})
"""Parameters every ROS 2 node has (the node's clock follows /clock when use_sim_time is true)."""
READ_ONLY = frozenset(name for name, o in PARAMETERS.items() if o.read_only)


class ParamsError(ValueError):
    """A params file that cannot be used (one line: the file, the parameter, the problem)."""


def describe_parameter(name: str) -> str:
    """The descriptor's description (``ros2 param describe``)."""
    o = PARAMETERS[name]
    text = o.help + (f" [{o.unit}]" if o.unit else "") + ("; 0 = no limit" if o.none_as == 0.0 else "")
    return text + (" (read-only at run time)" if o.read_only else "")


def check_parameter(name: str, value: Any) -> Any:
    """The parameter's value checked (ValueError: ``parameter 'name': problem, got value``)."""
    option = PARAMETERS.get(name)
    if option is None:
        raise ValueError(f"parameter {name!r}: unknown")
    try:
        return option.check_ros(value)
    except ValueError as exc:
        raise ValueError(f"parameter {name!r}: {exc}, got {value!r}") from None


class NodeParams(Mapping[str, Any]):
    """The node's parameter values by ROS name (every one checked), with attribute access."""

    def __init__(self, values: Mapping[str, Any] | None = None) -> None:
        given = dict(values or {})
        self._values = {name: check_parameter(name, given[name]) if name in given else o.ros_default()
                        for name, o in PARAMETERS.items()}

    def __getattr__(self, name: str) -> Any:
        try:
            return self._values[name]
        except KeyError:
            raise AttributeError(name) from None

    def __getitem__(self, name: str) -> Any:
        return self._values[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, NodeParams) and other._values == self._values

    __hash__ = None  # type: ignore[assignment]

    def updated(self, changes: Mapping[str, Any]) -> NodeParams:
        """These values with ``changes`` (a ``ros2 param set``) applied, each checked; ValueError with a one-line
        reason naming the parameter when one is unknown, read-only or invalid."""
        for name, value in changes.items():
            if name in READ_ONLY and name in self._values and value != self._values[name]:
                raise ValueError(f"parameter {name!r}: read-only at run time (restart the node to change it)")
            check_parameter(name, value)
        return NodeParams({**self._values, **changes})

    def plan_options(self) -> PlanOptions:
        """The plan options these parameters set (0 = no time limit)."""
        values = {o.name: self._values[o.ros] for o in PLAN_OPTIONS if o.ros is not None}
        values["time_limit_s"] = values["time_limit_s"] or None  # 0: no limit
        return build_plan_options(values)

    def rules(self, scenario: Scenario) -> ServiceRules:
        """The service's rules these parameters set (metres to nm, turn times to seconds of the scenario)."""
        v = self._values
        limit = v["planning_time_limit_s"] or None
        return ServiceRules(deviation_nm=m_to_nm(v["deviation_threshold_m"]), min_interval_s=v["min_replan_interval_s"],
                            period_s=v["replan_period_s"],
                            filter_time_constant_s=Scales.of(scenario).seconds(v["track_filter_turn_times"]),
                            track_timeout_s=v["track_timeout_s"], kept_plan_expiry_s=v["kept_plan_expiry_s"],
                            settle_time_s=v["settle_time_s"], min_aircraft=v["min_aircraft"],
                            replan_time_limit_s=limit, frame_id=v["frame_id"],
                            replan_what_changed=v["replan_what_changed"])


def read_params_file(path: str | Path | None, node_name: str, namespace: str, log: logging.Logger
                     ) -> dict[str, Any]:
    """The checked values of a ROS 2 params YAML (unknown names are logged and ignored); ParamsError (one line)
    when the file cannot be read or a value is bad: the node must not start with a setting nobody asked for."""
    if not path:
        return {}
    try:
        values = load_params_file(path, node_name, namespace)
    except OSError as exc:
        raise ParamsError(f"params file {path}: cannot read ({exc.strerror or exc})") from None
    except Exception as exc:  # yaml errors and malformed structures
        raise ParamsError(f"params file {path}: invalid ({' '.join(str(exc).split())})") from None
    known = set(PARAMETERS) | ROS_STANDARD
    for name in sorted(set(values) - known):
        log.warning("params file %s: unknown parameter %r (ignored)", path, name)
    for name in sorted(set(values) & set(PARAMETERS)):
        try:
            check_parameter(name, values[name])
        except ValueError as exc:
            raise ParamsError(f"params file {path}: {exc}") from None
    return {k: v for k, v in values.items() if k in known}


def declare_parameters(node: Any) -> NodeParams:
    """Declare every parameter on ``node`` (its overrides: the checked params file) and return their values."""
    values = {name: node.declare_parameter(name, o.ros_default(), describe_parameter(name),
                                           value_range=o.value_range).value for name, o in PARAMETERS.items()}
    return NodeParams(values)


def describe(params: Mapping[str, Any]) -> str:
    """``name=value`` list for the start-up log line."""
    return ", ".join(f"{k}={v!r}" for k, v in params.items())


def closed_loop_values(scenario: Scenario, noise_m: float, radar_period_s: float) -> dict[str, Any]:
    """The parameters that give the node the closed loop's rules (:meth:`ServiceRules.closed_loop`) for a radar of
    ``noise_m`` every ``radar_period_s``: simulated time, no settling, the margins of flown plans."""
    rules = ServiceRules.closed_loop(scenario, noise_sigma_nm=m_to_nm(noise_m), radar_period_s=radar_period_s)
    return {"use_sim_time": True, "settle_time_s": 0.0, "tracking_margins": True,
            "deviation_threshold_m": float(nm_to_m(rules.deviation_nm)), "min_replan_interval_s": rules.min_interval_s}
