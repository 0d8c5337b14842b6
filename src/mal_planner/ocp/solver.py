"""OCPSolver: NLP caching per mesh and the hp mesh-refinement loop."""

from __future__ import annotations

import logging
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from .functions import bound_vector, column, phase_function
from .mesh import control_overshoot, estimate_errors, path_overshoot, refine, segment_errors, state_overshoot
from .nodes import midpoint_functions, node_functions
from .options import OCPOptions
from .problem import PhaseGuess, PhaseMesh, Problem
from .solution import MeshIteration, OCPSolution, PhaseSolution
from .transcription import NLPResult, Transcription
from .watch import IterationWatch

log = logging.getLogger("mal_planner.ocp")

INFEASIBLE = "Infeasible_Problem_Detected"
"""IPOPT's status when its restoration phase finds no point that satisfies the constraints (locally)."""

MeshKey = tuple


GuessArg = Sequence[PhaseGuess | None] | OCPSolution | None


@dataclass
class _Refinement:
    """What the mesh-refinement loop carries from one mesh iteration to the next."""

    visited: set[MeshKey] = field(default_factory=set)
    history: list[MeshIteration] = field(default_factory=list)
    total_time: float = 0.0
    total_iter: int = 0
    sol: OCPSolution | None = None
    """The last mesh iteration's solution."""
    best: OCPSolution | None = None
    """The successful iteration with the smallest mesh error."""
    best_iteration: int = -1
    best_bulging: int = 0
    converged: bool = False


def _first_output(f: ca.Function) -> ca.Function:
    args = f.sx_in()
    return ca.Function(f"{f.name()}_dyn", args, [f(*args)[0]])


class OCPSolver:
    """Solves a :class:`Problem`; NLPs are built once per mesh and cached.

    Re-solving with new parameter values or guesses reuses every NLP already built for
    the meshes visited (``n_builds`` counts constructions).
    """

    def __init__(self, problem: Problem, options: OCPOptions | None = None) -> None:
        self.problem = problem
        self.options = options or OCPOptions()
        self._funcs = [phase_function(ph, problem.n_params) for ph in problem.phases]
        self._nodes = ([node_functions(ph, f, problem.n_params) for ph, f in zip(problem.phases, self._funcs,
                                                                                 strict=True)]
                       if self.options.structured_derivatives else None)
        self._midpoints = [midpoint_functions(ph, problem.n_params) for ph in problem.phases]
        self._f_only = [_first_output(f) for f in self._funcs]
        self._f_maps: dict[tuple[int, int], ca.Function] = {}
        self._state_scales = [ph.scales()[0] for ph in problem.phases]
        """The error estimate works on the states as the NLP sees them (divided by their scales), so that its
        relative error means the same in a scenario of any size."""
        self._control_paths = [_control_path_eval(ph) for ph in problem.phases]
        self._cache: OrderedDict[MeshKey, Transcription] = OrderedDict()
        self._nlp_opts = {False: self.options.nlpsol_options(), True: self.options.nlpsol_options(True)}
        self.n_builds = 0
        self.watch = IterationWatch()

    # ------------------------------------------------------------------ caching
    def transcription(self, meshes: Sequence[PhaseMesh], warm: bool = False) -> tuple[Transcription, bool]:
        """Cached NLP for ``meshes`` (cold or warm-start options); also whether it was built now."""
        warm = warm and bool(self.options.warm_ipopt)
        key = (tuple(m.key() for m in meshes), warm)
        tr = self._cache.get(key)
        if tr is not None:
            self._cache.move_to_end(key)
            return tr, False
        tr = Transcription(self.problem, meshes, self._funcs, self._nlp_opts[warm], self.watch, self._nodes,
                           self._midpoints)
        self._cache[key] = tr
        while len(self._cache) > self.options.cached_nlps:  # the meshes passed on the way stay cheap to drop
            self._cache.popitem(last=False)
        self.n_builds += 1
        return tr, True

    def _dynamics_eval(self, phase: int, params: np.ndarray) -> Callable[..., np.ndarray]:
        """The phase's dynamics on scaled states (columns): what the error estimate integrates."""
        scale = self._state_scales[phase][:, None]

        def f_eval(x: np.ndarray, u: np.ndarray, t: np.ndarray) -> np.ndarray:
            k = t.size
            fm = self._f_maps.get((phase, k))
            if fm is None:
                fm = self._f_maps[(phase, k)] = self._f_only[phase].map(k)
            return np.asarray(fm(x * scale, u, t.reshape(1, -1), params)).reshape(x.shape[0], k) / scale

        return f_eval

    # ------------------------------------------------------------------ solve
    def solve(
        self,
        params: Sequence[float] | np.ndarray | None = None,
        guess: GuessArg = None,
        meshes: Sequence[PhaseMesh] | None = None,
        refine_mesh: bool | None = None,
        warm: bool | None = None,
        deadline: Any = None,
        retry_infeasible: bool = True,
    ) -> OCPSolution:
        """Solve, refining the mesh until the error estimate is below ``mesh_tol``.

        ``guess`` is a list of per-phase :class:`PhaseGuess` (``None`` entries use the
        phase's own guess) or a previous :class:`OCPSolution` (polynomial warm start).
        ``meshes`` overrides the phases' initial meshes (e.g. ``previous.meshes``). ``warm`` forces the
        warm-start IPOPT options on (or off) for the first solve, e.g. for a guess built from a previous
        solution shifted in time; by default they are used when ``guess`` is an :class:`OCPSolution`.
        ``deadline`` (an object with ``expired()``) stops IPOPT and the refinement when it expires; the
        best successful mesh iteration so far is returned. ``retry_infeasible=False``: a warm solve that IPOPT finds
        locally infeasible is not retried cold (a caller with a surer recovery for it, such as a replan's later
        landing, saves the second infeasible solve).
        """
        opt = self.options
        do_refine = opt.refine if refine_mesh is None else refine_mesh
        p = self._parameters(params)
        cur = tuple(meshes) if meshes is not None else tuple(ph.mesh for ph in self.problem.phases)
        run = _Refinement()
        src: GuessArg = guess
        previous: list = [None] * len(cur)  # per phase, the segment errors of the last iteration
        self.watch.start(deadline)
        for it in range(opt.max_mesh_iterations + 1):
            if it > 0 and deadline is not None and deadline.expired():
                log.warning("time limit reached after %d mesh iterations", it)
                break
            run.visited.add(tuple(m.key() for m in cur))
            warm_now = isinstance(src, OCPSolution) if warm is None or it > 0 else warm
            sol, errors, bulges = self._mesh_iteration(it, cur, src, p, warm_now, retry_infeasible, run)
            if not sol.nlp_success:
                break
            n_bulging = sum(int(b.sum()) for b in bulges)
            if run.best is None or sol.max_error <= run.best.max_error:
                run.best, run.best_iteration, run.best_bulging = sol, it, n_bulging
            if sol.max_error <= opt.mesh_tol and not n_bulging:
                run.converged = True
                break
            if not do_refine:
                break
            step = self._refined(it, cur, errors, previous, bulges, run)
            if step is None:
                break
            cur, previous = step
            src = sol
        return self._outcome(run, do_refine)

    def _parameters(self, params: Sequence[float] | np.ndarray | None) -> np.ndarray:
        p = np.zeros(self.problem.n_params) if params is None else np.asarray(params, dtype=float).reshape(-1)
        if p.size != self.problem.n_params:
            raise ValueError(f"expected {self.problem.n_params} parameters, got {p.size}")
        return p

    def _solve_nlp(self, cur: tuple[PhaseMesh, ...], src: GuessArg, p: np.ndarray, warm_now: bool,
                   retry_infeasible: bool, run: _Refinement) -> tuple[Transcription, NLPResult, float]:
        """One NLP solve on the meshes ``cur`` (a failed warm solve retried cold); also the NLP build time."""
        tr, built = self.transcription(cur, warm_now)
        build_time = tr.build_time if built else 0.0
        w0 = tr.initial_guess(src)
        res = tr.solve(p, w0)
        if (not res.success and warm_now and self.options.warm_ipopt and not self.watch.stopped
                and (retry_infeasible or res.status != INFEASIBLE)):
            log.info("warm-started NLP failed (%s); retrying cold", res.status)
            run.total_time += res.solve_time
            run.total_iter += res.iterations
            tr, built = self.transcription(cur, False)
            build_time += tr.build_time if built else 0.0
            res = tr.solve(p, w0)
        run.total_time += res.solve_time
        run.total_iter += res.iterations
        return tr, res, build_time

    def _mesh_iteration(self, it: int, cur: tuple[PhaseMesh, ...], src: GuessArg, p: np.ndarray, warm_now: bool,
                        retry_infeasible: bool, run: _Refinement
                        ) -> tuple[OCPSolution, tuple[np.ndarray, ...], list[np.ndarray]]:
        """Solve on ``cur`` and assess the solution: per phase its segment errors and the segments whose
        interpolants pass a bound; the iteration is logged and recorded in ``run``."""
        tr, res, build_time = self._solve_nlp(cur, src, p, warm_now, retry_infeasible, run)
        sol = self._make_solution(tr, res, p)
        errors = tuple(
            estimate_errors(ps.layout, ps.t0, ps.tf, ps.x.T / self._state_scales[i][:, None], ps.u[:-1].T,
                            self._dynamics_eval(i, p))
            for i, ps in enumerate(sol.phases)
        )
        max_err = max((float(e.max()) for e in errors if e.size), default=0.0)
        bulges = [b | cut for b, cut in zip(self._bulging_segments(sol), self._cutting_segments(sol, p),
                                             strict=True)]
        rec = MeshIteration(
            iteration=it,
            segments=tuple(m.n_segments for m in cur),
            degrees=tuple(m.degrees for m in cur),
            max_error=max_err,
            errors=errors,
            nlp_iterations=res.iterations,
            nlp_time=res.solve_time,
            build_time=build_time,
            status=res.status,
            nlp_success=res.success,
        )
        run.history.append(rec)
        run.sol = sol
        n_bulging = sum(int(b.sum()) for b in bulges)
        log.info(
            "mesh iter %d: segments=%s degrees=%s max_err=%.3e%s nlp_iter=%d nlp_time=%.3fs build=%.3fs %s",
            it,
            rec.segments,
            rec.degrees,
            max_err,
            f" segments_past_bounds={n_bulging}" if n_bulging else "",
            res.iterations,
            res.solve_time,
            rec.build_time,
            res.status,
        )
        if self.options.callback is not None:
            self.options.callback(rec)
        sol.max_error = max_err
        return sol, errors, bulges

    def _refined(self, it: int, cur: tuple[PhaseMesh, ...], errors: tuple[np.ndarray, ...], previous: list,
                 bulges: list[np.ndarray], run: _Refinement) -> tuple[tuple[PhaseMesh, ...], list] | None:
        """The next meshes and the segment errors they were refined from, or None when the refinement stops
        (stalled, back on a solved mesh, or too many segments)."""
        opt = self.options
        if it - run.best_iteration >= 2:
            log.info("mesh refinement stalled: no better error in 2 iterations; stopping")
            return None
        new = tuple(refine(m, e, opt.mesh_tol, opt.n_min, opt.n_max, before, split)
                    for m, e, before, split in zip(cur, errors, previous, bulges, strict=True))
        previous = [segment_errors(m, e) for m, e in zip(cur, errors, strict=True)]
        key = tuple(m.key() for m in new)
        if key in run.visited:
            log.warning("mesh refinement revisits a solved mesh; stopping")
            return None
        if any(m.n_segments > opt.max_segments for m in new):
            log.warning("mesh refinement exceeds max_segments=%d; stopping", opt.max_segments)
            return None
        return new, previous

    def _outcome(self, run: _Refinement, do_refine: bool) -> OCPSolution:
        """The last mesh iteration's solution, or the best successful one when the refinement did not converge;
        with the effort of all of them."""
        opt = self.options
        sol, best = run.sol, run.best
        assert sol is not None
        if best is not None and (best is not sol or (do_refine and not run.converged)):
            # A later mesh iteration failed, or the refinement stopped above the tolerance: the best
            # successful iteration is the answer; its accuracy is reported, and the caller's independent
            # checks decide whether it is good enough.
            # Not converged means the error is above the tolerance or segments still pass the bounds.
            past = f", {run.best_bulging} segments past the bounds" if run.best_bulging else ""
            log.warning("mesh refinement stopped at error %.2e (tolerance %.0e%s); keeping mesh iteration %d",
                        best.max_error, opt.mesh_tol, past, run.best_iteration)
            sol = best
            sol.status = f"{sol.status} (mesh error {sol.max_error:.1e}, tolerance {opt.mesh_tol:.0e}{past})"
        sol.mesh_history = run.history
        sol.iterations = run.total_iter
        sol.solve_time = run.total_time
        sol.mesh_converged = run.converged
        sol.success = sol.nlp_success
        return sol

    def _bulging_segments(self, sol: OCPSolution) -> list[np.ndarray]:
        """Per phase, the segments whose control interpolant passes a bound by more than the tolerance."""
        tol = self.options.control_overshoot_tol
        out = []
        for ph, ps, path in zip(self.problem.phases, sol.phases, self._control_paths, strict=True):
            if tol is None or not ph.nu:
                out.append(np.zeros(ps.layout.mesh.n_segments, bool))
                continue
            b = ph.bounds()
            over = control_overshoot(ps.layout, ps.u[:-1], b["u_lb"], b["u_ub"], *path)
            out.append(over > tol)
        return out

    def _cutting_segments(self, sol: OCPSolution, params: np.ndarray) -> list[np.ndarray]:
        """Per phase, the segments whose interpolants pass a path bound by more than the phase's
        ``path_overshoot_tol``, or a state bound by more than its ``state_overshoot_tol``, between the points where
        the NLP holds it."""
        out = []
        for i, (ph, ps) in enumerate(zip(self.problem.phases, sol.phases, strict=True)):
            flags = np.zeros(ps.layout.mesh.n_segments, bool)
            x_tol = bound_vector(ph.state_overshoot_tol, ph.nx, np.inf)
            if np.any(np.isfinite(x_tol)):
                b = ph.bounds()
                flags |= np.any(state_overshoot(ps.layout, ps.x, b["x_lb"], b["x_ub"]) > x_tol, axis=1)
            tol = bound_vector(ph.path_overshoot_tol, self._funcs[i].size1_out(2), np.inf)
            if not np.any(np.isfinite(tol)):
                out.append(flags)
                continue

            def path(x: np.ndarray, u: np.ndarray, t: np.ndarray, i: int = i) -> np.ndarray:
                return np.asarray(self._funcs[i].map(t.size)(x, u, t.reshape(1, -1), params)[2])

            b_lb = bound_vector(ph.path_lb, tol.size, -np.inf)
            b_ub = bound_vector(ph.path_ub, tol.size, np.inf)
            out.append(flags | path_overshoot(ps.layout, ps.t0, ps.tf, ps.x, ps.u[:-1], path, b_lb, b_ub,
                                              np.where(np.isfinite(tol), tol, np.inf)))
        return out

    def _make_solution(self, tr: Transcription, res, params: np.ndarray) -> OCPSolution:
        phases = []
        q = np.asarray(tr.integrals(res.w, params)).reshape(-1)
        for i, ph in enumerate(self.problem.phases):
            t0, tf, x, u = tr.unpack(res.w, i)
            lay = tr.slots[i].layout
            t = t0 + (tf - t0) * (lay.tau + 1.0) / 2.0
            u_all = np.hstack([u, u[:, -1:]]) if u.shape[1] else np.zeros((ph.nu, lay.n_nodes))
            phases.append(PhaseSolution(ph.name, t0, tf, t, x.T.copy(), u_all.T.copy(), float(q[i]), lay))
        return OCPSolution(
            phases=phases,
            objective=res.objective,
            status=res.status,
            success=res.success,
            nlp_success=res.success,
            mesh_converged=False,
            iterations=res.iterations,
            solve_time=res.solve_time,
            max_error=float("nan"),
            w=res.w,
        )


def _control_path_eval(phase) -> tuple:
    """(path, lb, ub): the phase's ``control_path`` as a numeric function of (nu, K) controls, or (None,)."""
    if phase.control_path is None or not phase.nu:
        return (None,)
    u = ca.SX.sym("u", phase.nu)
    fun = ca.Function(f"{phase.name}_control_path", [u], [column(phase.control_path(u))])
    n = fun.size1_out(0)

    def path(v: np.ndarray) -> np.ndarray:
        return np.asarray(fun.map(v.shape[1])(v))

    return path, bound_vector(phase.control_path_lb, n, -np.inf), bound_vector(phase.control_path_ub, n, np.inf)
