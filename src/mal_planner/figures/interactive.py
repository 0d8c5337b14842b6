"""``plan.html``: the plan in an interactive 3-D view (plotly, one self-contained offline file).

Obstacles as meshes, the gate holes, one path per aircraft (hover: callsign, time, altitude, bank) and a
time slider with a play button that moves every aircraft along its plan.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import plotly.io as pio

from mal_planner.dynamics import bank_angle
from mal_planner.figures import style
from mal_planner.figures.data import PlanView
from mal_planner.figures.geometry import gate_outline, obstacle_mesh
from mal_planner.units import METRES_PER_NM

FEET_PER_NM = METRES_PER_NM / 0.3048
MAX_FRAMES = 400
"""Frames of the animation: one per second up to this many, then a coarser step."""
PATH_DT = 1.0
"""Sample step of the drawn paths (s); events and ends are kept."""


def _sample(view: PlanView, dt: float) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per aircraft: times, positions (k, 3) and bank angle (deg) on a ``dt`` grid plus the ends and events."""
    out = {}
    for a in view.aircraft:
        tr = a.trajectory
        events = [t for t in (a.gate_time, a.landing_time) if t is not None and tr.t[0] <= t <= tr.t[-1]]
        t = np.union1d(np.arange(tr.t[0], tr.t[-1], dt), [tr.t[0], tr.t[-1], *events])
        pos = np.stack([np.interp(t, tr.t, tr.positions[:, k]) for k in range(3)], axis=1)
        bank = np.zeros(len(t))
        if tr.controls is not None:
            bank = np.interp(t, tr.t, np.degrees(bank_angle(tr.controls[:, 0], tr.controls[:, 1])))
        out[a.callsign] = (t, pos, bank)
    return out


def _hover(t: np.ndarray, pos: np.ndarray, bank: np.ndarray) -> np.ndarray:
    return np.column_stack([np.round(t, 2), np.round(pos[:, 2] * FEET_PER_NM), np.round(bank, 1)])


HOVER = ("<b>%{fullData.name}</b><br>t = %{customdata[0]:.1f} s<br>altitude %{customdata[1]:.0f} ft "
         "(z %{z:.3f} nm)<br>x %{x:.3f} nm, y %{y:.3f} nm<br>bank %{customdata[2]:.1f}°<extra></extra>")


def _markers(view: PlanView, samples: dict, colors: dict[str, str], t: float) -> list[dict]:
    """One marker per aircraft at time ``t`` (empty once landed or before its plan starts)."""
    traces = []
    for a in view.aircraft:
        ts, pos, bank = samples[a.callsign]
        if ts[0] - 1e-9 <= t <= ts[-1] + 1e-9:
            p = np.array([[np.interp(t, ts, pos[:, k]) for k in range(3)]])
            cd = _hover(np.array([t]), p, np.array([np.interp(t, ts, bank)]))
        else:
            p, cd = np.zeros((0, 3)), np.zeros((0, 3))
        traces.append(dict(type="scatter3d", x=p[:, 0], y=p[:, 1], z=p[:, 2], customdata=cd, text=[a.callsign] * len(p),
                                   mode="markers+text", textposition="top center", name=a.callsign,
                                   marker={"size": 6, "color": colors[a.callsign], "line": {"width": 1,
                                                                                           "color": "black"}},
                                   textfont={"color": colors[a.callsign], "size": 12}, hovertemplate=HOVER,
                                   legendgroup=a.callsign, showlegend=False))
    return traces


def _scene_traces(view: PlanView, samples: dict, colors: dict[str, str]) -> list[dict]:
    """The traces that do not move: obstacles, gate holes, the runway threshold and each aircraft's path."""
    data: list[dict] = []
    for k, ob in enumerate(view.obstacles):
        verts, tris = obstacle_mesh(ob, n=28)
        data.append(dict(type="mesh3d", x=verts[:, 0], y=verts[:, 1], z=verts[:, 2], i=tris[:, 0], j=tris[:, 1],
                                k=tris[:, 2], color=style.OBSTACLE_COLOR, opacity=0.3, flatshading=True,
                                name="obstacles", legendgroup="obstacles", showlegend=k == 0,
                                hovertemplate=f"{ob.name}<extra></extra>"))
    for k, gate in enumerate(view.gates):
        p = gate_outline(gate)
        data.append(dict(type="scatter3d", x=p[:, 0], y=p[:, 1], z=p[:, 2], mode="lines", name="gate hole",
                                   line={"color": style.GATE_COLOR, "width": 7}, legendgroup="gate",
                                   showlegend=k == 0, hovertemplate=f"{gate.name}<extra></extra>"))
    rw = view.runway
    data.append(dict(type="scatter3d", x=[rw[0]], y=[rw[1]], z=[rw[2]], mode="markers", name="runway",
                               marker={"symbol": "square", "size": 6, "color": style.RUNWAY_COLOR},
                               hovertemplate="runway threshold<extra></extra>"))
    for a in view.aircraft:
        t, pos, bank = samples[a.callsign]
        data.append(dict(type="scatter3d", x=pos[:, 0], y=pos[:, 1], z=pos[:, 2], mode="lines", name=a.callsign,
                                   line={"color": colors[a.callsign], "width": 5}, customdata=_hover(t, pos, bank),
                                   hovertemplate=HOVER, legendgroup=a.callsign))
    return data


def figure(view: PlanView) -> dict:
    """The interactive figure as a plotly figure dict (see the module docstring).

    Plain dicts, not plotly's validated objects: building hundreds of frames that way takes seconds.
    """
    colors = style.color_map(view.callsigns)
    samples = _sample(view, PATH_DT)
    data = _scene_traces(view, samples, colors)
    t_end = max(float(s[0][-1]) for s in samples.values())
    t_start = min(float(s[0][0]) for s in samples.values())
    step = max(1.0, math.ceil((t_end - t_start) / MAX_FRAMES))
    times = np.append(np.arange(t_start, t_end, step), t_end)
    first_marker = len(data)
    data += _markers(view, samples, colors, float(times[0]))
    marker_idx = list(range(first_marker, len(data)))
    frames = [{"name": f"{t:.1f}", "data": _markers(view, samples, colors, float(t)), "traces": marker_idx}
              for t in times]
    play = {"frame": {"duration": 60, "redraw": True}, "fromcurrent": True, "transition": {"duration": 0}}
    slider_steps = [{"label": f"{t:.0f} s", "method": "animate",
                     "args": [[f"{t:.1f}"], {"mode": "immediate", "frame": {"duration": 0, "redraw": True},
                                             "transition": {"duration": 0}}]} for t in times]
    (x0, x1), (y0, y1), (z0, z1) = view.airspace
    span = max(x1 - x0, y1 - y0)
    verdict = "verified" if view.verified else view.status.replace("_", " ")
    layout = dict(
        title={"text": f"{view.name}: {len(view.aircraft)} aircraft, landing order "
                       f"{' → '.join(view.callsigns)} ({verdict})", "x": 0.01},
        margin={"l": 0, "r": 0, "t": 40, "b": 0},
        legend={"title": {"text": "aircraft"}, "itemclick": "toggle", "x": 0.0, "y": 0.95},
        scene={"xaxis": {"title": {"text": "x (nm)"}, "range": [x0, x1]},
               "yaxis": {"title": {"text": "y (nm)"}, "range": [y0, y1]},
               "zaxis": {"title": {"text": "z (nm)"}, "range": [z0, z1]},
               "aspectmode": "manual",
               "aspectratio": {"x": (x1 - x0) / span, "y": (y1 - y0) / span, "z": 0.35},
               "camera": {"eye": {"x": 0.95, "y": -1.4, "z": 0.7}}, "domain": {"x": [0.08, 1.0], "y": [0.0, 1.0]}},
        updatemenus=[{"type": "buttons", "showactive": False, "x": 0.0, "y": 0.0, "xanchor": "left",
                      "yanchor": "top", "direction": "left", "pad": {"t": 40, "r": 10},
                      "buttons": [{"label": "▶ play", "method": "animate", "args": [None, play]},
                                  {"label": "❚❚ pause", "method": "animate",
                                   "args": [[None], {"mode": "immediate", "frame": {"duration": 0}}]}]}],
        sliders=[{"active": 0, "x": 0.16, "len": 0.82, "y": 0.0, "yanchor": "top", "pad": {"t": 30},
                  "currentvalue": {"prefix": "t = ", "font": {"size": 14, "color": "#333333"}}, "steps": slider_steps,
                  "font": {"color": "rgba(0,0,0,0)"}, "ticklen": 2, "minorticklen": 0}],
    )
    return {"data": data, "layout": layout, "frames": frames}


def write_html(view: PlanView, path: str | Path, post_script: str | None = None) -> Path:
    """Write ``plan.html`` with plotly.js embedded (opens with no network access).

    ``post_script``: JavaScript run after the plot is made (``{plot_id}`` names its div).
    """
    path = Path(path)
    pio.write_html(figure(view), path, include_plotlyjs=True, full_html=True, auto_play=False, validate=False,
                   default_height="96vh", config={"displaylogo": False, "responsive": True}, post_script=post_script)
    return path
