"""Collision checking for the path planners: airspace bounds, obstacles and gate (hole) crossings.

Obstacle tests use :meth:`Superquadric.contains` and the exact :meth:`Superquadric.segment_hits`, so no
step size can skip a thin wall. Gates are enforced as well: near a gate plane (within ``gate_band`` of
it) a path must lie inside the gate's hole, shrunk by ``gate_margin``. This keeps paths out of the
rounded corners of the p-norm wall pieces, where a thin sliver outside the hole is technically free.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mal_planner.obstacles import Gate, Superquadric
from mal_planner.scenario import Scenario


@dataclass
class CheckCounts:
    """How many points and segments were checked (for statistics)."""

    points: int = 0
    segments: int = 0
    calls: int = 0

    def as_dict(self) -> dict[str, int]:
        return {"points": self.points, "segments": self.segments, "calls": self.calls}


@dataclass
class CollisionChecker:
    """Free-space test for points and straight segments in planner units (nm).

    ``margin`` inflates every obstacle's semi-axes by that fraction; ``gate_band`` (nm) is the
    half-width of the slab around each gate plane in which a path must be inside the hole (0: only the
    crossing point is checked); ``gate_margin`` (nm) shrinks the hole.
    """

    airspace: np.ndarray
    obstacles: tuple[Superquadric, ...] = ()
    gates: tuple[Gate, ...] = ()
    margin: float = 0.0
    gate_band: float = 0.01
    gate_margin: float = 0.005
    counts: CheckCounts = field(default_factory=CheckCounts)

    def __post_init__(self) -> None:
        self.airspace = np.asarray(self.airspace, dtype=float).reshape(3, 2)
        boxes = [ob.bounding_box() for ob in self.obstacles]
        self._boxes = np.array(boxes, dtype=float).reshape(-1, 3, 2)
        if len(self.obstacles):
            centre = self._boxes.mean(axis=2, keepdims=True)
            self._boxes = centre + (self._boxes - centre) * (1.0 + self.margin) + np.array([-1e-9, 1e-9])
        self._box_list = [[(float(lo), float(hi)) for lo, hi in box] for box in self._boxes]
        self._air = [(float(lo), float(hi)) for lo, hi in self.airspace]

    @classmethod
    def from_scenario(
        cls, scenario: Scenario, margin: float = 0.0, gate_band: float = 0.01, gate_margin: float = 0.005
    ) -> CollisionChecker:
        """A checker for the scenario's airspace, obstacles and gates."""
        return cls(scenario.airspace, tuple(scenario.obstacles), tuple(scenario.gates), margin, gate_band,
                   gate_margin)

    @property
    def lower(self) -> np.ndarray:
        return self.airspace[:, 0]

    @property
    def upper(self) -> np.ndarray:
        return self.airspace[:, 1]

    def points_free(self, points: np.ndarray) -> np.ndarray:
        """Boolean per row of ``points`` (shape (..., 3)): in the airspace, outside obstacles, gate-legal."""
        pts = np.asarray(points, dtype=float)
        flat = pts.reshape(-1, 3)
        self.counts.calls += 1
        self.counts.points += len(flat)
        ok = np.all((flat >= self.lower) & (flat <= self.upper), axis=1)
        for ob in self.obstacles:
            idx = np.flatnonzero(ok)
            if idx.size == 0:
                break
            ok[idx] &= ~ob.contains(flat[idx], self.margin)
        for gate in self.gates:
            near = np.abs(gate.signed_distance(flat)) <= self.gate_band
            ok &= ~near | gate.in_hole(flat, -self.gate_margin)
        return ok.reshape(pts.shape[:-1])

    def point_free(self, point: np.ndarray) -> bool:
        """Scalar fast path of :meth:`points_free` (bounding boxes first, in plain Python)."""
        p = [float(v) for v in np.asarray(point, dtype=float).reshape(3)]
        self.counts.calls += 1
        self.counts.points += 1
        if not all(lo <= v <= hi for v, (lo, hi) in zip(p, self._air, strict=True)):
            return False
        for ob, box in zip(self.obstacles, self._box_list, strict=True):
            if all(lo <= v <= hi for v, (lo, hi) in zip(p, box, strict=True)) and ob.contains(
                np.array(p), self.margin
            ):
                return False
        for gate in self.gates:
            if abs(p[gate.axis] - gate.position) <= self.gate_band and not self._in_hole(gate, p):
                return False
        return True

    def _in_hole(self, gate: Gate, p: list[float]) -> bool:
        m = self.gate_margin
        return all(lo + m <= p[ax] <= hi - m for (lo, hi), ax in zip(gate.bounds, gate.other_axes, strict=True))

    def segments_free(self, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
        """Boolean per segment start->end (rows, shape (K, 3)); endpoints must be in the airspace.

        The airspace is a box, so a segment is inside when both ends are. Obstacles are tested only for
        segments whose bounding box meets the obstacle's (inflated) bounding box.
        """
        a = np.atleast_2d(np.asarray(starts, dtype=float))
        b = np.atleast_2d(np.asarray(ends, dtype=float))
        a, b = np.broadcast_arrays(a, b)
        self.counts.calls += 1
        self.counts.segments += len(a)
        ok = np.all((a >= self.lower) & (a <= self.upper) & (b >= self.lower) & (b <= self.upper), axis=1)
        if len(self.obstacles):
            seg_lo, seg_hi = np.minimum(a, b), np.maximum(a, b)
            overlap = np.all(
                (seg_hi[:, None, :] >= self._boxes[None, :, :, 0]) & (seg_lo[:, None, :] <= self._boxes[None, :, :, 1]),
                axis=2,
            )
            for j, ob in enumerate(self.obstacles):
                idx = np.flatnonzero(ok & overlap[:, j])
                if idx.size:
                    ok[idx] &= ~ob.segment_hits(a[idx], b[idx], self.margin)
        for gate in self.gates:
            idx = np.flatnonzero(ok)
            if idx.size:
                ok[idx] &= self._gate_legal(gate, a[idx], b[idx])
        return ok

    def segment_free(self, start: np.ndarray, end: np.ndarray) -> bool:
        """Scalar fast path of :meth:`segments_free` (bounding boxes first, in plain Python)."""
        a = [float(v) for v in np.asarray(start, dtype=float).reshape(3)]
        b = [float(v) for v in np.asarray(end, dtype=float).reshape(3)]
        self.counts.calls += 1
        self.counts.segments += 1
        for u, v, (lo, hi) in zip(a, b, self._air, strict=True):
            if not (lo <= u <= hi and lo <= v <= hi):
                return False
        for gate in self.gates:
            if not self._gate_legal_one(gate, a, b):
                return False
        lo_seg = [min(u, v) for u, v in zip(a, b, strict=True)]
        hi_seg = [max(u, v) for u, v in zip(a, b, strict=True)]
        for ob, box in zip(self.obstacles, self._box_list, strict=True):
            if all(sl <= bh and sh >= bl for sl, sh, (bl, bh) in zip(lo_seg, hi_seg, box, strict=True)) and bool(
                ob.segment_hits(np.array([a]), np.array([b]), self.margin)[0]
            ):
                return False
        return True

    def _gate_legal_one(self, gate: Gate, a: list[float], b: list[float]) -> bool:
        ax, w = gate.axis, self.gate_band
        sa, sb = a[ax] - gate.position, b[ax] - gate.position
        if min(sa, sb) > w or max(sa, sb) < -w:
            return True
        if sa == sb:
            return self._in_hole(gate, a) and self._in_hole(gate, b)
        t1, t2 = (-w - sa) / (sb - sa), (w - sa) / (sb - sa)
        for t in (min(max(min(t1, t2), 0.0), 1.0), min(max(max(t1, t2), 0.0), 1.0)):
            if not self._in_hole(gate, [u + t * (v - u) for u, v in zip(a, b, strict=True)]):
                return False
        return True

    def path_free(self, path: np.ndarray) -> bool:
        """True when every vertex and every segment of the polyline (K, 3) is free."""
        path = np.asarray(path, dtype=float)
        if not np.all(self.points_free(path)):
            return False
        return len(path) < 2 or bool(np.all(self.segments_free(path[:-1], path[1:])))

    def _gate_legal(self, gate: Gate, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """The part of each segment within the gate's slab lies in the (shrunk) hole.

        The hole is convex, so checking the two ends of the clipped part suffices.
        """
        da, db = gate.signed_distance(a), gate.signed_distance(b)
        w = self.gate_band
        lo_d, hi_d = np.minimum(da, db), np.maximum(da, db)
        touches = (hi_d >= -w) & (lo_d <= w)
        legal = np.ones(len(a), dtype=bool)
        idx = np.flatnonzero(touches)
        if idx.size == 0:
            return legal
        pa, pb, sa, sb = a[idx], b[idx], da[idx], db[idx]
        span = sb - sa
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = np.where(span != 0.0, (-w - sa) / span, 0.0)
            t2 = np.where(span != 0.0, (w - sa) / span, 1.0)
        t_lo = np.clip(np.minimum(t1, t2), 0.0, 1.0)
        t_hi = np.clip(np.maximum(t1, t2), 0.0, 1.0)
        p_lo = pa + t_lo[:, None] * (pb - pa)
        p_hi = pa + t_hi[:, None] * (pb - pa)
        legal[idx] = gate.in_hole(p_lo, -self.gate_margin) & gate.in_hole(p_hi, -self.gate_margin)
        return legal
