"""LGR nodes, weights, differentiation/integration matrices and mesh helpers."""

from __future__ import annotations

import numpy as np
import pytest

from mal_planner.ocp import (
    PhaseMesh,
    diff_matrix,
    integration_matrix,
    lagrange_matrix,
    lgr_nodes,
    lgr_weights,
)
from mal_planner.ocp.lgr import support_points
from mal_planner.ocp.mesh import control_overshoot, estimate_errors, layout, path_overshoot, refine, state_overshoot


def test_known_nodes_and_weights() -> None:
    # N = 3: roots of P2 + P3 are -1 and (1 +- sqrt(6))/5.
    s6 = np.sqrt(6.0)
    np.testing.assert_allclose(lgr_nodes(3), [-1.0, (1 - s6) / 5, (1 + s6) / 5], atol=1e-14)
    np.testing.assert_allclose(lgr_weights(3), [2 / 9, (16 + s6) / 18, (16 - s6) / 18], atol=1e-14)
    np.testing.assert_allclose(lgr_nodes(2), [-1.0, 1 / 3], atol=1e-15)
    np.testing.assert_allclose(lgr_weights(2), [0.5, 1.5], atol=1e-15)


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8, 12, 16])
def test_quadrature_exact_to_degree_2n_minus_2(n: int) -> None:
    tau, w = lgr_nodes(n), lgr_weights(n)
    assert tau[0] == -1.0 and np.all(np.diff(tau) > 0) and tau[-1] < 1.0
    for k in range(2 * n - 1):
        exact = (1.0 - (-1.0) ** (k + 1)) / (k + 1)
        assert abs(w @ tau**k - exact) < 1e-12


@pytest.mark.parametrize("n", [1, 2, 4, 7, 10, 15])
def test_differentiation_exact_to_degree_n(n: int) -> None:
    d = diff_matrix(n)
    assert d.shape == (n, n + 1)
    s, tau = support_points(n), lgr_nodes(n)
    np.testing.assert_allclose(d.sum(axis=1), 0.0, atol=1e-11)
    for k in range(n + 1):
        deriv = k * tau ** (k - 1) if k else np.zeros(n)
        np.testing.assert_allclose(d @ s**k, deriv, atol=1e-9 * max(1, n * n))


@pytest.mark.parametrize("n", [2, 5, 9])
def test_integration_matrix_inverts_d(n: int) -> None:
    s = support_points(n)
    poly = np.polynomial.Polynomial(np.arange(1.0, n + 2))  # degree n
    x = poly(s)
    xdot = poly.deriv()(lgr_nodes(n))
    np.testing.assert_allclose(x[0] + integration_matrix(n) @ xdot, x[1:], atol=1e-10)


def test_lagrange_matrix_reproduces_polynomials() -> None:
    s = support_points(6)
    xq = np.linspace(-1, 1, 17)
    np.testing.assert_allclose(lagrange_matrix(s, xq) @ (s**5 - 2 * s), xq**5 - 2 * xq, atol=1e-12)


def test_layout_shares_segment_boundaries() -> None:
    mesh = PhaseMesh((0.0, 0.3, 1.0), (3, 4))
    lay = layout(mesh)
    assert lay.n_col == 7 and lay.n_nodes == 8
    np.testing.assert_allclose(lay.tau[[0, 3, 7]], [-1.0, -0.4, 1.0])
    assert abs(lay.w.sum() - 2.0) < 1e-13
    assert layout(mesh) is lay  # cached


def test_error_estimate_zero_for_polynomial_state_and_refine_rules() -> None:
    # xdot = t^2 has a cubic solution, reproduced exactly by degree >= 3.
    mesh = PhaseMesh.uniform(2, 4)
    lay = layout(mesh)
    t = (lay.tau + 1.0) / 2.0
    x = (t**3 / 3.0)[None, :]
    errs = estimate_errors(lay, 0.0, 1.0, x, np.zeros((0, lay.n_col)), lambda xx, uu, tt: tt[None, :] ** 2)
    assert errs.max() < 1e-13
    m = refine(PhaseMesh.uniform(2, 4), np.array([1e-3, 1e-9]), 1e-6, 3, 10)
    assert m.degrees == (10, 4)  # P = ceil(log(1e3)/log(4)) + 1 = 6
    m = refine(PhaseMesh.uniform(2, 8), np.array([1e-1, 1e-9]), 1e-6, 3, 10)
    # P = ceil(log(1e5)/log(8)) + 1 = 7 -> 15 > 10: split into two halves of degree 8 (not five of degree 3).
    assert m.degrees == (8, 8, 8) and np.allclose(m.breaks, [0.0, 0.25, 0.5, 1.0])


def test_interpolation_at_a_mesh_break_gives_the_node_value() -> None:
    """A sample exactly at a mesh break is the next segment's first collocation point, not the previous
    segment's extrapolated end (round-off in the time -> fraction mapping used to pick the latter)."""
    from mal_planner.ocp.solution import PhaseSolution

    mesh = PhaseMesh((0.0, 0.1, 1.0), (4, 5))  # this break and these times round the fraction down
    lay = layout(mesh)
    t0, tf = 12.7, 93.1
    t = t0 + (tf - t0) * (lay.tau + 1.0) / 2.0
    rng = np.random.default_rng(0)
    x, u = rng.normal(size=(lay.n_nodes, 2)), rng.normal(size=(lay.n_nodes, 1))
    phase = PhaseSolution("p", t0, tf, t, x, u, 0.0, lay)
    k = int(lay.offsets[1])  # first node of the second segment: the break
    xi, ui = phase.interpolate(t[k:k + 1])
    np.testing.assert_allclose(ui[0], u[k], rtol=0, atol=1e-12)
    np.testing.assert_allclose(xi[0], x[k], rtol=0, atol=1e-12)


def test_control_overshoot_finds_bulges_between_nodes_and_splits_them() -> None:
    """A control at its bound at every collocation point but one bulges past it in between (the interpolant is
    a polynomial through them); the refinement halves that segment however small its state error."""
    mesh = PhaseMesh((0.0, 0.5, 1.0), (6, 6))
    lay = layout(mesh)
    smooth = (lay.tau[:12] ** 2)[:, None]  # within [0, 1] everywhere
    bulging = smooth.copy()
    bulging[6:12, 0] = [1.0, 1.0, 0.0, 1.0, 1.0, 1.0]
    lb, ub = np.array([0.0]), np.array([1.0])
    assert np.all(control_overshoot(lay, smooth, lb, ub) == 0.0)
    over = control_overshoot(lay, bulging, lb, ub)
    assert over[0] == 0.0 and over[1] > 0.1
    # The bulge, by dense sampling of the same interpolant.
    from mal_planner.ocp.lgr import lagrange_matrix, lgr_nodes
    dense = lagrange_matrix(lgr_nodes(6), np.linspace(-1, 1, 2001)) @ bulging[6:12, 0]
    assert over[1] == pytest.approx(dense.max() - 1.0, rel=0.05)
    refined = refine(mesh, np.zeros(2), 1e-6, 3, 10, split=over > 1e-3)
    assert refined.breaks == (0.0, 0.5, 0.75, 1.0) and refined.degrees == (6, 6, 6)


def test_state_overshoot_measures_bulges_past_a_bound_between_nodes_only() -> None:
    """A state at its upper bound at two adjacent nodes of a segment and below elsewhere bulges past it between them
    (a plan level at the ceiling, ten-aircraft closed loop traffic-0017); an initial state given outside the bound is
    not a bulge."""
    mesh = PhaseMesh((0.0, 0.5, 1.0), (3, 3))
    lay = layout(mesh)
    x = np.zeros((lay.n_nodes, 1))
    x[4:6, 0] = 1.0  # second segment: two adjacent nodes on the bound
    lb, ub = np.array([-10.0]), np.array([1.0])
    over = state_overshoot(lay, x, lb, ub)
    from mal_planner.ocp.lgr import lagrange_matrix, support_points
    dense = lagrange_matrix(support_points(3), np.linspace(-1, 1, 2001)) @ x[3:7, 0]
    assert over[0, 0] == 0.0 and over[1, 0] == pytest.approx(dense.max() - 1.0, rel=0.05) and over[1, 0] > 0.05
    x[0, 0] = 1.5  # the first node outside the bound (radar): only what the polynomial adds beyond it counts
    assert state_overshoot(lay, x, lb, ub)[0, 0] == pytest.approx(max(0.0, (lagrange_matrix(
        support_points(3), np.linspace(-1, 1, 2001)) @ x[0:4, 0]).max() - 1.5), abs=0.02)


def test_path_overshoot_finds_states_past_a_path_bound_between_nodes() -> None:
    """A state at or above 0 at every node of a segment but dipping below 0 between two of them (a path cutting an
    obstacle's corner) marks that segment, unless the dip is within the tolerance."""
    mesh = PhaseMesh((0.0, 0.5, 1.0), (3, 3))
    lay = layout(mesh)
    x = np.ones((lay.n_nodes, 1))
    x[4:6, 0] = 0.0  # two adjacent nodes of the second segment on the bound: its cubic dips between them
    u = np.zeros((lay.n_col, 1))

    def path(xs: np.ndarray, us: np.ndarray, ts: np.ndarray) -> np.ndarray:
        return xs[:1]

    lb, ub = np.array([0.0]), np.array([np.inf])
    assert path_overshoot(lay, 0.0, 10.0, x, u, path, lb, ub, np.array([1e-3])).tolist() == [False, True]
    assert path_overshoot(lay, 0.0, 10.0, x, u, path, lb, ub, np.array([10.0])).tolist() == [False, False]
