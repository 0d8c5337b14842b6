"""Aircraft performance from OpenAP and the arrival procedures, checked on hand-built paths and by the verification."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mal_planner.performance import UnknownAircraftType, cas_of_tas, performance_of, tas_of_cas
from mal_planner.scenario import ScenarioError, scenario_from_text
from mal_planner.trajectory import Trajectory
from mal_planner.units import METRES_PER_NM, ft_to_nm, kt_to_nm_per_s, nm_per_s_to_kt, nm_to_ft
from mal_planner.verification import verify
from mal_planner.verification.procedures import procedure_breaks

# A runway at the origin landing towards -x; aircraft 10 nm east, at 150 kt and 300 kt true airspeed.
REAL = """
name: procedures
runway: {{position: [0.0, 0.0, 0.0], flight_path_angle_deg: -3.0, heading_deg: 180.0}}
airspace: {{x: [-20.0, 20.0], y: [-20.0, 20.0], z: [-0.01, 3.0]}}
aircraft:
  - {{callsign: SLOW, position: [10.0, 4.0, 0.5], flight_path_angle_deg: -3.0, heading_deg: 180.0,
      speed: {slow}, aircraft_type: b738}}
  - {{callsign: FAST, position: [10.0, 0.0, 0.5240777928304121], flight_path_angle_deg: -3.0, heading_deg: 180.0,
      speed: {fast}}}
separation: {{distance_nm: 3.0, landing_spacing_s: 90.0, max_landing_spacing_s: 180.0}}
limits: {{bank_angle_deg: 30.0}}
{procedures}
"""


def real(procedures: str = "procedures: {aircraft_type: A320}"):
    return scenario_from_text(REAL.format(slow=kt_to_nm_per_s(150.0), fast=kt_to_nm_per_s(300.0),
                                          procedures=procedures))


def glide(speed: float, x0: float = 10.0, gamma_deg: float = -3.0, dt: float = 1.0):
    """Straight down a glide path towards the threshold at the origin (heading 180 deg) until the threshold."""
    gamma = math.radians(gamma_deg)
    duration = x0 / (speed * math.cos(gamma))
    t = np.linspace(0.0, duration, max(3, int(duration / dt)))
    x = np.zeros((len(t), 5))
    x[:, 0] = x0 - speed * math.cos(gamma) * t
    x[:, 2] = -math.tan(gamma) * x[:, 0]
    x[:, 3], x[:, 4] = gamma, math.pi
    return t, x


def test_performance_is_openaps() -> None:
    from openap import WRAP, prop

    a320 = performance_of("a320")
    assert a320.final_approach_cas.default * METRES_PER_NM == pytest.approx(WRAP("A320").finalapp_vcas()["default"])
    assert a320.descent_rate.low * METRES_PER_NM == pytest.approx(WRAP("A320").descent_vs_concas()["minimum"])
    assert nm_per_s_to_kt(a320.vmo) == pytest.approx(prop.aircraft("A320")["vmo"])
    assert a320.source.startswith("OpenAP ") and a320.source.endswith("A320")
    assert performance_of("A20N").type_code == "A20N"  # a synonym OpenAP resolves
    # VMO near the ground; MMO (less than VMO in CAS) at FL350
    assert float(a320.max_cas(ft_to_nm(5000.0))) == a320.vmo
    assert nm_per_s_to_kt(float(a320.max_cas(ft_to_nm(35000.0)))) < 300.0
    # true and calibrated airspeeds: equal at sea level, TAS higher aloft, each the other's inverse
    v = kt_to_nm_per_s(250.0)
    assert float(cas_of_tas(v, 0.0)) == pytest.approx(v, rel=1e-9)
    assert float(tas_of_cas(v, ft_to_nm(10000.0))) > 1.15 * v
    assert float(cas_of_tas(tas_of_cas(v, 1.0), 1.0)) == pytest.approx(v, rel=1e-9)
    with pytest.raises(UnknownAircraftType, match="'ZZ99' is not in OpenAP"):
        performance_of("ZZ99")


def test_scenario_names_types_and_procedures() -> None:
    sc = real()
    assert [sc.type_of(a) for a in sc.aircraft] == ["B738", "A320"]
    assert sc.procedures.final_speed == kt_to_nm_per_s(180.0)
    assert real("").procedures is None and real("").type_of(real("").aircraft[1]) is None
    with pytest.raises(ScenarioError, match=r"^<scenario>: aircraft\[0\].aircraft_type: aircraft type 'XY12' is not"):
        scenario_from_text(REAL.format(slow=0.04, fast=0.08, procedures="").replace("b738", "XY12"))
    with pytest.raises(ScenarioError, match=r"procedures.speed_limit_kt"):
        real("procedures: {speed_limit_kt: -250}")


def test_a_stable_approach_keeps_every_rule() -> None:
    sc = real()
    slow = sc.aircraft[0]
    assert procedure_breaks(sc, slow, *glide(slow.speed)) == []
    assert procedure_breaks(real(""), sc.aircraft[1], *glide(sc.aircraft[1].speed)) == []  # no procedures: no rules


def test_each_rule_is_caught() -> None:
    sc = real()
    slow, fast = sc.aircraft
    breaks = [b.text for b in procedure_breaks(sc, fast, *glide(fast.speed))]
    assert any("limit 250 kt below 10000 ft" in b for b in breaks)
    assert any("limit 180 kt inside 4 nm" in b for b in breaks)
    assert all(b.startswith("FAST (A320): ") for b in breaks)
    steep = [b.text for b in procedure_breaks(sc, slow, *glide(slow.speed, gamma_deg=-12.0))]  # 3,200 ft/min at 150 kt
    assert any("vertical speed" in b for b in steep)
    t, x = glide(slow.speed)
    x[:, 2] += ft_to_nm(1600.0) * np.maximum(0.0, 1.0 - np.abs(t / t[-1] - 0.5) / 0.1)  # up 1,600 ft and down
    assert any("climbs" in b.text for b in procedure_breaks(sc, slow, t, x))
    t, x = glide(slow.speed)
    x[(x[:, 0] > 5.0) & (x[:, 0] < 7.0), 2] = ft_to_nm(800.0)  # 800 ft 5-7 nm out
    low = [b.text for b in procedure_breaks(sc, slow, t, x)]
    assert any("at least 1000 ft beyond 4 nm" in b for b in low) and not any("flies away" in b for b in low)
    t, x = glide(slow.speed)
    x[:, 0] = 2.0 + np.cos(t / t[-1] * 2 * np.pi)  # a loop at 500 ft, 1-3 nm out
    x[:, 2] = ft_to_nm(500.0)
    assert any("flies away from the threshold 500 ft above it" in b.text for b in procedure_breaks(sc, slow, t, x))


def test_the_verification_refuses_a_plan_that_breaks_a_rule() -> None:
    t, x = glide(kt_to_nm_per_s(300.0))
    plan = Trajectory("FAST", t, x, np.tile((0.0, math.cos(x[0, 3])), (len(t), 1)))
    assert verify(real(""), [plan]).verified  # a straight glide to the threshold, at 300 kt
    refused = verify(real(), [plan])
    assert not refused.verified and any(r.startswith("FAST (A320): ") and "limit 250 kt" in r for r in refused.reasons)


HIGH = """
name: high
runway: {position: [0.0, 0.0, 0.0], flight_path_angle_deg: -3.0, heading_deg: 180.0}
airspace: {x: [-20.0, 20.0], y: [-20.0, 20.0], z: [0.0, 2.0]}
aircraft:
  - {callsign: HIGH, position: [12.0, 3.0, 1.3], flight_path_angle_deg: 0.0, heading_deg: 180.0, speed: 0.0414}
  - {callsign: LOW, position: [14.0, -6.0, 0.5], flight_path_angle_deg: 0.0, heading_deg: 150.0, speed: 0.0414}
separation: {distance_nm: 3.0, landing_spacing_s: 90.0, max_landing_spacing_s: 180.0}
limits: {bank_angle_deg: 30.0, n_h: [-1.0, 1.0], n_v: [0.7, 1.3]}
"""


def test_the_optimizer_keeps_the_profile_rules() -> None:
    """HIGH starts 7,900 ft high 12 nm out at 149 kt true airspeed: without the procedures its plan climbs (for room:
    its landing is 90 s after nobody); with them it descends within the A320's rate, never climbs and is verified
    under every rule (its constant speed keeps the speed rules: 132 kt CAS up there, 149 kt over the threshold, the
    A320's final approach speeds being 130-150 kt)."""
    from mal_planner.options import PlanOptions
    from mal_planner.pipeline import plan

    ruled = scenario_from_text(HIGH + "procedures: {aircraft_type: A320}\n")
    free = plan(scenario_from_text(HIGH), PlanOptions(seed=0))
    assert free.verification.verified
    broken = [b.text for tr in free.trajectories() for b in
              procedure_breaks(ruled, ruled.aircraft_by_callsign(tr.callsign), tr.t, tr.states)]
    assert any("HIGH (A320): climbs" in b for b in broken)
    kept = plan(ruled, PlanOptions(seed=0))
    assert kept.verification.verified, kept.verification.reasons
    for tr in kept.trajectories():
        z = tr.states[:, 2]  # level at most at the collocation points, a few feet between them
        assert float(np.max(z - np.minimum.accumulate(z))) < ft_to_nm(10.0)


def test_a_high_aircraft_cannot_land_before_it_has_descended() -> None:
    """7,900 ft high 3 nm out: 64 s in a straight line, but at the A320's steepest 2,890 ft/min (OpenAP) 164 s;
    with procedures no plan that keeps them lands sooner, and the sequencer knows it."""
    from mal_planner.sequencing.timing import earliest_landing_time, reachable_lower_bound

    text = HIGH.replace("position: [12.0, 3.0, 1.3]", "position: [3.0, 0.0, 1.3]")
    ruled, free = scenario_from_text(text + "procedures: {aircraft_type: A320}\n"), scenario_from_text(text)
    high = ruled.aircraft_by_callsign("HIGH")
    steepest = -performance_of("A320").descent_rate.low
    assert reachable_lower_bound(ruled, high) == pytest.approx(1.3 / steepest)
    assert reachable_lower_bound(free, free.aircraft_by_callsign("HIGH")) < 0.5 * 1.3 / steepest
    assert earliest_landing_time(ruled, high) >= 1.3 / steepest


def test_an_aircraft_starting_at_the_minimum_height_starts_above_the_nlps_floor() -> None:
    """The floor of an aircraft that starts at (or below) the minimum height beyond 4 nm is its first height less
    the NLP's margin: it starts above it (the margin the NLP keeps), and the rule's own floor is its first height."""
    from mal_planner.landing.profile import floor_height

    sc = real()
    slow = sc.aircraft[0]  # 10 nm out
    at_minimum = dataclasses.replace(slow, state0=np.array([10.0, 4.0, ft_to_nm(1000.0), 0.0, math.pi]))
    margin = 1e-3
    for ac in (slow, at_minimum):
        floor = float(floor_height(sc, ac, *ac.state0[:2], margin))
        assert ac.state0[2] - floor >= margin - 1e-12
        assert floor <= ft_to_nm(1000.0)


def test_the_nlps_floor_keeps_the_minimum_height_a_little_inside_the_final_distance() -> None:
    """A path that rides the floor bends down at its knee and starts down a little before it (between collocation
    points, and flown by its controls): the NLP's knee is inside the rules' 4 nm, so that the dip comes where the rules
    ask nothing (10 airliners, at the rules' knee: 8 of 10 plans dipped 0-1 ft below 1,000 ft 4.0-4.2 nm out and were
    solved again)."""
    from mal_planner.landing.profile import floor_height

    sc = real()
    slow, rules = sc.aircraft[0], sc.procedures

    def floor(distance_nm: float) -> float:  # the runway is at the origin
        return float(floor_height(sc, slow, distance_nm, 0.0, 1e-3))

    final, minimum = rules.final_distance_nm, rules.min_height_nm
    assert floor(2.0 * final) == pytest.approx(minimum) and floor(final) == pytest.approx(minimum)
    assert floor(0.97 * final) == pytest.approx(minimum)
    assert floor(0.9 * final) < minimum and floor(0.0) < 0.0


def test_the_final_speed_holds_on_the_final_approach_not_over_the_airport() -> None:
    """Level across the threshold at 300 kt: at 1,500 ft it is on the final approach and breaks the 180-kt rule; at
    13,000 ft (above the glide path at 4 nm plus the minimum height: 2,270 ft) it overflies the airport and does not."""
    sc = real()
    fast = sc.aircraft[1]
    for height_ft, broken in ((1500.0, True), (13000.0, False)):
        t = np.linspace(0.0, 200.0, 401)
        x = np.zeros((len(t), 5))
        x[:, 0] = 10.0 - fast.speed * t
        x[:, 2] = ft_to_nm(height_ft)
        x[:, 4] = math.pi
        texts = [b.text for b in procedure_breaks(sc, fast, t, x)]
        assert any("inside 4 nm" in b for b in texts) == broken, texts
    assert nm_to_ft(sc.procedures.final_approach_height(math.radians(-3.0))) == pytest.approx(2274.0, abs=1.0)
