"""The independent verification catches what it must, on trajectories built by hand."""

from __future__ import annotations

import ast
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mal_planner.dynamics import make_dynamics
from mal_planner.scenario import load_scenario
from mal_planner.trajectory import Trajectory
from mal_planner.verification import Tolerances, chord_error_bound, fly, fly_all, fly_reference, verify

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


@pytest.mark.parametrize(("dz_ft", "dy_nm", "verified"), [(1100.0, 0.1, True), (900.0, 0.1, False),
                                                          (900.0, 0.2, True)])
def test_cylindrical_separation_is_horizontal_or_vertical(thesis, dz_ft: float, dy_nm: float,
                                                          verified: bool) -> None:
    """ATC's protected zone (0.15 nm or 1000 ft here): crossing 0.1 nm apart 1100 ft above is separated (a 0.25 nm
    sphere would not be), 900 ft above is not, 0.2 nm apart at 900 ft is again."""
    from mal_planner.units import ft_to_nm
    cyl = dataclasses.replace(thesis, separation_nm=0.15, vertical_separation_nm=ft_to_nm(1000.0))
    a = np.array([-1.0, 5.0, 0.05])
    b = np.array([1.0, 5.0 + dy_nm, 0.05 + ft_to_nm(dz_ft)])
    sc = cyl.with_initial_states({"A1": np.array([*a, 0.0, 0.0]), "A2": np.array([*b, 0.0, math.pi])})
    trajs = [straight_level("A1", a, 0.0, 30.0), straight_level("A2", b, math.pi, 30.0)]
    report = verify(sc, trajs)
    reasons = [r for r in report.reasons if "A1-A2" in r]
    assert (not reasons) == verified, reasons
    if not verified:
        assert "0.1000 nm apart horizontally and 900 ft vertically at t=25.00 s" in reasons[0]
        assert report.pairs[0].min_distance_nm < 0.15
    sphere = verify(dataclasses.replace(sc, vertical_separation_nm=None, separation_nm=0.25), trajs)
    assert any("A1-A2" in r for r in sphere.reasons)  # inside a 0.25 nm sphere in every case


def test_cylinder_chords_are_exact() -> None:
    """The chord test against a dense sampling: the same verdict, and the smallest ratio to 1e-4.

    1e-4 is the dense sampling's own error.
    """
    from mal_planner.verification.separation import _cylinder_chords
    rng = np.random.default_rng(1)
    n = 600
    rel = rng.uniform(-1, 1, (3, n)) * np.array([[1], [1], [0.3]])
    step = rng.uniform(-1, 1, (3, n)) * np.array([[1], [1], [0.3]])
    step[2, :100] = 0.0  # level chords
    step[:, 100:150] = 0.0  # points
    spare = rng.uniform(0, 0.01, n)
    inside, ratio, _ = _cylinder_chords(rel, step, spare, 0.5, 0.1)
    s = np.linspace(0.0, 1.0, 100001)
    for i in range(n):
        p = rel[:, i:i + 1] + step[:, i:i + 1] * s
        r = np.maximum((np.hypot(p[0], p[1]) - spare[i]) / 0.5, (np.abs(p[2]) - spare[i]) / 0.1)
        assert ratio[i] <= r.min() + 1e-12 and r.min() - ratio[i] < 1e-4
        assert inside[i] == (r.min() < 1.0) or abs(r.min() - 1.0) < 1e-6
    assert 0.05 < inside.mean() < 0.5


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


def manoeuvring(callsign: str, duration: float = 60.0, dt: float = 1.5, seed: int = 0) -> Trajectory:
    """Controls sampled every ``dt`` s (irregularly) with a jump at a duplicated time; the states are not used."""
    rng = np.random.default_rng(seed)
    t = np.sort(np.r_[0.0, rng.uniform(0.0, duration, int(duration / dt)), duration, duration / 3])
    after = np.arange(len(t)) > np.flatnonzero(t == duration / 3)[0]  # the second sample there starts a piece
    controls = np.column_stack([np.where(after, -0.6, 0.8) * np.sin(t / 7.0 + 0.5),
                                np.cos(0.2) + np.where(after, -0.05, 0.05) * np.sin(t / 2.0)])  # gamma -> -0.2
    return Trajectory(callsign, t, np.zeros((len(t), 5)), controls)


def scipy_flight(traj: Trajectory, scenario, rtol: float) -> tuple[np.ndarray, np.ndarray]:
    """Reference written here, sharing no code with fly: solve_ivp restarted at every sample of the plan."""
    model = scenario.aircraft_by_callsign(traj.callsign).dynamics
    state = scenario.aircraft_by_callsign(traj.callsign).state0.astype(float)
    times, states = [traj.t[0]], [state]
    for k in range(len(traj.t) - 1):
        t0, t1, u0, u1 = traj.t[k], traj.t[k + 1], traj.controls[k], traj.controls[k + 1]
        if t1 <= t0:
            continue  # a jump: the next interval starts with the new controls from the same state
        ev = np.r_[np.arange(t0, t1, 0.05)[1:], t1]

        def rhs(t: float, x: np.ndarray, t0=t0, t1=t1, u0=u0, u1=u1) -> np.ndarray:
            return model.rhs(x, u0 + (t - t0) / (t1 - t0) * (u1 - u0))

        sol = solve_ivp(rhs, (t0, t1), state, method="DOP853", t_eval=ev, rtol=rtol, atol=rtol * 1e-2)
        assert sol.success, sol.message
        times += ev.tolist()
        states += list(sol.y.T)
        state = sol.y[:, -1]
    return np.array(times), np.array(states)


def test_fly_matches_an_independent_scipy_reference(thesis) -> None:
    sc = thesis.with_initial_states({"A1": np.array([0.0, 4.0, 0.2, 0.05, 0.3])})
    traj = manoeuvring("A1", dt=1.5)
    t_ref, x_ref = scipy_flight(traj, sc, rtol=1e-11)
    times, flown = fly(traj, sc, Tolerances())
    assert np.max(np.diff(times)) <= 0.05 + 1e-12 and np.all(np.isin(traj.t, times))
    # Where the times coincide (the plan's samples), and at every dense sample against fly_reference (the
    # adaptive SciPy integration the verification used before).
    common, i_fly, i_ref = np.intersect1d(times, t_ref, return_indices=True)
    assert len(common) >= len(np.unique(traj.t))
    np.testing.assert_allclose(flown[i_fly], x_ref[i_ref], rtol=0.0, atol=1e-7)
    t_old, x_old = fly_reference(traj, sc, Tolerances(rtol=1e-11, atol=1e-13))
    np.testing.assert_array_equal(times, t_old)
    np.testing.assert_allclose(flown, x_old, rtol=0.0, atol=1e-7)


def test_fly_error_falls_at_sixth_order_with_the_step(thesis) -> None:
    """Halving the integration step divides the error by about 2^6 (the method's order), down to ~1e-12 nm."""
    sc = thesis.with_initial_states({"A1": np.array([0.0, 4.0, 0.2, 0.05, 0.3])})
    traj = manoeuvring("A1", duration=40.0, dt=4.0)
    t_ref, x_ref = scipy_flight(traj, sc, rtol=1e-13)
    errors = []
    for h in (2.0, 1.0, 0.5):
        times, flown = fly(traj, sc, Tolerances(integration_step_s=h))
        common, i_fly, i_ref = np.intersect1d(times, t_ref, return_indices=True)
        errors.append(np.max(np.abs(flown[i_fly, :3] - x_ref[i_ref, :3])))
    assert errors[0] / errors[1] > 30.0 and errors[1] > errors[2]
    times, flown = fly(traj, sc, Tolerances())
    common, i_fly, i_ref = np.intersect1d(times, t_ref, return_indices=True)
    assert np.max(np.abs(flown[i_fly, :3] - x_ref[i_ref, :3])) < 1e-11


def test_fly_honours_a_control_jump_at_a_duplicated_time(thesis) -> None:
    """Level and straight for 10 s, then at once (not ramped over 10-15 s) a coordinated turn at n_h = 0.5."""
    g, n_h = thesis.gravity, 0.5
    start = np.array([0.0, 4.0, 0.2])
    sc = thesis.with_initial_states({"A1": np.array([*start, 0.0, 0.0])})
    rate = g * n_h / V
    t = np.array([0.0, 4.0, 10.0, 10.0, 15.0, 20.0])
    controls = np.array([[0.0, 1.0], [0.0, 1.0], [0.0, 1.0], [n_h, 1.0], [n_h, 1.0], [n_h, 1.0]])
    times, flown = fly(Trajectory("A1", t, np.zeros((len(t), 5)), controls), sc, Tolerances())
    assert np.sum(times == 10.0) == 1 and times[-1] == 20.0
    turn = np.clip(times - 10.0, 0.0, None)
    expected = np.column_stack([start[0] + V * np.minimum(times, 10.0) + V / rate * np.sin(rate * turn),
                                start[1] + V / rate * (1 - np.cos(rate * turn)), np.full_like(times, 0.2),
                                np.zeros_like(times), rate * turn])
    np.testing.assert_allclose(flown, expected, rtol=0.0, atol=1e-12)


def test_fly_all_flies_each_aircraft_as_alone(thesis) -> None:
    """Aircraft of other speeds, types and durations flown together give what each gives alone."""
    models = {"A1": make_dynamics("point_mass", 0.05), "A2": make_dynamics("rotorcraft", 0.02),
              "A3": make_dynamics("point_mass", 0.03)}
    sc = dataclasses.replace(thesis, aircraft=tuple(dataclasses.replace(a, dynamics=models[a.callsign])
                                                    for a in thesis.aircraft))
    trajs = [manoeuvring("A1", 30.0, 1.0, seed=1), manoeuvring("A2", 50.0, 0.7, seed=2),
             manoeuvring("A3", 20.0, 2.5, seed=3)]
    together = fly_all(trajs, sc, Tolerances())
    for traj, (t_all, x_all) in zip(trajs, together, strict=True):
        t_one, x_one = fly(traj, sc, Tolerances())
        np.testing.assert_array_equal(t_all, t_one)
        np.testing.assert_allclose(x_all, x_one, rtol=0.0, atol=1e-13)
        t_old, x_old = fly_reference(traj, sc, Tolerances(rtol=1e-11, atol=1e-13))
        np.testing.assert_array_equal(t_all, t_old)
        np.testing.assert_allclose(x_all, x_old, rtol=0.0, atol=1e-7)


def test_separation_of_pairs_of_unequal_lengths(thesis) -> None:
    """Every pair's minimum distance, with the aircraft landing at different times, against brute force."""
    starts = {"A1": np.array([-1.0, 5.0, 0.2]), "A2": np.array([1.0, 5.3, 0.2]), "A3": np.array([0.0, 4.0, 0.2])}
    headings = {"A1": 0.0, "A2": math.pi, "A3": math.pi / 2}
    sc = thesis.with_initial_states({cs: np.array([*p, 0.0, headings[cs]]) for cs, p in starts.items()})
    trajs = [straight_level(cs, starts[cs], headings[cs], d) for cs, d in (("A1", 30.0), ("A2", 22.0), ("A3", 40.0))]
    report = verify(sc, trajs)
    assert [p.pair for p in report.pairs] == ["A1-A2", "A1-A3", "A2-A3"]
    fine = np.linspace(0.0, 40.0, 400001)
    for p in report.pairs:
        a, b = (next(t for t in trajs if t.callsign == cs) for cs in p.pair.split("-"))
        on = fine[fine <= min(a.t[-1], b.t[-1])]
        gap = np.linalg.norm(a.state_at(on)[:, :3] - b.state_at(on)[:, :3], axis=1)
        spare = sum(chord_error_bound(sc.aircraft_by_callsign(t.callsign), fly(t, sc, Tolerances())[0])
                    for t in (a, b))
        assert p.min_distance_nm == pytest.approx(np.min(gap) - spare, abs=1e-6)
        assert p.at_time_s == pytest.approx(on[np.argmin(gap)], abs=1e-3)


def test_verification_is_independent_of_the_transcription() -> None:
    trees = [ast.parse(path.read_text()) for path in sorted(Path("src/mal_planner/verification").glob("*.py"))]
    modules = {node.module for tree in trees for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    modules |= {alias.name for tree in trees for node in ast.walk(tree) if isinstance(node, ast.Import)
                for alias in node.names}
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
