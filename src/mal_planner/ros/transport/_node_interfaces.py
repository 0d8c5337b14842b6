"""The services and topics every ROS 2 node offers, for the built-in backend, following rclpy/rcl:

* parameter services ``~/{list,get,set,describe}_parameters``, ``~/get_parameter_types``,
  ``~/set_parameters_atomically`` (rcl_interfaces, QoS rmw_qos_profile_parameters), with rclpy's answers
  (rclpy/parameter_service.py, ``Node.list_parameters``);
* ``/parameter_events`` (rcl_interfaces/msg/ParameterEvent) on declaring and setting parameters;
* ``/rosout`` (rcl_interfaces/msg/Log) through :class:`..._common.RosoutHandler`;
* ``~/get_type_description`` (type_description_interfaces/srv/GetTypeDescription) for the types we know.
"""

from __future__ import annotations

from typing import Any

import mal_msgs_py

from ._common import (
    DOUBLE,
    INTEGER,
    NOT_SET,
    QOS_PARAMETER_EVENTS,
    QOS_PARAMETERS,
    QOS_ROSOUT,
    Parameter,
    ParameterStore,
    RosoutHandler,
    node_fqn,
    value_from_msg,
    value_to_msg,
)
from ._node_api import InterfaceHost

SEPARATOR = "."
DEPTH_RECURSIVE = 0


def list_parameters(names: list[str], prefixes: list[str], depth: int) -> tuple[list[str], list[str]]:
    """(names, prefixes) answering ListParameters like ``rclpy.Node.list_parameters``."""

    def shallow(name: str) -> bool:
        return name.count(SEPARATOR) < depth

    out_names: list[str] = []
    out_prefixes: list[str] = []
    recursive = not prefixes and depth == DEPTH_RECURSIVE
    for name in names:
        if not recursive and not (not prefixes and shallow(name)) and not any(
                name == pre or (name.startswith(pre + SEPARATOR)
                                and (depth == DEPTH_RECURSIVE or shallow(name[len(pre + SEPARATOR):])))
                for pre in prefixes):
            continue
        out_names.append(name)
        if SEPARATOR in name and (pre := name.rsplit(SEPARATOR, 1)[0]) not in out_prefixes:
            out_prefixes.append(pre)
    return out_names, out_prefixes


class NodeInterfaces:
    """Creates and serves a built-in node's standard services and topics."""

    def __init__(self, node: InterfaceHost, store: ParameterStore) -> None:
        self._node = node
        self._store = store
        self._fqn = node_fqn(node.get_name(), node.get_namespace())
        T = node.types
        self._param_msg = T.msg("rcl_interfaces/msg/Parameter")
        self._value_msg = T.msg("rcl_interfaces/msg/ParameterValue")
        self._result_msg = T.msg("rcl_interfaces/msg/SetParametersResult")
        self._event_msg = T.msg("rcl_interfaces/msg/ParameterEvent")
        self._events = node.create_publisher("rcl_interfaces/msg/ParameterEvent", "/parameter_events",
                                             QOS_PARAMETER_EVENTS)
        rosout = node.create_publisher("rcl_interfaces/msg/Log", "/rosout", QOS_ROSOUT)
        self.rosout = RosoutHandler(self._fqn.strip("/").replace("/", "."), T.msg("rcl_interfaces/msg/Log"),
                                    node.time_msg, rosout.publish)
        services = {
            "describe_parameters": ("DescribeParameters", self._describe),
            "get_parameters": ("GetParameters", self._get),
            "get_parameter_types": ("GetParameterTypes", self._get_types),
            "list_parameters": ("ListParameters", self._list),
            "set_parameters": ("SetParameters", self._set),
            "set_parameters_atomically": ("SetParametersAtomically", self._set_atomically),
        }
        for suffix, (srv, callback) in services.items():
            node.create_service(f"rcl_interfaces/srv/{srv}", f"~/{suffix}", callback, qos=QOS_PARAMETERS)
        node.create_service("type_description_interfaces/srv/GetTypeDescription", "~/get_type_description",
                            self._type_description)

    # -- parameter events ------------------------------------------------------------------------------
    def _param(self, name: str, value: Any) -> Any:
        return self._param_msg(name=name, value=value_to_msg(self._value_msg, value))

    def parameter_event(self, new: list[Parameter] = (), changed: list[Parameter] = ()) -> None:  # type: ignore[assignment]
        """Publish a ParameterEvent for declared (``new``) or set (``changed``) parameters."""
        self._events.publish(self._event_msg(
            stamp=self._node.time_msg(), node=self._fqn, new_parameters=[self._param(p.name, p.value) for p in new],
            changed_parameters=[self._param(p.name, p.value) for p in changed]))

    # -- parameter services (callbacks on the node's executor) ----------------------------------------
    def _describe(self, request: Any, response: Any) -> Any:
        desc = self._node.types.msg("rcl_interfaces/msg/ParameterDescriptor")
        names = self._store.names()
        if not all(n in names for n in request.names):  # rclpy: all default descriptors
            response.descriptors = [desc() for _ in request.names]
            return response
        response.descriptors = [self._descriptor(desc, n) for n in request.names]
        return response

    def _descriptor(self, desc: Any, name: str) -> Any:
        """A parameter's descriptor: type, description and, where declared, its range (as rclpy's)."""
        out = desc(name=name, type=self._store.types[name], description=self._store.descriptions[name])
        bounds = self._store.ranges.get(name)
        if bounds is not None and out.type == INTEGER:
            out.integer_range = [self._node.types.msg("rcl_interfaces/msg/IntegerRange")(
                from_value=int(bounds[0]), to_value=int(bounds[1]), step=0)]
        elif bounds is not None and out.type == DOUBLE:
            out.floating_point_range = [self._node.types.msg("rcl_interfaces/msg/FloatingPointRange")(
                from_value=float(bounds[0]), to_value=float(bounds[1]), step=0.0)]
        return out

    def _get(self, request: Any, response: Any) -> Any:
        names = self._store.names()
        if all(n in names for n in request.names):  # rclpy: nothing when one is not declared
            response.values = [value_to_msg(self._value_msg, self._store.get(n).value) for n in request.names]
        return response

    def _get_types(self, request: Any, response: Any) -> Any:
        response.types = [self._store.types.get(n, NOT_SET) for n in request.names]
        return response

    def _list(self, request: Any, response: Any) -> Any:
        names, prefixes = list_parameters(self._store.names(), list(request.prefixes), int(request.depth))
        response.result.names, response.result.prefixes = names, prefixes
        return response

    def _apply(self, msgs: list[Any]) -> Any:
        try:
            params = [Parameter(str(m.name), value_from_msg(m.value)) for m in msgs]
        except ValueError as exc:
            return self._result_msg(successful=False, reason=str(exc))
        ok, reason = self._store.set_atomically(params)
        if ok:
            self.parameter_event(changed=params)
        return self._result_msg(successful=ok, reason=reason)

    def _set(self, request: Any, response: Any) -> Any:
        response.results = [self._apply([p]) for p in request.parameters]
        return response

    def _set_atomically(self, request: Any, response: Any) -> Any:
        response.result = self._apply(list(request.parameters))
        return response

    # -- type descriptions -----------------------------------------------------------------------------
    def _type_description(self, request: Any, response: Any) -> Any:
        name = str(request.type_name)
        try:
            known = mal_msgs_py.type_hash(name)
        except KeyError:
            response.successful, response.failure_reason = False, f"unknown type {name!r}"
            return response
        if request.type_hash and request.type_hash != known:
            response.successful, response.failure_reason = False, f"type hash of {name!r} differs from ours"
            return response
        T = self._node.types

        def individual(d: dict[str, Any]) -> Any:
            fields = [T.msg("type_description_interfaces/msg/Field")(
                name=f["name"], type=T.msg("type_description_interfaces/msg/FieldType")(**f["type"]))
                for f in d["fields"]]
            return T.msg("type_description_interfaces/msg/IndividualTypeDescription")(type_name=d["type_name"],
                                                                                      fields=fields)

        desc = mal_msgs_py.type_description(name)
        response.type_description = T.msg("type_description_interfaces/msg/TypeDescription")(
            type_description=individual(desc["type_description"]),
            referenced_type_descriptions=[individual(d) for d in desc["referenced_type_descriptions"]])
        response.successful = True
        return response
