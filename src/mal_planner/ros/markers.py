"""RViz markers of a plan: obstacles (CUBE/SPHERE), gates (LINE_STRIP rectangles), paths (LINE_STRIP).

All in the runway frame, metres. A superquadric with p = 2 is an ellipsoid (SPHERE marker); larger p is
drawn as a CUBE. Marker ``scale`` is the full extent, i.e. twice the semi-axes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from mal_planner.obstacles import Gate, Superquadric
from mal_planner.ros.convert import time_to_msg
from mal_planner.trajectory import Trajectory
from mal_planner.units import PLANNER_FRAME, nm_to_m

# visualization_msgs/Marker constants
ARROW, CUBE, SPHERE, LINE_STRIP = 0, 1, 2, 4
ADD, DELETEALL = 0, 3
SPHERE_MAX_P = 2

_PALETTE = [(0.12, 0.47, 0.71), (1.0, 0.5, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16), (0.58, 0.4, 0.74),
            (0.55, 0.34, 0.29), (0.89, 0.47, 0.76), (0.5, 0.5, 0.5)]


def _color(types: Any, rgb: Sequence[float], a: float = 1.0) -> Any:
    return types.msg("std_msgs/msg/ColorRGBA")(r=float(rgb[0]), g=float(rgb[1]), b=float(rgb[2]), a=a)


def _point(types: Any, xyz_nm: Sequence[float]) -> Any:
    x, y, z = (float(nm_to_m(float(v))) for v in xyz_nm)
    return types.msg("geometry_msgs/msg/Point")(x=x, y=y, z=z)


def _marker(types: Any, stamp: float, frame: str, ns: str, mid: int, mtype: int, **fields: Any) -> Any:
    header = types.msg("std_msgs/msg/Header")(stamp=time_to_msg(types, stamp), frame_id=frame)
    return types.msg("visualization_msgs/msg/Marker")(header=header, ns=ns, id=mid, type=mtype, action=ADD,
                                                         **fields)


def obstacle_marker(types: Any, ob: Superquadric, mid: int, stamp: float, frame: str = PLANNER_FRAME) -> Any:
    """CUBE (p > 2) or SPHERE (p = 2) centred on the obstacle, scale = 2 x semi-axes [m]."""
    pose = types.msg("geometry_msgs/msg/Pose")(position=_point(types, ob.center),
                                              orientation=types.msg("geometry_msgs/msg/Quaternion")(w=1.0))
    sx, sy, sz = (2.0 * float(nm_to_m(float(a))) for a in ob.semi_axes)
    return _marker(types, stamp, frame, "obstacles", mid, SPHERE if ob.p <= SPHERE_MAX_P else CUBE, pose=pose,
                   scale=types.msg("geometry_msgs/msg/Vector3")(x=sx, y=sy, z=sz),
                   color=_color(types, (0.8, 0.1, 0.1), 0.5), text=ob.name)


def gate_marker(types: Any, gate: Gate, mid: int, stamp: float, frame: str = PLANNER_FRAME) -> Any:
    """The gate's hole as a closed LINE_STRIP rectangle in its plane."""
    a, b = gate.other_axes
    (a0, a1), (b0, b1) = gate.bounds
    corners = []
    for ua, ub in ((a0, b0), (a1, b0), (a1, b1), (a0, b1), (a0, b0)):
        p = [0.0, 0.0, 0.0]
        p[gate.axis], p[a], p[b] = gate.position, ua, ub
        corners.append(_point(types, p))
    return _marker(types, stamp, frame, "gates", mid, LINE_STRIP, points=corners,
                   scale=types.msg("geometry_msgs/msg/Vector3")(x=20.0),
                   color=_color(types, (0.1, 0.8, 0.1)), text=gate.name,
                   pose=types.msg("geometry_msgs/msg/Pose")(orientation=types.msg("geometry_msgs/msg/Quaternion")(
                       w=1.0)))


def path_marker(types: Any, traj: Trajectory, mid: int, stamp: float, frame: str = PLANNER_FRAME) -> Any:
    """The planned path of one aircraft as a LINE_STRIP (ns "paths", text = callsign)."""
    pts = [_point(types, p) for p in np.asarray(traj.states)[:, :3]]
    return _marker(types, stamp, frame, "paths", mid, LINE_STRIP, points=pts,
                   scale=types.msg("geometry_msgs/msg/Vector3")(x=15.0),
                   color=_color(types, _PALETTE[mid % len(_PALETTE)]), text=traj.callsign,
                   pose=types.msg("geometry_msgs/msg/Pose")(orientation=types.msg("geometry_msgs/msg/Quaternion")(
                       w=1.0)))


def marker_array(types: Any, obstacles: Sequence[Superquadric], gates: Sequence[Gate],
                 trajectories: Sequence[Trajectory], stamp: float, frame: str = PLANNER_FRAME) -> Any:
    """DELETEALL, then obstacles, gates and paths (so removed obstacles and aircraft disappear)."""
    markers = [types.msg("visualization_msgs/msg/Marker")(
        header=types.msg("std_msgs/msg/Header")(stamp=time_to_msg(types, stamp), frame_id=frame), action=DELETEALL)]
    markers += [obstacle_marker(types, ob, i, stamp, frame) for i, ob in enumerate(obstacles)]
    markers += [gate_marker(types, g, i, stamp, frame) for i, g in enumerate(gates)]
    markers += [path_marker(types, tr, i, stamp, frame) for i, tr in enumerate(trajectories)]
    return types.msg("visualization_msgs/msg/MarkerArray")(markers=markers)
