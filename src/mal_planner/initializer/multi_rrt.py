"""The multiple-tree RRT of chapter 3 (Clifton et al.; the thesis's Algorithm 3-4) in 3-D on NumPy.

Each iteration draws a point (first the grid seeds, then uniform samples, with a goal bias), steers it to
within ``max_edge`` of its nearest node, and for every tree checks the edge from that tree's nearest node
to it: the point joins every tree it reaches (trees that both reach it are MERGED through it) or, when it
reaches none, becomes the root of a new tree (within ``max_trees``). The search stops when the start and
the goal are in one tree; the path is then smoothed by shortcutting.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from mal_planner.deadline import NO_DEADLINE, Deadline
from mal_planner.initializer.base import PlanningFailed, default_step, require_free_endpoints
from mal_planner.initializer.collision import CollisionChecker
from mal_planner.initializer.smoothing import SmoothedSearch


class _Forest:
    """Nodes, edges and tree labels; nearest-node queries through a lazily rebuilt cKDTree."""

    def __init__(self, capacity: int, rebuild_every: int) -> None:
        self.pos = np.empty((capacity, 3))
        self.label = np.empty(capacity, dtype=np.int64)
        self.n = 0
        self.edges: list[list[int]] = []
        self.members: dict[int, list[int]] = {}
        self._kd: cKDTree | None = None
        self._kd_n = 0
        self._rebuild_every = rebuild_every

    def add(self, point: np.ndarray, tree: int) -> int:
        if self.n == len(self.pos):
            self.pos = np.vstack([self.pos, np.empty_like(self.pos)])
            self.label = np.concatenate([self.label, np.empty_like(self.label)])
        i = self.n
        self.pos[i], self.label[i] = point, tree
        self.n += 1
        self.edges.append([])
        self.members.setdefault(tree, []).append(i)
        if self.n - self._kd_n >= self._rebuild_every:
            self._kd, self._kd_n = cKDTree(self.pos[: self.n]), self.n
        return i

    def connect(self, i: int, j: int) -> None:
        self.edges[i].append(j)
        self.edges[j].append(i)
        a, b = int(self.label[i]), int(self.label[j])
        if a != b:  # merge the smaller tree into the larger
            if len(self.members[a]) < len(self.members[b]):
                a, b = b, a
            moved = self.members.pop(b)
            self.label[moved] = a
            self.members[a].extend(moved)

    @property
    def trees(self) -> list[int]:
        return list(self.members)

    def nearest_per_tree(self, point: np.ndarray, k: int = 16) -> dict[int, tuple[int, float]]:
        """The nearest node of every tree: kd-tree candidates, a brute-force buffer of recent nodes and a
        brute-force fallback over the members of trees the candidates missed."""
        best: dict[int, tuple[int, float]] = {}

        def offer(idx: np.ndarray, dist: np.ndarray) -> None:
            for i, d in zip(idx.tolist(), dist.tolist(), strict=True):
                t = int(self.label[i])
                if t not in best or d < best[t][1]:
                    best[t] = (i, d)

        if self._kd is not None:
            kk = min(k, self._kd_n)
            dist, idx = self._kd.query(point, k=kk)
            offer(np.atleast_1d(idx), np.atleast_1d(dist))
        recent = np.arange(self._kd_n, self.n)
        if recent.size:
            offer(recent, np.linalg.norm(self.pos[recent] - point, axis=1))
        for t, members in self.members.items():
            if t not in best:
                m = np.asarray(members)
                d = np.linalg.norm(self.pos[m] - point, axis=1)
                j = int(np.argmin(d))
                best[t] = (int(m[j]), float(d[j]))
        return best

    def path(self, start: int, goal: int) -> list[int]:
        prev = {start: start}
        queue = deque([start])
        while queue:
            i = queue.popleft()
            if i == goal:
                break
            for j in self.edges[i]:
                if j not in prev:
                    prev[j] = i
                    queue.append(j)
        out = [goal]
        while out[-1] != start:
            out.append(prev[out[-1]])
        return out[::-1]


def grid_seeds(checker: CollisionChecker, per_axis: tuple[int, int, int] | int) -> np.ndarray:
    """Free cell centres of a grid over the airspace, plus points in each gate's hole (its centre and a
    3 x 3 grid inside it, on the gate plane) so that trees grow through narrow holes."""
    n = np.broadcast_to(np.asarray(per_axis, dtype=int), (3,))
    axes = [lo + (np.arange(k) + 0.5) * (hi - lo) / k for (lo, hi), k in zip(checker.airspace, n, strict=True)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    extra = []
    for gate in checker.gates:
        (u0, u1), (v0, v1) = gate.bounds
        mu, mv = checker.gate_margin, checker.gate_margin
        for fu in (0.5, 0.25, 0.75):
            for fv in (0.5, 0.25, 0.75):
                p = np.zeros(3)
                p[gate.axis] = gate.position
                p[gate.other_axes[0]] = u0 + mu + fu * (u1 - u0 - 2 * mu)
                p[gate.other_axes[1]] = v0 + mv + fv * (v1 - v0 - 2 * mv)
                extra.append(p)
    seeds = np.vstack([np.array(extra).reshape(-1, 3), grid])
    return seeds[checker.points_free(seeds)]


@dataclass
class MultiRRT(SmoothedSearch):
    """Multiple-tree RRT (Algorithm 3-4). Options:

    ``max_trees`` (>= 2, start and goal trees included), ``seeds_per_axis`` (grid seeds, an int or one per
    axis), ``max_iterations``, ``max_edge`` (nm; the steering step; None: :func:`default_step` of the
    airspace, 1 nm in the thesis), ``goal_bias`` (probability that the
    sample is the goal or the start, alternately), ``smooth_rounds`` (random-shortcut rounds; 0: greedy
    shortcut only), ``rebuild_every`` (nodes added between kd-tree rebuilds).
    """

    max_trees: int = 8
    seeds_per_axis: tuple[int, int, int] | int = (4, 4, 2)
    max_iterations: int = 5000
    max_edge: float | None = None
    goal_bias: float = 0.05
    smooth_rounds: int = 40
    rebuild_every: int = 64
    spec: str = "multi-rrt"

    def __post_init__(self) -> None:
        if self.max_trees < 2:
            raise ValueError(f"max_trees must be >= 2, got {self.max_trees}")
        if self.max_iterations < 1 or (self.max_edge is not None and self.max_edge <= 0):
            raise ValueError("max_iterations must be >= 1 and max_edge > 0")
        self.last_iterations = 0
        self.last_trees = 0

    def search(
        self, checker: CollisionChecker, start: np.ndarray, goal: np.ndarray, rng: np.random.Generator,
        deadline: Deadline | None = None,
    ) -> np.ndarray:
        """The unsmoothed path through the merged tree (K, 3); ``deadline`` is checked every iteration."""
        deadline = deadline or NO_DEADLINE
        start, goal = require_free_endpoints(checker, self.spec, start, goal)
        if checker.segment_free(start, goal):
            self.last_iterations, self.last_trees = 0, 1
            return np.array([start, goal])
        forest = _Forest(1024, self.rebuild_every)
        i_start, i_goal = forest.add(start, 0), forest.add(goal, 1)
        next_tree = 2
        seeds = grid_seeds(checker, self.seeds_per_axis)
        seeds = seeds[rng.permutation(len(seeds))]
        lo, hi = checker.lower, checker.upper
        max_edge = self.max_edge or default_step(checker)
        for it in range(self.max_iterations):
            deadline.check()
            if it < len(seeds):
                sample = seeds[it]
            elif rng.random() < self.goal_bias:
                sample = goal if it % 2 else start
            else:
                sample = rng.uniform(lo, hi)
            nearest = forest.nearest_per_tree(sample)
            near_i, near_d = min(nearest.values(), key=lambda v: v[1])
            if near_d > max_edge:  # steer towards the sample
                sample = forest.pos[near_i] + (sample - forest.pos[near_i]) * (max_edge / near_d)
                nearest = forest.nearest_per_tree(sample)
            if not checker.point_free(sample):
                continue
            trees = list(nearest)
            idx = np.array([nearest[t][0] for t in trees])
            dist = np.array([nearest[t][1] for t in trees])
            existing = int(idx[np.argmin(dist)]) if dist.min() < 1e-12 else None
            free = checker.segments_free(forest.pos[idx], np.repeat(sample[None], len(idx), axis=0))
            if existing is not None:  # the sample is a node already (goal bias): connect trees to it
                free[idx == existing] = False
                new = existing
            elif free.any():
                new = forest.add(sample, trees[int(np.flatnonzero(free)[0])])
            else:
                if len(forest.trees) < self.max_trees:
                    forest.add(sample, next_tree)
                    next_tree += 1
                continue
            for j in np.flatnonzero(free):
                forest.connect(int(idx[j]), new)
            if forest.label[i_start] == forest.label[i_goal]:
                self.last_iterations, self.last_trees = it + 1, len(forest.trees)
                return forest.pos[forest.path(i_start, i_goal)].copy()
        self.last_iterations, self.last_trees = self.max_iterations, len(forest.trees)
        raise PlanningFailed(
            f"multi-rrt: no path from {np.round(start, 3).tolist()} to {np.round(goal, 3).tolist()} "
            f"in {self.max_iterations} iterations ({len(forest.trees)} trees, {forest.n} nodes)"
        )
