"""Time series of one aircraft's states (and controls), the common currency of every stage.

The initializer, the optimizer, the verification, the JSON result, the plots and the ROS node all
exchange :class:`Trajectory` objects in planner units (nm, s, rad).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mal_planner.dynamics import CONTROL_NAMES, STATE_NAMES


def closest_approach(a_t: np.ndarray, a_pos: np.ndarray, b_t: np.ndarray, b_pos: np.ndarray) -> float:
    """Smallest distance (nm) between two sampled paths while both fly, on a's sample times."""
    keep = a_t <= min(a_t[-1], b_t[-1])
    if not keep.any():
        return float("inf")
    other = np.column_stack([np.interp(a_t[keep], b_t, b_pos[:, k]) for k in range(3)])
    return float(np.linalg.norm(a_pos[keep] - other, axis=1).min())


@dataclass(frozen=True)
class Trajectory:
    callsign: str
    t: np.ndarray
    """(n,) times in s."""
    states: np.ndarray
    """(n, 5): x, y, z (nm), flight-path angle, heading (rad)."""
    controls: np.ndarray | None = None
    """(n, 2): n_h, n_v, or None where only the path is known (the initializer)."""
    phase: np.ndarray | None = None
    """(n,) index of the optimizer phase each sample belongs to, or None."""
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.states.shape != (len(self.t), len(STATE_NAMES)):
            raise ValueError(f"{self.callsign}: states shape {self.states.shape} != ({len(self.t)}, 5)")
        if self.controls is not None and self.controls.shape != (len(self.t), len(CONTROL_NAMES)):
            raise ValueError(f"{self.callsign}: controls shape {self.controls.shape} != ({len(self.t)}, 2)")

    @property
    def positions(self) -> np.ndarray:
        return self.states[:, :3]

    def state_at(self, t: float | np.ndarray) -> np.ndarray:
        """Linear interpolation of the states (headings unwrapped first)."""
        states = self.states.copy()
        states[:, 4] = np.unwrap(states[:, 4])
        return np.stack([np.interp(t, self.t, states[:, k]) for k in range(states.shape[1])], axis=-1)

    def to_dict(self) -> dict:
        """JSON-ready columns: t, x, y, z, gamma, heading [, n_h, n_v, phase]."""
        out: dict = {"t": self.t.tolist()}
        for k, name in enumerate(STATE_NAMES):
            out[name] = self.states[:, k].tolist()
        if self.controls is not None:
            for k, name in enumerate(CONTROL_NAMES):
                out[name] = self.controls[:, k].tolist()
        if self.phase is not None:
            out["phase"] = [int(p) for p in self.phase]
        return out

    @classmethod
    def from_dict(cls, callsign: str, data: dict) -> Trajectory:
        states = np.column_stack([np.asarray(data[name], float) for name in STATE_NAMES])
        controls = None
        if all(name in data for name in CONTROL_NAMES):
            controls = np.column_stack([np.asarray(data[name], float) for name in CONTROL_NAMES])
        phase = np.asarray(data["phase"], int) if "phase" in data else None
        return cls(callsign, np.asarray(data["t"], float), states, controls, phase)
