"""The path planners (multi-tree RRT and OMPL) on the thesis's wall with a hole."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mal_planner.initializer.base import PathPlanner, PlanningFailed, path_length
from mal_planner.initializer.collision import CollisionChecker
from mal_planner.initializer.planners import make_planner
from mal_planner.obstacles import Superquadric
from mal_planner.scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
WALL_PLANES = (3.0, 3.001)
HOLE_X, HOLE_Z = (-1.0, 1.0), (0.1, 0.2)
# Fewer iterations than the defaults keep the test quick; RRT* is the slowest (it rewires).
PLANNERS = {
    "multi-rrt": {},
    "ompl:RRT": {},
    "ompl:RRTConnect": {},
    "ompl:RRTstar": {"max_iterations": 300, "smooth_rounds": 20},
}


@pytest.fixture(scope="module")
def thesis():
    return load_scenario(SCENARIOS / "thesis.yaml")


@pytest.fixture(scope="module")
def checker(thesis):
    return CollisionChecker.from_scenario(thesis)


def assert_through_hole(path: np.ndarray) -> None:
    """Geometric check, independent of the planner's checker: wherever a segment meets the wall's faces
    y = 3 and y = 3.001 (or lies between them), x and z are in the hole."""
    for a, b in zip(path[:-1], path[1:], strict=True):
        for y0 in WALL_PLANES:
            if (a[1] - y0) * (b[1] - y0) > 0.0:
                continue
            if a[1] == b[1]:
                points = [a, b]
            else:
                f = (y0 - a[1]) / (b[1] - a[1])
                points = [a + f * (b - a)]
            for p in points:
                assert HOLE_X[0] <= p[0] <= HOLE_X[1], f"crosses y={y0} at x={p[0]:.6f} (segment {a} -> {b})"
                assert HOLE_Z[0] <= p[2] <= HOLE_Z[1], f"crosses y={y0} at z={p[2]:.6f} (segment {a} -> {b})"


def assert_in_airspace(path: np.ndarray, airspace: np.ndarray) -> None:
    assert np.all(path >= airspace[:, 0] - 1e-12) and np.all(path <= airspace[:, 1] + 1e-12)


@pytest.mark.parametrize("spec", list(PLANNERS))
def test_planner_succeeds_for_20_seeds(spec, thesis, checker):
    planner = make_planner(spec, **PLANNERS[spec])
    assert isinstance(planner, PathPlanner)
    goal = thesis.runway_state[:3]
    ac = thesis.aircraft_by_callsign("A3")  # the one whose straight line hits the wall
    for seed in range(20):
        path = planner.plan(checker, ac.position, goal, np.random.default_rng(seed))
        assert path.shape[1] == 3 and len(path) >= 2
        np.testing.assert_array_equal(path[0], ac.position)
        np.testing.assert_array_equal(path[-1], goal)
        assert_in_airspace(path, thesis.airspace)
        assert_through_hole(path)
        assert path_length(path) < 1.2 * 6.4, f"{spec} seed {seed}: path {path_length(path):.3f} nm"


@pytest.mark.parametrize("spec", ["multi-rrt", "ompl:RRTConnect"])
def test_same_seed_same_path(spec, thesis, checker):
    planner = make_planner(spec)
    start, goal = thesis.aircraft[2].position, thesis.runway_state[:3]
    p1 = planner.plan(checker, start, goal, np.random.default_rng(7))
    p2 = planner.plan(checker, start, goal, np.random.default_rng(7))
    np.testing.assert_array_equal(p1, p2)


def test_multi_rrt_raw_tree_path_crosses_hole(thesis, checker):
    planner = make_planner("multi-rrt", max_trees=4, seeds_per_axis=3)
    for seed in range(5):
        raw = planner.search(checker, thesis.aircraft[2].position, thesis.runway_state[:3],
                             np.random.default_rng(seed))
        assert_through_hole(raw)
        assert planner.last_trees >= 1 and planner.last_iterations >= 1


def test_scalar_and_batch_checks_agree(thesis, checker):
    rng = np.random.default_rng(3)
    lo, hi = thesis.airspace[:, 0], thesis.airspace[:, 1]
    a = rng.uniform(lo - 0.05, hi + 0.05, (400, 3))
    b = a + rng.normal(0.0, 1.0, (400, 3)) * [1.0, 1.0, 0.1]
    a[:200, 1], b[:200, 1] = 2.995 + 0.01 * rng.random(200), 3.2  # many near or through the wall
    batch = checker.segments_free(a, b)
    scalar = np.array([checker.segment_free(p, q) for p, q in zip(a, b, strict=True)])
    np.testing.assert_array_equal(batch, scalar)
    np.testing.assert_array_equal(checker.points_free(a), [checker.point_free(p) for p in a])


def test_thin_wall_cannot_be_stepped_through(checker):
    blocked = checker.segments_free(np.array([[2.0, 2.9, 0.15], [0.0, 2.9, 0.05]]),
                                    np.array([[2.0, 3.1, 0.15], [0.0, 3.1, 0.05]]))
    assert not blocked.any()
    assert checker.segment_free(np.array([0.0, 2.9, 0.15]), np.array([0.0, 3.1, 0.15]))
    assert not checker.point_free(np.array([2.0, 3.0005, 0.15]))
    assert not checker.point_free(np.array([0.0, 0.0, 0.31]))
    assert checker.counts.segments >= 3


def test_no_path_raises_planning_failed():
    wall = Superquadric("solid", (0.0, 3.0005, 0.15), (3.5, 0.0005, 0.2), 50)
    checker = CollisionChecker(np.array([[-3, 3], [0, 6], [0, 0.3]]), (wall,))
    start, goal = np.array([0.0, 5.0, 0.1]), np.zeros(3)
    for spec, options in (("multi-rrt", {"max_iterations": 300}), ("ompl:RRTConnect", {"time_limit": 0.3})):
        with pytest.raises(PlanningFailed) as info:
            make_planner(spec, **options).plan(checker, start, goal, np.random.default_rng(0))
        assert "\n" not in str(info.value)


def test_unknown_spec_names_known_specs():
    with pytest.raises(ValueError, match="multi-rrt.*ompl:RRTConnect"):
        make_planner("ompl:NoSuchPlanner")
    with pytest.raises(ValueError, match="max_trees"):
        make_planner("multi-rrt", max_trees=1)
