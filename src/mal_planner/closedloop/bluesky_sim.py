"""BlueSky as the closed loop's simulator: the plans flown by an independent simulator's aircraft and autopilot.

:class:`BlueSkySimulator` stands in for :class:`~mal_planner.closedloop.simulator.FlightSimulator` behind the same
interface (``t``, ``done``, ``advance``, ``set_plan``, ``measurements``, ``aircraft``, ``flown``), so the closed
loop, its metrics and its figure run unchanged. BlueSky (bluesky-simulator 1.1.1, optional extra ``bluesky``)
flies each aircraft with its own performance model (OpenAP, an A320) and autopilot, the way the BlueSky export
(:mod:`mal_planner.geo.bluesky`) does:

* each aircraft is created at its scenario state (``CRE``: its air heading made true, its true airspeed made CAS)
  and banks at its plan's limit (``BANK``; BlueSky's default is 25 deg);
* a plan, once flown (after the uptake delay, as in ``FlightSimulator``), replaces the route: ``DELRTE``, then
  ``ADDWPT`` one plan sample per turn time / 4 from then on, ending a turn time beyond the plan's end on its
  final line (so that an aircraft flies on through the threshold, and a late one does not turn back), then
  ``LNAV``/``VNAV ON``;
* time moves in BlueSky's own step (0.05 s); a plan is taken up at the first step at or after its time;
* the state read back is converted to the runway frame: the position, the air heading (BlueSky's heading, not
  its track) and the air-path angle asin(vertical speed / TAS); the heading is kept continuous;
* landings, missed approaches and exits are ``FlightSimulator``'s (same touchdown window), judged on the states
  read back; an aircraft whose flight ends is deleted from BlueSky;
* the mean wind is BlueSky's ``WIND`` (one point: the same wind everywhere; BlueSky applies it above 50 ft);
  BlueSky has no gusts, so gusts are refused;
* BlueSky's own conflict detection runs at the scenario's minima (``ASAS ON``, ``ZONER``/``ZONEDH``, as in the
  export): its losses of separation are :attr:`BlueSkySimulator.external_los_pairs`.

A local scenario is placed on the Earth by :data:`DEFAULT_FRAME` (its own geodetic frame, if it has one, wins).
BlueSky keeps global state: one simulation per process, reset for each new simulator
(:func:`mal_planner.geo.bluesky.start_bluesky`).
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np

from mal_planner.closedloop.simulator import FlightSimulator, SimAircraft, SimOptions
from mal_planner.geo.bluesky import (
    create_commands,
    detection_commands,
    route_commands,
    run_commands,
    start_bluesky,
    waypoint_interval_s,
    wind_command,
)
from mal_planner.geodesy import GeoFrame
from mal_planner.performance import DEFAULT_TYPE
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.units import m_to_ft, nm_per_s_to_kt

DEFAULT_FRAME = GeoFrame(49.02667786, 2.56169447, 392.0, 265.43)
"""Where a local scenario is flown: Paris-CDG 27R, where ``scenarios/thesis_geodetic.yaml`` places the thesis (an
elevation above BlueSky's 50 ft, below which it applies no wind)."""
EXTENSION_TURN_TIMES = 1.0
"""The route goes on this long past the plan's end, along its final line."""


def bluesky_available() -> bool:
    """True when bluesky-simulator is installed."""
    return importlib.util.find_spec("bluesky") is not None


class BlueSkySimulator(FlightSimulator):
    """The scenario's aircraft flown by BlueSky (see the module docstring); ``FlightSimulator``'s interface."""

    def __init__(self, scenario: Scenario, options: SimOptions | None = None, t0: float = 0.0,
                 frame: GeoFrame | None = None, workdir: str | Path | None = None,
                 aircraft_type: str | None = None, bank_angle_max: float | None = None) -> None:
        """``bank_angle_max`` (rad): the bank BlueSky turns at; None: each aircraft's limit, the plan's.
        ``aircraft_type``: BlueSky's type of every aircraft; None: each one's in the scenario, else
        :data:`~mal_planner.performance.DEFAULT_TYPE`."""
        options = options or SimOptions()
        if options.wind.gust_sigma > 0.0:
            raise ValueError("BlueSky flies a steady wind: no gusts (FlightSimulator has them)")
        variable = [a.callsign for a in scenario.aircraft if a.dynamics.variable_airspeed]
        if variable:
            raise ValueError(f"aircraft {variable[0]}: the BlueSky closed loop flies constant-speed plans only "
                             "(the airspeed model: the FlightSimulator, or the mal-plan export)")
        super().__init__(scenario, options, t0)
        self.frame = frame or scenario.geo_frame or DEFAULT_FRAME
        self.bs = start_bluesky(workdir)
        self.step_s = float(self.bs.sim.simdt)
        self.waypoint_dt = waypoint_interval_s(scenario)
        self.extension_s = Scales.of(scenario).seconds(EXTENSION_TURN_TIMES)
        self._t0 = float(t0)
        self.external_los_pairs: list[tuple[str, str]] = []
        """BlueSky's own losses of separation (pairs of callsigns, a pair again each time it enters one)."""
        commands = detection_commands(scenario)
        wind = wind_command(self.frame, options.wind.mean)
        commands += [wind] if wind else []
        for ac, spec in zip(self.aircraft, scenario.aircraft, strict=True):
            commands += create_commands(ac.callsign, self.frame, ac.state, nm_per_s_to_kt(ac.model.speed),
                                        bank_angle_max or spec.limits.bank_angle_max,
                                        aircraft_type or scenario.type_of(spec) or DEFAULT_TYPE)
        run_commands(self.bs, commands)

    # -- time ------------------------------------------------------------------------------------------
    def _clock(self) -> float:
        return self._t0 + float(self.bs.sim.simt)

    def advance(self, t_end: float) -> None:
        """Fly BlueSky's steps up to ``t_end`` (to the nearest step)."""
        while self._clock() + 0.5 * self.step_s <= t_end and not self.done:
            self._step(self.step_s)
        self.t = max(self.t, t_end)

    def _step(self, dt: float) -> None:
        """One BlueSky step (``dt`` is always its own): plans taken up, BlueSky stepped, the states read back."""
        now = self._clock()
        commands: list[str] = []
        for ac in self.aircraft:
            while ac.flying and ac.pending and ac.pending[0][0] <= now + 1e-9:
                ac.reference = ac.pending.pop(0)[1]
                commands += self._route(ac, now)
        if commands:
            run_commands(self.bs, commands)
        self.bs.sim.step()
        t_next = self._clock()
        traf = self.bs.traf
        ended = []
        for ac in self.aircraft:
            if not ac.flying:
                continue
            k = traf.id.index(ac.callsign.upper())
            before = ac.state
            ac.state = self._local_state(float(traf.lat[k]), float(traf.lon[k]), float(traf.alt[k]),
                                         float(traf.hdg[k]), float(traf.vs[k]), float(traf.tas[k]), before[4])
            ac.loads = self._loads(ac, before, t_next - ac.t[-1])
            self._after_step(ac, before, t_next)
            if not ac.flying:
                ended.append(f"DEL {ac.callsign}")
        if ended:
            run_commands(self.bs, ended)
        if len(traf.cd.lospairs_all) != len(self.external_los_pairs):
            self.external_los_pairs = [tuple(sorted(p)) for p in traf.cd.lospairs_all]  # type: ignore[misc]
        self.t = t_next

    # -- conversions -----------------------------------------------------------------------------------
    def _route(self, ac: SimAircraft, now: float) -> list[str]:
        """The commands that make ``ac`` fly its (new) reference from ``now``: the old route deleted first."""
        ref = ac.reference
        if ref is None:
            return [f"DELRTE {ac.callsign}"]
        ac.plans.append(ref)
        ac.plan_arrivals.append(now)
        t_on = ref.end + self.extension_s
        t = np.append(ref.t, t_on)
        states = np.vstack([ref.table[:, :5], ref.sample(t_on)[:5]])
        return [f"DELRTE {ac.callsign}", *route_commands(ac.callsign, self.frame, t, states,
                                                         nm_per_s_to_kt(ac.model.speed), self.waypoint_dt, now)]

    def _local_state(self, lat: float, lon: float, alt_m: float, hdg_deg: float, vs: float, tas: float,
                     previous_heading: float) -> np.ndarray:
        """BlueSky's aircraft (deg, m, m/s) as a planner state [x, y, z, gamma, heading] (nm, rad), the heading
        continuous with ``previous_heading``."""
        position = self.frame.to_local(lat, lon, m_to_ft(alt_m))
        fpa = math.degrees(math.asin(min(max(vs / tas, -1.0), 1.0))) if tas > 0.0 else 0.0
        heading, gamma = self.frame.direction_to_local(lat, lon, hdg_deg, fpa)
        heading = previous_heading + (heading - previous_heading + math.pi) % (2.0 * math.pi) - math.pi
        return np.array([*position, gamma, heading])

    @staticmethod
    def _loads(ac: SimAircraft, before: np.ndarray, dt: float) -> np.ndarray:
        """The load factors (n_h, n_v) BlueSky flew over the step, from the heading and path-angle rates."""
        if dt <= 0.0:
            return ac.loads
        v, g, gamma = ac.model.speed, ac.model.gravity, float(ac.state[3])
        rates = (ac.state[3:5] - before[3:5]) / dt
        return np.array([v * math.cos(gamma) * rates[1] / g, math.cos(gamma) + v * rates[0] / g])


def make_simulator(name: str):
    """The simulator factory of a name (``ours`` or ``bluesky``), for :class:`~mal_planner.closedloop.loop.ClosedLoop`;
    ValueError with a one-line reason if BlueSky is asked for and not installed."""
    if name == "ours":
        return FlightSimulator
    if name != "bluesky":
        raise ValueError(f"unknown simulator {name!r} (ours, bluesky)")
    if not bluesky_available():
        raise ValueError("--simulator bluesky: bluesky-simulator is not installed (pip install -e '.[bluesky]')")
    return BlueSkySimulator

