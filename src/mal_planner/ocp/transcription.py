"""LGR transcription of a :class:`Problem` on fixed phase meshes into one CasADi/IPOPT NLP.

Per phase the decision vector holds the (scaled) states at all ``Nk`` nodes, the (scaled)
controls at the ``Nc`` collocation nodes, then ``t0`` and ``tf``.  With
``t = t0 + (tf - t0)(tau + 1)/2`` and a segment spanning the fraction ``h`` of the phase,
the collocation constraint of each segment is ``D X = (tf - t0)/2 * h * f``; it is built
for all segments at once with a block-sparse D and one mapped dynamics call, so the graph
contains no per-node Python structure.

Path constraints are enforced at every collocation node and at the phase end point; the
end point uses the control of the last collocation node (Radau has no control there).
This keeps e.g. altitude limits valid at phase boundaries where linkages join phases.

The rows are assembled in :mod:`mal_planner.ocp.assembly`; the derivatives IPOPT gets in
:mod:`mal_planner.ocp.derivatives`.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from .assembly import (
    NLPParts,
    PhaseSlots,
    add_collocation,
    add_control_rows,
    add_duration,
    add_events,
    add_linkages,
    add_midpoints,
    declare_phase,
    phase_endpoint,
)
from .derivatives import structured_derivatives
from .functions import column
from .guess import GuessSource, sample_guess
from .nodes import NodeFunctions, midpoint_functions, node_functions
from .problem import Endpoints, PhaseGuess, PhaseMesh, Problem
from .watch import IterationWatch


@dataclass
class NLPResult:
    w: np.ndarray
    objective: float
    status: str
    success: bool
    iterations: int
    solve_time: float
    lam_g: np.ndarray


class Transcription:
    """The NLP of ``problem`` on ``meshes``; build once, then :meth:`solve` many times.

    With ``nodes`` (one :class:`NodeFunctions` per phase) IPOPT gets the constraint Jacobian and the Hessian of
    the Lagrangian assembled from the nodes' own derivatives (see :mod:`mal_planner.ocp.nodes`); without,
    CasADi differentiates the whole NLP.
    """

    def __init__(
        self,
        problem: Problem,
        meshes: Sequence[PhaseMesh],
        funcs: Sequence[ca.Function],
        solver_options: dict[str, Any],
        watch: IterationWatch | None = None,
        nodes: Sequence[NodeFunctions] | None = None,
        midpoints: Sequence[NodeFunctions | None] | None = None,
    ) -> None:
        t_start = time.perf_counter()
        self.problem = problem
        self.meshes = tuple(meshes)
        p = ca.MX.sym("p", problem.n_params)
        nlp = NLPParts()
        self.slots: list[PhaseSlots] = []
        endpoints, qs = [], []
        cost = ca.MX(0)
        for i_ph, (ph, mesh, fun) in enumerate(zip(problem.phases, self.meshes, funcs, strict=True)):
            slot, sym = declare_phase(nlp, ph, mesh)
            self.slots.append(slot)
            fns = nodes[i_ph] if nodes is not None else node_functions(ph, fun, problem.n_params)
            q = add_collocation(nlp, ph, slot, sym, fns, p)
            mid = midpoints[i_ph] if midpoints is not None else midpoint_functions(ph, problem.n_params)
            if mid is not None:
                add_midpoints(nlp, ph, slot, sym, mid, p)
            add_control_rows(nlp, ph, slot, sym)
            add_duration(nlp, ph, slot, sym)
            endpoints.append(phase_endpoint(slot, sym, q))
            qs.append(q)
            if problem.lagrange_in_cost and ph.lagrange is not None:
                cost = cost + q

        ends = Endpoints(endpoints, [ph.name for ph in problem.phases])
        mayer = column(problem.mayer(ends, p)) if problem.mayer is not None else ca.MX(0)
        cost = cost + mayer
        if problem.events is not None:
            add_events(nlp, problem, ends, p)
        add_linkages(nlp, problem, ends, self.slots)
        self._make_solver(nlp, p, cost, mayer, qs, solver_options, watch, structured=nodes is not None)
        self.build_time = time.perf_counter() - t_start

    def _make_solver(self, nlp: NLPParts, p: ca.MX, cost: ca.MX, mayer: ca.MX, qs: list[ca.MX],
                     solver_options: dict[str, Any], watch: IterationWatch | None, structured: bool) -> None:
        """The bound vectors, the phase integrals' function and the nlpsol of the assembled NLP."""
        problem = self.problem
        self.n_w = nlp.nw
        self.lbw = np.concatenate([np.asarray(a, dtype=float) for a in nlp.lbw])
        self.ubw = np.concatenate([np.asarray(a, dtype=float) for a in nlp.ubw])
        self.lbg = np.concatenate(nlp.lbg)
        self.ubg = np.concatenate(nlp.ubg)
        w = ca.vertcat(*nlp.w)
        g = ca.vertcat(*nlp.g)
        if not problem.objective_scale > 0.0:
            raise ValueError("objective_scale must be > 0")
        self.objective_scale = float(problem.objective_scale)
        nlp_dict = {"x": w, "p": p, "f": cost / self.objective_scale, "g": g}
        self.integrals = ca.Function("integrals", [w, p], [ca.vertcat(*qs)])
        options = dict(solver_options)
        if structured:
            options.update(structured_derivatives(nlp, w, p, g, mayer, nlp_dict["f"], self.objective_scale,
                                                  problem.lagrange_in_cost))
        if watch is not None:
            self._watch_fn = watch.function(nlp.nw, int(self.lbg.size), problem.n_params)
            options["iteration_callback"] = self._watch_fn
        self.solver = ca.nlpsol("ocp", "ipopt", nlp_dict, options)

    # ------------------------------------------------------------------ guesses
    def initial_guess(self, guesses: Sequence[PhaseGuess | None] | GuessSource | None) -> np.ndarray:
        """Decision vector from per-phase samples (linear interp.) or a previous solution."""
        w0 = np.zeros(self.n_w)
        for i, (ph, sl) in enumerate(zip(self.problem.phases, self.slots, strict=True)):
            lay = sl.layout
            if guesses is not None and hasattr(guesses, "interpolate"):
                t0, tf = guesses.phase_times(i)  # type: ignore[union-attr]
                tn = t0 + (tf - t0) * (lay.tau + 1.0) / 2.0
                x, u = guesses.interpolate(i, tn)  # type: ignore[union-attr]
                x, u = x.T, u[: lay.n_col].T
            else:
                g = None if guesses is None else guesses[i]  # type: ignore[index]
                g = g if g is not None else ph.guess
                t0, tf, x, u = sample_guess(ph, g, lay)
            w0[sl.x] = (x / sl.sx[:, None]).ravel(order="F")
            w0[sl.u] = (u / sl.su[:, None]).ravel(order="F")
            w0[sl.t0], w0[sl.tf] = t0 / sl.st, tf / sl.st
            w0[sl.h] = (tf - t0) / 2.0 / sl.st
        return w0

    # ------------------------------------------------------------------ solve
    def solve(self, params: np.ndarray, w0: np.ndarray) -> NLPResult:
        t_start = time.perf_counter()
        res = self.solver(x0=w0, p=params, lbx=self.lbw, ubx=self.ubw, lbg=self.lbg, ubg=self.ubg)
        elapsed = time.perf_counter() - t_start
        st = self.solver.stats()
        return NLPResult(
            w=np.asarray(res["x"]).reshape(-1),
            objective=float(res["f"]) * self.objective_scale,
            status=str(st.get("return_status", "")),
            success=bool(st.get("success", False)),
            iterations=int(st.get("iter_count", -1)),
            solve_time=elapsed,
            lam_g=np.asarray(res["lam_g"]).reshape(-1),
        )

    def unpack(self, w: np.ndarray, phase: int) -> tuple[float, float, np.ndarray, np.ndarray]:
        """``(t0, tf, X (nx, Nk), U (nu, Nc))`` in physical units."""
        ph, sl = self.problem.phases[phase], self.slots[phase]
        nk, nc = sl.layout.n_nodes, sl.layout.n_col
        x = w[sl.x].reshape((ph.nx, nk), order="F") * sl.sx[:, None]
        u = w[sl.u].reshape((ph.nu, nc), order="F") * sl.su[:, None]
        return float(w[sl.t0]) * sl.st, float(w[sl.tf]) * sl.st, x, u
