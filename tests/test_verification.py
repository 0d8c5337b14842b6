"""The independent verification catches what it must, on trajectories built by hand."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from mal_planner.scenario import load_scenario
from mal_planner.trajectory import Trajectory
from mal_planner.verification import Tolerances, fly, verify

V = 0.04


@pytest.fixture(scope="module")
def thesis():
    return load_scenario("scenarios/thesis.yaml")


def straight_level(callsign: str, start: np.ndarray, heading: float, duration: float, dt: float = 0.5,
                   controls: tuple[float, float] = (0.0, 1.0)) -> Trajectory:
    """Level straight flight (n_h = 0, n_v = 1 keeps gamma = 0 and the heading)."""
    t = np.arange(0.0, duration + 1e-9, dt)
    states = np.zeros((len(t), 5))
    states[:, 0] = start[0] + V * t * math.cos(heading)
    states[:, 1] = start[1] + V * t * math.sin(heading)
    states[:, 2] = start[2]
    states[:, 4] = heading
    return Trajectory(callsign, t, states, np.tile(controls, (len(t), 1)))


def test_flying_through_the_wall_beside_the_hole_is_caught(thesis) -> None:
    start = np.array([2.0, 4.0, 0.15])
    sc = thesis.with_initial_states({"A1": np.array([*start, 0.0, -math.pi / 2])})
    traj = straight_level("A1", start, -math.pi / 2, 40.0)
    report = verify(sc, [traj])
    assert not report.verified
    text = " | ".join(report.reasons)
    assert "crosses the plane of 'hole' outside the hole" in text
    assert "enters obstacle 'wall-2'" in text
    assert "ends" in text and "from the runway" in text
    check = report.aircraft[0]
    assert check.max_position_deviation_nm < 1e-6  # the plan itself is flyable
    assert check.gate_events and not check.gate_events[0]["in_hole"]


def test_flying_through_the_hole_passes_the_gate_check(thesis) -> None:
    start = np.array([0.0, 3.5, 0.15])
    sc = thesis.with_initial_states({"A1": np.array([*start, 0.0, -math.pi / 2])})
    report = verify(sc, [straight_level("A1", start, -math.pi / 2, 20.0)])
    assert not any("hole" in r or "obstacle" in r for r in report.reasons), report.reasons
    event = report.aircraft[0].gate_events[0]
    assert event["in_hole"] and event["time_s"] == pytest.approx(0.5 / V)


def test_loss_of_separation_is_caught(thesis) -> None:
    a = np.array([-1.0, 5.0, 0.2])
    b = np.array([1.0, 5.1, 0.2])
    sc = thesis.with_initial_states({"A1": np.array([*a, 0.0, 0.0]), "A2": np.array([*b, 0.0, math.pi])})
    report = verify(sc, [straight_level("A1", a, 0.0, 30.0), straight_level("A2", b, math.pi, 30.0)])
    pair = report.pairs[0]
    assert pair.pair == "A1-A2"
    assert pair.min_distance_nm == pytest.approx(0.1, abs=1e-3)
    assert pair.at_time_s == pytest.approx(25.0, abs=0.1)
    assert any("A1-A2: 0.1000 nm apart" in r for r in report.reasons)
    assert report.violation_times() and abs(report.violation_times()[0] - 25.0) < 0.1


def test_bank_limit_and_deviation_are_caught(thesis) -> None:
    start = np.array([0.0, 5.0, 0.2])
    sc = thesis.with_initial_states({"A1": np.array([*start, 0.0, -math.pi / 2])})
    # Commanding n_h = 1.2 with n_v = 1 is a 50 deg bank, and the stated states ignore the turn.
    traj = straight_level("A1", start, -math.pi / 2, 10.0, controls=(1.2, 1.0))
    report = verify(sc, [traj])
    text = " | ".join(report.reasons)
    assert "bank angle reaches 50.194 deg" in text
    assert "re-integrated path deviates" in text
    assert report.aircraft[0].max_position_deviation_nm > 0.01


def test_fly_matches_an_analytic_turn(thesis) -> None:
    """A coordinated level turn at constant n_h: heading rate g n_h / V, a circle of radius V^2/(g n_h)."""
    g = thesis.gravity
    n_h = 0.5
    start = np.array([0.0, 4.0, 0.2])
    sc = thesis.with_initial_states({"A1": np.array([*start, 0.0, 0.0])})
    t = np.linspace(0.0, 20.0, 11)
    controls = np.tile([n_h, 1.0], (len(t), 1))
    rate = g * n_h / V
    radius = V / rate
    states = np.column_stack([start[0] + radius * np.sin(rate * t), start[1] + radius * (1 - np.cos(rate * t)),
                              np.full_like(t, 0.2), np.zeros_like(t), rate * t])
    times, flown = fly(Trajectory("A1", t, states, controls), sc, Tolerances())
    assert np.max(np.diff(times)) <= 0.05 + 1e-12
    np.testing.assert_allclose(flown[-1], states[-1], atol=1e-8)


def test_verification_is_independent_of_the_transcription() -> None:
    tree = ast.parse(Path("src/mal_planner/verification.py").read_text())
    modules = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    modules |= {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    assert not any(m and ("ocp" in m or "landing" in m or "casadi" in m) for m in modules), modules


def test_reasons_are_attributed_to_their_aircraft(thesis) -> None:
    a = np.array([-1.0, 5.0, 0.2])
    b = np.array([1.0, 5.1, 0.2])
    c = np.array([0.0, 3.5, 0.15])
    sc = thesis.with_initial_states({"A1": np.array([*a, 0.0, 0.0]), "A2": np.array([*b, 0.0, math.pi]),
                                     "A3": np.array([*c, 0.0, -math.pi / 2])})
    report = verify(sc, [straight_level("A1", a, 0.0, 30.0), straight_level("A2", b, math.pi, 30.0),
                         straight_level("A3", c, -math.pi / 2, 30.0, controls=(1.2, 1.0))])
    assert any("A1-A2" in r for r in report.by_aircraft["A1"])
    assert any("A1-A2" in r for r in report.by_aircraft["A2"])
    assert not any("A1-A2" in r for r in report.by_aircraft["A3"])
    assert any("bank angle" in r for r in report.by_aircraft["A3"])
    assert not any("bank angle" in r for r in report.by_aircraft["A1"])
    assert not report.aircraft_verified("A3")
