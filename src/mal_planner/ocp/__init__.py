"""General multi-phase optimal control on CasADi + IPOPT (GPOPS-II style).

Legendre-Gauss-Radau collocation on per-phase meshes with hp-adaptive refinement
(Patterson, Hager & Rao 2015).  Independent of the aircraft model.

The NLP is assembled from CasADi SX (so ``expand`` is implicit) and cached per mesh:
re-solving with new parameter values ``p`` or a new guess does not rebuild it.

Example (two phases, parameter = initial state, linkage, event)::

    import casadi as ca
    from mal_planner.ocp import OCPSolver, Phase, PhaseGuess, Problem

    def di(name, **kw):
        return Phase(name=name, states=["x", "v"], controls=["u"],
                     dynamics=lambda x, u, t, p: ca.vertcat(x[1], u[0]),
                     lagrange=lambda x, u, t, p: 0.5 * u[0] ** 2, **kw)

    a = di("a", t0_bounds=(0, 0), tf_bounds=(0.1, 0.9),
           guess=PhaseGuess(t=[0, 0.5], x=[[0, 1], [0.1, 0]], u=[[0], [0]]))
    b = di("b", tf_bounds=(1, 1), final_state_lb=[0, -1], final_state_ub=[0, -1],
           guess=PhaseGuess(t=[0.5, 1], x=[[0.1, 0], [0, -1]], u=[[0], [0]]))
    prob = Problem(phases=[a, b], n_params=2,
                   events=lambda E, p: E["a"].x0 - p, events_lb=0.0, events_ub=0.0)
    prob.link("a", "b")                      # x, v and time continuous
    solver = OCPSolver(prob)
    sol = solver.solve(params=[0.0, 1.0])    # builds the NLP(s)
    sol2 = solver.solve(params=[0.2, 0.5])   # reuses them
    x, u = sol2.interpolate("b", [0.7, 0.8])
"""

from .lgr import diff_matrix, integration_matrix, lagrange_matrix, lgr_nodes, lgr_weights
from .options import OCPOptions
from .problem import Endpoint, Endpoints, Linkage, Phase, PhaseGuess, PhaseMesh, Problem
from .solution import MeshIteration, OCPSolution, PhaseSolution
from .solver import OCPSolver
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
