"""Obstacle shapes: p-norm superquadrics in the thesis's log form, and the gate (hole) of a wall.

One definition serves every stage: :meth:`Superquadric.log_pnorm` is the thesis's smooth constraint
function (>= 0 outside) and runs on NumPy arrays and CasADi symbols alike; :meth:`Superquadric.contains`
is the exact containment test, evaluated in a numerically stable way for checking results;
:meth:`Superquadric.segment_hits` is the exact segment test the RRT uses, so no step size can skip a
thin wall.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mal_planner.dynamics import array_module

AXES = "xyz"


@dataclass(frozen=True)
class Superquadric:
    """Region |(x-xc)/a|^p + |(y-yc)/b|^p + |(z-zc)/c|^p < 1 (p even): ellipsoid at p=2, box-like at 50."""

    name: str
    center: tuple[float, float, float]
    semi_axes: tuple[float, float, float]
    p: int

    def log_pnorm(self, x, y, z):
        """ln(sum of ((q - q_c)/a_q)^p): the thesis's obstacle path constraint, >= 0 outside.

        Works on floats, NumPy arrays and CasADi expressions (p is even, so no absolute value needed).
        """
        xp = array_module(x, y, z)
        (xc, yc, zc), (a, b, c) = self.center, self.semi_axes
        return xp.log(((x - xc) / a) ** self.p + ((y - yc) / b) ** self.p + ((z - zc) / c) ** self.p)

    def _normalized(self, points: np.ndarray) -> np.ndarray:
        return (np.asarray(points, dtype=float) - np.asarray(self.center)) / np.asarray(self.semi_axes)

    def contains(self, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Exact test: True where a point (rows of ``points``, shape (..., 3)) lies strictly inside.

        ``margin`` > 0 inflates the semi-axes by that fraction. Evaluated as
        p ln(m) + ln(sum (|r_i|/m)^p) < 0 with m = max |r_i|, which never overflows.
        """
        r = np.abs(self._normalized(points)) / (1.0 + margin)
        m = np.max(r, axis=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            scaled = np.sum((r / np.where(m > 0, m, 1.0)[..., None]) ** self.p, axis=-1)
            log_f = self.p * np.log(np.where(m > 0, m, 1e-300)) + np.log(scaled)
        return log_f < 0.0

    def segment_hits(self, starts: np.ndarray, ends: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """True where the segment start->end (rows, shape (K, 3)) enters the obstacle.

        The superquadric lies in its bounding box, so each segment is first clipped to the box (slab
        method); along the clipped part F(t) = sum |r_i(t)|^p is convex, and a golden-section search finds
        its minimum to 2e-6 of the clipped length. Exact for any wall thickness, unlike fixed-step sampling.
        """
        r0 = np.atleast_2d(self._normalized(starts)) / (1.0 + margin)
        r1 = np.atleast_2d(self._normalized(ends)) / (1.0 + margin)
        d = r1 - r0
        with np.errstate(divide="ignore", invalid="ignore"):
            ta = (-1.0 - r0) / d
            tb = (1.0 - r0) / d
        parallel = d == 0.0
        t_lo = np.where(parallel, np.where(np.abs(r0) < 1.0, -np.inf, np.inf), np.minimum(ta, tb))
        t_hi = np.where(parallel, np.where(np.abs(r0) < 1.0, np.inf, -np.inf), np.maximum(ta, tb))
        lo = np.maximum(np.max(t_lo, axis=1), 0.0)
        hi = np.minimum(np.min(t_hi, axis=1), 1.0)
        hits = np.zeros(len(r0), dtype=bool)
        idx = np.flatnonzero(lo < hi)
        if idx.size == 0:
            return hits
        a, b = lo[idx], hi[idx]
        p0, dd = r0[idx], d[idx]

        def f(t: np.ndarray) -> np.ndarray:
            return np.sum(np.abs(p0 + t[:, None] * dd) ** self.p, axis=1)

        # Golden-section search for the minimum of the convex F on [a, b]: 0.618^27 ~ 2e-6 of the clipped
        # interval, where F is flat (its error is ~ the square of that); any evaluation below 1 is a hit.
        ratio = (np.sqrt(5.0) - 1.0) / 2.0
        c, d = b - ratio * (b - a), a + ratio * (b - a)
        fc, fd = f(c), f(d)
        hit = (fc < 1.0) | (fd < 1.0)
        for _ in range(25):
            left = fc < fd  # the minimum lies in [a, d]: drop (d, b]
            b = np.where(left, d, b)
            a = np.where(left, a, c)
            x_new = np.where(left, b - ratio * (b - a), a + ratio * (b - a))
            f_new = f(x_new)
            hit |= f_new < 1.0
            c, d = np.where(left, x_new, d), np.where(left, c, x_new)
            fc, fd = np.where(left, f_new, fd), np.where(left, fc, f_new)
        hits[idx] = hit
        return hits

    def inflated(self, margin: float) -> Superquadric:
        """The same shape with every semi-axis longer by ``margin`` (nm): a safety margin around it."""
        return Superquadric(self.name, self.center, tuple(a + margin for a in self.semi_axes), self.p)

    def bounding_box(self) -> np.ndarray:
        """(3, 2) array of [min, max] per axis."""
        c, s = np.asarray(self.center), np.asarray(self.semi_axes)
        return np.stack([c - s, c + s], axis=1)


@dataclass(frozen=True)
class Gate:
    """The hole of a wall: a plane the aircraft must cross inside a rectangle, with a set attitude.

    ``axis`` is the index of the plane's normal (1 = y for the thesis's wall at y = 3); ``direction``
    is the sign of travel along that axis when passing (-1: towards smaller y). These are the event
    constraints of chapter 5: position in the hole, flight-path angle and heading fixed.
    """

    name: str
    axis: int
    position: float
    direction: int
    bounds: tuple[tuple[float, float], tuple[float, float]]
    """Bounds of the hole along the two other axes, in increasing axis order."""
    flight_path_angle: float
    heading: float
    """The ground track to pass on (rad); in a wind the aircraft's heading there is crabbed (see
    :meth:`mal_planner.scenario.Aircraft.heading_for_track`)."""

    @property
    def other_axes(self) -> tuple[int, int]:
        a, b = (i for i in range(3) if i != self.axis)
        return a, b

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """Distance ahead of the gate plane along the direction of travel (> 0 before passing)."""
        return -self.direction * (np.asarray(points, dtype=float)[..., self.axis] - self.position)

    def in_hole(self, points: np.ndarray, tol: float = 0.0) -> np.ndarray:
        """True where the two in-plane coordinates of a point lie in the hole (within ``tol``)."""
        pts = np.asarray(points, dtype=float)
        ok = np.ones(pts.shape[:-1], dtype=bool)
        for (lo, hi), ax in zip(self.bounds, self.other_axes, strict=True):
            ok &= (pts[..., ax] >= lo - tol) & (pts[..., ax] <= hi + tol)
        return ok

    def center(self) -> np.ndarray:
        """Centre point of the hole on the gate plane."""
        point = np.zeros(3)
        point[self.axis] = self.position
        for (lo, hi), ax in zip(self.bounds, self.other_axes, strict=True):
            point[ax] = 0.5 * (lo + hi)
        return point


def wall_with_hole(
    name: str,
    axis: int,
    position: float,
    thickness: float,
    span: tuple[tuple[float, float], tuple[float, float]],
    hole: tuple[tuple[float, float], tuple[float, float]],
    p: int = 50,
) -> list[Superquadric]:
    """Four box-like superquadrics forming a wall with a rectangular hole (thesis Figure 2-3).

    The wall occupies [position, position + thickness] along ``axis``; ``span`` and ``hole`` give the
    [min, max] of the wall and of the hole along the two other axes (in increasing axis order). The
    pieces are: left and right full-height columns beside the hole, then the parts above and below it,
    exactly as Table 2-3 builds the thesis's wall.
    """
    (u_lo, u_hi), (v_lo, v_hi) = span
    (hu_lo, hu_hi), (hv_lo, hv_hi) = hole
    if not (u_lo < hu_lo < hu_hi < u_hi and v_lo < hv_lo < hv_hi < v_hi):
        raise ValueError(f"wall {name!r}: the hole must lie strictly inside the wall's span")
    pieces = [
        ("left", (u_lo, hu_lo), (v_lo, v_hi)),
        ("right", (hu_hi, u_hi), (v_lo, v_hi)),
        ("top", (hu_lo, hu_hi), (hv_hi, v_hi)),
        ("bottom", (hu_lo, hu_hi), (v_lo, hv_lo)),
    ]
    u_ax, v_ax = (i for i in range(3) if i != axis)
    result = []
    for label, (a0, a1), (b0, b1) in pieces:
        center, semi = [0.0] * 3, [0.0] * 3
        center[axis], semi[axis] = position + thickness / 2.0, thickness / 2.0
        center[u_ax], semi[u_ax] = (a0 + a1) / 2.0, (a1 - a0) / 2.0
        center[v_ax], semi[v_ax] = (b0 + b1) / 2.0, (b1 - b0) / 2.0
        result.append(Superquadric(f"{name}-{label}", tuple(center), tuple(semi), p))
    return result
