"""What every landing optimizer shares: its options and its result (the joint and the sequential strategies alike)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from mal_planner.landing.layout import PhaseLayout
from mal_planner.landing.margins import SafetyMargins
from mal_planner.landing.pairs import PairScreen
from mal_planner.ocp import MeshIteration, OCPSolution
from mal_planner.trajectory import Trajectory

LANDING_IPOPT: dict = {
    # The initial guess is already close (the initializer's obstacle-free paths): start with a small
    # barrier and little push off the bounds. Measured on scenarios/thesis.yaml (benchmarks/bench_landing.py):
    # 61 -> 44 IPOPT iterations. AMD ordering and a smaller MUMPS workspace cut the time per iteration.
    "mu_init": 1e-4,
    "bound_push": 1e-5,
    "bound_frac": 1e-5,
    "mumps_pivot_order": 0,
    "mumps_mem_percent": 100,
}


@dataclass(frozen=True)
class LandingOptions:
    guess: Literal["initializer", "straight"] = "initializer"
    """Initial guess: the initializer's paths (the thesis's method) or naive straight lines."""
    fixed_landing_times: bool = True
    """Fix the landing times at the schedule's (the scenario's where it gives them); False: the optimizer
    chooses them, subject to the minimum spacing."""
    replanning: bool = False
    """The guesses are the previous plan (set by :class:`mal_planner.pipeline.Planner` on replans): an aircraft that
    finds no plan for its slot has most likely fallen behind that plan (gusts), so the sequential strategy's
    recovery 'later landing' comes first."""
    leave_out_failed: bool = False
    """Sequential strategy: an aircraft that finds no plan, recoveries included, is left out and the ones after it
    are planned without it (set by the Planner for partial plans: the service holds it and plans it later); False:
    the solve stops there."""
    segments: int = 4
    """Initial mesh without ``segment_turn_times``: this many segments per phase ..."""
    degree: int = 6
    """... of this many collocation points each."""
    segment_turn_times: float | None = 4.0
    """About one initial segment per this many turn times of (guessed) phase duration (thesis: one per 20 s);
    None: ``segments`` in every phase. Short phases then start on small meshes (measured: thesis 3.5 -> 2.2 s,
    five aircraft 15 -> 7 s)."""
    mesh_tol: float = 1e-5
    """The hp refinement's tolerance on the relative state error of each segment (states scaled by the turn radius).
    The published paths then deviate from the flown ones by about 5e-5 nm (thesis and terminal area alike), a
    hundredth of the verification's accuracy; at 1e-4 a terminal-area plan drifted 0.018 nm and left the airspace
    by 0.0009 nm (its margin is a fifth of the accuracy), and 1e-6 costs a mesh iteration more (formerly the
    default)."""
    n_min: int = 3
    n_max: int = 10
    max_mesh_iterations: int = 8
    nlp_tol: float = 1e-8
    max_nlp_iterations: int = 3000
    refine: bool = True
    output_dt: float | None = None
    """Sampling step (s) of the output trajectories (dense samples of the solution's interpolants); None: a round
    step near a thirtieth of the scenario's turn time (thesis: 0.25 s)."""
    control_tol: float = 1e-5
    """The published controls, linear between samples, stay this close (load factor) to the solution's control
    interpolant at every midpoint: where they do not, samples are added (see :func:`published_times`)."""
    margins: SafetyMargins = field(default_factory=SafetyMargins)
    """How much stricter than the scenario the NLP is (the verification allows no tolerance)."""
    ipopt: dict = field(default_factory=lambda: dict(LANDING_IPOPT))
    """IPOPT options on top of the engine's defaults (see LANDING_IPOPT)."""
    strategy: Literal["auto", "joint", "sequential"] = "auto"
    """joint: one NLP for all aircraft; sequential: one small NLP per aircraft in landing order against the
    fixed plans of those before it (:mod:`mal_planner.landing.sequential`); auto: sequential from
    ``sequential_from`` aircraft on, joint below (the thesis's 3 aircraft are planned jointly)."""
    sequential_from: int = 4
    sequential_max_iterations: int = 400
    """IPOPT iterations of one aircraft's NLP in the sequential strategy, at most: its solves take 20-100; one that
    runs on is stuck (a terminal-area case took 1,270 for a plan its recovery then found in 60)."""
    pair_screen: PairScreen | None = field(default_factory=PairScreen)
    """Separation constraints only for pairs that can come close (see :mod:`mal_planner.landing.pairs`);
    None: every pair in every phase."""


@dataclass
class LandingResult:
    success: bool
    status: str
    trajectories: list[Trajectory]
    """In landing order, with controls and phase indices."""
    gate_times: dict[str, float | None]
    landing_times: dict[str, float]
    objective: float
    solve_time: float
    build_time: float
    nlp_iterations: int
    mesh_history: list[MeshIteration]
    layout: PhaseLayout
    solution: OCPSolution
    phase_names: list[str] = field(default_factory=list)
    required_landing_times: dict[str, float] = field(default_factory=dict)
    """The landing times the problem was given (fixed mode), relative to the plan start."""
    parts: list[LandingResult] = field(default_factory=list)
    """Sequential decomposition: the per-aircraft results in landing order (empty for a joint solve)."""
    strategy: str = "joint"
    recoveries: list = field(default_factory=list)
    """Sequential decomposition: the recoveries tried (:class:`mal_planner.landing.recovery.Recovery`)."""
    left_out: tuple[str, ...] = ()
    """Sequential decomposition: aircraft left out for want of a plan (:attr:`LandingOptions.leave_out_failed`)."""

    def stats(self) -> dict:
        return {
            "success": self.success,
            "status": self.status,
            "strategy": self.strategy,
            "objective": self.objective,
            "solve_time_s": self.solve_time,
            "build_time_s": self.build_time,
            "nlp_iterations": self.nlp_iterations,
            "recoveries": [{"callsign": r.callsign, "recovery": r.name, "success": r.success, "seconds": r.seconds}
                           for r in self.recoveries],
            "phases": self.phase_names,
            "mesh_iterations": [
                {"iteration": m.iteration, "segments": list(m.segments), "degrees": [list(d) for d in m.degrees],
                 "max_error": m.max_error, "nlp_iterations": m.nlp_iterations, "nlp_time_s": m.nlp_time,
                 "build_time_s": m.build_time, "status": m.status}
                for m in self.mesh_history
            ],
        }
