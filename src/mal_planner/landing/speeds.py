"""The speed envelope of an airspeed-model aircraft as the landing NLP keeps it (:class:`~mal_planner.dynamics.
AirspeedModel`; the verification checks the same limits on the flown path, with no tolerance).

Each row is >= 0 where the calibrated airspeed (CAS, from the true airspeed state and the altitude in OpenAP's ISA,
on CasADi symbols) keeps a limit, less :attr:`~mal_planner.landing.margins.Margins.speed_share` of it:

* the type's envelope: above its slowest final approach speed, below VMO/MMO (:mod:`mal_planner.performance`), and
  (a bound of the final state) at most its fastest final approach speed over the threshold;
* with arrival procedures, the speed limit below its altitude and the final approach speed inside the final
  distance. Both are step rules; the NLP keeps smooth cones above them that a real aircraft could still fly: above
  the limit's altitude the speed may be higher by what the altitude could buy at equal energy, V^2 <= V_limit^2 +
  2 g (h - h_limit), and beyond the final distance by what the type's idle deceleration in level flight takes off
  over the way, V^2 <= V_final^2 + 2 a (d - D) (+ 2 g (h - H) above the final approach's height H: the rule is for
  the final approach, not an aircraft overflying the airport). An aircraft that starts faster than a limit (a
  radar state) may instead slow down from its first speed, at half that deceleration once it has had a turn time to
  settle (the rules allow it to slow down to the limit);
* with arrival procedures, the descent rate V sin(gamma) within the rules' and the type's, less the reserve of
  :mod:`mal_planner.landing.profile` (where the constant-speed model bounds the flight-path angle instead).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import casadi as ca

from mal_planner.landing.profile import DISTANCE_SMOOTHING, RATE_RESERVE
from mal_planner.performance import Performance, cas_of_tas, performance_of, tas_of_cas
from mal_planner.scales import level_turn_radius
from mal_planner.scenario import Aircraft, Scenario
from mal_planner.scenario.procedures import Procedures
from mal_planner.units import METRES_PER_NM

SLOWING_SHARE = 0.5
"""The share of the type's idle deceleration in level flight an aircraft that starts too fast is asked for (it
descends at the same time)."""


KNEE_SHARE = 0.01
"""The knees of the cones (where the altitude passes the speed limit's, the distance the final distance) are rounded
over this share of that altitude or distance, from below: the NLP's limit is never above the rule's."""


def _below_max(a, b, width: float):
    """A smooth max(a, b), never above it: (a + b + sqrt((a - b)^2 + w^2)) / 2 - w / 2 (equal where a = b, within
    w / 2 of it elsewhere): IPOPT and the mesh refinement dislike kinks."""
    return 0.5 * (a + b + ca.sqrt((a - b) ** 2 + width**2)) - 0.5 * width


class StartSpeed(NamedTuple):
    """A measured airspeed brought into what the aircraft may fly (:func:`start_airspeed`)."""

    tas: float
    """The true airspeed it starts with (nm/s)."""
    measured_cas: float
    """The measurement's calibrated airspeed (nm/s)."""
    cas: float
    """The calibrated airspeed it starts with (nm/s; the measured one where that is inside)."""
    low: float
    high: float
    """The calibrated airspeeds it may start between (nm/s)."""


def start_airspeed(tas: float, altitude_nm: float, perf: Performance, rules: Procedures | None,
                   share: float) -> StartSpeed:
    """The airspeed an airspeed-model aircraft measured at true airspeed ``tas`` (nm/s) at pressure altitude
    ``altitude_nm`` starts with: between its type's slowest final approach speed and VMO/MMO and at most the
    procedures' speed limit below its altitude, ``share`` of each kept free (the NLP's speed share). A radar or ADS-B
    speed outside that is a ground speed in a wind nobody measured, or a measurement's error: a real airliner on
    final does not fly below its approach speed, nor one at 4,500 ft above 250 kt. Starting inside, the NLP keeps the
    rules from the first instant (a start above a limit must slow down at once, which a steep descent at idle cannot:
    its airspeed still rises for a second)."""
    keep = 1.0 - share
    cas = float(cas_of_tas(tas, altitude_nm))
    high = keep * float(perf.max_cas(altitude_nm))
    if rules is not None and altitude_nm < rules.speed_limit_below_nm:
        high = min(high, keep * rules.speed_limit)
    low = perf.final_approach_cas.low / keep
    kept = min(max(cas, low), high)
    return StartSpeed(tas if kept == cas else float(tas_of_cas(kept, altitude_nm)), cas, kept, low, high)


def cas_expression(tas, altitude_nm):
    """Calibrated airspeed (nm/s) of the true airspeed ``tas`` (nm/s) at pressure altitude ``altitude_nm`` (nm), on
    CasADi symbols (OpenAP's CasADi atmosphere, the same ISA as :func:`mal_planner.performance.cas_of_tas`)."""
    from openap.casadi import aero

    return aero.tas2cas(tas * METRES_PER_NM, altitude_nm * METRES_PER_NM) / METRES_PER_NM


def landing_airspeed(scenario: Scenario, aircraft: Aircraft, share: float) -> float:
    """The fastest true airspeed (nm/s) ``aircraft`` may cross the threshold at: its type's fastest final approach
    speed (CAS) less ``share`` of it, at the threshold's elevation (the final state's bound)."""
    perf = performance_of(scenario.type_of(aircraft))
    return float(tas_of_cas((1.0 - share) * perf.final_approach_cas.high, scenario.runway_state[2] +
                            scenario.elevation_nm))


@dataclass(frozen=True)
class SpeedRules:
    """The speed rows of one airspeed-model aircraft."""

    perf: Performance
    share: float
    """Of each limit kept free."""
    first_cas: float
    """Its calibrated airspeed at the start (nm/s)."""
    deceleration: float
    """Its idle deceleration in level flight (nm/s^2, > 0)."""
    settle_s: float
    """Its turn time (the time to turn one radian at its bank limit): an aircraft that starts too fast, descending,
    slows down at once only as much as its first flight-path angle allows; the required slowing grows to its rate
    over about this long (``a t^2 / (t + T)``: no slowing asked at t = 0, where its speed is given)."""
    procedures: bool

    @classmethod
    def of(cls, scenario: Scenario, aircraft: Aircraft, share: float) -> SpeedRules | None:
        """The rows of ``aircraft`` (None: its model's airspeed is constant)."""
        if not aircraft.dynamics.variable_airspeed:
            return None
        perf = performance_of(scenario.type_of(aircraft))
        state = aircraft.state0
        first = float(cas_of_tas(aircraft.dynamics.airspeed(state), state[2] + scenario.elevation_nm))
        deceleration = -aircraft.limits.n_x[0] * aircraft.dynamics.gravity
        settle = level_turn_radius(aircraft) / aircraft.speed
        return cls(perf, share, first, max(deceleration, 0.0), settle, scenario.procedures is not None)

    @property
    def n_rows(self) -> int:
        return 5 if self.procedures else 2

    def rows(self, state, scenario: Scenario, aircraft: Aircraft, t) -> list:
        """The rows (each >= 0; dimensionless, in shares of the type's final approach speed) at ``state``, time
        ``t``."""
        altitude = state[2] + scenario.elevation_nm
        cas = cas_expression(state[5], altitude)
        ref = self.perf.final_approach_cas.default
        keep = 1.0 - self.share
        slowing = self.first_cas - SLOWING_SHARE * self.deceleration * t**2 / (t + self.settle_s)
        top = ca.fmin(self.perf.vmo, cas_expression(self._mmo_tas(altitude), altitude))
        lowest = min(self.perf.final_approach_cas.low / keep, self.first_cas)  # a radar state may be slower
        # An aircraft slowing down from its first speed rides that branch from t = 0: an exact max keeps it feasible.
        out = [(cas - lowest) / ref, (ca.fmax(keep * top, slowing) - cas) / ref]
        if not self.procedures:
            return out
        rules = scenario.procedures
        above = _below_max(altitude - rules.speed_limit_below_nm, 0.0, KNEE_SHARE * rules.speed_limit_below_nm)
        limit = ca.sqrt((keep * rules.speed_limit) ** 2 + 2.0 * scenario.gravity * above)
        runway = scenario.runway_state
        smoothing = DISTANCE_SMOOTHING * rules.final_distance_nm  # smooth at the threshold (the final state)
        distance = ca.sqrt((state[0] - runway[0]) ** 2 + (state[1] - runway[1]) ** 2 + smoothing**2)
        beyond = _below_max(distance - rules.final_distance_nm, 0.0, KNEE_SHARE * rules.final_distance_nm)
        higher = _below_max(state[2] - runway[2] - rules.final_approach_height(float(runway[3])), 0.0,
                            KNEE_SHARE * rules.final_distance_nm)
        final = ca.sqrt((keep * rules.final_speed) ** 2 + 2.0 * self.deceleration * beyond +
                        2.0 * scenario.gravity * higher)
        sink = scenario.descent_rate_limit(aircraft) * (1.0 - RATE_RESERVE) + state[5] * ca.sin(state[3])
        return [*out, (ca.fmax(limit, slowing) - cas) / ref, (ca.fmax(final, slowing) - cas) / ref, sink / ref]

    def _mmo_tas(self, altitude_nm):
        from openap.casadi import aero

        return aero.mach2tas(self.perf.mmo, altitude_nm * METRES_PER_NM) / METRES_PER_NM
