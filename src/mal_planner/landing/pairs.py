"""Which pairs of aircraft carry a separation constraint in which phase.

Every phase carries all aircraft airborne in it, so constraining every pair in every phase gives
O(N^3) pair constraints, and each couples two aircraft's states at every collocation point: the KKT
factorisation then fills in across all aircraft (measured at 10 aircraft: 88 % of the IPOPT time, see
the README's profile). Most pairs never come near each other. A pair is constrained in a phase only if the
initial guess brings it within ``near`` of the separation around that phase's time span (widened by
``slack``); after each solve, any unconstrained pair that came within ``recheck`` of the separation
is added where it did and the problem is solved again (warm). The independent verification still checks
every pair, so screening can cost a re-solve but never a missed conflict.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mal_planner.landing.guess import AircraftGuess
from mal_planner.landing.layout import PhaseLayout
from mal_planner.scales import Scales

PhasePairs = list[set[tuple[int, int]]]
"""Per phase, the constrained pairs (a, b), a < b, as landing-order indices."""


@dataclass(frozen=True)
class PairScreen:
    """Distances in turn radii L and times in turn times T of the scenario (:class:`mal_planner.scales.Scales`);
    the thesis values they were tuned as are given in brackets."""

    near: float = 10.0 / 3.0
    """A pair is constrained where the guess brings it within the separation plus this (1 nm) ..."""
    near_separations: float = 1.0
    """... or plus this many separations if that is more (at a terminal area's size the optimized paths moved 3 nm
    from the guesses)."""
    slack: float = 2.5
    """The phase's guessed time span is widened by this on both sides, events move in the solve (20 s)."""
    recheck: float = 2.0 / 3.0
    """After a solve, unconstrained pairs closer than the separation plus this are added (0.2 nm)."""
    max_rounds: int = 4
    """Re-solves with added pairs, at most."""

    def near_nm(self, scales: Scales) -> float:
        return max(scales.lengths(self.near), self.near_separations * scales.separation_nm)

    def slack_s(self, scales: Scales) -> float:
        return scales.seconds(self.slack)

    def recheck_nm(self, scales: Scales) -> float:
        return scales.lengths(self.recheck)


SAMPLES_PER_TURN_TIME = 7.5
"""Guesses and solutions are compared this often per turn time (thesis: every second)."""


def all_pairs(layout: PhaseLayout) -> PhasePairs:
    """Every pair of aircraft airborne together, in every phase (no screening)."""
    return [set(itertools.combinations(layout.airborne(k), 2)) for k in range(layout.n_phases)]


def screen_pairs(layout: PhaseLayout, guesses: Sequence[AircraftGuess], scales: Scales,
                 screen: PairScreen) -> PhasePairs:
    """The pairs each phase constrains, from the guessed trajectories (``guesses`` in landing order)."""
    dt = scales.seconds(1.0 / SAMPLES_PER_TURN_TIME)
    horizon = max(g.landing_time for g in guesses)
    t = np.arange(0.0, horizon + dt, dt)
    pos = np.stack([np.column_stack([np.interp(t, g.t, g.states[:, k]) for k in range(3)]) for g in guesses])
    flying = np.stack([t <= g.landing_time + dt for g in guesses])
    starts = [0.0] + [ev.time_guess for ev in layout.events[:-1]]
    ends = [ev.time_guess for ev in layout.events]
    near = scales.separation_nm + screen.near_nm(scales)
    slack = screen.slack_s(scales)
    out: PhasePairs = []
    for k in range(layout.n_phases):
        window = (t >= starts[k] - slack) & (t <= ends[k] + slack)
        pairs = set()
        for a, b in itertools.combinations(layout.airborne(k), 2):
            both = window & flying[a] & flying[b]
            if both.any() and np.linalg.norm(pos[a, both] - pos[b, both], axis=1).min() < near:
                pairs.add((a, b))
        out.append(pairs)
    return out


def close_unconstrained(layout: PhaseLayout, phase_states: Sequence[tuple[np.ndarray, np.ndarray]],
                        constrained: PhasePairs, threshold_nm: float, widths: Sequence[int]) -> PhasePairs:
    """Per phase, the unconstrained pairs that come closer than ``threshold_nm`` in a solution.

    ``phase_states`` holds, per phase, sample times and the stacked states (K, sum of the airborne aircraft's state
    counts) there; ``widths`` are the aircraft's state counts (landing order).
    """
    out: PhasePairs = []
    for k, (_, x) in enumerate(phase_states):
        who = layout.airborne(k)
        at = dict(zip(who, np.concatenate([[0], np.cumsum([widths[i] for i in who])[:-1]]).astype(int), strict=True))
        found = set()
        for a, b in itertools.combinations(who, 2):
            if (a, b) in constrained[k]:
                continue
            d = np.linalg.norm(x[:, at[a]:at[a] + 3] - x[:, at[b]:at[b] + 3], axis=1)
            if d.min() < threshold_nm:
                found.add((a, b))
        out.append(found)
    return out


def count(pairs: PhasePairs) -> int:
    return sum(len(p) for p in pairs)
