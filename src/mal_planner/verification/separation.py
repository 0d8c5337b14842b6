"""The separation of every pair of flown aircraft while both are airborne, with no tolerance: on the union of both
tracks' samples (their chords exact), each path's chord error taken off, a sphere or a cylinder."""

from __future__ import annotations

import itertools
import math
from collections.abc import Set
from dataclasses import dataclass

import numpy as np

from mal_planner.scenario import Scenario
from mal_planner.units import nm_to_ft
from mal_planner.verification.report import PairCheck, Tolerances
from mal_planner.verification.space import chord_error_bound


def separation_checks(flown: dict[str, tuple[np.ndarray, np.ndarray]], scenario: Scenario, fail) -> list[PairCheck]:
    """Closest approach of every pair of flown tracks (``fail(callsigns, text)`` for each loss), as :func:`verify`
    checks plans: on the union of both tracks' samples, the chord errors taken off."""
    return pair_separations(flown, scenario, Tolerances.for_scenario(scenario), fail)


def pair_separations(flown: dict[str, tuple[np.ndarray, np.ndarray]], scenario: Scenario, tol: Tolerances,
                     fail, fixed: Set[str] = frozenset()) -> list[PairCheck]:
    """Minimum distance of every pair while both are airborne, on a common dense grid.

    Each pair has its own grid (the union of both aircraft's samples while both fly); the grids of all pairs
    are concatenated and evaluated at once, with the same arithmetic per sample as pair by pair. ``fixed``: paths
    flown as their chords (no chord error: another plan's path as its aircraft follows it); a pair of two is not
    checked.
    """
    spare_of = {cs: 0.0 if cs in fixed else chord_error_bound(scenario.aircraft_by_callsign(cs), t)
                for cs, (t, _) in flown.items()}
    names, grids = [], []
    for (a, (ta, xa)), (b, (tb, xb)) in itertools.combinations(flown.items(), 2):
        if a in fixed and b in fixed:
            continue
        t_end = min(ta[-1], tb[-1])
        t_start = max(ta[0], tb[0])
        if t_end <= t_start:
            continue
        # On the union of both sample grids both chords are linear, so the closest approach on each interval
        # is exact; each path departs from its chords by at most its chord error: both are taken off. A pair a
        # coarse grid proves separated is evaluated only where its closest approach can be (see _far_apart).
        windows = _far_apart(scenario, a, b, ta, xa, tb, xb, t_start, t_end, spare_of[a] + spare_of[b])
        for lo, hi in windows or [(t_start, t_end)]:
            grid = np.union1d(ta[(ta >= lo) & (ta <= hi)], tb[(tb >= lo) & (tb <= hi)])
            names.append((a, b))
            grids.append(np.union1d(grid, [lo, hi]))
    checks: list[PairCheck] = []
    for k in range(0, len(names), PAIRS_PER_BATCH):  # batches bound the memory (20 aircraft: 600 -> 200 MB)
        checks += _closest_approaches(names[k:k + PAIRS_PER_BATCH], grids[k:k + PAIRS_PER_BATCH], flown, spare_of,
                                      scenario, fail)
    pairs: dict[str, PairCheck] = {}
    for check in checks:  # a pair evaluated in windows: its closest one, and every violation (none: it is proven)
        best = pairs.get(check.pair)
        if best is None or check.min_distance_nm < best.min_distance_nm:
            check.violation_times_s = (best.violation_times_s if best else []) + check.violation_times_s
            pairs[check.pair] = check
        else:
            best.violation_times_s += check.violation_times_s
    return list(pairs.values())


PAIRS_PER_BATCH = 16


def _far_apart(scenario: Scenario, a: str, b: str, ta: np.ndarray, xa: np.ndarray, tb: np.ndarray, xb: np.ndarray,
               t_start: float, t_end: float, spare: float) -> list[tuple[float, float]] | None:
    """The time windows that can hold a pair's closest approach when a coarse grid proves the pair separated,
    else None (the pair is checked all along).

    Between grid times dt apart, two aircraft at speeds V_a and V_b close in by at most (V_a + V_b) dt / 2 from
    the nearer grid time, so a pair whose grid distances all exceed the separation by that (plus both chord
    errors) is separated all along; its smallest distance lies in an interval whose lower bound is below the
    grid's smallest distance, which is one or a few. The dense check all along was most of the verification's
    time at 20 aircraft of a terminal area. The grid step is separation / (V_a + V_b): half a separation of slack.
    V_a + V_b (airspeeds) bounds the closing speed in a wind too: a uniform wind moves both alike, so their relative
    velocity is that of their air velocities.
    """
    speeds = _fastest(scenario, a, xa) + _fastest(scenario, b, xb)
    radius = scenario.separation_radius_nm  # farther apart than this is separated, also for a cylinder
    dt = radius / speeds
    grid = np.append(np.arange(t_start, t_end, dt), t_end)
    if len(grid) < 3:
        return None
    pa = np.column_stack([np.interp(grid, ta, xa[:, k]) for k in range(3)])
    pb = np.column_stack([np.interp(grid, tb, xb[:, k]) for k in range(3)])
    dist = np.linalg.norm(pa - pb, axis=1)
    lower = np.minimum(dist[:-1], dist[1:]) - 0.5 * speeds * np.diff(grid)
    if lower.min() - spare <= radius:
        return None
    keep = np.flatnonzero(lower <= dist.min())
    return [(float(grid[k]), float(grid[k + 1])) for k in keep]


def _fastest(scenario: Scenario, callsign: str, x: np.ndarray) -> float:
    """The fastest airspeed (nm/s) of a flown path: its airspeed state's largest, else its model's constant one."""
    return float(np.max(x[:, 5])) if x.shape[1] > 5 else scenario.aircraft_by_callsign(callsign).speed


def _closest_approaches(names: list[tuple[str, str]], grids: list[np.ndarray],
                        flown: dict[str, tuple[np.ndarray, np.ndarray]], spare_of: dict[str, float],
                        scenario: Scenario, fail) -> list[PairCheck]:
    """Closest approach of each pair on its grid, all pairs of the batch evaluated at once."""
    counts = np.array([len(g) for g in grids])
    first = np.cumsum(counts) - counts
    last = first + counts - 1
    grid = np.concatenate(grids)
    pair = np.repeat(np.arange(len(grids)), counts)
    rel = _relative_positions(names, grids, flown, first, last, len(grid))
    step = np.zeros_like(rel)  # rel[i+1] - rel[i] within a pair; 0 at a pair's last sample
    step[:, :-1] = np.diff(rel, axis=1)
    step[:, last] = 0.0
    spare = np.array([spare_of[a] + spare_of[b] for a, b in names])[pair]
    gap = np.zeros(len(grid))
    gap[:-1] = np.diff(grid)
    chords = _chord_separations(rel, step, spare, grid, gap, last, scenario)
    violations = np.flatnonzero(chords.low & _local_minima(chords.dist, first, last))
    pairs = []
    for j, (a, b) in enumerate(names):
        k = first[j] + int(np.argmin(chords.dist[first[j]:last[j] + 1]))
        mine = violations[(violations >= first[j]) & (violations <= last[j])]
        pairs.append(PairCheck(f"{a}-{b}", float(chords.dist[k]), float(chords.at[k]), chords.at[mine].tolist()))
        _tell_loss(a, b, k, mine, chords, scenario, fail)
    return pairs


def _relative_positions(names: list[tuple[str, str]], grids: list[np.ndarray],
                        flown: dict[str, tuple[np.ndarray, np.ndarray]], first: np.ndarray, last: np.ndarray,
                        n: int) -> np.ndarray:
    """Positions of both aircraft of every pair on its grid (coordinates in rows, so the sums are cheap): a - b."""
    pa, pb = np.empty((3, n)), np.empty((3, n))
    for j, (a, b) in enumerate(names):
        part = slice(first[j], last[j] + 1)
        for out, (t, x) in ((pa, flown[a]), (pb, flown[b])):
            for k in range(3):
                out[k, part] = np.interp(grids[j], t, x[:, k])
    return pa - pb


@dataclass
class _Chords:
    """The chords ``rel + s step`` (s in [0, 1]) between consecutive grid times of the pairs of a batch."""

    rel: np.ndarray
    step: np.ndarray
    grid: np.ndarray
    gap: np.ndarray
    """Each chord's duration (0 at a pair's last sample)."""
    low: np.ndarray
    """Whether the pair loses its separation on the chord."""
    dist: np.ndarray
    """The chord's smallest distance, chord errors taken off (a cylinder: its separation in minima, times the
    horizontal minimum)."""
    at: np.ndarray
    """The time of that smallest distance."""


def _chord_separations(rel: np.ndarray, step: np.ndarray, spare: np.ndarray, grid: np.ndarray, gap: np.ndarray,
                       last: np.ndarray, scenario: Scenario) -> _Chords:
    """Each chord's closest approach, against a sphere or (a vertical minimum given) a cylinder."""
    with np.errstate(divide="ignore", invalid="ignore"):
        s_min = np.clip(np.nan_to_num(-np.sum(rel * step, axis=0) / np.sum(step * step, axis=0)), 0.0, 1.0)
    near = rel + s_min * step
    closest = np.sqrt(np.sum(near * near, axis=0))
    closest[last] = np.sqrt(np.sum(rel[:, last] * rel[:, last], axis=0))
    dist = closest - spare
    at = grid + s_min * gap
    at[last] = grid[last]
    low = dist < scenario.separation_nm
    if scenario.vertical_separation_nm is not None:  # a cylinder: separated horizontally OR vertically
        low, ratio, s_at = _cylinder_chords(rel, step, spare, scenario.separation_nm, scenario.vertical_separation_nm)
        dist = scenario.separation_nm * ratio
        at = grid + s_at * gap
        at[last] = grid[last]
    return _Chords(rel, step, grid, gap, low, dist, at)


def _local_minima(dist: np.ndarray, first: np.ndarray, last: np.ndarray) -> np.ndarray:
    """The samples where each pair's distance is a local minimum (a pair's ends count on their open side)."""
    left = np.ones(len(dist), bool)
    left[1:] = dist[1:] <= dist[:-1]
    left[first] = True
    right = np.ones(len(dist), bool)
    right[:-1] = dist[:-1] <= dist[1:]
    right[last] = True
    return left & right


def _tell_loss(a: str, b: str, k: int, mine: np.ndarray, chords: _Chords, scenario: Scenario, fail) -> None:
    """``fail`` with where the pair ``a``-``b`` comes closest, if it loses its separation (``mine``: the
    violating chords; ``k``: its closest one)."""
    if scenario.vertical_separation_nm is not None:
        if len(mine):
            rel, step, grid, gap = chords.rel, chords.step, chords.grid, chords.gap
            # Told at the closest horizontal approach on the violating chords (the ratio is often flat there).
            dh, r0 = step[:2, mine], rel[:2, mine]
            dd = np.sum(dh * dh, axis=0)
            s_h = np.clip(-np.sum(r0 * dh, axis=0) / np.where(dd > 0.0, dd, 1.0), 0.0, 1.0)
            i = int(np.argmin(np.linalg.norm(r0 + s_h * dh, axis=0)))
            k, s_k = int(mine[i]), float(s_h[i])
            p = rel[:, k] + s_k * step[:, k]
            fail((a, b), f"{a}-{b}: {math.hypot(p[0], p[1]):.4f} nm apart horizontally and "
                         f"{nm_to_ft(abs(p[2])):.0f} ft vertically at t={grid[k] + s_k * gap[k]:.2f} s "
                         f"(minima {scenario.separation_nm} nm or "
                         f"{nm_to_ft(scenario.vertical_separation_nm):.0f} ft)")
    elif chords.dist[k] < scenario.separation_nm:
        fail((a, b), f"{a}-{b}: {chords.dist[k]:.4f} nm apart at t={chords.at[k]:.2f} s "
                     f"(minimum {scenario.separation_nm} nm)")


def _cylinder_chords(rel: np.ndarray, step: np.ndarray, spare: np.ndarray, h_min: float, v_min: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A cylindrical protected zone on the chords rel + s step, s in [0, 1] (columns; spare: the chord errors).

    Returns, per chord: whether some s has h < H + spare AND |dz| < V + spare (exact: the first set is the inside
    of a quadratic's roots, the second an interval); the smallest max((h - spare) / H, (|dz| - spare) / V) over the
    chord (the pair's separation in minima, < 1 inside; a convex function: its minimum lies at an end, at the
    smallest h, at dz = 0, or where the two terms are equal); and the s where it is reached.
    """
    h0, dh, z0, dz = rel[:2], step[:2], rel[2], step[2]
    qa, qb = np.sum(dh * dh, axis=0), 2.0 * np.sum(h0 * dh, axis=0)
    qc = np.sum(h0 * h0, axis=0)
    big_h, big_v = h_min + spare, v_min + spare
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = qb * qb - 4.0 * qa * (qc - big_h * big_h)
        root = np.sqrt(np.maximum(disc, 0.0))
        flat = qa <= 0.0
        h_lo = np.where(flat, np.where(qc < big_h * big_h, -np.inf, np.inf), (-qb - root) / (2.0 * qa))
        h_hi = np.where(flat, np.where(qc < big_h * big_h, np.inf, -np.inf), (-qb + root) / (2.0 * qa))
        h_lo, h_hi = np.where(~flat & (disc <= 0.0), np.inf, h_lo), np.where(~flat & (disc <= 0.0), -np.inf, h_hi)
        level = dz == 0.0
        v_a, v_b = (-big_v - z0) / dz, (big_v - z0) / dz
        v_lo = np.where(level, np.where(np.abs(z0) < big_v, -np.inf, np.inf), np.minimum(v_a, v_b))
        v_hi = np.where(level, np.where(np.abs(z0) < big_v, np.inf, -np.inf), np.maximum(v_a, v_b))
    inside = np.maximum.reduce([np.zeros_like(qa), h_lo, v_lo]) < np.minimum.reduce([np.ones_like(qa), h_hi, v_hi])
    # Candidates of the smallest ratio: the ends, the smallest h, dz = 0, and where both terms are equal.
    k = h_min / v_min
    cands = [np.zeros_like(qa), np.ones_like(qa)]
    with np.errstate(divide="ignore", invalid="ignore"):
        cands.append(np.where(qa > 0.0, -qb / (2.0 * qa), 0.0))
        cands.append(np.where(level, 0.0, -z0 / dz))
        for sign in (1.0, -1.0):  # h(s) = k (sign dz(s) - spare) + spare, squared: a quadratic in s
            c1, c0 = k * sign * dz, k * (sign * z0 - spare) + spare
            a2, b2, c2 = qa - c1 * c1, qb - 2.0 * c1 * c0, qc - c0 * c0
            d2 = np.sqrt(np.maximum(b2 * b2 - 4.0 * a2 * c2, 0.0))
            for r in ((-b2 - d2) / (2.0 * a2), (-b2 + d2) / (2.0 * a2)):
                cands.append(np.where(np.abs(a2) > 1e-300, r, np.where(b2 != 0.0, -c2 / b2, 0.0)))
    best_ratio = np.full(qa.shape, np.inf)
    best_s = np.zeros_like(qa)
    for s in cands:
        s = np.clip(np.nan_to_num(s, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
        h = np.sqrt(np.maximum(qa * s * s + qb * s + qc, 0.0))
        ratio = np.maximum((h - spare) / h_min, (np.abs(z0 + s * dz) - spare) / v_min)
        better = ratio < best_ratio
        best_ratio, best_s = np.where(better, ratio, best_ratio), np.where(better, s, best_s)
    return inside, best_ratio, best_s
