"""The NLP of a :class:`Problem` on fixed phase meshes, assembled block of rows by block of rows.

Each function below adds one kind of rows (or the decision variables of one phase) to :class:`NLPParts` and
records where they sit: the constant entries of the constraint Jacobian, the node blocks whose derivatives
:mod:`mal_planner.ocp.derivatives` scatters, and the few other rows CasADi differentiates itself.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from .functions import bound_vector, column
from .mesh import MeshLayout, between_matrix, layout
from .nodes import NodeFunctions
from .problem import Endpoint, Endpoints, Phase, PhaseMesh, Problem


@dataclass
class PhaseSlots:
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
class PhaseSymbols:
    """One phase's decision variables (all scaled) and its physical end times."""

    z: ca.MX
    """States at the nodes (nx, Nk)."""
    v: ca.MX
    """Controls at the collocation nodes (nu, Nc)."""
    t0: ca.MX
    tf: ca.MX
    h: ca.MX
    """Half the phase duration, one copy per collocation node."""
    t0_phys: ca.MX
    tf_phys: ca.MX


@dataclass
class NodeBlock:
    """One phase's node functions mapped over its nodes, with where their inputs and outputs sit in the NLP."""

    fns: NodeFunctions
    args: list
    """The mapped call's arguments (z, v, t0, tf, h, s, frac, w, p)."""
    rows: np.ndarray
    """(n_out, nk) NLP row of each output of each node (-1: none, e.g. the end node's defect)."""
    cols: np.ndarray
    """(n_in, nk) NLP variable of each differentiated input of each node (-1: none)."""


@dataclass
class NLPParts:
    """The NLP as it grows: decision variables and constraint rows with their bounds, and what is known of the
    constraint Jacobian."""

    w: list[ca.MX] = field(default_factory=list)
    lbw: list[np.ndarray] = field(default_factory=list)
    ubw: list[np.ndarray] = field(default_factory=list)
    g: list[ca.MX] = field(default_factory=list)
    lbg: list[np.ndarray] = field(default_factory=list)
    ubg: list[np.ndarray] = field(default_factory=list)
    lin: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)
    """Constant Jacobian entries (rows, cols, values)."""
    blocks: list[NodeBlock] = field(default_factory=list)
    ad_rows: list[tuple[int, ca.MX]] = field(default_factory=list)
    """Other nonlinear rows: (first row, expression)."""
    nw: int = 0
    ng: int = 0

    def add_g(self, expr: ca.MX, lo: np.ndarray, hi: np.ndarray) -> int:
        """Append constraint rows ``lo <= expr <= hi``; returns the first row's index."""
        self.g.append(expr)
        self.lbg.append(np.asarray(lo, float).reshape(-1))
        self.ubg.append(np.asarray(hi, float).reshape(-1))
        first, self.ng = self.ng, self.ng + int(expr.numel())
        return first


def declare_phase(nlp: NLPParts, ph: Phase, mesh: PhaseMesh) -> tuple[PhaseSlots, PhaseSymbols]:
    """The phase's decision variables, bounded: states at all nodes, controls at the collocation nodes, t0, tf and
    the half-duration copies."""
    lay = layout(mesh)
    nx, nu, nk, nc = ph.nx, ph.nu, lay.n_nodes, lay.n_col
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
    nlp.w += [ca.vec(z), ca.vec(v), t0_s, tf_s, h_s]
    x0_col, u0_col = nlp.nw, nlp.nw + nx * nk
    slot = PhaseSlots(lay, slice(x0_col, u0_col), slice(u0_col, u0_col + nu * nc), u0_col + nu * nc,
                      u0_col + nu * nc + 1, sx, su, slice(u0_col + nu * nc + 2, u0_col + nu * nc + 2 + nc), st)
    nlp.nw += nx * nk + nu * nc + 2 + nc
    sym = PhaseSymbols(z, v, t0_s, tf_s, h_s, st * t0_s, st * tf_s)
    _bound_variables(nlp, ph, slot)
    return slot, sym


def _bound_variables(nlp: NLPParts, ph: Phase, slot: PhaseSlots) -> None:
    b = ph.bounds()
    sx, su, st = slot.sx, slot.su, slot.st
    nk, nc = slot.layout.n_nodes, slot.layout.n_col
    xlb = np.tile((b["x_lb"] / sx)[:, None], (1, nk))
    xub = np.tile((b["x_ub"] / sx)[:, None], (1, nk))
    xlb[:, 0], xub[:, 0] = b["x0_lb"] / sx, b["x0_ub"] / sx
    xlb[:, -1], xub[:, -1] = b["xf_lb"] / sx, b["xf_ub"] / sx
    nlp.lbw += [xlb.ravel(order="F"), np.tile(b["u_lb"] / su, nc), [ph.t0_bounds[0] / st],
                [ph.tf_bounds[0] / st], np.full(nc, -np.inf)]
    nlp.ubw += [xub.ravel(order="F"), np.tile(b["u_ub"] / su, nc), [ph.t0_bounds[1] / st],
                [ph.tf_bounds[1] / st], np.full(nc, np.inf)]


def add_collocation(nlp: NLPParts, ph: Phase, slot: PhaseSlots, sym: PhaseSymbols, fns: NodeFunctions,
                    p: ca.MX) -> ca.MX:
    """The nonlinear terms, node by node: the defect's dynamics part, the path constraints, the integrand.

    Adds the half-duration chain, the defects and the path rows; returns the phase's integral.
    """
    lay = slot.layout
    nu, nk, nc = ph.nu, lay.n_nodes, lay.n_col
    z, v = sym.z, sym.v
    args = [z, ca.horzcat(v, v[:, nc - 1]) if nu else ca.MX(0, nk), sym.t0, sym.tf,
            ca.horzcat(sym.h.T, ca.MX(1, 1)), ca.DM((lay.tau + 1.0) / 2.0).T, ca.DM(np.append(lay.frac, 0.0)).T,
            ca.DM(np.append(lay.w, 0.0)).T, p]
    out_all, q_all = fns.out.map(nk)(*args)
    _add_time_copies(nlp, slot, sym)
    d_row = _add_defects(nlp, ph, slot, z, out_all)
    q = ca.sum2(q_all)
    p_row = _add_path(nlp, ph, fns.n_path, nk, out_all)
    nlp.blocks.append(_node_block(ph, slot, fns, args, d_row, p_row))
    return q


def _add_time_copies(nlp: NLPParts, slot: PhaseSlots, sym: PhaseSymbols) -> None:
    nc, h_s = slot.layout.n_col, sym.h
    h_row = nlp.add_g(ca.vertcat(h_s[0] - (sym.tf - sym.t0) / 2.0, h_s[1:] - h_s[:-1]), np.zeros(nc), np.zeros(nc))
    hc = slot.h.start + np.arange(nc)
    nlp.lin.append((np.concatenate([[h_row] * 3, h_row + np.repeat(np.arange(1, nc), 2)]),
                    np.concatenate([[hc[0], slot.tf, slot.t0], np.column_stack([hc[1:], hc[:-1]]).ravel()]),
                    np.concatenate([[1.0, -0.5, 0.5], np.tile([1.0, -1.0], nc - 1)])))


def _add_defects(nlp: NLPParts, ph: Phase, slot: PhaseSlots, z: ca.MX, out_all: ca.MX) -> int:
    """``z D' + d = 0``: the differentiation matrix's part is constant in the Jacobian."""
    lay, nx = slot.layout, ph.nx
    nc = lay.n_col
    defect = ca.mtimes(z, lay.D.T) + out_all[:nx, :nc]
    d_row = nlp.add_g(ca.vec(defect), np.zeros(nx * nc), np.zeros(nx * nc))
    dk, dj = np.nonzero(np.asarray(ca.DM(lay.D)))
    dv = np.asarray(ca.DM(lay.D))[dk, dj]
    comp = np.arange(nx)
    nlp.lin.append(((d_row + dk[:, None] * nx + comp).ravel(), (slot.x.start + dj[:, None] * nx + comp).ravel(),
                    np.repeat(dv, nx)))
    return d_row


def _add_path(nlp: NLPParts, ph: Phase, npath: int, nk: int, out_all: ca.MX) -> int:
    """The path constraints at every node (divided by their scales); returns their first row."""
    p_row = nlp.ng
    if npath:
        sp = bound_vector(ph.path_scale, npath, 1.0)
        if np.any(sp <= 0.0):
            raise ValueError(f"phase {ph.name!r}: path_scale must be positive")
        nlp.add_g(ca.vec(out_all[ph.nx:, :]), np.tile(bound_vector(ph.path_lb, npath, -np.inf) / sp, nk),
                  np.tile(bound_vector(ph.path_ub, npath, np.inf) / sp, nk))
    return p_row


def _node_block(ph: Phase, slot: PhaseSlots, fns: NodeFunctions, args: list, d_row: int, p_row: int) -> NodeBlock:
    """Where each node's outputs (defect, path) and differentiated inputs (z, v, t0, tf, h) sit in the NLP."""
    nx, nu, npath = ph.nx, ph.nu, fns.n_path
    nk, nc = slot.layout.n_nodes, slot.layout.n_col
    comp = np.arange(nx)
    k = np.arange(nk)
    rows = np.full((nx + npath, nk), -1)
    rows[:nx, :nc] = d_row + k[None, :nc] * nx + comp[:, None]
    rows[nx:, :] = p_row + k[None, :] * npath + np.arange(npath)[:, None]
    cols = np.full((nx + nu + 3, nk), -1)
    cols[:nx, :] = slot.x.start + k[None, :] * nx + comp[:, None]
    cols[nx:nx + nu, :] = slot.u.start + np.minimum(k, nc - 1)[None, :] * nu + np.arange(nu)[:, None]
    cols[nx + nu, :], cols[nx + nu + 1, :] = slot.t0, slot.tf
    cols[nx + nu + 2, :nc] = slot.h.start + np.arange(nc)
    return NodeBlock(fns, args, rows, cols)


def add_midpoints(nlp: NLPParts, ph: Phase, slot: PhaseSlots, sym: PhaseSymbols, mid: NodeFunctions,
                  p: ca.MX) -> None:
    """The phase's ``midpoint_path`` at the middle of the chord between every two consecutive nodes."""
    lay, nx = slot.layout, ph.nx
    nk = lay.n_nodes
    z, x0_col = sym.z, slot.x.start
    s_nodes = (lay.tau + 1.0) / 2.0
    pairs = [z[:, :-1], z[:, 1:], sym.t0, sym.tf, ca.DM(0.5 * (s_nodes[:-1] + s_nodes[1:])).T, p]
    scale = bound_vector(ph.midpoint_path_scale, mid.n_out, 1.0)
    m_row = nlp.add_g(ca.vec(mid.out.map(nk - 1)(*pairs)),
                      np.tile(bound_vector(ph.midpoint_path_lb, mid.n_out, -np.inf) / scale, nk - 1),
                      np.tile(bound_vector(ph.midpoint_path_ub, mid.n_out, np.inf) / scale, nk - 1))
    kk = np.arange(nk - 1)
    comp = np.arange(nx)
    m_cols = np.vstack([x0_col + kk[None, :] * nx + comp[:, None],
                        x0_col + (kk[None, :] + 1) * nx + comp[:, None],
                        np.full((1, nk - 1), slot.t0), np.full((1, nk - 1), slot.tf)])
    nlp.blocks.append(NodeBlock(mid, pairs, m_row + kk[None, :] * mid.n_out + np.arange(mid.n_out)[:, None],
                                m_cols))


def add_control_rows(nlp: NLPParts, ph: Phase, slot: PhaseSlots, sym: PhaseSymbols) -> None:
    """The control bounds between the collocation points (``bound_controls_between``) and ``control_path``."""
    nu, nc, su, v = ph.nu, slot.layout.n_col, slot.su, sym.v
    b = ph.bounds()
    between = between_matrix(slot.layout.mesh) if ph.bound_controls_between and nu else np.zeros((0, nc))
    if between.shape[0]:
        b_row = nlp.add_g(ca.vec(ca.mtimes(v, ca.sparsify(ca.DM(between.T)))),
                          np.tile(b["u_lb"] / su, between.shape[0]), np.tile(b["u_ub"] / su, between.shape[0]))
        bb, bj = np.nonzero(between)
        comp_u = np.arange(nu)
        nlp.lin.append(((b_row + bb[:, None] * nu + comp_u).ravel(),
                        (slot.u.start + bj[:, None] * nu + comp_u).ravel(), np.repeat(between[bb, bj], nu)))
    us = ca.mtimes(ca.diag(ca.DM(su)), v)
    if ph.control_path is not None and nu:
        u_sym = ca.SX.sym("u", nu)
        c_fun = ca.Function(f"{ph.name}_cu", [u_sym], [column(ph.control_path(u_sym))])
        nc_rows = c_fun.size1_out(0)
        u_at = us if not between.shape[0] else ca.horzcat(us, ca.mtimes(us, ca.sparsify(ca.DM(between.T))))
        n_at = nc + between.shape[0]
        expr = ca.vec(c_fun.map(n_at)(u_at))
        nlp.ad_rows.append((nlp.add_g(expr, np.tile(bound_vector(ph.control_path_lb, nc_rows, -np.inf), n_at),
                                      np.tile(bound_vector(ph.control_path_ub, nc_rows, np.inf), n_at)), expr))


def add_duration(nlp: NLPParts, ph: Phase, slot: PhaseSlots, sym: PhaseSymbols) -> None:
    dur_row = nlp.add_g(sym.tf - sym.t0, [ph.min_duration / slot.st], [ph.max_duration / slot.st])
    nlp.lin.append((np.array([dur_row, dur_row]), np.array([slot.tf, slot.t0]), np.array([1.0, -1.0])))


def phase_endpoint(slot: PhaseSlots, sym: PhaseSymbols, q: ca.MX) -> Endpoint:
    """The phase's end points in physical units, as ``mayer`` and ``events`` see them."""
    xs = ca.mtimes(ca.diag(ca.DM(slot.sx)), sym.z)
    return Endpoint(sym.t0_phys, sym.tf_phys, xs[:, 0], xs[:, slot.layout.n_nodes - 1], q)


def add_events(nlp: NLPParts, problem: Problem, ends: Endpoints, p: ca.MX) -> None:
    """``events(E, p)`` divided by ``events_scale``."""
    ev = column(problem.events(ends, p))
    se = bound_vector(problem.events_scale, ev.numel(), 1.0)
    if np.any(se <= 0.0):
        raise ValueError("events_scale must be positive")
    expr = ev * ca.DM(1.0 / se)
    nlp.ad_rows.append((nlp.add_g(expr, bound_vector(problem.events_lb, ev.numel(), -np.inf) / se,
                                  bound_vector(problem.events_ub, ev.numel(), np.inf) / se), expr))


def add_linkages(nlp: NLPParts, problem: Problem, ends: Endpoints, slots: Sequence[PhaseSlots]) -> None:
    """Each linkage's equalities, divided by the second phase's state and time scales (linear: constant
    Jacobian entries)."""
    for lk in problem.linkages:
        ia, ib = problem.phase_index(lk.phase_a), problem.phase_index(lk.phase_b)
        pa, pb = problem.phases[ia], problem.phases[ib]
        ea, eb = ends[ia], ends[ib]
        sa_slot, sb_slot = slots[ia], slots[ib]
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
            first = nlp.add_g(ca.vertcat(*rows_), np.zeros(len(rows_)), np.zeros(len(rows_)))
            nlp.lin.append((first + np.array(r_i), np.array(c_i), np.array(vals)))
