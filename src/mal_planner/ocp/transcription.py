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
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import casadi as ca
import numpy as np

from .mesh import MeshLayout, between_matrix, layout
from .nodes import NodeFunctions, midpoint_functions, node_functions, scatter
from .problem import Endpoint, Endpoints, Phase, PhaseGuess, PhaseMesh, Problem

_log = logging.getLogger("mal_planner.ocp")


class GuessSource(Protocol):
    """Anything that can be sampled like a previous solution (used for warm starts)."""

    def phase_times(self, phase: int) -> tuple[float, float]: ...

    def interpolate(self, phase: int, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


def _col(value: object) -> ca.SX:
    if isinstance(value, list | tuple):
        return ca.vertcat(*value) if value else ca.SX(0, 1)
    return value if isinstance(value, (ca.SX, ca.MX)) else ca.DM(value)


def phase_function(phase: Phase, n_params: int) -> ca.Function:
    """``(x, u, t, p) -> (xdot, lagrange, path)`` as one SX Function, built once per phase."""
    x = ca.SX.sym("x", phase.nx)
    u = ca.SX.sym("u", phase.nu)
    t = ca.SX.sym("t")
    p = ca.SX.sym("p", n_params)
    xdot = _col(phase.dynamics(x, u, t, p))
    if xdot.shape != (phase.nx, 1):
        raise ValueError(f"phase {phase.name!r}: dynamics must return {phase.nx} values, got {xdot.shape}")
    lag = _col(phase.lagrange(x, u, t, p)) if phase.lagrange else ca.SX(0)
    path = _col(phase.path(x, u, t, p)) if phase.path else ca.SX(0, 1)
    return ca.Function(f"{phase.name}_f", [x, u, t, p], [xdot, lag, path], ["x", "u", "t", "p"], ["f", "l", "c"])


def _bounds(values: Sequence[float] | float | None, n: int, default: float) -> np.ndarray:
    if values is None:
        return np.full(n, default)
    return np.broadcast_to(np.asarray(values, dtype=float).reshape(-1), (n,)).copy()


@dataclass
class _PhaseSlots:
    layout: MeshLayout
    x: slice
    u: slice
    t0: int
    tf: int
    sx: np.ndarray
    su: np.ndarray
    h: slice
    st: float
    """The phase's time scale: t0, tf and the half-duration copies are stored divided by it."""


@dataclass
class NLPResult:
    w: np.ndarray
    objective: float
    status: str
    success: bool
    iterations: int
    solve_time: float
    lam_g: np.ndarray


class IterationWatch:
    """Sees every IPOPT iteration: stops the solve at a deadline and logs progress on long solves.

    One watch serves every NLP of a solver (they are cached); :attr:`deadline` is set per solve.
    """

    def __init__(self, log_every_s: float = 5.0) -> None:
        self.deadline: Any = None
        """An object with ``expired()`` (e.g. :class:`mal_planner.deadline.Deadline`), or None."""
        self.log_every_s = log_every_s
        self.iterations = 0
        self._started = 0.0
        self._last_log = 0.0
        self.stopped = False

    def start(self, deadline: Any) -> None:
        self.deadline, self.iterations, self.stopped = deadline, 0, False
        self._started = self._last_log = time.perf_counter()

    def __call__(self, objective: float) -> int:
        """0 to go on, 1 to stop IPOPT (it then returns User_Requested_Stop)."""
        self.iterations += 1
        now = time.perf_counter()
        if now - self._last_log >= self.log_every_s:
            _log.info("IPOPT: iteration %d, objective %.6g, %.0f s", self.iterations, objective, now - self._started)
            self._last_log = now
        if self.deadline is not None and self.deadline.expired():
            self.stopped = True
            return 1
        return 0

    def function(self, nx: int, ng: int, n_params: int) -> ca.Function:
        return _WatchCallback(self, nx, ng, n_params)


class _WatchCallback(ca.Callback):
    """CasADi's form of an IPOPT intermediate callback (inputs: nlpsol's outputs)."""

    def __init__(self, watch: IterationWatch, nx: int, ng: int, n_params: int) -> None:
        ca.Callback.__init__(self)
        self._watch, self._nx, self._ng, self._np = watch, nx, ng, n_params
        self.construct("watch", {})

    def get_n_in(self) -> int:
        return ca.nlpsol_n_out()

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return ca.nlpsol_out(i)

    def get_name_out(self, i: int) -> str:
        return "ret"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        name = ca.nlpsol_out(i)
        sizes = {"f": 1, "x": self._nx, "lam_x": self._nx, "g": self._ng, "lam_g": self._ng, "p": self._np,
                 "lam_p": self._np}
        return ca.Sparsity.dense(sizes.get(name, 0), 1) if name in sizes else ca.Sparsity(0, 0)

    def eval(self, arg: list) -> list:
        return [self._watch(float(arg[ca.nlpsol_out().index("f")]))]


@dataclass
class _NodeBlock:
    """One phase's node functions mapped over its nodes, with where their inputs and outputs sit in the NLP."""

    fns: NodeFunctions
    args: list
    """The mapped call's arguments (z, v, t0, tf, h, s, frac, w, p)."""
    rows: np.ndarray
    """(n_out, nk) NLP row of each output of each node (-1: none, e.g. the end node's defect)."""
    cols: np.ndarray
    """(n_in, nk) NLP variable of each differentiated input of each node (-1: none)."""


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
        w_parts: list[ca.MX] = []
        lbw: list[np.ndarray] = []
        ubw: list[np.ndarray] = []
        g_parts: list[ca.MX] = []
        lbg: list[np.ndarray] = []
        ubg: list[np.ndarray] = []
        endpoints: list[Endpoint] = []
        qs: list[ca.MX] = []
        self.slots: list[_PhaseSlots] = []
        lin: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # constant Jacobian entries (rows, cols, values)
        blocks: list[_NodeBlock] = []
        ad_rows: list[tuple[int, ca.MX]] = []  # other nonlinear rows: (first row, expression)
        nw = 0
        ng = 0
        cost = ca.MX(0)

        def add_g(expr: ca.MX, lo: np.ndarray, hi: np.ndarray) -> int:
            nonlocal ng
            g_parts.append(expr)
            lbg.append(np.asarray(lo, float).reshape(-1))
            ubg.append(np.asarray(hi, float).reshape(-1))
            first, ng = ng, ng + int(expr.numel())
            return first

        for i_ph, (ph, mesh, fun) in enumerate(zip(problem.phases, self.meshes, funcs, strict=True)):
            lay = layout(mesh)
            nx, nu, nk, nc = ph.nx, ph.nu, lay.n_nodes, lay.n_col
            b = ph.bounds()
            sx, su = ph.scales()
            st = float(ph.time_scale)
            z = ca.MX.sym(f"{ph.name}_x", nx, nk)
            v = ca.MX.sym(f"{ph.name}_u", nu, nc)
            t0_s = ca.MX.sym(f"{ph.name}_t0")
            tf_s = ca.MX.sym(f"{ph.name}_tf")
            # Half the phase duration, one copy per collocation point chained by equalities: each defect
            # row then depends on its own copy, not on t0/tf, which keeps the KKT matrix free of dense
            # columns (measured: 17x less fill-in in the factorisation on the landing problem).
            h_s = ca.MX.sym(f"{ph.name}_h", nc)
            w_parts += [ca.vec(z), ca.vec(v), t0_s, tf_s, h_s]
            x0_col, u0_col = nw, nw + nx * nk
            slot = _PhaseSlots(lay, slice(x0_col, u0_col), slice(u0_col, u0_col + nu * nc), u0_col + nu * nc,
                               u0_col + nu * nc + 1, sx, su, slice(u0_col + nu * nc + 2, u0_col + nu * nc + 2 + nc),
                               st)
            self.slots.append(slot)
            nw += nx * nk + nu * nc + 2 + nc
            t0, tf = st * t0_s, st * tf_s  # physical times

            xlb = np.tile((b["x_lb"] / sx)[:, None], (1, nk))
            xub = np.tile((b["x_ub"] / sx)[:, None], (1, nk))
            xlb[:, 0], xub[:, 0] = b["x0_lb"] / sx, b["x0_ub"] / sx
            xlb[:, -1], xub[:, -1] = b["xf_lb"] / sx, b["xf_ub"] / sx
            lbw += [xlb.ravel(order="F"), np.tile(b["u_lb"] / su, nc), [ph.t0_bounds[0] / st],
                    [ph.tf_bounds[0] / st], np.full(nc, -np.inf)]
            ubw += [xub.ravel(order="F"), np.tile(b["u_ub"] / su, nc), [ph.t0_bounds[1] / st],
                    [ph.tf_bounds[1] / st], np.full(nc, np.inf)]

            # The nonlinear terms, node by node: the defect's dynamics part, the path constraints, the integrand.
            fns = nodes[i_ph] if nodes is not None else node_functions(ph, fun, problem.n_params)
            args = [z, ca.horzcat(v, v[:, nc - 1]) if nu else ca.MX(0, nk), t0_s, tf_s,
                    ca.horzcat(h_s.T, ca.MX(1, 1)), ca.DM((lay.tau + 1.0) / 2.0).T, ca.DM(np.append(lay.frac, 0.0)).T,
                    ca.DM(np.append(lay.w, 0.0)).T, p]
            out_all, q_all = fns.out.map(nk)(*args)

            h_row = add_g(ca.vertcat(h_s[0] - (tf_s - t0_s) / 2.0, h_s[1:] - h_s[:-1]), np.zeros(nc), np.zeros(nc))
            hc = slot.h.start + np.arange(nc)
            lin.append((np.concatenate([[h_row] * 3, h_row + np.repeat(np.arange(1, nc), 2)]),
                        np.concatenate([[hc[0], slot.tf, slot.t0], np.column_stack([hc[1:], hc[:-1]]).ravel()]),
                        np.concatenate([[1.0, -0.5, 0.5], np.tile([1.0, -1.0], nc - 1)])))
            defect = ca.mtimes(z, lay.D.T) + out_all[:nx, :nc]
            d_row = add_g(ca.vec(defect), np.zeros(nx * nc), np.zeros(nx * nc))
            dk, dj = np.nonzero(np.asarray(ca.DM(lay.D)))
            dv = np.asarray(ca.DM(lay.D))[dk, dj]
            comp = np.arange(nx)
            lin.append(((d_row + dk[:, None] * nx + comp).ravel(), (x0_col + dj[:, None] * nx + comp).ravel(),
                        np.repeat(dv, nx)))
            q = ca.sum2(q_all)
            npath = fns.n_path
            p_row = ng
            if npath:
                sp = _bounds(ph.path_scale, npath, 1.0)
                if np.any(sp <= 0.0):
                    raise ValueError(f"phase {ph.name!r}: path_scale must be positive")
                add_g(ca.vec(out_all[nx:, :]), np.tile(_bounds(ph.path_lb, npath, -np.inf) / sp, nk),
                      np.tile(_bounds(ph.path_ub, npath, np.inf) / sp, nk))
            k = np.arange(nk)
            rows = np.full((nx + npath, nk), -1)
            rows[:nx, :nc] = d_row + k[None, :nc] * nx + comp[:, None]
            rows[nx:, :] = p_row + k[None, :] * npath + np.arange(npath)[:, None]
            cols = np.full((nx + nu + 3, nk), -1)
            cols[:nx, :] = x0_col + k[None, :] * nx + comp[:, None]
            cols[nx:nx + nu, :] = u0_col + np.minimum(k, nc - 1)[None, :] * nu + np.arange(nu)[:, None]
            cols[nx + nu, :], cols[nx + nu + 1, :] = slot.t0, slot.tf
            cols[nx + nu + 2, :nc] = hc
            blocks.append(_NodeBlock(fns, args, rows, cols))
            mid = midpoints[i_ph] if midpoints is not None else midpoint_functions(ph, problem.n_params)
            if mid is not None:
                s_nodes = (lay.tau + 1.0) / 2.0
                pairs = [z[:, :-1], z[:, 1:], t0_s, tf_s, ca.DM(0.5 * (s_nodes[:-1] + s_nodes[1:])).T, p]
                scale = _bounds(ph.midpoint_path_scale, mid.n_out, 1.0)
                m_row = add_g(ca.vec(mid.out.map(nk - 1)(*pairs)),
                              np.tile(_bounds(ph.midpoint_path_lb, mid.n_out, -np.inf) / scale, nk - 1),
                              np.tile(_bounds(ph.midpoint_path_ub, mid.n_out, np.inf) / scale, nk - 1))
                kk = np.arange(nk - 1)
                m_cols = np.vstack([x0_col + kk[None, :] * nx + comp[:, None],
                                    x0_col + (kk[None, :] + 1) * nx + comp[:, None],
                                    np.full((1, nk - 1), slot.t0), np.full((1, nk - 1), slot.tf)])
                blocks.append(_NodeBlock(mid, pairs, m_row + kk[None, :] * mid.n_out + np.arange(mid.n_out)[:, None],
                                         m_cols))

            between = between_matrix(lay.mesh) if ph.bound_controls_between and nu else np.zeros((0, nc))
            if between.shape[0]:
                b_row = add_g(ca.vec(ca.mtimes(v, ca.sparsify(ca.DM(between.T)))),
                              np.tile(b["u_lb"] / su, between.shape[0]), np.tile(b["u_ub"] / su, between.shape[0]))
                bb, bj = np.nonzero(between)
                comp_u = np.arange(nu)
                lin.append(((b_row + bb[:, None] * nu + comp_u).ravel(), (u0_col + bj[:, None] * nu + comp_u).ravel(),
                            np.repeat(between[bb, bj], nu)))
            us = ca.mtimes(ca.diag(ca.DM(su)), v)
            if ph.control_path is not None and nu:
                u_sym = ca.SX.sym("u", nu)
                c_fun = ca.Function(f"{ph.name}_cu", [u_sym], [_col(ph.control_path(u_sym))])
                nc_rows = c_fun.size1_out(0)
                u_at = us if not between.shape[0] else ca.horzcat(us, ca.mtimes(us, ca.sparsify(ca.DM(between.T))))
                n_at = nc + between.shape[0]
                expr = ca.vec(c_fun.map(n_at)(u_at))
                ad_rows.append((add_g(expr, np.tile(_bounds(ph.control_path_lb, nc_rows, -np.inf), n_at),
                                      np.tile(_bounds(ph.control_path_ub, nc_rows, np.inf), n_at)), expr))
            dur_row = add_g(tf_s - t0_s, [ph.min_duration / st], [ph.max_duration / st])
            lin.append((np.array([dur_row, dur_row]), np.array([slot.tf, slot.t0]), np.array([1.0, -1.0])))
            xs = ca.mtimes(ca.diag(ca.DM(sx)), z)
            endpoints.append(Endpoint(t0, tf, xs[:, 0], xs[:, nk - 1], q))
            qs.append(q)
            if problem.lagrange_in_cost and ph.lagrange is not None:
                cost = cost + q

        ends = Endpoints(endpoints, [ph.name for ph in problem.phases])
        mayer = _col(problem.mayer(ends, p)) if problem.mayer is not None else ca.MX(0)
        cost = cost + mayer
        if problem.events is not None:
            ev = _col(problem.events(ends, p))
            se = _bounds(problem.events_scale, ev.numel(), 1.0)
            if np.any(se <= 0.0):
                raise ValueError("events_scale must be positive")
            expr = ev * ca.DM(1.0 / se)
            ad_rows.append((add_g(expr, _bounds(problem.events_lb, ev.numel(), -np.inf) / se,
                                  _bounds(problem.events_ub, ev.numel(), np.inf) / se), expr))
        for lk in problem.linkages:
            ia, ib = problem.phase_index(lk.phase_a), problem.phase_index(lk.phase_b)
            pa, pb = problem.phases[ia], problem.phases[ib]
            ea, eb = ends[ia], ends[ib]
            sa_slot, sb_slot = self.slots[ia], self.slots[ib]
            rows_, r_i, c_i, vals = [], [], [], []
            for sa, sb in lk.pairs:
                ja, jb = list(pa.states).index(sa), list(pb.states).index(sb)
                scale = float(sb_slot.sx[jb])
                rows_.append((ea.xf[ja] - eb.x0[jb]) / scale)
                last_a = sa_slot.x.start + (sa_slot.layout.n_nodes - 1) * pa.nx + ja
                r_i += [len(rows_) - 1] * 2
                c_i += [last_a, sb_slot.x.start + jb]
                vals += [float(sa_slot.sx[ja]) / scale, -1.0]
            if lk.time:
                rows_.append((ea.tf - eb.t0) / sb_slot.st)
                r_i += [len(rows_) - 1] * 2
                c_i += [sa_slot.tf, sb_slot.t0]
                vals += [sa_slot.st / sb_slot.st, -1.0]
            if rows_:
                first = add_g(ca.vertcat(*rows_), np.zeros(len(rows_)), np.zeros(len(rows_)))
                lin.append((first + np.array(r_i), np.array(c_i), np.array(vals)))

        self.n_w = nw
        self.lbw = np.concatenate([np.asarray(a, dtype=float) for a in lbw])
        self.ubw = np.concatenate([np.asarray(a, dtype=float) for a in ubw])
        self.lbg = np.concatenate(lbg)
        self.ubg = np.concatenate(ubg)
        w = ca.vertcat(*w_parts)
        g = ca.vertcat(*g_parts)
        if not problem.objective_scale > 0.0:
            raise ValueError("objective_scale must be > 0")
        self.objective_scale = float(problem.objective_scale)
        nlp = {"x": w, "p": p, "f": cost / self.objective_scale, "g": g}
        self.integrals = ca.Function("integrals", [w, p], [ca.vertcat(*qs)])
        options = dict(solver_options)
        if nodes is not None:
            options.update(self._derivatives(w, p, g, ng, lin, blocks, ad_rows, mayer, nlp["f"]))
        if watch is not None:
            self._watch_fn = watch.function(nw, int(self.lbg.size), problem.n_params)
            options["iteration_callback"] = self._watch_fn
        self.solver = ca.nlpsol("ocp", "ipopt", nlp, options)
        self.build_time = time.perf_counter() - t_start

    def _derivatives(self, w: ca.MX, p: ca.MX, g: ca.MX, ng: int, lin, blocks: list[_NodeBlock],
                     ad_rows: list[tuple[int, ca.MX]], mayer: ca.MX, cost: ca.MX) -> dict[str, ca.Function]:
        """``grad_f``, ``jac_g`` and ``hess_lag`` for nlpsol, assembled from the nodes' derivatives (see
        :mod:`mal_planner.ocp.nodes`), constant entries, and CasADi's differentiation of the few other rows."""
        nw = self.n_w
        rows = np.concatenate([r for r, _, _ in lin])
        cols = np.concatenate([c for _, c, _ in lin])
        vals = np.concatenate([v for _, _, v in lin])
        jac = ca.MX(ca.DM.triplet(rows.tolist(), cols.tolist(), vals.tolist(), ng, nw))
        lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", ng)
        lam_ext = ca.vertcat(lam_g, 0.0)
        sigma = lam_f / self.objective_scale if self.problem.lagrange_in_cost else ca.MX(0)
        hess = ca.MX(nw, nw)
        grad = ca.MX(nw, 1)
        for blk in blocks:
            nk = blk.rows.shape[1]
            if blk.fns.grad is not None and self.problem.lagrange_in_cost:
                grad_all = blk.fns.grad.map(nk)(*blk.args)
                pat = blk.fns.grad.sparsity_out(0)
                c_loc = np.array(pat.get_col(), dtype=int)
                node = np.repeat(np.arange(nk), len(c_loc))
                grad = grad + scatter(grad_all, blk.cols[np.tile(c_loc, nk), node], np.zeros(len(node), int), (nw, 1))
            jac_all = blk.fns.jac.map(nk)(*blk.args)
            pat = blk.fns.jac.sparsity_out(0)
            r_loc, c_loc = np.array(pat.row(), dtype=int), np.array(pat.get_col(), dtype=int)
            node = np.repeat(np.arange(nk), len(r_loc))
            jac = jac + scatter(jac_all, blk.rows[np.tile(r_loc, nk), node], blk.cols[np.tile(c_loc, nk), node],
                                (ng, nw))
            idx = np.where(blk.rows >= 0, blk.rows, ng).ravel(order="F")
            mu = ca.reshape(lam_ext.nz[idx.tolist()], blk.rows.shape[0], nk)
            hess_all = blk.fns.hess.map(nk)(*blk.args, mu, sigma)
            pat = blk.fns.hess.sparsity_out(0)
            r_loc, c_loc = np.array(pat.row(), dtype=int), np.array(pat.get_col(), dtype=int)
            node = np.repeat(np.arange(nk), len(r_loc))
            hess = hess + scatter(hess_all, blk.cols[np.tile(r_loc, nk), node], blk.cols[np.tile(c_loc, nk), node],
                                  (nw, nw), upper=True)
        if ad_rows:
            first = np.concatenate([np.arange(r0, r0 + int(e.numel())) for r0, e in ad_rows])
            expr = ca.vertcat(*[e for _, e in ad_rows])
            select = ca.DM(ca.Sparsity.triplet(ng, len(first), first.tolist(), list(range(len(first)))),
                           np.ones(len(first)))
            jac = jac + ca.mtimes(select, ca.jacobian(expr, w))
            lagrangian = ca.dot(lam_g[first.tolist()], expr) + lam_f * mayer / self.objective_scale
        else:
            lagrangian = lam_f * mayer / self.objective_scale
        hess = hess + ca.triu(ca.hessian(lagrangian, w)[0])
        grad = (grad + ca.gradient(mayer, w)) / self.objective_scale
        return {
            "grad_f": ca.Function("ocp_grad_f", [w, p], [cost, grad], ["x", "p"], ["f", "grad_f_x"]),
            "jac_g": ca.Function("ocp_jac_g", [w, p], [g, jac], ["x", "p"], ["g", "jac_g_x"]),
            "hess_lag": ca.Function("ocp_hess_lag", [w, p, lam_f, lam_g], [ca.triu(hess)],
                                    ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"]),
        }

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
                t0, tf, x, u = _sample_guess(ph, g, lay)
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


def _sample_guess(ph: Phase, g: PhaseGuess | None, lay: MeshLayout) -> tuple[float, float, np.ndarray, np.ndarray]:
    nk, nc = lay.n_nodes, lay.n_col
    if g is None:
        # Straight line between the (finite) endpoint bound midpoints: a poor but legal start.
        b = ph.bounds()
        lo = np.clip(0.0, ph.t0_bounds[0], ph.t0_bounds[1])
        hi = np.clip(max(lo + 1.0, ph.tf_bounds[0]), ph.tf_bounds[0], ph.tf_bounds[1])
        xa = _mid(b["x0_lb"], b["x0_ub"], b["x_lb"], b["x_ub"])
        xb = _mid(b["xf_lb"], b["xf_ub"], b["x_lb"], b["x_ub"])
        s = (lay.tau + 1.0) / 2.0
        x = xa[:, None] + (xb - xa)[:, None] * s[None, :]
        u = np.tile(_mid(b["u_lb"], b["u_ub"], b["u_lb"], b["u_ub"])[:, None], (1, nc))
        return float(lo), float(hi), x, u
    t0, tf = float(g.t[0]), float(g.t[-1])
    tn = t0 + (tf - t0) * (lay.tau + 1.0) / 2.0
    x = np.vstack([np.interp(tn, g.t, g.x[:, j]) for j in range(ph.nx)]) if ph.nx else np.zeros((0, nk))
    u = np.vstack([np.interp(tn[:nc], g.t, g.u[:, j]) for j in range(ph.nu)]) if ph.nu else np.zeros((0, nc))
    return t0, tf, x, u


def _mid(lb: np.ndarray, ub: np.ndarray, glb: np.ndarray, gub: np.ndarray) -> np.ndarray:
    both = np.isfinite(lb) & np.isfinite(ub)
    mid = np.where(both, 0.5 * (np.where(both, lb, 0) + np.where(both, ub, 0)), 0.0)
    return np.clip(mid, glb, gub)
