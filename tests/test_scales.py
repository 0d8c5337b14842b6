"""The scenario's own scales: the thesis's tuned numbers come back at its size, and a real-size scenario gets its
own (turn radius L, turn time T; mal_planner.scales)."""

from __future__ import annotations

import math

import pytest

from mal_planner.campaign.traffic import TrafficSpec, generate_one
from mal_planner.landing.margins import SafetyMargins
from mal_planner.landing.pairs import PairScreen
from mal_planner.profiles import TMA
from mal_planner.scales import Scales
from mal_planner.scenario import load_scenario
from mal_planner.sequencing.schedule import landing_spacing
from mal_planner.verification import Tolerances


def test_thesis_scales_give_back_the_numbers_tuned_there() -> None:
    thesis = load_scenario("scenarios/thesis.yaml")
    scales = Scales.of(thesis)
    assert scales.length_nm == pytest.approx(0.04**2 / 0.0052952, rel=1e-9)  # 45 deg bank: tan = 1
    assert scales.time_s == pytest.approx(scales.length_nm / 0.04, rel=1e-12)
    margins = SafetyMargins().in_nm(scales)
    assert margins.separation_nm == pytest.approx(0.01, rel=0.01)
    assert margins.obstacle_nm == pytest.approx(0.01, rel=0.01) and margins.gate_nm == pytest.approx(0.002, rel=0.01)
    assert margins.airspace_nm == pytest.approx(0.001, rel=0.01)
    tol = Tolerances.for_scenario(thesis)
    assert tol.deviation_nm == pytest.approx(Tolerances().deviation_nm, rel=0.01)
    assert tol.sample_dt == pytest.approx(0.05, rel=0.01) and tol.integration_step_s == pytest.approx(0.5, rel=0.01)
    screen = PairScreen()
    assert screen.near_nm(scales) == pytest.approx(1.0, rel=0.01)
    assert screen.recheck_nm(scales) == pytest.approx(0.2, rel=0.01)
    assert screen.slack_s(scales) == pytest.approx(18.9, rel=0.01)


def test_real_size_scales_follow_the_slowest_tightest_turner() -> None:
    sc = generate_one(TrafficSpec((5, 5), seed=3, profile="tma", layout="no-fly-zones"), 0).scenario
    scales = Scales.of(sc)
    slowest = min(ac.speed for ac in sc.aircraft)
    # 30 deg bank: R = V^2 / (g tan 30); the smallest radius is the slowest aircraft's
    assert scales.length_nm == pytest.approx(slowest**2 / (0.0052952 * math.tan(math.radians(30.0))), rel=1e-9)
    assert 0.5 < scales.length_nm < 0.9 and 12.0 < scales.time_s < 16.0
    assert SafetyMargins().in_nm(scales).separation_nm == pytest.approx(2 * scales.length_nm / 60)
    assert Tolerances.for_scenario(sc).deviation_nm == pytest.approx(scales.length_nm / 60)


def test_tma_traffic_has_a_terminal_area_s_numbers() -> None:
    for i in range(4):
        sc = generate_one(TrafficSpec((4, 8), seed=11, profile="tma"), i).scenario
        assert sc.separation_nm == TMA.separation_nm == 3.0 and sc.landing_spacing_s == 90.0
        width = sc.airspace[:, 1] - sc.airspace[:, 0]
        assert width[0] >= 45.0 and width[1] >= 45.0 and sc.airspace[2, 1] == pytest.approx(1.2)
        for ac in sc.aircraft:
            assert 0.042 <= ac.speed <= 0.058 and 0.5 <= ac.position[2] <= 1.0
            assert math.degrees(ac.limits.bank_angle_max) == pytest.approx(30.0)
            assert math.hypot(*ac.position[:2]) >= 15.0


def test_a_slow_aircraft_behind_a_fast_one_lands_later_than_the_spacing() -> None:
    """Landing spacing keeps the separation on the common approach: a slow follower needs S / V_l + D (1 / V_f -
    1 / V_l) (it is closest when it joins the approach), a fast one S / V_f; never less than the scenario's."""
    sc = generate_one(TrafficSpec((3, 3), seed=5, profile="tma", layout="wall"), 0).scenario
    fast, slow = sorted(sc.aircraft, key=lambda a: a.speed)[::-1][:2]
    d = float(((sc.gates[0].center() - sc.runway_state[:3]) ** 2).sum() ** 0.5)
    expected = sc.separation_nm / fast.speed + d * (1 / slow.speed - 1 / fast.speed)
    assert landing_spacing(sc, fast, slow) == pytest.approx(max(90.0, expected))
    assert landing_spacing(sc, slow, fast) == pytest.approx(max(90.0, sc.separation_nm / fast.speed))
    thesis = load_scenario("scenarios/thesis.yaml")
    a, b = thesis.aircraft[:2]
    assert landing_spacing(thesis, a, b) == thesis.landing_spacing_s  # equal speeds: the scenario's spacing
