"""How much stricter than the scenario's minima the landing NLP is."""

from __future__ import annotations

import math
from dataclasses import dataclass

from mal_planner.scales import Scales

GATE_ROOM_SHARE = 0.5
"""The share of a hole's room (its half-size beyond the open-loop inset) that a flown plan's gate event may give to
its aircraft's stray (a terminal area's 0.175-nm-high hole: 0.03 nm; a 3.8-nm-wide one: the whole 0.15-nm replan
threshold)."""


@dataclass(frozen=True)
class SafetyMargins:
    """How much stricter than the scenario's minima the NLP is (the verifier allows no tolerance at all).

    Path constraints hold at the collocation points; between them, and after re-integrating the published
    controls, a trajectory that rides a constraint can cross it by a little. These margins keep that
    little on the safe side; where it is not enough the verification finds it and the mesh is refined.
    Lengths are in units of the scenario's path accuracy (:attr:`mal_planner.scales.Scales.accuracy_nm`,
    the verification's largest deviation between the published and the flown path: L / 60, 0.005 nm in the
    thesis, where these were tuned in nm); :meth:`in_nm` resolves them for one scenario.
    """

    separation: float = 2.0
    """Added to the minimum separation: each of the two published paths may be the accuracy off the flown one
    (thesis: 0.01 nm, about 18 m)."""
    obstacle: float = 2.0
    """Obstacles are inflated by this in every semi-axis (thesis: 0.01 nm)."""
    clearance: float = 1e-4
    """Lower bound of ln ||r||_p of the inflated obstacles at the collocation points (dimensionless)."""
    gate: float = 0.4
    """The gate event stays this far inside the hole's edges, beyond the obstacle margin (the wall pieces
    are rounded p-norm shapes; thesis: 0.002 nm)."""
    airspace: float = 0.2
    """The airspace is shrunk by this (thesis: 0.001 nm, about 2 m); the runway threshold is crossed this high
    above the floor (real approaches cross it at about 15 m), so the flown path never touches the ground early."""
    bank_rad: float = math.radians(0.5)
    """Taken off the bank-angle limit (the control interpolant overshoots a riding limit between its
    collocation points by up to about this; campaigns measured 0.2 deg past a 0.25 deg margin)."""
    load_factor: float = 1e-3
    """Taken off both ends of the load-factor limits (dimensionless)."""
    airspace_bulge: float | None = None
    """How far a path may pass the airspace less ``airspace`` (and the gate's plane, where a phase keeps it on one
    side) between its collocation points before the mesh refinement splits the segment; None: unchecked (open loop:
    the margin absorbs it, and the verification refines where the airspace itself is crossed). Plans that are flown
    keep the rest of the margin for the aircraft's stray (:func:`mal_planner.options.plan.tracking_margins`)."""
    zone: float = 0.0
    """Added to ``obstacle`` for obstacles with volume (no-fly zones; not the thin pieces of a wall, whose holes it
    would close). Open loop: none. Plans that are flown: the deviation an aircraft may stray before the service
    replans (:func:`mal_planner.options.plan.tracking_margins`)."""

    speed: float = 0.01
    """The share of each speed limit the NLP keeps free (the airspeed model: the calibrated airspeed's polynomial
    between the collocation points, and the verification's finer samples)."""
    ceiling: float | None = None
    """The ceiling's own margin (None: ``airspace``), for plans that are flown: the floor's is held down by the
    threshold's crossing height, the ceiling's is not (:func:`mal_planner.options.plan.tracking_margins`)."""
    spacing_s: float = 0.0
    """Added to every pair's landing spacing, in s (the sequencer's and the optimizer's; the verification checks
    the minimum). Open loop: none. Plans that are flown: the time the replan threshold takes on final
    (:func:`mal_planner.options.plan.tracking_margins`)."""

    def in_nm(self, scales: Scales) -> Margins:
        unit = scales.accuracy_nm
        return Margins(self.separation * unit, self.obstacle * unit, self.clearance, self.gate * unit,
                       self.airspace * unit, self.bank_rad, self.load_factor,
                       None if self.airspace_bulge is None else self.airspace_bulge * unit,
                       (self.obstacle + self.zone) * unit, self.speed,
                       None if self.ceiling is None else self.ceiling * unit)


@dataclass(frozen=True)
class Margins:
    """:class:`SafetyMargins` of one scenario, lengths in nm."""

    separation_nm: float
    obstacle_nm: float
    clearance: float
    gate_nm: float
    airspace_nm: float
    bank_rad: float
    load_factor: float
    airspace_bulge_nm: float | None = None
    zone_nm: float | None = None
    """The inflation of obstacles with volume (None: ``obstacle_nm``)."""
    speed_share: float = 0.0
    """:attr:`SafetyMargins.speed`."""
    ceiling_nm: float | None = None
    """:attr:`SafetyMargins.ceiling` (None: ``airspace_nm``)."""

    @property
    def top_nm(self) -> float:
        """How far below the ceiling plans stay."""
        return self.airspace_nm if self.ceiling_nm is None else self.ceiling_nm

    def inflation_nm(self, bulky: bool) -> float:
        """How much an obstacle's semi-axes are inflated: a thin wall piece by ``obstacle_nm``, one with volume by
        ``zone_nm``."""
        return self.zone_nm if bulky and self.zone_nm is not None else self.obstacle_nm

    @property
    def hole_nm(self) -> float:
        """How far inside the hole's edges the gate event is kept (at least; see :meth:`gate_inset_nm`)."""
        return self.obstacle_nm + self.gate_nm

    def gate_inset_nm(self, lo: float, hi: float) -> float:
        """How far inside the edges ``lo``, ``hi`` (nm, one axis) of a hole the gate event is kept: :attr:`hole_nm`,
        and for plans that are flown also the deviation an aircraft may stray before the service replans (the inflation
        of no-fly zones beyond ``obstacle_nm``), up to :data:`GATE_ROOM_SHARE` of the room the hole leaves. Twenty
        aircraft in closed loop (traffic-0031): a plan passed a 3.8-nm-wide hole 0.025 nm inside its edge, and its
        aircraft, 0.045 nm off it (under a third of the 0.15-nm replan threshold), touched the wall's side."""
        stray = 0.0 if self.zone_nm is None else self.zone_nm - self.obstacle_nm
        room = max(0.0, 0.5 * (hi - lo) - self.hole_nm)
        return self.hole_nm + min(stray, GATE_ROOM_SHARE * room)
