"""Dynamics and obstacle models against hand-computed values, on NumPy and on CasADi."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from mal_planner.dynamics import (
    DYNAMICS_MODELS,
    GRAVITY_NM_S2,
    DynamicsModel,
    bank_angle,
    bank_limit_residuals,
    make_dynamics,
    stacked_model,
)
from mal_planner.obstacles import Superquadric, wall_with_hole
from mal_planner.scenario import load_scenario

V = 0.04
G = 0.0052952


def test_point_mass_rhs_hand_computed() -> None:
    model = make_dynamics("point_mass", V)
    gamma, phi = math.radians(5.0), math.radians(-10.0)
    xdot = model.rhs(np.array([1.0, 2.0, 0.2, gamma, phi]), np.array([0.3, 1.1]))
    assert xdot[0] == pytest.approx(0.04 * math.cos(gamma) * math.cos(phi))
    assert xdot[1] == pytest.approx(0.04 * math.cos(gamma) * math.sin(phi))
    assert xdot[2] == pytest.approx(0.04 * math.sin(gamma))
    assert xdot[3] == pytest.approx(G / V * (1.1 - math.cos(gamma)))
    assert xdot[4] == pytest.approx(G / V * 0.3 / math.cos(gamma))
    # Level, straight flight due east: only x changes.
    level = model.rhs(np.array([0.0, 0.0, 0.0, 0.0, 0.0]), model.level_flight_control(0.0))
    np.testing.assert_allclose(level, [V, 0.0, 0.0, 0.0, 0.0], atol=1e-15)
    assert GRAVITY_NM_S2 == G


def test_rhs_same_on_casadi_and_numpy() -> None:
    model = make_dynamics("point_mass", V)
    x = ca.SX.sym("x", 5)
    u = ca.SX.sym("u", 2)
    f = ca.Function("f", [x, u], [model.rhs(x, u)])
    state = np.array([0.5, 4.0, 0.1, 0.05, -1.2])
    control = np.array([-0.4, 0.9])
    np.testing.assert_allclose(np.array(f(state, control)).ravel(), model.rhs(state, control), rtol=1e-14)
    # Vectorised over many states (trailing axis).
    many = np.tile(state[:, None], (1, 4))
    assert model.rhs(many, np.tile(control[:, None], (1, 4))).shape == (5, 4)


def test_stacked_model_evaluates_each_vehicle_with_its_own_parameters() -> None:
    models = [make_dynamics("point_mass", 0.04), make_dynamics("point_mass", 0.06), make_dynamics("point_mass", 0.05)]
    rng = np.random.default_rng(0)
    states = rng.uniform(-0.3, 0.3, (5, 7))
    controls = rng.uniform(0.0, 1.5, (2, 7))
    index = np.array([0, 2, 1, 1, 0, 2, 2])
    together = stacked_model(models, index).rhs(states, controls)
    for j, i in enumerate(index):
        np.testing.assert_allclose(together[:, j], models[i].rhs(states[:, j], controls[:, j]), rtol=1e-15)
    np.testing.assert_allclose(stacked_model(models).rhs(states[:, :3], controls[:, :3])[:, 1],
                               models[1].rhs(states[:, 1], controls[:, 1]), rtol=1e-15)
    assert stacked_model([models[0], models[0]]) == models[0]
    with pytest.raises(TypeError):
        stacked_model([models[0], make_dynamics("rotorcraft", 0.02)])


def test_registry_and_rotorcraft() -> None:
    assert {"point_mass", "rotorcraft"} <= set(DYNAMICS_MODELS)
    heli = make_dynamics("rotorcraft", 0.02)
    assert heli.default_limits.bank_angle_max < DynamicsModel.default_limits.bank_angle_max
    with pytest.raises(KeyError, match="unknown dynamics model"):
        make_dynamics("glider", 0.01)


def test_bank_angle_and_linear_limit() -> None:
    assert bank_angle(1.0, 1.0) == pytest.approx(math.pi / 4)
    assert bank_angle(-0.5, 1.0) == pytest.approx(-math.atan(0.5))
    limit = math.radians(45.0)
    assert np.all(bank_limit_residuals(0.9, 1.0, limit) <= 0)  # 42 deg: inside
    assert np.any(bank_limit_residuals(1.1, 1.0, limit) > 0)  # 47.7 deg: outside
    assert np.any(bank_limit_residuals(-1.1, 1.0, limit) > 0)


TABLE_2_3 = [  # centre, semi-axes (a, b, c), p
    ((-2.0, 3.0005, 0.15), (1.0, 0.0005, 0.15)),
    ((2.0, 3.0005, 0.15), (1.0, 0.0005, 0.15)),
    ((0.0, 3.0005, 0.25), (1.0, 0.0005, 0.05)),
    ((0.0, 3.0005, 0.05), (1.0, 0.0005, 0.05)),
]


def test_thesis_scenario_has_table_2_3_and_5_1() -> None:
    sc = load_scenario("scenarios/thesis.yaml")
    assert [(ob.center, ob.semi_axes, ob.p) for ob in sc.obstacles] == [(c, s, 50) for c, s in TABLE_2_3]
    starts = [ac.state0 for ac in sc.aircraft]
    np.testing.assert_allclose(starts[0], [1.2, 5.8, 0.28, 0.0, math.radians(-15)])
    np.testing.assert_allclose(starts[1], [-1.8, 6.0, 0.25, math.radians(5), math.radians(-10)])
    np.testing.assert_allclose(starts[2], [3.0, 5.5, 0.22, 0.0, math.radians(-105)])
    assert [ac.landing_time for ac in sc.aircraft] == [155.0, 170.0, 185.0]
    assert all(ac.speed == 0.04 and ac.dynamics.gravity == 0.0052952 for ac in sc.aircraft)
    np.testing.assert_array_equal(sc.airspace, [[-3, 3], [0, 6], [0, 0.3]])
    assert sc.separation_nm == 0.25
    assert all(ac.limits.bank_angle_max == pytest.approx(math.radians(45)) for ac in sc.aircraft)


def test_wall_helper_reproduces_table_2_3() -> None:
    pieces = wall_with_hole("w", 1, 3.0, 0.001, ((-3.0, 3.0), (0.0, 0.3)), ((-1.0, 1.0), (0.1, 0.2)))
    for piece, (center, semi) in zip(pieces, TABLE_2_3, strict=True):
        np.testing.assert_allclose(piece.center, center, atol=1e-12)
        np.testing.assert_allclose(piece.semi_axes, semi, atol=1e-12)
        assert piece.p == 50
    with pytest.raises(ValueError, match="strictly inside"):
        wall_with_hole("w", 1, 3.0, 0.001, ((-3.0, 3.0), (0.0, 0.3)), ((-1.0, 4.0), (0.1, 0.2)))


def test_log_pnorm_sign_inside_outside_each_obstacle() -> None:
    sc = load_scenario("scenarios/thesis.yaml")
    for ob in sc.obstacles:
        c, s = np.array(ob.center), np.array(ob.semi_axes)
        inside = c + 0.5 * s * np.array([0.3, -0.2, 0.5])
        assert ob.log_pnorm(*inside) < 0 and ob.contains(inside)
        for axis in range(3):
            outside = c.copy()
            outside[axis] += 1.05 * s[axis]
            assert ob.log_pnorm(*outside) > 0 and not ob.contains(outside)
    # Points in the hole and on either side of the wall are free of every piece.
    for point in ([0.0, 3.0005, 0.15], [0.9, 3.0005, 0.11], [0.0, 3.5, 0.15], [2.5, 2.9, 0.2]):
        assert all(ob.log_pnorm(*point) > 0 for ob in sc.obstacles)
        assert not sc.collides(np.array(point))
    # A point in the wall beside the hole is inside obstacle 2 (x in [1, 3]).
    assert sc.obstacles[1].contains(np.array([1.5, 3.0005, 0.15]))


def test_log_pnorm_hand_value_and_casadi() -> None:
    ob = Superquadric("e", (0.0, 0.0, 0.0), (2.0, 1.0, 1.0), 2)
    assert ob.log_pnorm(2.0, 1.0, 0.0) == pytest.approx(math.log(2.0))
    x = ca.SX.sym("x", 3)
    f = ca.Function("f", [x], [ob.log_pnorm(x[0], x[1], x[2])])
    assert float(f([1.0, 0.5, 0.5])) == pytest.approx(math.log(0.25 + 0.25 + 0.25))


def test_contains_is_stable_far_away() -> None:
    thin = Superquadric("thin", (0.0, 0.0, 0.0), (1.0, 1e-6, 1.0), 50)
    assert not thin.contains(np.array([0.0, 100.0, 0.0]))  # (1e8)^50 overflows a naive sum
    assert thin.contains(np.array([0.0, 5e-7, 0.0]))


def test_segment_hits_cannot_step_through_thin_wall() -> None:
    sc = load_scenario("scenarios/thesis.yaml")
    starts = np.array([[1.5, 4.0, 0.15], [0.0, 4.0, 0.15], [0.0, 4.0, 0.25], [-2.0, 3.2, 0.1], [1.5, 4.0, 0.15]])
    ends = np.array([[1.5, 2.0, 0.15], [0.0, 2.0, 0.15], [0.0, 2.0, 0.25], [-2.0, 3.1, 0.1], [1.5, 3.01, 0.15]])
    hit = np.zeros(len(starts), dtype=bool)
    for ob in sc.obstacles:
        hit |= ob.segment_hits(starts, ends)
    # Through the wall beside the hole; through the hole; through the top piece; parallel in front;
    # stopping just short of the wall face.
    assert hit.tolist() == [True, False, True, False, False]
