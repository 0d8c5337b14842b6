"""Flight simulator node: flies a scenario's aircraft under guidance and publishes their (noisy) radar tracks.

Each aircraft flies its dynamics model (:class:`mal_planner.closedloop.FlightSimulator`): it follows the latest
plan received as ``nav_msgs/Path`` on ``aircraft/<callsign>/path`` with the path-following guidance, in the
scenario's wind plus seeded gusts, and holds its heading and levels off without a plan. Tracks go out as
``mal_msgs/AircraftState`` on ``aircraft/<callsign>/state`` and/or ``radar/tracks``, stamped with simulated
time (start + t), which ``--clock`` also publishes on ``/clock`` (nodes with ``use_sim_time`` follow it).
An aircraft that lands (or leaves) is no longer tracked; ``--until-landed`` stops once every one has, with a
summary of what was flown (``<--out>/closed_loop.json``).

    python -m mal_planner.ros.radar_sim --scenario scenarios/thesis.yaml --rate 2 --noise-m 5 --duration 60
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from mal_planner import jsonio
from mal_planner.closedloop.disturbances import RadarNoise, WindSpec
from mal_planner.closedloop.simulator import FlightSimulator, SimAircraft, SimOptions
from mal_planner.ros.bagio import stop_event
from mal_planner.ros.convert import path_to_planner, planner_to_aircraft_state, time_to_msg
from mal_planner.scenario import Scenario, ScenarioError, load_scenario
from mal_planner.trajectory import Reference
from mal_planner.units import PLANNER_FRAME, kt_to_nm_per_s

STATE_TYPE = "mal_msgs/msg/AircraftState"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"


PROGRESS_PERIOD_S = 10.0
"""A progress line every this many wall-clock seconds: simulated time, aircraft airborne and landed."""
FIRST_PATHS_WAIT_S = 2.0
"""Wall-clock seconds the simulated time still stands after the first path for the others of the first plan."""


class Progress:
    """Prints where a long run is, every ``period_s`` wall-clock seconds."""

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self.next_at = time.monotonic() + period_s

    def tick(self, sim: FlightSimulator) -> None:
        if time.monotonic() < self.next_at:
            return
        self.next_at = time.monotonic() + self.period_s
        flying = len(sim.measurements())
        print(f"radar_sim: t = {sim.t:.0f} s simulated, {flying} airborne, {len(sim.aircraft) - flying} landed or "
              "gone", flush=True)


class RadarSimulator:
    """The simulated aircraft and their radar (no DDS): advance with :meth:`step_to`, read :meth:`measurements`.

    Times are absolute (the radar clock): the simulation's time 0 is ``t0``.
    """

    def __init__(self, scenario: Scenario, t0: float = 0.0, noise_m: float = 0.0, seed: int | None = None,
                 options: SimOptions | None = None) -> None:
        self.t0 = float(t0)
        self.sim = FlightSimulator(scenario, options or SimOptions(wind=WindSpec(scenario.wind), seed=seed))
        self.noise = RadarNoise(noise_m, None if seed is None else seed + 1)

    @property
    def t(self) -> float:
        return self.t0 + self.sim.t

    @property
    def tracks(self) -> list[SimAircraft]:
        return self.sim.aircraft

    def set_plan(self, callsign: str, stamps: np.ndarray, states: np.ndarray) -> bool:
        """Fly ``states`` at absolute ``stamps`` [s] (a Path message; empty: none); False for unknown callsigns."""
        reference = Reference(np.asarray(stamps, float) - self.t0, states) if len(stamps) >= 2 else None
        return self.sim.set_plan(callsign, reference)

    def step_to(self, t: float) -> None:
        """Advance every aircraft to absolute time ``t`` [s]."""
        self.sim.advance(t - self.t0)

    def measurements(self) -> list[tuple[str, np.ndarray, float, str | None]]:
        """``(callsign, state, airspeed nm/s, wake)`` of every aircraft still flying, with position noise."""
        return [(ac.callsign, self.noise.apply(self.sim.radar_state(ac)), self.sim.radar_speed(ac), ac.wake)
                for ac in self.sim.measurements()]


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="mal-radar-sim", description=__doc__.split("\n")[0])
    p.add_argument("--scenario", required=True, help="scenario YAML file (its wind: is the mean wind flown)")
    p.add_argument("--rate", type=float, default=2.0, help="publish rate [Hz] (default 2)")
    p.add_argument("--noise-m", type=float, default=0.0, help="position noise sigma [m] (default 0)")
    p.add_argument("--duration", type=float, default=0.0, help="simulated seconds, 0 = forever (default 0)")
    p.add_argument("--seed", type=int, default=None, help="seed of the noise and the gusts")
    p.add_argument("--topics", choices=("per-aircraft", "shared", "both"), default="both")
    p.add_argument("--namespace", default="", help="node namespace")
    p.add_argument("--no-follow", action="store_true", help="ignore plans on aircraft/<callsign>/path")
    p.add_argument("--gust-kt", type=float, default=0.0, help="gusts, rms per horizontal axis [kt] (default 0)")
    p.add_argument("--delay-s", type=float, default=0.0, help="delay before a received plan is flown [s]")
    p.add_argument("--speed", type=float, default=1.0, help="simulated seconds per wall-clock second (default 1)")
    p.add_argument("--clock", action="store_true", help="publish the simulated time on /clock")
    p.add_argument("--wait-for-plan", type=float, default=0.0, metavar="S",
                   help="hold the simulated time (tracks still published) until the first plan arrives, at most S "
                        "wall-clock seconds (default 0: do not wait)")
    p.add_argument("--until-landed", action="store_true", help="stop when every aircraft has landed (or left)")
    p.add_argument("--out", default=None, help="folder for closed_loop.json (with --until-landed)")
    args = p.parse_args(argv)
    if args.rate <= 0 or args.noise_m < 0 or args.duration < 0 or args.gust_kt < 0 or args.delay_s < 0 \
            or args.speed <= 0 or args.wait_for_plan < 0:
        p.error("--rate and --speed must be > 0; --noise-m, --duration, --gust-kt, --delay-s, --wait-for-plan >= 0")
    return args


def _checked_inputs(args: argparse.Namespace) -> tuple[Scenario, WindSpec] | str:
    """The scenario and the wind to fly, or why not (one line)."""
    try:
        scenario = load_scenario(args.scenario)
    except ScenarioError as exc:
        return str(exc)
    wind = WindSpec(scenario.wind, kt_to_nm_per_s(args.gust_kt))
    if wind.speed + 3.0 * wind.gust_sigma >= min(a.speed * math.cos(a.state0[3]) for a in scenario.aircraft):
        return "--gust-kt: the wind plus 3 x the gusts is not below the slowest airspeed"
    return scenario, wind


class SimulatorNode:
    """The simulator on a node: radar out on a timer, plans in on each aircraft's path topic."""

    def __init__(self, args: argparse.Namespace, scenario: Scenario, wind: WindSpec) -> None:
        from mal_planner.ros.transport import QOS_DEFAULT, QOS_LATCHED, create_node

        self.args = args
        self.node = node = create_node("radar_sim", args.namespace)
        self.log = node.get_logger()
        options = SimOptions(wind=wind, plan_delay_s=args.delay_s, seed=args.seed)
        self.sim = sim = RadarSimulator(scenario, t0=node.now(), noise_m=args.noise_m, seed=args.seed,
                                        options=options)
        self.per_ac = {} if args.topics == "shared" else {
            tr.callsign: node.create_publisher(STATE_TYPE, f"aircraft/{tr.callsign}/state", QOS_DEFAULT)
            for tr in sim.tracks}
        self.shared = node.create_publisher(STATE_TYPE, "radar/tracks", QOS_DEFAULT) \
            if args.topics != "per-aircraft" else None
        self.clock = node.create_publisher(CLOCK_TYPE, "/clock", QOS_DEFAULT) if args.clock else None
        self.plans: dict[str, int] = {}
        self.started = time.monotonic()
        self.first_plan_s: float | None = None
        """Wall-clock seconds from the start to the first plan received."""
        if not args.no_follow:
            for tr in sim.tracks:
                node.create_subscription("nav_msgs/msg/Path", f"aircraft/{tr.callsign}/path",
                                         self._on_path(tr.callsign), QOS_LATCHED)
        self.ticks, self.held, self.frozen = 0, 0, None
        self.hold_until = time.monotonic() + args.wait_for_plan
        self.progress = Progress(PROGRESS_PERIOD_S)
        self.stop = stop_event()
        node.create_timer(1.0 / args.rate, self._on_timer)

    def _on_timer(self) -> None:
        args, sim = self.args, self.sim
        if args.wait_for_plan > 0 and self._waiting():
            self.held += 1  # the same tracks again (duplicates to the planner): the traffic appears, time stands still
        else:
            self.ticks += 1
            self.frozen = None
            sim.step_to(sim.t0 + self.ticks * args.speed / args.rate)
        if self.clock is not None:
            self.clock.publish(self.node.types.msg(CLOCK_TYPE)(clock=time_to_msg(self.node.types, sim.t)))
        if self.frozen is None:
            self.frozen = sim.measurements()
        for callsign, state, speed, wake in self.frozen:
            msg = planner_to_aircraft_state(self.node.types, callsign, sim.t, state, speed, wake, PLANNER_FRAME)
            if callsign in self.per_ac:
                self.per_ac[callsign].publish(msg)
            if self.shared is not None:
                self.shared.publish(msg)
        self.progress.tick(sim.sim)
        if (args.until_landed and sim.sim.done) or (args.duration and sim.sim.t >= args.duration):
            self.stop.set()

    def _waiting(self) -> bool:
        """Time stands still until every aircraft has its first path (the first plan's paths come one by one, on
        topics of their own: an aircraft whose path came a scan late would fly on without it), at most
        :data:`FIRST_PATHS_WAIT_S` after the first one and ``--wait-for-plan`` in all."""
        now = time.monotonic()
        if now >= self.hold_until:
            return False
        if self.first_plan_s is None:
            return True
        return len(self.plans) < len(self.sim.tracks) and now < self.started + self.first_plan_s + FIRST_PATHS_WAIT_S

    def _on_path(self, callsign: str) -> Any:
        def callback(msg: Any) -> None:
            stamps, states, _bank = path_to_planner(msg)
            self.sim.set_plan(callsign, stamps, states)
            self.plans[callsign] = self.plans.get(callsign, 0) + 1
            if self.first_plan_s is None and len(stamps):
                self.first_plan_s = time.monotonic() - self.started
            if len(stamps):
                self.log.info("%s: flying plan #%d (%d poses, %.0f s) from t=%.1f s", callsign, self.plans[callsign],
                              len(stamps), stamps[-1] - stamps[0], self.sim.sim.t)
            else:
                self.log.info("%s: plan withdrawn at t=%.1f s: holding heading, levelling off", callsign,
                              self.sim.sim.t)

        return callback

    def spin(self) -> None:
        try:
            while not self.stop.is_set():
                self.node.spin_once(0.1)
        except KeyboardInterrupt:
            pass
        finally:
            self.node.shutdown()
        self.log.info("published %d updates (%.0f s simulated)", self.ticks + self.held, self.sim.sim.t)


def main(argv: list[str] | None = None) -> int:
    """Run the simulator node; 0 on clean exit (with --until-landed: everyone landed safely), 1 if not, 2 on bad
    input."""
    args = parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="[%(levelname)s] [%(name)s]: %(message)s")
    inputs = _checked_inputs(args)
    if isinstance(inputs, str):
        print(f"radar_sim: {inputs}", file=sys.stderr)
        return 2
    scenario, wind = inputs
    sim_node = SimulatorNode(args, scenario, wind)
    print(f"radar_sim: {len(sim_node.sim.tracks)} aircraft at {args.rate:g} Hz ({args.topics}), {args.speed:g}x real "
          f"time{', /clock' if args.clock else ''}", flush=True)
    sim_node.spin()
    if args.until_landed:
        return _report(scenario, sim_node.sim.sim, args.out, time.monotonic() - sim_node.started,
                       sim_node.first_plan_s)
    return 0


def _report(scenario: Scenario, sim: FlightSimulator, out: str | None, wall_s: float,
            first_plan_s: float | None) -> int:
    """Print (and save) what was flown; 0 when everyone landed with every minimum kept."""
    from mal_planner.closedloop.cli import summary_lines
    from mal_planner.closedloop.metrics import measure_flight

    metrics = measure_flight(scenario, sim, wall_s=wall_s, first_plan_s=first_plan_s)
    print("\n".join(summary_lines(metrics, planner_side=False)), flush=True)
    if out:
        from mal_planner.closedloop.figure import figure_closed_loop

        Path(out).mkdir(parents=True, exist_ok=True)
        jsonio.write(Path(out) / "closed_loop.json", metrics.to_dict(), indent=1, default=float)
        figure_closed_loop(scenario, sim, Path(out) / "closed_loop.png")
    return 0 if metrics.success else 1


__all__ = ["RadarSimulator", "SimulatorNode", "main"]

if __name__ == "__main__":
    sys.exit(main())
