"""Locate and parse the ROS 2 interface definitions (.msg/.srv) into rosbags type dictionaries.

``mal_msgs`` (ours) and the vendored ROS 2 Jazzy packages the built-in backend needs without a ROS
installation (``vendor/``: builtin_interfaces, rcl_interfaces, service_msgs, type_description_interfaces;
Apache-2.0, see ``vendor/README.md``).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from rosbags.interfaces import Nodetype
from rosbags.typesys import get_types_from_msg

if TYPE_CHECKING:
    from rosbags.interfaces.typing import Typesdict

PACKAGE = "mal_msgs"

#: Standard services we use that the rosbags Jazzy store lacks (as in ros2/common_interfaces).
STD_SRVS: dict[str, str] = {
    "std_srvs/srv/Trigger": "---\nbool success   # indicate successful run of triggered service\n"
    "string message # informational, e.g. for error messages\n",
}

SERVICE_EVENT_INFO = "service_msgs/msg/ServiceEventInfo"


def interface_dir() -> Path:
    """Directory of the ``mal_msgs`` package (holding ``msg/`` and ``srv/``).

    Search order: ``$MAL_MSGS_DIR``; ``interfaces/`` shipped inside this package (package data, a symlink
    to ``ros2_ws/src/mal_msgs`` in the source tree); ``ros2_ws/src/mal_msgs`` in a parent directory.
    """
    env = os.environ.get("MAL_MSGS_DIR")
    candidates = [Path(env)] if env else []
    here = Path(__file__).resolve().parent
    candidates.append(Path(__file__).parent / "interfaces")
    candidates += [parent / "ros2_ws" / "src" / PACKAGE for parent in here.parents]
    for cand in candidates:
        if (cand / "msg").is_dir():
            return cand
    msg = f"cannot find the {PACKAGE} interface definitions (set MAL_MSGS_DIR)"
    raise FileNotFoundError(msg)


def split_srv(text: str) -> tuple[str, str]:
    """Split .srv text into request and response parts at the ``---`` line."""
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if line.strip() == "---":
            return "\n".join(lines[:i]) + "\n", "\n".join(lines[i + 1 :]) + "\n"
    msg = "service definition without '---' separator"
    raise ValueError(msg)


def _parse(text: str, pkg: str, name: str) -> Typesdict:
    # rosbags resolves relative type names against the package of the message name.
    return get_types_from_msg(text, f"{pkg}/msg/{name}")


def srv_typesdict(srv_name: str, text: str) -> Typesdict:
    """Type dictionary of a service: ``_Request``, ``_Response``, ``_Event`` and the service description.

    The service description struct (fields request_message/response_message/event_message) and the event
    message follow rosidl, so that RIHS01 hashes of services equal the ones ROS 2 computes.
    """
    pkg, _, name = srv_name.split("/")
    req_text, res_text = split_srv(text)
    out: Typesdict = {}
    for suffix, part in (("_Request", req_text), ("_Response", res_text)):
        parsed = _parse(part, pkg, name + suffix)
        out[f"{srv_name}{suffix}"] = parsed.pop(f"{pkg}/msg/{name}{suffix}")
        out.update(parsed)
    req, res, evt = f"{srv_name}_Request", f"{srv_name}_Response", f"{srv_name}_Event"
    out[evt] = (
        [],
        [
            ("info", (Nodetype.NAME, SERVICE_EVENT_INFO)),
            ("request", (Nodetype.SEQUENCE, ((Nodetype.NAME, req), 1))),
            ("response", (Nodetype.SEQUENCE, ((Nodetype.NAME, res), 1))),
        ],
    )
    out[srv_name] = (
        [],
        [
            ("request_message", (Nodetype.NAME, req)),
            ("response_message", (Nodetype.NAME, res)),
            ("event_message", (Nodetype.NAME, evt)),
        ],
    )
    return out


def vendor_dir() -> Path:
    """Directory of the vendored ROS 2 Jazzy interface packages (``vendor/<package>/{msg,srv}``)."""
    return Path(__file__).resolve().parent / "vendor"


def package_roots() -> dict[str, Path]:
    """Interface packages parsed at run time: the vendored ROS 2 ones, then ``mal_msgs``."""
    roots = {p.name: p for p in sorted(vendor_dir().iterdir()) if (p / "msg").is_dir() or (p / "srv").is_dir()}
    roots[PACKAGE] = interface_dir()
    return roots


def package_typesdicts() -> tuple[Typesdict, list[str]]:
    """Parse the messages/services of :func:`package_roots` plus :data:`STD_SRVS`; return (types, service
    names)."""
    types: Typesdict = {}
    srv_texts: dict[str, str] = {}
    services: list[str] = []
    for pkg, root in package_roots().items():
        for path in sorted(root.glob("msg/*.msg")):
            types.update(_parse(path.read_text(encoding="utf-8"), pkg, path.stem))
        srv_texts.update({f"{pkg}/srv/{p.stem}": p.read_text(encoding="utf-8") for p in root.glob("srv/*.srv")})
    srv_texts.update(STD_SRVS)
    for srv_name, text in sorted(srv_texts.items()):
        types.update(srv_typesdict(srv_name, text))
        services.append(srv_name)
    return types, services
