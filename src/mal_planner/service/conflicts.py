"""Short-term prediction of the traffic along its instructions, and the conflicts in it (as an STCA predicts).

Each aircraft is predicted along the instruction it flies (a plan, a hold or a vector), from where the radar sees
it: from the instruction's point closest to it, as the guidance follows it (:mod:`mal_planner.closedloop.guidance`;
an along-track error stays: searched around where the aircraft was on it at the last scan,
:meth:`~mal_planner.service.book.PlanBook.plan_times`), with the cross-track offset taken out at the guidance's
position time constant.
An aircraft without an instruction flies straight on. Separation is measured in minima: the distance over the
separation (a protected sphere) or, with a vertical minimum, the larger of the horizontal and vertical distances
over their minima (a cylinder): below 1 is a loss of separation.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from mal_planner.scenario import Scenario
from mal_planner.service.tracks import Track
from mal_planner.trajectory import Reference

POSITION_TIME_PER_TURN_TIME = 0.5
"""The guidance's position time constant over the turn time (:mod:`mal_planner.closedloop.guidance` flies with it):
a cross-track offset decays with it in the prediction."""


@dataclass(frozen=True)
class Minima:
    """The protected zone: ``horizontal_nm`` (a sphere's radius when ``vertical_nm`` is None)."""

    horizontal_nm: float
    vertical_nm: float | None = None

    @classmethod
    def of(cls, scenario: Scenario) -> Minima:
        return cls(scenario.separation_nm, scenario.vertical_separation_nm)

    def ratio(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Separation of positions ``a`` and ``b`` (..., 3) in minima."""
        d = np.asarray(a, float) - np.asarray(b, float)
        if self.vertical_nm is None:
            return np.linalg.norm(d, axis=-1) / self.horizontal_nm
        return np.maximum(np.linalg.norm(d[..., :2], axis=-1) / self.horizontal_nm,
                          np.abs(d[..., 2]) / self.vertical_nm)


@dataclass(frozen=True)
class Picture:
    """Every aircraft's predicted positions on one time grid (absolute times)."""

    times: np.ndarray
    paths: dict[str, np.ndarray]
    """(len(times), 3) per callsign."""


@dataclass(frozen=True)
class Conflict:
    """A pair predicted closer than ``threshold`` minima: first at ``t``, closest ``ratio`` minima at ``t_closest``."""

    a: str
    b: str
    t: float
    t_closest: float
    ratio: float


def predict(track: Track, instruction: Reference | None, times: np.ndarray, *, search_s: float, settle_s: float,
            s0: float | None = None) -> np.ndarray:
    """(len(times), 3) positions of ``track``'s aircraft flying ``instruction`` (None: straight on); ``s0``: the
    instruction's time the aircraft is at (None: its closest point within ``search_s`` of the track's time)."""
    tau = np.asarray(times, float) - track.stamp
    if instruction is None:
        return np.array([track.at(track.stamp + dt)[:3] for dt in tau])
    if s0 is None:
        s0 = instruction.closest_time(track.state[:3], track.stamp, search_s)
    offset = track.state[:3] - instruction.position(s0)
    fade = np.exp(-np.maximum(tau, 0.0) / settle_s)[:, None]
    return instruction.positions(s0 + tau) + fade * offset


def picture(tracks: Mapping[str, Track], instructions: Mapping[str, Reference], times: np.ndarray, *,
            search_s: float, settle_s: float, plan_times: Mapping[str, float] | None = None) -> Picture:
    """Every tracked aircraft predicted along its instruction at ``times`` (``plan_times``: where each is on it)."""
    at = plan_times or {}
    return Picture(np.asarray(times, float),
                   {cs: predict(tr, instructions.get(cs), times, search_s=search_s, settle_s=settle_s,
                                s0=at.get(cs)) for cs, tr in tracks.items()})


def closest_to_others(path: np.ndarray, pic: Picture, minima: Minima, exclude: str) -> tuple[float, str]:
    """The smallest separation (minima) of ``path`` (on ``pic``'s times) from everyone in ``pic`` but ``exclude``,
    and from whom (inf, '' when alone)."""
    best, who = np.inf, ""
    for cs, other in pic.paths.items():
        if cs == exclude:
            continue
        r = float(minima.ratio(path, other).min())
        if r < best:
            best, who = r, cs
    return best, who


def conflicts(pic: Picture, minima: Minima, threshold: float = 1.0, ignore: frozenset[str] = frozenset()
              ) -> list[Conflict]:
    """The pairs predicted below ``threshold`` minima, soonest first; pairs inside ``ignore`` (both in it) are
    left out."""
    found = []
    for a, b in itertools.combinations(sorted(pic.paths), 2):
        if a in ignore and b in ignore:
            continue
        r = minima.ratio(pic.paths[a], pic.paths[b])
        below = np.flatnonzero(r < threshold)
        if below.size:
            k = int(np.argmin(r))
            found.append(Conflict(a, b, float(pic.times[below[0]]), float(pic.times[k]), float(r[k])))
    return sorted(found, key=lambda c: c.t)
