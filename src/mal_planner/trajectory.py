"""Time series of one aircraft's states (and controls), the common currency of every stage.

The initializer, the optimizer, the verification, the JSON result, the plots and the ROS node all
exchange :class:`Trajectory` objects in planner units (nm, s, rad).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mal_planner.dynamics import AIRSPEED_CONTROL_NAMES, AIRSPEED_STATE_NAMES, CONTROL_NAMES, STATE_NAMES


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
    """(n, 5): x, y, z (nm), flight-path angle, heading (rad); (n, 6) with the airspeed (nm/s) of the airspeed
    model."""
    controls: np.ndarray | None = None
    """(n, 2): n_h, n_v ((n, 3) with n_x: the airspeed model), or None where only the path is known (the
    initializer)."""
    phase: np.ndarray | None = None
    """(n,) index of the optimizer phase each sample belongs to, or None."""
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.states.ndim != 2 or self.states.shape[0] != len(self.t) or self.states.shape[1] not in (5, 6):
            raise ValueError(f"{self.callsign}: states shape {self.states.shape} != ({len(self.t)}, 5 or 6)")
        if self.controls is not None and self.controls.shape != (len(self.t), self.states.shape[1] - 3):
            raise ValueError(f"{self.callsign}: controls shape {self.controls.shape} != ({len(self.t)}, "
                             f"{self.states.shape[1] - 3})")

    @property
    def state_names(self) -> tuple[str, ...]:
        return STATE_NAMES if self.states.shape[1] == len(STATE_NAMES) else AIRSPEED_STATE_NAMES

    @property
    def control_names(self) -> tuple[str, ...]:
        return CONTROL_NAMES if self.states.shape[1] == len(STATE_NAMES) else AIRSPEED_CONTROL_NAMES

    @property
    def airspeed(self) -> np.ndarray | None:
        """(n,) airspeed (nm/s) of an airspeed-model plan; None: the model's constant one."""
        return self.states[:, 5] if self.states.shape[1] > 5 else None

    @property
    def positions(self) -> np.ndarray:
        return self.states[:, :3]

    def state_at(self, t: float | np.ndarray) -> np.ndarray:
        """Linear interpolation of the states (headings unwrapped first)."""
        states = self.states.copy()
        states[:, 4] = np.unwrap(states[:, 4])
        return np.stack([np.interp(t, self.t, states[:, k]) for k in range(states.shape[1])], axis=-1)

    def to_dict(self) -> dict:
        """JSON-ready columns: t, x, y, z, gamma, heading [, airspeed] [, n_h, n_v [, n_x], phase]."""
        out: dict = {"t": self.t.tolist()}
        for k, name in enumerate(self.state_names):
            out[name] = self.states[:, k].tolist()
        if self.controls is not None:
            for k, name in enumerate(self.control_names):
                out[name] = self.controls[:, k].tolist()
        if self.phase is not None:
            out["phase"] = [int(p) for p in self.phase]
        return out

    @classmethod
    def from_dict(cls, callsign: str, data: dict) -> Trajectory:
        airspeed = "airspeed" in data
        states = np.column_stack([np.asarray(data[name], float)
                                  for name in (AIRSPEED_STATE_NAMES if airspeed else STATE_NAMES)])
        controls = None
        names = AIRSPEED_CONTROL_NAMES if airspeed else CONTROL_NAMES
        if all(name in data for name in names):
            controls = np.column_stack([np.asarray(data[name], float) for name in names])
        phase = np.asarray(data["phase"], int) if "phase" in data else None
        return cls(callsign, np.asarray(data["t"], float), states, controls, phase)


AIRSPEED_COLUMN = 10
"""Where a :class:`Reference`'s table holds the airspeed (after the states, velocities and rates)."""


class Reference:
    """A plan to fly: positions and angles by time, sampled with one search per query; the airspeed too where the
    states carry it (a sixth column: the airspeed model's plans, and the holds and vectors drawn at an airspeed)."""

    def __init__(self, t: np.ndarray, states: np.ndarray) -> None:
        t = np.asarray(t, float)
        states = np.asarray(states, float)
        keep = np.concatenate([[True], np.diff(t) > 0])  # duplicate stamps (phase boundaries) carry no rate
        t, states = t[keep], states[keep].copy()
        if len(t) < 2:
            raise ValueError("a plan needs at least two poses at distinct times")
        states[:, 4] = np.unwrap(states[:, 4])
        velocity = np.gradient(states[:, :3], t, axis=0)
        rates = np.gradient(states[:, 3:5], t, axis=0)
        self.t = t
        # p(3), gamma, heading, v(3), gamma', heading' [, airspeed]
        self.table = np.column_stack([states[:, :5], velocity, rates, states[:, 5:6]])

    @property
    def has_airspeed(self) -> bool:
        return self.table.shape[1] > AIRSPEED_COLUMN

    def states(self, width: int) -> np.ndarray:
        """The plan's states with ``width`` columns (5; 6 with the airspeed, which the plan must carry)."""
        if width > 5 and not self.has_airspeed:
            raise ValueError("this plan carries no airspeed")
        return self.table[:, [0, 1, 2, 3, 4, AIRSPEED_COLUMN][:width]]

    def airspeed(self, t: float) -> float | None:
        """The planned airspeed at ``t`` (nm/s; its first or last outside the plan), None where it carries none."""
        return float(np.interp(t, self.t, self.table[:, AIRSPEED_COLUMN])) if self.has_airspeed else None

    @property
    def start(self) -> float:
        return float(self.t[0])

    @property
    def end(self) -> float:
        return float(self.t[-1])

    def sample(self, t: float) -> np.ndarray:
        """Row [x, y, z, gamma, heading, vx, vy, vz, gamma', heading'] at ``t``; before the plan its start, after
        it the final state carried on along its final velocity (a late aircraft flies on down the runway's
        centreline, the extended final approach, instead of drifting with the wind)."""
        if t > self.t[-1]:
            row = self.table[-1].copy()
            row[:3] += (t - self.t[-1]) * row[5:8]
            row[8:10] = 0.0
            return row
        k = int(np.clip(np.searchsorted(self.t, t) - 1, 0, len(self.t) - 2))
        t0, t1 = self.t[k], self.t[k + 1]
        w = min(max((t - t0) / (t1 - t0), 0.0), 1.0)
        return (1.0 - w) * self.table[k] + w * self.table[k + 1]

    def position(self, t: float) -> np.ndarray:
        return self.sample(t)[:3]

    def positions(self, times: np.ndarray) -> np.ndarray:
        """(n, 3) positions at ``times``, as :meth:`sample` gives them (its start before it, its final line after)."""
        times = np.asarray(times, float)
        out = np.column_stack([np.interp(times, self.t, self.table[:, k]) for k in range(3)])
        past = times > self.t[-1]
        if past.any():
            out[past] = self.table[-1, :3] + (times[past] - self.t[-1])[:, None] * self.table[-1, 5:8]
        return out

    def follow(self, p: np.ndarray, t: float, window_s: float, last: tuple[float, float] | None = None) -> float:
        """Where an aircraft at ``p`` is on the plan at time ``t``: :meth:`closest_time` searched within ``window_s``
        of where it was at the last look moved on by the time since (``last``: that look's time and plan time; None:
        of ``t``, for a plan just received). Path following keeps its place so: an aircraft more than a window late
        is still found where it is, not at the window's edge ahead of it."""
        centre = t if last is None else last[1] + (t - last[0])
        return self.closest_time(p, centre, window_s)

    def closest_time(self, p: np.ndarray, t: float, window_s: float) -> float:
        """The plan's time whose position is closest to ``p``, searched within ``window_s`` of ``t`` (a plan that
        loops passes near itself again only a turn later), on the plan's chords and on the final line beyond its
        end. Path following flies the plan from there: the along-track error stays (a constant-airspeed aircraft
        cannot take it out; replans move the landing times), the cross-track and height errors are taken out."""
        p = np.asarray(p, float)[:3]
        times = self.t
        lo = max(int(np.searchsorted(times, t - window_s)) - 1, 0)
        hi = min(int(np.searchsorted(times, t + window_s)) + 1, len(times))
        if hi - lo < 2:  # the window lies wholly past the end (or before the start): the final line (the start)
            lo, hi = (len(times) - 2, len(times)) if t > times[-1] else (0, 2)
        a, b = self.table[lo:hi - 1, :3], self.table[lo + 1:hi, :3]
        ab = b - a
        u = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0)
        k = int(np.argmin(np.linalg.norm(a + u[:, None] * ab - p, axis=1)))
        s = float(times[lo + k] + u[k] * (times[lo + k + 1] - times[lo + k]))
        if s >= times[-1]:  # on or past the end: along the final line (see :meth:`sample`)
            v = self.table[-1, 5:8]
            s = float(times[-1] + max(np.dot(p - self.table[-1, :3], v), 0.0) / max(float(np.dot(v, v)), 1e-300))
        return s
