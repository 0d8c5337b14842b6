"""The meshes a re-solve starts on: cut around the places a verification found violated, or with the part of a
plan already flown cut off."""

from __future__ import annotations

from collections.abc import Sequence

from mal_planner.ocp import OCPSolution, PhaseMesh

REFINE_PAD_TURN_TIMES = 1.0 / 7.5
"""A verification-driven refinement cuts a new segment this far around a violation (thesis: 1 s)."""


def split_segments(mesh: PhaseMesh, t0: float, tf: float, times: Sequence[float], pad_s: float) -> PhaseMesh:
    """The phase ``[t0, tf]``'s mesh with a new segment (same degree) around the times in each segment that
    contains some: from the first to the last of them, ``pad_s`` wider on each side (a cut closer than
    ``pad_s / 2`` to the segment's end is left out); a segment the times (nearly) cover is halved instead.

    Halving alone was too slow where a path cuts an obstacle's corner between collocation points: three
    rounds left points about 1 s apart at a 20 s segment's centre, and the chord still cut 0.05 nm into a
    no-fly zone (campaign traffic-0128); a short segment at the cut puts all its points there.
    """
    duration = tf - t0
    fractions = [(t - t0) / duration for t in times if t0 <= t <= tf] if duration > 0 else []
    pad = pad_s / duration if duration > 0 else 0.0
    breaks, degrees = [mesh.breaks[0]], []
    for s, n in enumerate(mesh.degrees):
        a, b = mesh.breaks[s], mesh.breaks[s + 1]
        inside = [f for f in fractions if a <= f <= b]
        if inside:
            cuts = [c for c in (min(inside) - pad, max(inside) + pad) if a + pad / 2 < c < b - pad / 2]
            for c in cuts or [0.5 * (a + b)]:
                breaks.append(c)
                degrees.append(n)
        breaks.append(b)
        degrees.append(n)
    return PhaseMesh(tuple(breaks), tuple(degrees))


MERGED_PIECE = 0.25
"""A segment cut by :func:`mesh_after` to less than this share of its width joins the next segment."""


def mesh_after(mesh: PhaseMesh, t0: float, tf: float, t: float) -> PhaseMesh:
    """The mesh of phase ``[t0, tf]`` with the part before ``t`` cut off, over ``[t, tf]``, once a whole segment lies
    before ``t`` (before that: the mesh itself).

    A replan starts on the previous plan's meshes: uncut, the segments of the part already flown squeezed into what
    is left (at ten aircraft the last replans solved 12 segments over 60 s where the first plan had 12 over 250 s).
    """
    duration = tf - t0
    f = (t - t0) / duration if duration > 0 else 0.0
    if f < mesh.breaks[1]:  # not a whole segment flown: the same mesh (a joint NLP on it is cached)
        return mesh
    if f >= 1.0:
        return PhaseMesh.uniform(1, mesh.degrees[-1])
    breaks, degrees = [0.0], []
    for s, n in enumerate(mesh.degrees):
        a, b = mesh.breaks[s], mesh.breaks[s + 1]
        if b <= f:
            continue
        if degrees and a > f:
            breaks.append((a - f) / (1.0 - f))
        if not degrees and a < f and (b - f) < MERGED_PIECE * (b - a) and s + 1 < len(mesh.degrees):
            continue  # a sliver: the next segment starts at the cut
        degrees.append(n)
    breaks.append(1.0)
    return PhaseMesh(tuple(breaks), tuple(degrees))


def meshes_after(solution: OCPSolution, t: float) -> list[PhaseMesh]:
    """:func:`mesh_after` for every phase of ``solution`` (an :class:`~mal_planner.ocp.solution.OCPSolution`)."""
    return [mesh_after(p.layout.mesh, p.t0, p.tf, t) for p in solution.phases]
