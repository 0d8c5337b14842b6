"""Figures like the thesis's (4-1 to 4-4 for the initializer, 6-1 to 6-14 for the optimizer), as PNG."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from mal_planner.dynamics import bank_angle  # noqa: E402
from mal_planner.obstacles import Gate, Superquadric  # noqa: E402
from mal_planner.scenario import Scenario  # noqa: E402
from mal_planner.trajectory import Trajectory  # noqa: E402

PHASE_COLOURS = ["tab:blue", "m", "tab:green", "tab:red", "c", "k", "tab:orange", "tab:brown", "tab:olive",
                 "tab:gray"]
AIRCRAFT_COLOURS = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink",
                    "tab:olive", "tab:cyan", "tab:gray"]
SERIES_LABELS = {
    "x": ("x (nm)", 0, 1.0),
    "y": ("y (nm)", 1, 1.0),
    "z": ("z (nm)", 2, 1.0),
    "gamma": ("flight-path angle (deg)", 3, 180.0 / np.pi),
    "heading": ("heading (deg)", 4, 180.0 / np.pi),
}


def superquadric_surface(ob: Superquadric, n: int = 24) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mesh of the surface |x/a|^p + |y/b|^p + |z/c|^p = 1 (signed-power parametrisation)."""
    u, v = np.meshgrid(np.linspace(-np.pi, np.pi, n), np.linspace(-np.pi / 2, np.pi / 2, n))
    e = 2.0 / ob.p

    def spow(w: np.ndarray) -> np.ndarray:
        return np.sign(w) * np.abs(w) ** e

    (xc, yc, zc), (a, b, c) = ob.center, ob.semi_axes
    return xc + a * spow(np.cos(v) * np.cos(u)), yc + b * spow(np.cos(v) * np.sin(u)), zc + c * spow(np.sin(v))


def _gate_outline(gate: Gate) -> np.ndarray:
    (a0, a1), (b0, b1) = gate.bounds
    ax_u, ax_v = gate.other_axes
    corners = [(a0, b0), (a1, b0), (a1, b1), (a0, b1), (a0, b0)]
    pts = np.zeros((5, 3))
    pts[:, gate.axis] = gate.position
    pts[:, ax_u] = [c[0] for c in corners]
    pts[:, ax_v] = [c[1] for c in corners]
    return pts


def draw_scenario(ax, scenario: Scenario) -> None:
    """Obstacles (translucent), gate outlines and the runway on a 3-D axis."""
    for ob in scenario.obstacles:
        ax.plot_surface(*superquadric_surface(ob), color="tab:blue", alpha=0.25, linewidth=0, shade=False)
    for gate in scenario.gates:
        pts = _gate_outline(gate)
        ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], color="navy", lw=1.5)
    rw = scenario.runway_state
    ax.scatter([rw[0]], [rw[1]], [rw[2]], marker="s", color="k", s=30, label="runway")
    ax.set_xlim(*scenario.airspace[0])
    ax.set_ylim(*scenario.airspace[1])
    ax.set_zlim(*scenario.airspace[2])
    ax.set_xlabel("x (nm)")
    ax.set_ylabel("y (nm)")
    ax.set_zlabel("z (nm)")


def _segments_by_phase(traj: Trajectory):
    """Yield (phase or None, index slice) runs; consecutive runs share their boundary sample."""
    if traj.phase is None:
        yield None, slice(0, len(traj.t))
        return
    change = np.flatnonzero(np.diff(traj.phase)) + 1
    bounds = [0, *change.tolist(), len(traj.t)]
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        yield int(traj.phase[a]), slice(max(a - 1, 0), b)


def _colour(i: int, phase: int | None) -> str:
    return PHASE_COLOURS[phase % len(PHASE_COLOURS)] if phase is not None else AIRCRAFT_COLOURS[
        i % len(AIRCRAFT_COLOURS)]


def figure_paths_3d(scenario: Scenario, trajectories: Sequence[Trajectory],
                    direct_paths: dict[str, np.ndarray] | None = None, title: str = "") -> plt.Figure:
    """3-D paths with the obstacles (thesis Figures 4-1 and 6-1)."""
    fig = plt.figure(figsize=(9, 7))
    ax = fig.add_subplot(projection="3d")
    draw_scenario(ax, scenario)
    for i, traj in enumerate(trajectories):
        for phase, sl in _segments_by_phase(traj):
            p = traj.positions[sl]
            ax.plot(p[:, 0], p[:, 1], p[:, 2], color=_colour(i, phase), lw=1.8)
        p0 = traj.positions[0]
        ax.text(p0[0], p0[1], p0[2], f" {traj.callsign}", fontsize=9)
        if direct_paths and traj.callsign in direct_paths:
            d = direct_paths[traj.callsign]
            ax.plot(d[:, 0], d[:, 1], d[:, 2], color=_colour(i, None), lw=1.0, ls="--")
    ax.set_title(title or f"{scenario.name}: paths (dashed: shortest path before sequencing)")
    ax.set_box_aspect((1, 1, 0.3))
    fig.tight_layout()
    return fig


def figure_yz(scenario: Scenario, trajectories: Sequence[Trajectory]) -> plt.Figure:
    """Y-Z view (thesis Figure 6-2) with the gates drawn."""
    fig, ax = plt.subplots(figsize=(9, 4))
    for gate in scenario.gates:
        if gate.axis == 1:
            (_, _), (z0, z1) = gate.bounds
            ax.plot([gate.position] * 2, [scenario.airspace[2][0], z0], color="navy", lw=3)
            ax.plot([gate.position] * 2, [z1, scenario.airspace[2][1]], color="navy", lw=3)
    for i, traj in enumerate(trajectories):
        for phase, sl in _segments_by_phase(traj):
            ax.plot(traj.states[sl, 1], traj.states[sl, 2], color=_colour(i, phase))
        ax.annotate(traj.callsign, traj.states[0, 1:3])
    ax.set_xlabel("y (nm)")
    ax.set_ylabel("z (nm)")
    ax.set_title("Y-Z view")
    ax.invert_xaxis()
    fig.tight_layout()
    return fig


def figure_series(trajectories: Sequence[Trajectory], key: str) -> plt.Figure:
    """A state against time for every aircraft (thesis Figures 4-2 to 4-4 and 6-3 to 6-7)."""
    label, col, scale = SERIES_LABELS[key]
    fig, ax = plt.subplots(figsize=(8, 4))
    for i, traj in enumerate(trajectories):
        values = traj.states[:, col] * scale
        if key == "heading":
            values = np.degrees(np.unwrap(traj.states[:, col]))
        for phase, sl in _segments_by_phase(traj):
            ax.plot(traj.t[sl], values[sl], color=_colour(i, phase))
        ax.annotate(traj.callsign, (traj.t[0], values[0]))
    ax.set_xlabel("time (s)")
    ax.set_ylabel(label)
    ax.grid(True, alpha=0.3)
    ax.set_title(f"{label.split(' (')[0]} against time")
    fig.tight_layout()
    return fig


def figure_controls(traj: Trajectory, bank_limit: float) -> plt.Figure:
    """Load factors and bank angle of one aircraft (thesis Figures 6-8 to 6-13)."""
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    assert traj.controls is not None
    for phase, sl in _segments_by_phase(traj):
        c = _colour(0, phase)
        ax1.plot(traj.t[sl], traj.controls[sl, 0], color=c, ls="-")
        ax1.plot(traj.t[sl], traj.controls[sl, 1], color=c, ls="--")
        ax2.plot(traj.t[sl], np.degrees(bank_angle(traj.controls[sl, 0], traj.controls[sl, 1])), color=c)
    ax1.set_ylabel("load factor (solid n_h, dashed n_v)")
    ax2.axhline(np.degrees(bank_limit), color="gray", ls=":")
    ax2.axhline(-np.degrees(bank_limit), color="gray", ls=":")
    ax2.set_ylabel("bank angle (deg)")
    ax2.set_xlabel("time (s)")
    ax1.set_title(f"{traj.callsign}: controls")
    for ax in (ax1, ax2):
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


def figure_min_distance(pairs: Sequence[tuple[str, float]], minimum: float) -> plt.Figure:
    """Minimum distance per pair of aircraft against the required separation (thesis Figure 6-14)."""
    fig, ax = plt.subplots(figsize=(7, 4))
    labels = [p[0] for p in pairs]
    ax.bar(labels, [p[1] for p in pairs], color="tab:blue")
    ax.axhline(minimum, color="tab:red", ls="--", label=f"required {minimum} nm")
    ax.set_ylabel("minimum distance (nm)")
    ax.legend()
    ax.set_title("Separation between aircraft")
    fig.tight_layout()
    return fig


def save(fig: plt.Figure, path: Path) -> Path:
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
