"""Path-following guidance: the load factors that make an aircraft fly a published plan.

A plan is a time-stamped reference (a ``nav_msgs/Path`` or a :class:`~mal_planner.trajectory.Trajectory`):
where the aircraft should be at each moment. The law, per aircraft and control step:

1. the reference at the plan's point closest to the aircraft (path following: searched within a turn time of
   where the aircraft was on the plan a step before, :func:`plan_time`; of the clock for a new plan): position
   p_r, ground velocity v_r (the path's own rate of change, so it holds whatever wind the
   planner assumed), flight-path angle, heading and their rates. An along-track error (late or early) is kept:
   a constant-airspeed aircraft can take it out only by cutting or stretching the path, which near the runway
   puts it off the centreline; the service replans when it grows (new landing times);
2. the ground velocity wanted: v_r + (p_r - p) / T_p, the reference's plus a correction of the cross-track and
   height errors;
3. the air velocity that gives it in the wind the aircraft measures (air data and satellite navigation do
   that on board): its direction sets the wanted heading and flight-path angle (the airspeed is constant, so
   only the direction can be chosen; the vertical component is met first, within the planner's own flight-path
   angle bound: an aircraft far below its reference was otherwise sent straight up, past the angle its load
   factors can still level off from, and looped through the ceiling);
4. heading and flight-path-angle rates: the reference's (feedforward) plus the wanted angle errors over
   ``T_a``, converted to load factors by the model's equations and clipped to the aircraft's load-factor
   and bank limits.

An aircraft of the airspeed model also sets n_x: the airspeed that flies the plan's ground velocity in the measured
wind at its closest point, raised or lowered by the lateness (the clock minus that point's time) over
:data:`SPEED_TIME_PER_POSITION_TIME` position times, by at most :data:`SPEED_SHARE`, with the plan's own speed change
as feedforward: it takes out an along-track error by speed, as controllers ask aircraft to.

The time constants are fractions of the scenario's turn time T (the time to turn one radian at the bank
limit; :mod:`mal_planner.scales`): T_a = T/4 and T_p = T/2 (a cross-track error then decays with damping
0.71), so the same law flies the thesis's box and a terminal area. Without a plan the aircraft holds its heading
and levels off; after its plan's end (an aircraft running late) it flies on along the plan's final line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mal_planner.dynamics import ControlLimits, DynamicsModel
from mal_planner.landing.problem import GAMMA_BOUND
from mal_planner.service.conflicts import POSITION_TIME_PER_TURN_TIME
from mal_planner.trajectory import Reference

ATTITUDE_TIME_PER_TURN_TIME = 0.25
"""T_a / T: how fast heading and flight-path-angle errors are taken out."""
# T_p / T: how fast position errors are taken out (T_a / T_p = 1/2: damping 1 / (2 sqrt(1/2)) = 0.71); the service's
# prediction of the traffic flies with the same.
CAPTURE_SHARE = 0.5
"""The share of the vertical acceleration near level flight that a height capture plans to stop with (the rest for the
flight-path angle's lag and the gusts)."""
SPEED_TIME_PER_POSITION_TIME = 2.0
"""An airspeed-model aircraft takes out an along-track error (its lateness) by speed over this many position times."""
SPEED_SHARE = 0.05
"""... by at most this share of the plan's airspeed (7 kt at 150 kt: a controller's speed adjustments are 10 kt)."""
SEARCH_TURN_TIMES = 1.0
"""How far from the clock the closest point of the plan is searched, in turn times: along-track errors are seconds,
and a plan that loops comes back near itself only after 2 pi turn times."""




@dataclass(frozen=True)
class GuidanceGains:
    attitude_s: float
    """T_a: heading and flight-path-angle errors decay with this time constant."""
    position_s: float
    """T_p: position errors decay with this time constant."""
    search_s: float = math.inf
    """Path following: the plan's closest point is searched this long either side of the clock (a turn time)."""

    @classmethod
    def for_turn_time(cls, turn_time_s: float) -> GuidanceGains:
        return cls(ATTITUDE_TIME_PER_TURN_TIME * turn_time_s, POSITION_TIME_PER_TURN_TIME * turn_time_s,
                   SEARCH_TURN_TIMES * turn_time_s)


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def clip_to_limits(n_h: float, n_v: float, limits: ControlLimits) -> tuple[float, float]:
    """Load factors clipped into the box and the bank cone |n_h| <= tan(mu_max) n_v."""
    n_v = min(max(n_v, limits.n_v[0]), limits.n_v[1])
    cap = math.tan(limits.bank_angle_max) * n_v
    n_h = min(max(n_h, limits.n_h[0], -cap), limits.n_h[1], cap)
    return n_h, n_v


def plan_time(reference: Reference, state: np.ndarray, t: float, gains: GuidanceGains,
              last: tuple[float, float] | None = None) -> float:
    """The time of ``reference``'s point closest to the aircraft at ``state``: searched within a turn time of where it
    was on the plan a step before, moved on by the step (``last``: that step's clock and plan time; None: of the clock
    ``t``, for a plan just received; :meth:`~mal_planner.trajectory.Reference.follow`).

    Searched around the clock, an aircraft more than a turn time late lost its place: the reference ran ahead of it
    down the glide path and, past the plan's end, collapsed onto the threshold, below which the aircraft levelled
    off (twenty aircraft in closed loop, traffic-0003: T05 18 s late crossed the threshold 86 ft low; a straight-in
    plan flown 20 s late crossed it 49 ft low). Around the aircraft's own progress it flies the plan's path late,
    as an FMS flies its vertical path by position, and the service replans it for the lateness."""
    if not math.isfinite(gains.search_s):
        return t
    return reference.follow(state[:3], t, gains.search_s, last)


def guidance_controls(model: DynamicsModel, limits: ControlLimits, gains: GuidanceGains, state: np.ndarray,
                      wind: np.ndarray, reference: Reference | None, t: float, lead_s: float = 0.0,
                      s: float | None = None) -> np.ndarray:
    """Controls (n_h, n_v[, n_x]) that track ``reference`` at time ``t``, or hold heading and level off (and the
    airspeed) without one.

    ``wind`` is the horizontal wind the aircraft measures now (nm/s). ``lead_s``: the feedforward rates are the
    reference's this much later, which makes up for a first-order lag of that time constant between the
    commanded and the flown load factors (to first order in the lag). ``s``: the plan's time to follow
    (:func:`plan_time`; None: searched around the clock).
    """
    v, g = float(model.airspeed(state)), model.gravity
    gamma, heading = float(state[3]), float(state[4])
    cos_g = math.cos(gamma)
    speed_rate = 0.0
    if reference is None:
        gamma_rate, heading_rate = -gamma / gains.attitude_s, 0.0
    else:
        if s is None:
            s = plan_time(reference, state, t, gains)
        r = reference.sample(s)
        wanted = r[5:8] + (r[:3] - state[:3]) / gains.position_s
        wanted[2] = r[7] + _height_capture(float(r[2] - state[2]), gains, limits, g)
        air = wanted - np.array([wind[0], wind[1], 0.0])
        gamma_d = min(max(math.asin(min(max(air[2] / v, -1.0), 1.0)), -GAMMA_BOUND), GAMMA_BOUND)
        heading_d = math.atan2(air[1], air[0])
        ahead = reference.sample(s + lead_s) if lead_s > 0 else r
        gamma_rate = ahead[8] + (gamma_d - gamma) / gains.attitude_s
        heading_rate = ahead[9] + _wrap(heading_d - heading) / gains.attitude_s
        if model.variable_airspeed:
            speed_rate = _speed_rate(reference, gains, wind, s, t, v)
    n_h = v * cos_g * heading_rate / g
    n_v = cos_g + v * gamma_rate / g
    n_h, n_v = clip_to_limits(n_h, n_v, limits)
    if not model.variable_airspeed:
        return np.array([n_h, n_v])
    n_x = math.sin(gamma) + speed_rate / g
    return np.array([n_h, n_v, min(max(n_x, limits.n_x[0]), limits.n_x[1])])


def _height_capture(error: float, gains: GuidanceGains, limits: ControlLimits, g: float) -> float:
    """The vertical speed (nm/s) that takes out a height ``error`` (nm, reference minus aircraft): the error over the
    position time, at most what the aircraft can still stop within the error at :data:`CAPTURE_SHARE` of the vertical
    acceleration its load factors give near level flight, sqrt(2 a |error|), as an autopilot's altitude capture does.
    Asked for the whole error at once, an aircraft 0.75 nm above its reference dived into the ground short of the
    runway (15 aircraft, traffic-0010: T05 at -0.106 nm)."""
    rate = error / gains.position_s
    authority = min(limits.n_v[1] - 1.0, 1.0 - limits.n_v[0])
    if authority <= 0.0:
        return rate
    cap = math.sqrt(2.0 * CAPTURE_SHARE * authority * g * abs(error))
    return min(max(rate, -cap), cap)


def _air_speed_on(reference: Reference, s: float, wind: np.ndarray) -> float:
    """The airspeed that flies ``reference``'s ground velocity at its time ``s`` in ``wind``."""
    return float(np.linalg.norm(reference.sample(s)[5:8] - np.array([wind[0], wind[1], 0.0])))


def _speed_rate(reference: Reference, gains: GuidanceGains, wind: np.ndarray, s: float, t: float, v: float) -> float:
    """V' that keeps an airspeed-model aircraft on the plan's times: the airspeed that flies the plan's ground speed
    in the measured wind at the plan's point closest to the aircraft, raised (lowered) by the lateness t - s over
    :data:`SPEED_TIME_PER_POSITION_TIME` position times, within :data:`SPEED_SHARE` of it; reached over an attitude
    time, with the plan's own speed change as feedforward."""
    planned = _air_speed_on(reference, s, wind)
    late = (t - s) / (SPEED_TIME_PER_POSITION_TIME * gains.position_s)
    wanted = planned * (1.0 + min(max(late, -SPEED_SHARE), SPEED_SHARE))
    step = gains.attitude_s
    feedforward = (_air_speed_on(reference, s + step, wind) - planned) / step
    return feedforward + (wanted - v) / gains.attitude_s
