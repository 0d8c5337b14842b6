"""Drawable geometry of the scenario's obstacles (meshes, outlines, sections) for every view.

The obstacle itself is :class:`mal_planner.obstacles.Superquadric`; this only samples its surface.
Superquadrics with a large exponent (the wall pieces, p = 50) are drawn as their bounding box, from
which they differ by a rounding of the edges far below the line width.
"""

from __future__ import annotations

import numpy as np

from mal_planner.obstacles import Gate, Superquadric

BOX_EXPONENT = 16
"""From this exponent on, a superquadric is drawn as its bounding box."""

_BOX_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                       [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])


def _spow(w: np.ndarray, e: float) -> np.ndarray:
    return np.sign(w) * np.abs(w) ** e


def obstacle_mesh(ob: Superquadric, n: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """Triangle mesh of the surface: (V, 3) vertices and (T, 3) vertex indices."""
    box = ob.bounding_box()
    if ob.p >= BOX_EXPONENT:
        corners = np.array([[box[0, i], box[1, j], box[2, k]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
        return corners, _BOX_FACES.copy()
    e = 2.0 / ob.p
    u, v = np.meshgrid(np.linspace(-np.pi, np.pi, n), np.linspace(-np.pi / 2, np.pi / 2, n // 2 + 1))
    (xc, yc, zc), (a, b, c) = ob.center, ob.semi_axes
    pts = np.stack([xc + a * _spow(np.cos(v) * np.cos(u), e), yc + b * _spow(np.cos(v) * np.sin(u), e),
                    zc + c * _spow(np.sin(v), e)], axis=-1)
    rows, cols = u.shape
    idx = np.arange(rows * cols).reshape(rows, cols)
    a0, a1, b0, b1 = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    tris = np.concatenate([np.stack([a0, a1, b1], 1), np.stack([a0, b1, b0], 1)])
    return pts.reshape(-1, 3), tris


def superellipse(center: tuple[float, float], semi: tuple[float, float], p: int, n: int = 96) -> np.ndarray:
    """(n, 2) closed outline of |u/a|^p + |v/b|^p = 1 (a rectangle from :data:`BOX_EXPONENT` on)."""
    (uc, vc), (a, b) = center, semi
    if p >= BOX_EXPONENT:
        return np.array([[uc - a, vc - b], [uc + a, vc - b], [uc + a, vc + b], [uc - a, vc + b], [uc - a, vc - b]])
    th = np.linspace(0.0, 2.0 * np.pi, n)
    return np.column_stack([uc + a * _spow(np.cos(th), 2.0 / p), vc + b * _spow(np.sin(th), 2.0 / p)])


def projection(ob: Superquadric, axes: tuple[int, int]) -> np.ndarray:
    """Outline of the obstacle's shadow on the plane of ``axes`` (its footprint for (0, 1))."""
    return superellipse((ob.center[axes[0]], ob.center[axes[1]]), (ob.semi_axes[axes[0]], ob.semi_axes[axes[1]]), ob.p)


def section(ob: Superquadric, axes: tuple[int, int], value: float) -> np.ndarray | None:
    """Outline of the cut by the plane {third axis = value}, or None where the plane misses it."""
    k = 3 - sum(axes)
    r = abs((value - ob.center[k]) / ob.semi_axes[k])
    if r >= 1.0:
        return None
    scale = (1.0 - r ** ob.p) ** (1.0 / ob.p)
    semi = (ob.semi_axes[axes[0]] * scale, ob.semi_axes[axes[1]] * scale)
    return superellipse((ob.center[axes[0]], ob.center[axes[1]]), semi, ob.p)


def gate_outline(gate: Gate) -> np.ndarray:
    """(5, 3) closed rectangle of the gate's hole in 3-D."""
    (a0, a1), (b0, b1) = gate.bounds
    u, v = gate.other_axes
    pts = np.zeros((5, 3))
    pts[:, gate.axis] = gate.position
    pts[:, u] = [a0, a1, a1, a0, a0]
    pts[:, v] = [b0, b0, b1, b1, b0]
    return pts
