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


class Transcription:
    """The NLP of ``problem`` on ``meshes``; build once, then :meth:`solve` many times."""

    def __init__(
        self,
        problem: Problem,
        meshes: Sequence[PhaseMesh],
        funcs: Sequence[ca.Function],
        solver_options: dict[str, Any],
        watch: IterationWatch | None = None,
    ) -> None:
        t_start = time.perf_counter()
        self.problem = problem
        self.meshes = tuple(meshes)
        p = ca.MX.sym("p", problem.n_params)
        w_parts: list[ca.SX] = []
        lbw: list[np.ndarray] = []
        ubw: list[np.ndarray] = []
        g_parts: list[ca.SX] = []
        lbg: list[np.ndarray] = []
        ubg: list[np.ndarray] = []
        endpoints: list[Endpoint] = []
        qs: list[ca.SX] = []
        self.slots: list[_PhaseSlots] = []
        nw = 0
        cost = ca.MX(0)
        for ph, mesh, fun in zip(problem.phases, self.meshes, funcs, strict=True):
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
            t0, tf, h = st * t0_s, st * tf_s, st * h_s  # physical times
            self.slots.append(
                _PhaseSlots(
                    lay,
                    slice(nw, nw + nx * nk),
                    slice(nw + nx * nk, nw + nx * nk + nu * nc),
                    nw + nx * nk + nu * nc,
                    nw + nx * nk + nu * nc + 1,
                    sx,
                    su,
                    slice(nw + nx * nk + nu * nc + 2, nw + nx * nk + nu * nc + 2 + nc),
                    st,
                )
            )
            nw += nx * nk + nu * nc + 2 + nc

            xlb = np.tile((b["x_lb"] / sx)[:, None], (1, nk))
            xub = np.tile((b["x_ub"] / sx)[:, None], (1, nk))
            xlb[:, 0], xub[:, 0] = b["x0_lb"] / sx, b["x0_ub"] / sx
            xlb[:, -1], xub[:, -1] = b["xf_lb"] / sx, b["xf_ub"] / sx
            lbw += [xlb.ravel(order="F"), np.tile(b["u_lb"] / su, nc), [ph.t0_bounds[0] / st],
                    [ph.tf_bounds[0] / st], np.full(nc, -np.inf)]
            ubw += [xub.ravel(order="F"), np.tile(b["u_ub"] / su, nc), [ph.t0_bounds[1] / st],
                    [ph.tf_bounds[1] / st], np.full(nc, np.inf)]

            xs = ca.mtimes(ca.diag(ca.DM(sx)), z)
            us = ca.mtimes(ca.diag(ca.DM(su)), v)
            tn = t0 + (tf - t0) * ca.DM((lay.tau + 1.0) / 2.0).T
            u_ext = ca.horzcat(us, us[:, nc - 1]) if nu else ca.MX(0, nk)
            f_all, l_all, c_all = fun.map(nk)(xs, u_ext, tn, p)
            g_parts += [h_s[0] - (tf_s - t0_s) / 2.0, h_s[1:] - h_s[:-1]]
            lbg.append(np.zeros(nc))
            ubg.append(np.zeros(nc))
            defect = ca.mtimes(z, lay.D.T) - ca.repmat(h.T, nx, 1) * (
                ca.mtimes(ca.diag(ca.DM(1.0 / sx)), f_all[:, :nc]) * ca.repmat(ca.DM(lay.frac).T, nx, 1)
            )
            g_parts.append(ca.vec(defect))
            lbg.append(np.zeros(nx * nc))
            ubg.append(np.zeros(nx * nc))
            q = ca.mtimes(l_all[:, :nc] * h.T, ca.DM(lay.w))
            npath = fun.size1_out(2)
            if npath:
                sp = _bounds(ph.path_scale, npath, 1.0)
                if np.any(sp <= 0.0):
                    raise ValueError(f"phase {ph.name!r}: path_scale must be positive")
                g_parts.append(ca.vec(c_all * ca.repmat(ca.DM(1.0 / sp), 1, nk)))
                lbg.append(np.tile(_bounds(ph.path_lb, npath, -np.inf) / sp, nk))
                ubg.append(np.tile(_bounds(ph.path_ub, npath, np.inf) / sp, nk))
            between = between_matrix(lay.mesh) if ph.bound_controls_between and nu else np.zeros((0, nc))
            if between.shape[0]:
                g_parts.append(ca.vec(ca.mtimes(v, ca.sparsify(ca.DM(between.T)))))
                lbg.append(np.tile(b["u_lb"] / su, between.shape[0]))
                ubg.append(np.tile(b["u_ub"] / su, between.shape[0]))
            if ph.control_path is not None and nu:
                u_sym = ca.SX.sym("u", nu)
                c_fun = ca.Function(f"{ph.name}_cu", [u_sym], [_col(ph.control_path(u_sym))])
                nc_rows = c_fun.size1_out(0)
                u_at = us if not between.shape[0] else ca.horzcat(us, ca.mtimes(us, ca.sparsify(ca.DM(between.T))))
                n_at = nc + between.shape[0]
                g_parts.append(ca.vec(c_fun.map(n_at)(u_at)))
                lbg.append(np.tile(_bounds(ph.control_path_lb, nc_rows, -np.inf), n_at))
                ubg.append(np.tile(_bounds(ph.control_path_ub, nc_rows, np.inf), n_at))
            g_parts.append(tf_s - t0_s)
            lbg.append(np.array([ph.min_duration / st]))
            ubg.append(np.array([ph.max_duration / st]))
            endpoints.append(Endpoint(t0, tf, xs[:, 0], xs[:, nk - 1], q))
            qs.append(q)
            if problem.lagrange_in_cost and ph.lagrange is not None:
                cost = cost + q

        ends = Endpoints(endpoints, [ph.name for ph in problem.phases])
        if problem.mayer is not None:
            cost = cost + _col(problem.mayer(ends, p))
        if problem.events is not None:
            ev = _col(problem.events(ends, p))
            se = _bounds(problem.events_scale, ev.numel(), 1.0)
            if np.any(se <= 0.0):
                raise ValueError("events_scale must be positive")
            g_parts.append(ev * ca.DM(1.0 / se))
            lbg.append(_bounds(problem.events_lb, ev.numel(), -np.inf) / se)
            ubg.append(_bounds(problem.events_ub, ev.numel(), np.inf) / se)
        for lk in problem.linkages:
            ia, ib = problem.phase_index(lk.phase_a), problem.phase_index(lk.phase_b)
            pa, pb = problem.phases[ia], problem.phases[ib]
            ea, eb = ends[ia], ends[ib]
            sb_scale = self.slots[ib].sx
            rows = []
            for sa, sb in lk.pairs:
                jb = list(pb.states).index(sb)
                rows.append((ea.xf[list(pa.states).index(sa)] - eb.x0[jb]) / float(sb_scale[jb]))
            if lk.time:
                rows.append((ea.tf - eb.t0) / self.slots[ib].st)
            if rows:
                g_parts.append(ca.vertcat(*rows))
                lbg.append(np.zeros(len(rows)))
                ubg.append(np.zeros(len(rows)))

        self.n_w = nw
        self.lbw = np.concatenate([np.asarray(a, dtype=float) for a in lbw])
        self.ubw = np.concatenate([np.asarray(a, dtype=float) for a in ubw])
        self.lbg = np.concatenate(lbg)
        self.ubg = np.concatenate(ubg)
        w = ca.vertcat(*w_parts)
        if not problem.objective_scale > 0.0:
            raise ValueError("objective_scale must be > 0")
        self.objective_scale = float(problem.objective_scale)
        nlp = {"x": w, "p": p, "f": cost / self.objective_scale, "g": ca.vertcat(*g_parts)}
        self.integrals = ca.Function("integrals", [w, p], [ca.vertcat(*qs)])
        options = dict(solver_options)
        if watch is not None:
            self._watch_fn = watch.function(nw, int(self.lbg.size), problem.n_params)
            options["iteration_callback"] = self._watch_fn
        self.solver = ca.nlpsol("ocp", "ipopt", nlp, options)
        self.build_time = time.perf_counter() - t_start

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
