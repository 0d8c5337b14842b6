"""General multi-phase optimal control on CasADi + IPOPT (GPOPS-II style).

Legendre-Gauss-Radau collocation on per-phase meshes with hp-adaptive refinement
(Patterson, Hager & Rao 2015).  Independent of the aircraft model.
"""

from .lgr import diff_matrix, integration_matrix, lagrange_matrix, lgr_nodes, lgr_weights
from .problem import Endpoint, Endpoints, Linkage, Phase, PhaseGuess, PhaseMesh, Problem
from .solution import MeshIteration, OCPSolution, PhaseSolution
from .solver import OCPOptions, OCPSolver
from .transcription import Transcription

__all__ = [
    "Endpoint",
    "Endpoints",
    "Linkage",
    "MeshIteration",
    "OCPOptions",
    "OCPSolution",
    "OCPSolver",
    "Phase",
    "PhaseGuess",
    "PhaseMesh",
    "PhaseSolution",
    "Problem",
    "Transcription",
    "diff_matrix",
    "integration_matrix",
    "lagrange_matrix",
    "lgr_nodes",
    "lgr_weights",
]
