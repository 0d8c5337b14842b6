"""Closed loop: aircraft that fly the published plans, in wind, and a service that replans when they stray.

* :mod:`.guidance`: the path-following law (plan feedforward plus position and attitude feedback);
* :mod:`.disturbances`: wind with Gauss-Markov gusts, radar noise;
* :mod:`.simulator`: :class:`FlightSimulator`, every aircraft's own model under guidance until it lands;
* :mod:`.loop`: the service and the simulator in one process, planning time charged in simulated time;
* :mod:`.metrics`: what a run achieved on the flown tracks; :mod:`.cli`: ``mal-closed-loop``.

The simulator node (:mod:`mal_planner.ros.radar_sim`) flies the same :class:`FlightSimulator` over DDS.
"""

from mal_planner.closedloop.disturbances import RadarNoise, WindField, WindSpec
from mal_planner.closedloop.guidance import GuidanceGains, guidance_controls
from mal_planner.closedloop.loop import ClosedLoop, ClosedLoopOptions, ClosedLoopRun, run_closed_loop
from mal_planner.closedloop.simulator import FlightSimulator, SimOptions
from mal_planner.trajectory import Reference

__all__ = ["ClosedLoop", "ClosedLoopOptions", "ClosedLoopRun", "FlightSimulator", "GuidanceGains", "RadarNoise",
           "Reference", "SimOptions", "WindField", "WindSpec", "guidance_controls", "run_closed_loop"]
