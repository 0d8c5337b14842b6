"""Settings of the OCP solver and its hp mesh refinement."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from .solution import MeshIteration


@dataclass
class OCPOptions:
    """Solver and mesh-refinement settings.

    ``ipopt`` entries override the defaults below (keys without the ``ipopt.`` prefix).
    The monotone barrier strategy is the default because the adaptive one was measured
    ~30x slower on the landing problem.  Solves started from a previous solution (mesh
    iterations >= 1, or ``guess=<OCPSolution>``) use NLPs built with ``warm_ipopt`` added,
    which start IPOPT near the barrier's end (about 2x fewer iterations); if such a warm
    solve fails, the cold NLP is tried from the same guess.  ``warm_ipopt={}`` disables it.
    """

    tol: float = 1e-8
    max_iter: int = 3000
    ipopt: dict[str, Any] = field(default_factory=dict)
    refine: bool = True
    mesh_tol: float = 1e-6
    n_min: int = 3
    n_max: int = 10
    max_mesh_iterations: int = 10
    max_segments: int = 64
    warm_ipopt: dict[str, Any] = field(
        default_factory=lambda: {"mu_init": 1e-5, "bound_push": 1e-6, "bound_frac": 1e-6}
    )
    callback: Callable[[MeshIteration], None] | None = None
    structured_derivatives: bool = True
    """Give IPOPT the constraint Jacobian and the Lagrangian's Hessian assembled from each node's own derivatives
    (:mod:`mal_planner.ocp.nodes`); False: CasADi differentiates the whole NLP (the same numbers, slower)."""
    control_overshoot_tol: float | None = None
    """Split the segments whose control interpolant passes the control bounds (or ``control_path``'s) by more
    than this anywhere between the points where the NLP holds them (controls' units; None: no check). A caller
    whose bounds are a margin inside hard limits sets the margin: the interpolant then never passes the limits."""
    cached_nlps: int = 3
    """NLPs kept for re-solves (least recently used dropped): a replan reuses the final mesh's; the
    intermediate meshes of a refinement would otherwise hold memory (20 aircraft: ~300 MB each)."""

    def nlpsol_options(self, warm: bool = False) -> dict[str, Any]:
        """CasADi ``nlpsol`` options; ``warm`` adds ``warm_ipopt`` (small initial barrier)."""
        ip = {
            "mu_strategy": "monotone",
            "linear_solver": "mumps",
            "print_level": 0,
            "tol": self.tol,
            "max_iter": self.max_iter,
            "sb": "yes",
        }
        ip.update(self.ipopt)
        if warm:
            ip.update(self.warm_ipopt)
        opts: dict[str, Any] = {f"ipopt.{k}": v for k, v in ip.items()}
        opts["print_time"] = False
        return opts
