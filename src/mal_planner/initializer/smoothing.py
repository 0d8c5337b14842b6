"""Path smoothing by shortcutting, with the exact segment check (no step can skip a thin wall)."""

from __future__ import annotations

import numpy as np

from mal_planner.deadline import Deadline
from mal_planner.initializer.collision import CollisionChecker


def remove_repeats(path: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Drop consecutive points closer than ``tol`` (keeps the last point)."""
    path = np.asarray(path, dtype=float)
    if len(path) < 2:
        return path.copy()
    keep = np.ones(len(path), dtype=bool)
    keep[1:] = np.linalg.norm(np.diff(path, axis=0), axis=1) > tol
    out = path[keep]
    out[-1] = path[-1]
    return out


def greedy_shortcut(checker: CollisionChecker, path: np.ndarray) -> np.ndarray:
    """From each kept vertex jump to the farthest later vertex that it sees (one batch check per jump)."""
    path = remove_repeats(path)
    out = [path[0]]
    i = 0
    while i < len(path) - 1:
        later = path[i + 1:]
        free = checker.segments_free(np.repeat(path[i][None], len(later), axis=0), later)
        # the next vertex is always visible on a free path; take the farthest visible one
        j = i + 1 + (int(np.flatnonzero(free)[-1]) if free.any() else 0)
        out.append(path[j])
        i = j
    return np.array(out)


def _point_at(path: np.ndarray, cum: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    seg = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(path) - 2)
    seg_len = np.maximum(cum[seg + 1] - cum[seg], 1e-300)
    frac = ((s - cum[seg]) / seg_len)[:, None]
    return path[seg] + frac * (path[seg + 1] - path[seg]), seg


def random_shortcut(
    checker: CollisionChecker, path: np.ndarray, rng: np.random.Generator, rounds: int = 40, batch: int = 32
) -> np.ndarray:
    """Replace the part between two random points on the path by a straight segment when free.

    Each round draws ``batch`` pairs of arc-length positions, checks their chords in one call and applies
    the free chord that saves the most length. Converges towards the taut path around obstacles.
    """
    path = remove_repeats(path)
    for _ in range(rounds):
        if len(path) < 3:
            break
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
        s = np.sort(rng.uniform(0.0, cum[-1], size=(batch, 2)), axis=1)
        pa, ia = _point_at(path, cum, s[:, 0])
        pb, ib = _point_at(path, cum, s[:, 1])
        saving = (s[:, 1] - s[:, 0]) - np.linalg.norm(pb - pa, axis=1)
        useful = (ib > ia) & (saving > 1e-9)
        if not useful.any():
            continue
        idx = np.flatnonzero(useful)
        free = checker.segments_free(pa[idx], pb[idx])
        if not free.any():
            continue
        best = idx[free][np.argmax(saving[idx[free]])]
        path = np.vstack([path[: ia[best] + 1], pa[best], pb[best], path[ib[best] + 1:]])
        path = remove_repeats(path)
    return path


def smooth_path(
    checker: CollisionChecker, path: np.ndarray, rng: np.random.Generator, rounds: int = 40
) -> np.ndarray:
    """Greedy shortcut, random shortcuts, then greedy again; endpoints unchanged."""
    path = greedy_shortcut(checker, path)
    if rounds > 0:
        path = random_shortcut(checker, path, rng, rounds)
        path = greedy_shortcut(checker, path)
    return path


class SmoothedSearch:
    """Mixin for planners: :meth:`plan` = the planner's raw ``search`` path, then shortcut smoothing.

    ``deadline``: the plan's time limit, checked in the search's loop (raises
    :class:`~mal_planner.errors.TimeLimitReached`); None: no limit."""

    smooth_rounds: int

    def search(self, checker: CollisionChecker, start: np.ndarray, goal: np.ndarray,
               rng: np.random.Generator, deadline: Deadline | None = None) -> np.ndarray:
        raise NotImplementedError

    def plan(self, checker: CollisionChecker, start: np.ndarray, goal: np.ndarray,
             rng: np.random.Generator, deadline: Deadline | None = None) -> np.ndarray:
        """The raw path from start to goal, smoothed; raises ``PlanningFailed``."""
        return smooth_path(checker, self.search(checker, start, goal, rng, deadline), rng, self.smooth_rounds)
