"""The flight simulator: every aircraft flies its own dynamics model under guidance, in wind, until it lands.

A pure library (no ROS): the closed loop (:mod:`mal_planner.closedloop.loop`) and the simulator node
(:mod:`mal_planner.ros.radar_sim`) drive it the same way: :meth:`FlightSimulator.set_plan` hands an aircraft a
plan (it is flown after the uptake delay), :meth:`FlightSimulator.advance` moves time on,
:meth:`FlightSimulator.measurements` gives the radar's view.

Each aircraft is the scenario's model (the same registry the planner uses) with its airspeed, flown through
the true wind (mean plus its own gusts), with a first-order lag between the commanded and the flown load
factors (the roll and pitch response; 0 s: none). Controls are held over a step (the guidance's rate), the
states integrated by one classical Runge-Kutta step.

An aircraft lands when it crosses the runway threshold (the plane through the runway point across the runway
course) inside the touchdown window: within half the runway's width of the centreline and within the
threshold-crossing height band. Crossing the extended threshold line elsewhere close by is a missed approach;
an aircraft more than a turn radius outside the airspace has left it. Either ends its flight.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mal_planner.closedloop.disturbances import WindField, WindSpec
from mal_planner.closedloop.guidance import GuidanceGains, guidance_controls, plan_time
from mal_planner.dynamics import ControlLimits, DynamicsModel
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.trajectory import Reference
from mal_planner.units import ft_to_nm, m_to_ft, m_to_nm, nm_to_m

STEPS_PER_TURN_TIME = 40
"""Guidance and integration steps per turn time (thesis: 0.19 s; a terminal area at 150 kt and 30 deg: 0.34 s)."""
RUNWAY_WIDTH_M = 45.0
"""ICAO Annex 14's runway width for code letters D-F (wide-bodies): the centreline +- 22.5 m is on the runway."""
THRESHOLD_HEIGHT_BAND_FT = 100.0
"""How high above the runway's threshold an aircraft may cross it: an ILS's reference datum is 50 ft above the
threshold; below the threshold's elevation an aircraft is in the ground, above 100 ft it lands too long (the flown
plans cross it at their airspace margin, thesis 15 ft, a terminal area 29 ft)."""
LOAD_FACTOR_LAG_S = 0.5
"""Time constant of the flown load factors behind the commanded ones: a transport aircraft's roll mode."""

FLYING, LANDED, MISSED, LEFT = "flying", "landed", "missed approach", "left the airspace"


@dataclass
class SimAircraft:
    callsign: str
    model: DynamicsModel
    """The aircraft's model in still air (the simulator adds the true wind)."""
    limits: ControlLimits
    state: np.ndarray
    wake: str | None = None
    loads: np.ndarray = field(default_factory=lambda: np.zeros(2))
    reference: Reference | None = None
    pending: list[tuple[float, Reference]] = field(default_factory=list)
    """Plans received and not yet flown: (time from which it is flown, plan)."""
    status: str = FLYING
    end_time: float | None = None
    end_note: str = ""
    t: list[float] = field(default_factory=list)
    states: list[np.ndarray] = field(default_factory=list)
    controls: list[np.ndarray] = field(default_factory=list)
    deviation_nm: float = 0.0
    """Largest distance from the plan being flown, over the flight."""
    plans: list[Reference] = field(default_factory=list)
    """Every plan flown, in order."""
    plan_arrivals: list[float] = field(default_factory=list)
    """When each began to be flown."""
    progress: tuple[float, float] | None = None
    """The clock and the plan's time where the aircraft was on its plan a step before (path following; None: none
    yet)."""

    @property
    def flying(self) -> bool:
        return self.status == FLYING


@dataclass(frozen=True)
class SimOptions:
    wind: WindSpec = WindSpec()
    step_s: float | None = None
    """Guidance and integration step; None: the turn time / STEPS_PER_TURN_TIME."""
    plan_delay_s: float = 0.0
    """Time between a plan's arrival and its being flown (crew and datalink)."""
    load_factor_lag_s: float = LOAD_FACTOR_LAG_S
    seed: int | None = 0


class FlightSimulator:
    """All aircraft of a scenario, flown together in simulated time ``t`` (s, the scenario's clock)."""

    def __init__(self, scenario: Scenario, options: SimOptions | None = None, t0: float = 0.0) -> None:
        self.options = opts = options or SimOptions()
        self.scenario = scenario
        scales = Scales.of(scenario)
        self.gains = GuidanceGains.for_turn_time(scales.time_s)
        self.step_s = opts.step_s or scales.time_s / STEPS_PER_TURN_TIME
        self.t = float(t0)
        self.aircraft = [SimAircraft(a.callsign, a.dynamics.with_wind(0.0, 0.0), a.limits,
                                     np.asarray(a.state0, float).copy(), a.wake_category)
                         for a in scenario.aircraft]
        for ac in self.aircraft:
            ac.loads = ac.model.level_flight_control(float(ac.state[3]))
            self._record(ac)
        self.wind = WindField(opts.wind, len(self.aircraft), opts.seed)
        self._runway = np.asarray(scenario.runway_state, float)
        self._lost_beyond = scales.length_nm
        self._half_width = m_to_nm(RUNWAY_WIDTH_M / 2.0)
        self._band = ft_to_nm(THRESHOLD_HEIGHT_BAND_FT)

    # -- plans ----------------------------------------------------------------------------------------
    def by_callsign(self, callsign: str) -> SimAircraft | None:
        return next((ac for ac in self.aircraft if ac.callsign == callsign), None)

    def set_plan(self, callsign: str, reference: Reference | None, received_at: float | None = None) -> bool:
        """Fly ``reference`` from ``received_at`` (default: now) plus the uptake delay, or from its start if that is
        later; None withdraws the plan.

        False for an unknown callsign."""
        ac = self.by_callsign(callsign)
        if ac is None:
            return False
        at = (self.t if received_at is None else received_at) + self.options.plan_delay_s
        if reference is not None:  # a plan that starts later is flown from its start (the previous one until then)
            at = max(at, reference.start)
        if reference is None:
            ac.pending.append((at, None))  # type: ignore[arg-type]
        else:
            ac.pending.append((at, reference))
        return True

    # -- time ------------------------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        return not any(ac.flying for ac in self.aircraft)

    def advance(self, t_end: float) -> None:
        """Fly every aircraft up to time ``t_end`` in guidance steps (the last one shortened to end there)."""
        while self.t < t_end - 1e-9 * max(1.0, abs(t_end)) and not self.done:
            self._step(min(self.step_s, t_end - self.t))
        self.t = max(self.t, t_end)

    def _step(self, dt: float) -> None:
        self.wind.step(dt)
        wind = self.wind.current()
        decay = math.exp(-dt / self.options.load_factor_lag_s) if self.options.load_factor_lag_s > 0 else 0.0
        t_next = self.t + dt
        for k, ac in enumerate(self.aircraft):
            if not ac.flying:
                continue
            while ac.pending and ac.pending[0][0] <= self.t:
                ac.reference, ac.progress = ac.pending.pop(0)[1], None
                if ac.reference is not None:
                    ac.plans.append(ac.reference)
                    ac.plan_arrivals.append(self.t)
            s = None
            if ac.reference is not None:
                s = plan_time(ac.reference, ac.state, self.t, self.gains, ac.progress)
                ac.progress = (self.t, s)
            command = guidance_controls(ac.model, ac.limits, self.gains, ac.state, wind[k], ac.reference,
                                        self.t, self.options.load_factor_lag_s, s)
            ac.loads = command + (ac.loads - command) * decay
            before = ac.state
            ac.state = ac.model.with_wind(wind[k, 0], wind[k, 1]).rk4_step(before, ac.loads, dt)
            self._after_step(ac, before, t_next)
        self.t = t_next

    def _after_step(self, ac: SimAircraft, before: np.ndarray, t: float) -> None:
        rw = self._runway
        course = np.array([math.cos(rw[4]), math.sin(rw[4])])
        s0 = float(np.dot(before[:2] - rw[:2], course))
        s1 = float(np.dot(ac.state[:2] - rw[:2], course))
        if s0 < 0.0 <= s1:  # crossed the threshold's plane, in the landing direction
            w = -s0 / (s1 - s0)
            cross = before + w * (ac.state - before)
            off = cross[:2] - rw[:2]
            lateral = float(course[0] * off[1] - course[1] * off[0])
            height = float(cross[2] - rw[2])
            if abs(lateral) <= self._lost_beyond and abs(height) <= self._lost_beyond:
                t_cross = t - (1.0 - w) * (t - ac.t[-1])
                ac.state = cross
                inside = abs(lateral) <= self._half_width and 0.0 <= height <= self._band
                self._end(ac, LANDED if inside else MISSED, t_cross,
                          f"threshold crossed {nm_to_m(lateral):+.1f} m from the centreline, "
                          f"{m_to_ft(nm_to_m(height)):+.0f} ft from the touchdown height")
                return
        lo, hi = self.scenario.airspace[:, 0], self.scenario.airspace[:, 1]
        if np.any(ac.state[:3] < lo - self._lost_beyond) or np.any(ac.state[:3] > hi + self._lost_beyond):
            self._end(ac, LEFT, t, f"left the airspace at {np.round(ac.state[:3], 3).tolist()} nm")
            return
        self._record(ac, t)

    def _end(self, ac: SimAircraft, status: str, t: float, note: str) -> None:
        ac.status, ac.end_time, ac.end_note = status, t, note
        self._record(ac, t)

    def _record(self, ac: SimAircraft, t: float | None = None) -> None:
        t = self.t if t is None else t
        ac.t.append(t)
        ac.states.append(ac.state.copy())
        ac.controls.append(ac.loads.copy())
        if ac.reference is not None and t <= ac.reference.end:
            ac.deviation_nm = max(ac.deviation_nm, float(np.linalg.norm(ac.reference.position(t) - ac.state[:3])))

    # -- outputs ---------------------------------------------------------------------------------------
    @staticmethod
    def radar_state(ac: SimAircraft) -> np.ndarray:
        """What a radar reports of ``ac``: its state with the heading in [-pi, pi) (the simulator's is continuous and
        passes 2 pi in a hold, which the service's gate rightly takes for degrees): (x, y, z, gamma, heading), its
        airspeed apart (:meth:`radar_speed`)."""
        state = ac.state[:5].copy()
        state[4] = (state[4] + math.pi) % (2.0 * math.pi) - math.pi
        return state

    @staticmethod
    def radar_speed(ac: SimAircraft) -> float:
        """The airspeed a track of ``ac`` reports (nm/s; air data, as ADS-B's airspeed reports)."""
        return float(ac.model.airspeed(ac.state))

    def measurements(self) -> list[SimAircraft]:
        """The aircraft still flying (their radar tracks; noise is the caller's)."""
        return [ac for ac in self.aircraft if ac.flying]

    def flown(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Per aircraft: (times, states) it flew, up to its landing or exit."""
        return {ac.callsign: (np.asarray(ac.t), np.asarray(ac.states)) for ac in self.aircraft}
