"""The objective's gradient, the constraint Jacobian and the Lagrangian's Hessian IPOPT gets, assembled from the
nodes' own derivatives (see :mod:`mal_planner.ocp.nodes`), the constant entries, and CasADi's differentiation of
the few other rows."""

from __future__ import annotations

import casadi as ca
import numpy as np

from .assembly import NLPParts
from .nodes import scatter


def structured_derivatives(nlp: NLPParts, w: ca.MX, p: ca.MX, g: ca.MX, mayer: ca.MX, cost: ca.MX,
                           objective_scale: float, lagrange_in_cost: bool) -> dict[str, ca.Function]:
    """``grad_f``, ``jac_g`` and ``hess_lag`` for nlpsol (``cost``: the scaled objective, ``mayer`` unscaled)."""
    nw, ng = nlp.nw, nlp.ng
    rows = np.concatenate([r for r, _, _ in nlp.lin])
    cols = np.concatenate([c for _, c, _ in nlp.lin])
    vals = np.concatenate([v for _, _, v in nlp.lin])
    jac = ca.MX(ca.DM.triplet(rows.tolist(), cols.tolist(), vals.tolist(), ng, nw))
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", ng)
    lam_ext = ca.vertcat(lam_g, 0.0)
    sigma = lam_f / objective_scale if lagrange_in_cost else ca.MX(0)
    hess = ca.MX(nw, nw)
    grad = ca.MX(nw, 1)
    for blk in nlp.blocks:
        nk = blk.rows.shape[1]
        if blk.fns.grad is not None and lagrange_in_cost:
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
    if nlp.ad_rows:
        first = np.concatenate([np.arange(r0, r0 + int(e.numel())) for r0, e in nlp.ad_rows])
        expr = ca.vertcat(*[e for _, e in nlp.ad_rows])
        select = ca.DM(ca.Sparsity.triplet(ng, len(first), first.tolist(), list(range(len(first)))),
                       np.ones(len(first)))
        jac = jac + ca.mtimes(select, ca.jacobian(expr, w))
        lagrangian = ca.dot(lam_g[first.tolist()], expr) + lam_f * mayer / objective_scale
    else:
        lagrangian = lam_f * mayer / objective_scale
    hess = hess + ca.triu(ca.hessian(lagrangian, w)[0])
    grad = (grad + ca.gradient(mayer, w)) / objective_scale
    return {
        "grad_f": ca.Function("ocp_grad_f", [w, p], [cost, grad], ["x", "p"], ["f", "grad_f_x"]),
        "jac_g": ca.Function("ocp_jac_g", [w, p], [g, jac], ["x", "p"], ["g", "jac_g_x"]),
        "hess_lag": ca.Function("ocp_hess_lag", [w, p, lam_f, lam_g], [ca.triu(hess)],
                                ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"]),
    }
