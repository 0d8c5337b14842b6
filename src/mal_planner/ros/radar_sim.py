"""Radar simulator node: flies a scenario's aircraft and publishes their (noisy) tracks.

Each aircraft flies level, turn-free (n_h = 0, n_v = cos gamma) along its initial heading with its dynamics
model, or follows a plan received as ``nav_msgs/Path`` on ``aircraft/<callsign>/path`` (poses by stamp,
linear interpolation) while the plan covers the current time. Tracks go out as ``mal_msgs/AircraftState``
on ``aircraft/<callsign>/state`` and/or ``radar/tracks``, stamped with simulated time (start + t).

    python -m mal_planner.ros.radar_sim --scenario scenarios/thesis.yaml --rate 2 --noise-m 5 --duration 60
"""

from __future__ import annotations

import argparse
import logging
import sys
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mal_planner.dynamics import DynamicsModel
from mal_planner.ros.bagio import stop_event
from mal_planner.ros.convert import path_to_planner, planner_to_aircraft_state
from mal_planner.scenario import Scenario, ScenarioError, load_scenario
from mal_planner.units import PLANNER_FRAME, m_to_nm

STATE_TYPE = "mal_msgs/msg/AircraftState"


def propagate_level(dynamics: DynamicsModel, state: np.ndarray, dt: float, max_step: float = 1.0) -> np.ndarray:
    """Integrate level, turn-free flight (n_h = 0, n_v = cos gamma0) for ``dt`` seconds (RK4 steps)."""
    x = np.asarray(state, dtype=float).copy()
    if dt <= 0:
        return x
    u = dynamics.level_flight_control(x[3])
    n = max(1, int(np.ceil(dt / max_step)))
    h = dt / n
    for _ in range(n):
        x = dynamics.rk4_step(x, u, h)
    return x


@dataclass
class SimTrack:
    """One simulated aircraft: true state [nm, rad] and an optional plan (absolute stamps, states)."""

    callsign: str
    dynamics: DynamicsModel
    state: np.ndarray
    wake: str | None = None
    plan: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)


class RadarSimulator:
    """Pure simulation (no DDS): advance with :meth:`step_to`, read tracks with :meth:`measurements`."""

    def __init__(self, scenario: Scenario, t0: float = 0.0, noise_m: float = 0.0, seed: int | None = None) -> None:
        self.t = float(t0)
        self.noise_m = float(noise_m)
        self.rng = np.random.default_rng(seed)
        self.tracks = [SimTrack(a.callsign, a.dynamics, np.asarray(a.state0, float).copy(), a.wake_category)
                       for a in scenario.aircraft]  # fmt: skip

    def set_plan(self, callsign: str, stamps: np.ndarray, states: np.ndarray) -> bool:
        """Follow ``states`` at absolute ``stamps`` [s] (from a Path message); False for unknown callsigns."""
        for tr in self.tracks:
            if tr.callsign == callsign:
                order = np.argsort(stamps)
                tr.plan = (np.asarray(stamps, float)[order], np.asarray(states, float)[order]) if len(stamps) else None
                return True
        return False

    def step_to(self, t: float) -> None:
        """Advance every aircraft to absolute time ``t`` [s]."""
        dt = t - self.t
        for tr in self.tracks:
            planned = _plan_state(tr.plan, t)
            tr.state = planned if planned is not None else propagate_level(tr.dynamics, tr.state, dt)
        self.t = t

    def measurements(self) -> list[tuple[str, np.ndarray, float, str | None]]:
        """``(callsign, state, speed nm/s, wake)`` per aircraft with Gaussian position noise (sigma in metres)."""
        out = []
        for tr in self.tracks:
            state = tr.state.copy()
            if self.noise_m > 0:
                state[:3] += m_to_nm(self.rng.normal(0.0, self.noise_m, 3))
            out.append((tr.callsign, state, tr.dynamics.speed, tr.wake))
        return out


def _plan_state(plan: tuple[np.ndarray, np.ndarray] | None, t: float) -> np.ndarray | None:
    if plan is None or len(plan[0]) == 0 or not plan[0][0] <= t <= plan[0][-1]:
        return None
    stamps, states = plan
    states = states.copy()
    states[:, 4] = np.unwrap(states[:, 4])
    return np.array([np.interp(t, stamps, states[:, i]) for i in range(states.shape[1])])


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="mal-radar-sim", description=__doc__.split("\n")[0])
    p.add_argument("--scenario", required=True, help="scenario YAML file")
    p.add_argument("--rate", type=float, default=2.0, help="publish rate [Hz] (default 2)")
    p.add_argument("--noise-m", type=float, default=0.0, help="position noise sigma [m] (default 0)")
    p.add_argument("--duration", type=float, default=0.0, help="simulated seconds, 0 = forever (default 0)")
    p.add_argument("--seed", type=int, default=None, help="noise seed")
    p.add_argument("--topics", choices=("per-aircraft", "shared", "both"), default="both")
    p.add_argument("--namespace", default="", help="node namespace")
    p.add_argument("--no-follow", action="store_true", help="ignore plans on aircraft/<callsign>/path")
    args = p.parse_args(argv)
    if args.rate <= 0 or args.noise_m < 0 or args.duration < 0:
        p.error("--rate must be > 0, --noise-m and --duration >= 0")
    return args


def main(argv: list[str] | None = None) -> int:
    """Run the radar simulator node; 0 on clean exit, 2 on bad input."""
    args = parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="[%(levelname)s] [%(name)s]: %(message)s")
    try:
        scenario = load_scenario(args.scenario)
    except ScenarioError as exc:
        print(f"radar_sim: {exc}", file=sys.stderr)
        return 2
    from mal_planner.ros.transport import QOS_DEFAULT, QOS_LATCHED, create_node

    node = create_node("radar_sim", args.namespace)
    stop = stop_event()
    log = node.get_logger()
    sim = RadarSimulator(scenario, t0=node.now(), noise_m=args.noise_m, seed=args.seed)
    start = sim.t
    per_ac = {}
    if args.topics in ("per-aircraft", "both"):
        per_ac = {tr.callsign: node.create_publisher(STATE_TYPE, f"aircraft/{tr.callsign}/state", QOS_DEFAULT)
                  for tr in sim.tracks}  # fmt: skip
    shared = node.create_publisher(STATE_TYPE, "radar/tracks", QOS_DEFAULT) if args.topics != "per-aircraft" else None
    if not args.no_follow:
        for tr in sim.tracks:
            node.create_subscription("nav_msgs/msg/Path", f"aircraft/{tr.callsign}/path",
                                     _on_path(sim, tr.callsign, log), QOS_LATCHED)  # fmt: skip
    tick = [0]

    def on_timer() -> None:
        t = tick[0] / args.rate
        sim.step_to(start + t)
        for callsign, state, speed, wake in sim.measurements():
            msg = planner_to_aircraft_state(node.types, callsign, sim.t, state, speed, wake, PLANNER_FRAME)
            if callsign in per_ac:
                per_ac[callsign].publish(msg)
            if shared is not None:
                shared.publish(msg)
        tick[0] += 1
        if args.duration and t >= args.duration:
            stop.set()

    node.create_timer(1.0 / args.rate, on_timer)
    print(f"radar_sim: {len(sim.tracks)} aircraft at {args.rate:g} Hz ({args.topics})", flush=True)
    try:
        while not stop.is_set():
            node.spin_once(0.1)
    except KeyboardInterrupt:
        pass
    finally:
        node.shutdown()
    log.info("published %d updates", tick[0])
    return 0


def _on_path(sim: RadarSimulator, callsign: str, log: Any) -> Any:
    def callback(msg: Any) -> None:
        stamps, states, _bank = path_to_planner(msg)
        sim.set_plan(callsign, stamps, states)
        log.info("%s: following a plan of %d poses", callsign, len(stamps))

    return callback


__all__ = ["RadarSimulator", "SimTrack", "main", "propagate_level"]

if __name__ == "__main__":
    sys.exit(main())
