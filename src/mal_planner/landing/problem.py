"""Build the landing problem as a multi-phase OCP (see :mod:`mal_planner.landing.layout`).

Per phase: the stacked states (x, y, z, gamma, heading) and controls (n_h, n_v) of the aircraft
airborne in it; path constraints: the thesis's log p-norm obstacle functions (>= 0), the linear bank
limit, and the squared distance of every pair that can come close in it (>= separation^2; see
:mod:`mal_planner.landing.pairs`). Events: initial states (parameters,
so a replan with new radar states reuses the NLP), continuity of each aircraft between phases (linkage),
gate conditions (in the hole, level, ground track set) at its gate event, runway state at its landing event
and the landing times (parameters when fixed, spacing constraints when free). Cost, as in the thesis:
-sum t_obs + sum of integrals of gamma'^2 + heading'^2; with free landing times, +sum t_land instead
of -sum t_obs (maximising t_obs is only meaningful when t_land is fixed); airspeed-model aircraft are left out of
-sum t_obs (see :meth:`_Events.mayer`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from mal_planner.landing.constraints import Intruder, PhaseConstraints, state_offsets
from mal_planner.landing.guess import AircraftGuess
from mal_planner.landing.layout import Event, PhaseLayout
from mal_planner.landing.margins import Margins, SafetyMargins
from mal_planner.landing.pairs import PhasePairs, all_pairs
from mal_planner.landing.profile import gamma_bounds
from mal_planner.landing.speeds import landing_airspeed
from mal_planner.obstacles import Gate
from mal_planner.ocp import Phase, PhaseGuess, PhaseMesh, Problem
from mal_planner.performance import performance_of
from mal_planner.scales import Scales
from mal_planner.scenario import Aircraft, Scenario
from mal_planner.sequencing.schedule import planned_spacing

GAMMA_BOUND = math.radians(30.0)
HEADING_BOUND = 4.0 * math.pi


@dataclass
class LandingProblem:
    problem: Problem
    layout: PhaseLayout
    n_aircraft: int
    fixed_landing_times: bool
    initial_headings: tuple[float, ...] = ()
    """The guesses' initial headings (landing order) the NLP was built around (its gate and runway headings
    are the representatives + 2 pi k nearest the guesses')."""

    def params(self, scenario: Scenario, landing_times: list[float]) -> np.ndarray:
        """Parameter vector: initial states (landing order) then landing times.

        Each initial heading is taken + 2 pi k nearest the heading the NLP was built around: a heading given
        as 177 deg against a build for -183 deg (or a radar heading that wrapped from 179 to -179 deg between
        replans) would otherwise ask for a turn of a full circle more and make a fixed landing time
        infeasible (campaign traffic-0096).
        """
        states = []
        for k, cs in enumerate(self.layout.callsigns):
            state = scenario.aircraft_by_callsign(cs).state0.astype(float)
            if k < len(self.initial_headings):
                state[4] = _wrap_near(float(state[4]), self.initial_headings[k])
            states.append(state)
        return np.concatenate([np.concatenate(states), np.asarray(landing_times, float)])


def _wrap_near(target: float, reference: float) -> float:
    """The representative of ``target`` + 2 pi k closest to ``reference`` (heading is not wrapped)."""
    return target + 2.0 * math.pi * round((reference - target) / (2.0 * math.pi))


def build_landing_problem(scenario: Scenario, layout: PhaseLayout, guesses: list[AircraftGuess],
                          fixed_landing_times: bool = True, mesh: PhaseMesh | None = None,
                          horizon: float | None = None, margins: SafetyMargins | None = None,
                          segment_turn_times: float | None = None, pairs: PhasePairs | None = None,
                          intruders: Sequence[Intruder] = (), earliest_landing: float | None = None,
                          scales: Scales | None = None) -> LandingProblem:
    """Assemble the OCP; ``guesses`` are in landing order and place each phase's initial guess.

    ``scales`` (default: the scenario's own, :meth:`Scales.of`; a subproblem of one aircraft gets the whole
    scenario's) scale the NLP: positions in turn radii L, times in turn times T, separations in the minimum
    separation, so that every scenario reaches IPOPT with numbers of the thesis's order. ``margins`` (see
    :class:`SafetyMargins`) make every constraint a little stricter than the scenario's.
    ``segment_turn_times`` scales the initial mesh to the guessed phase durations: about one segment per that
    many turn times (``mesh``'s degree); None: ``mesh`` for every phase.
    ``pairs`` are the pairs each phase keeps separated (see :mod:`mal_planner.landing.pairs`; None: all).
    ``intruders`` are aircraft with fixed trajectories (planned before) that every aircraft keeps separated
    from; with free landing times, ``earliest_landing`` bounds the first landing from below.
    """
    n = len(layout.callsigns)
    scales = scales or Scales.of(scenario)
    aircraft = [scenario.aircraft_by_callsign(cs) for cs in layout.callsigns]
    gate = scenario.gates[0] if scenario.gates else None
    horizon = horizon or 2.0 * max(g.landing_time for g in guesses) + scales.seconds(HORIZON_TURN_TIMES)
    mesh = mesh or PhaseMesh.uniform(4, 6)
    ctx = _Context(scenario, layout, aircraft, guesses, gate, horizon, (margins or SafetyMargins()).in_nm(scales),
                   scales, tuple(intruders))
    pairs = pairs if pairs is not None else all_pairs(layout)
    phases, members = _phases(ctx, mesh, segment_turn_times, pairs)
    events = _Events(layout, members, fixed_landing_times, earliest_landing, tuple(aircraft))
    lb, ub = events.bounds(scenario, aircraft)
    seconds = scales.time_s
    state_scale = [v for ac in aircraft for v in _state_scale(ac, scales)]
    problem = Problem(phases=phases, n_params=len(state_scale) + n, mayer=events.mayer, events=events.constraints,
                      events_lb=lb, events_ub=ub, objective_scale=seconds,
                      events_scale=state_scale + [seconds] * (len(lb) - len(state_scale)))
    _link_phases(problem, layout, phases, members, aircraft)
    return LandingProblem(problem, layout, n, fixed_landing_times, tuple(float(g.states[0, 4]) for g in guesses))


def _phases(ctx: _Context, mesh: PhaseMesh, segment_turn_times: float | None,
            pairs: PhasePairs) -> tuple[list[Phase], list[list[int]]]:
    """Every phase of the layout, and the aircraft airborne in each (landing-order indices)."""
    layout = ctx.layout
    event_times = [ev.time_guess for ev in layout.events]
    phases: list[Phase] = []
    members: list[list[int]] = []
    for k in range(layout.n_phases):
        who = layout.airborne(k)
        members.append(who)
        span = (event_times[k - 1] if k else 0.0, event_times[k])
        phase_mesh = mesh if segment_turn_times is None else _scaled_mesh(
            mesh, span[1] - span[0], ctx.scales.seconds(segment_turn_times))
        phases.append(_phase(ctx, k, who, phase_mesh, span, sorted(pairs[k])))
    return phases, members


@dataclass(frozen=True, eq=False)
class _Events:
    """The events and the Mayer cost of the landing problem (see the module docstring)."""

    layout: PhaseLayout
    members: list[list[int]]
    """Per phase, the aircraft airborne in it (landing-order indices)."""
    fixed_landing_times: bool
    earliest_landing: float | None
    aircraft: tuple[Aircraft, ...]
    """In landing order."""

    def constraints(self, E, p):
        layout, n = self.layout, len(self.layout.callsigns)
        out = []
        # Initial states of every aircraft (all are airborne in phase 0).
        in_params = state_offsets(list(self.aircraft))
        in_phase = state_offsets([self.aircraft[i] for i in self.members[0]])
        for i in range(n):
            j, width = self.members[0].index(i), self.aircraft[i].dynamics.n_states
            out.append(E[0].x0[in_phase[j]:in_phase[j] + width] - p[in_params[i]:in_params[i] + width])
        n_states = sum(ac.dynamics.n_states for ac in self.aircraft)
        # Landing times.
        for i in range(n):
            t_land = E[layout.event_index("land", i)].tf
            if self.fixed_landing_times:
                out.append(t_land - p[n_states + i])
        if not self.fixed_landing_times:
            for i in range(n - 1):
                out.append(E[layout.event_index("land", i + 1)].tf - E[layout.event_index("land", i)].tf)
            if self.earliest_landing is not None:
                out.append(E[layout.event_index("land", 0)].tf)
        return ca.vertcat(*out)

    def bounds(self, scenario: Scenario, aircraft: list[Aircraft]) -> tuple[list[float], list[float]]:
        """Equalities for the initial states (and fixed landing times); free landing times: each consecutive pair
        at least the spacing it needs (wake turbulence included), the first no earlier than ``earliest_landing``."""
        n = len(self.layout.callsigns)
        fixed = self.fixed_landing_times
        n_eq = sum(ac.dynamics.n_states for ac in aircraft) + (n if fixed else 0)
        spacing = [] if fixed else [planned_spacing(scenario, aircraft[i], aircraft[i + 1]) for i in range(n - 1)]
        if not fixed and self.earliest_landing is not None:
            spacing.append(self.earliest_landing)
        return [0.0] * n_eq + spacing, [0.0] * n_eq + [math.inf] * len(spacing)

    def mayer(self, E, p):
        layout, n = self.layout, len(self.layout.callsigns)
        # An airspeed-model aircraft's latest gate passage is its fastest way from the gate to the threshold: the
        # speed cones and the idle bound active all the way, a mesh that does not converge (its Lagrange cost
        # alone shapes it).
        gated = [i for i in range(n) if layout.has_gate_event(i) and not self.aircraft[i].dynamics.variable_airspeed]
        if self.fixed_landing_times:
            return -sum(E[layout.event_index("gate", i)].tf for i in gated) if gated else 0.0
        return sum(E[layout.event_index("land", i)].tf for i in range(n))


def _link_phases(problem: Problem, layout: PhaseLayout, phases: list[Phase], members: list[list[int]],
                 aircraft: list[Aircraft]) -> None:
    """Every aircraft airborne in the next phase continues its states (and the time) across the boundary."""
    for k in range(layout.n_phases - 1):
        linked = []
        for i in members[k + 1]:
            cs = layout.callsigns[i]
            linked += [f"{cs}.{s}" for s in aircraft[i].dynamics.state_names]
        problem.link(phases[k].name, phases[k + 1].name, linked, time=True)


MIN_DEGREE = 3
HORIZON_TURN_TIMES = 8.0
"""The phases' times are bounded by twice the last guessed landing plus this many turn times (thesis: 60 s)."""
MIN_DURATION_TURN_TIMES = 1e-3
"""A phase lasts at least this many turn times (thesis: 0.01 s)."""
EDGE_SHARE = 0.3
"""The first and last segments of a phase's initial mesh are this share of the others: at a gate, the runway and
the start the controls turn sharply, and the refinement spent its first iterations there (measured over
thesis-size and terminal-area scenarios: 24 % less planning time than with uniform segments)."""


def _scaled_mesh(mesh: PhaseMesh, duration: float, segment_seconds: float) -> PhaseMesh:
    """About one segment per ``segment_seconds`` (the first and last shorter, :data:`EDGE_SHARE`); a phase shorter
    than that gets one segment of a degree in proportion (at least 3). Every phase carries every airborne aircraft,
    and most of the 2N phases of a long stream are short: full-degree segments there made the NLP grow as N^2 x
    the degree."""
    degree = max(mesh.degrees)
    segments = max(1, int(round(duration / segment_seconds)))
    if duration < segment_seconds:
        degree = int(np.clip(math.ceil(degree * duration / segment_seconds), MIN_DEGREE, degree))
    if segments >= 2:  # short end segments: the controls turn sharply at the events that end a phase
        edge = EDGE_SHARE / segments
        return PhaseMesh(tuple([0.0, *np.linspace(edge, 1.0 - edge, segments - 1), 1.0]), (degree,) * segments)
    return PhaseMesh.uniform(segments, degree)


@dataclass(frozen=True)
class _Context:
    """What every phase of one landing problem is built from."""

    scenario: Scenario
    layout: PhaseLayout
    aircraft: list[Aircraft]
    """In landing order."""
    guesses: list[AircraftGuess]
    gate: Gate | None
    horizon: float
    margins: Margins
    scales: Scales
    intruders: tuple[Intruder, ...] = ()


def _phase(ctx: _Context, k: int, who: list[int], mesh: PhaseMesh, guess_span: tuple[float, float],
           separated: list[tuple[int, int]]) -> Phase:
    """Phase ``k`` with the aircraft ``who`` (landing-order indices) airborne in it, keeping the pairs
    ``separated`` (landing-order indices) apart."""
    scenario, margins, scales = ctx.scenario, ctx.margins, ctx.scales
    bounds = _phase_bounds(ctx, k, who, guess_span)
    cons = PhaseConstraints.of(scenario, [ctx.aircraft[i] for i in who], bounds.x_lb, bounds.x_ub,
                               [(who.index(a), who.index(b)) for a, b in separated], margins, scales, ctx.intruders)
    p_lb, p_ub, p_scale = cons.path_bounds()
    n_bulky, n_sep = cons.n_bulky, cons.n_separations
    return Phase(
        name=ctx.layout.phase_name(k),
        states=bounds.states,
        controls=bounds.controls,
        dynamics=cons.dynamics,
        lagrange=cons.lagrange,
        path=cons.path,
        path_lb=p_lb,
        path_ub=p_ub,
        path_overshoot_tol=cons.path_overshoot_tol(),
        state_overshoot_tol=None if margins.airspace_bulge_nm is None else
        [v for i in who for v in (*[margins.airspace_bulge_nm] * 3, *[math.inf] * (ctx.aircraft[i].dynamics.n_states
                                                                                   - 3))],
        state_lb=bounds.x_lb,
        state_ub=bounds.x_ub,
        final_state_lb=bounds.xf_lb,
        final_state_ub=bounds.xf_ub,
        control_lb=bounds.u_lb,
        control_ub=bounds.u_ub,
        # The initial states are given (radar): they may lie on the airspace boundary, inside the margin.
        initial_state_lb=[v for i in who for v in (*scenario.airspace[:, 0], -GAMMA_BOUND, -HEADING_BOUND,
                                                   *_speed_box(ctx.aircraft[i])[:1])] if k == 0 else None,
        initial_state_ub=[v for i in who for v in (*scenario.airspace[:, 1], GAMMA_BOUND, HEADING_BOUND,
                                                   *_speed_box(ctx.aircraft[i])[1:])] if k == 0 else None,
        t0_bounds=(0.0, 0.0) if k == 0 else (0.0, ctx.horizon),
        tf_bounds=(0.0, ctx.horizon),
        min_duration=scales.seconds(MIN_DURATION_TURN_TIMES),
        guess=phase_guess(who, ctx.aircraft, ctx.guesses, guess_span),
        mesh=mesh,
        bound_controls_between=True,
        control_path=cons.bank,
        control_path_ub=0.0,
        midpoint_path=cons.midpoint if n_bulky + n_sep else None,
        midpoint_path_lb=[margins.clearance] * n_bulky + [cons.zone.lower] * n_sep,
        midpoint_path_scale=[1.0] * n_bulky + [cons.zone.scale] * n_sep,
        state_scale=[v for i in who for v in _state_scale(ctx.aircraft[i], scales)],
        time_scale=scales.time_s,
        path_scale=p_scale,
    )


@dataclass
class _PhaseBounds:
    """Names and bounds of the stacked states and controls of the aircraft airborne in one phase."""

    states: list[str] = field(default_factory=list)
    controls: list[str] = field(default_factory=list)
    x_lb: list[float] = field(default_factory=list)
    x_ub: list[float] = field(default_factory=list)
    xf_lb: list[float] = field(default_factory=list)
    xf_ub: list[float] = field(default_factory=list)
    u_lb: list[float] = field(default_factory=list)
    u_ub: list[float] = field(default_factory=list)


def _phase_bounds(ctx: _Context, k: int, who: list[int], guess_span: tuple[float, float]) -> _PhaseBounds:
    """The airspace less its margin, each aircraft on its side of the gate plane; at the phase's end the
    conditions of its event; the load factors a margin inside their limits."""
    layout, gate, margins = ctx.layout, ctx.gate, ctx.margins
    space_lo = ctx.scenario.airspace[:, 0] + margins.airspace_nm
    space_hi = ctx.scenario.airspace[:, 1] - [margins.airspace_nm, margins.airspace_nm, margins.top_nm]
    out = _PhaseBounds()
    for i in who:
        ac, cs = ctx.aircraft[i], layout.callsigns[i]
        out.states += [f"{cs}.{s}" for s in ac.dynamics.state_names]
        out.controls += [f"{cs}.{c}" for c in ac.dynamics.control_names]
        gamma_lo, gamma_hi = gamma_bounds(ctx.scenario, ac, GAMMA_BOUND)
        lo = [*space_lo, gamma_lo, -HEADING_BOUND, *_speed_box(ac)[:1]]
        hi = [*space_hi, gamma_hi, HEADING_BOUND, *_speed_box(ac)[1:]]
        if gate is not None:  # keep each aircraft on its side of the gate plane in this phase
            if layout.approaching(k, i):
                (lo if gate.direction < 0 else hi)[gate.axis] = gate.position
            else:
                (hi if gate.direction < 0 else lo)[gate.axis] = gate.position
        out.x_lb += lo
        out.x_ub += hi
        guess_heading = float(ctx.guesses[i].state_at(np.array([guess_span[1]]))[0, 4])
        flo, fhi = _end_bounds(ctx, layout.events[k], i, lo, hi, (space_lo, space_hi), guess_heading)
        out.xf_lb += flo
        out.xf_ub += fhi
        pushes = [ac.limits.n_h, ac.limits.n_v, ac.limits.n_x][:ac.dynamics.n_controls]
        out.u_lb += [lo + margins.load_factor for lo, _ in pushes]
        out.u_ub += [hi - margins.load_factor for _, hi in pushes]
    return out


SPEED_BOX = (0.5, 2.0)
"""An airspeed state is boxed between these multiples of the slower of its first airspeed and its type's slowest final
approach speed, and of the faster of its first airspeed and its type's VMO (a box for the solver only: the speed rows
of :mod:`mal_planner.landing.speeds` keep the envelope)."""


def _speed_box(ac: Aircraft) -> tuple[float, ...]:
    """(lower, upper) of an airspeed state (nm/s); () for a constant-speed model."""
    if not ac.dynamics.variable_airspeed:
        return ()
    perf = performance_of(ac.type_code)
    return SPEED_BOX[0] * min(ac.speed, perf.final_approach_cas.low), SPEED_BOX[1] * max(ac.speed, perf.vmo)


def _state_scale(ac: Aircraft, scales: Scales) -> list[float]:
    """Positions in the scenario's length scale, angles in rad, an airspeed in its first airspeed."""
    return [scales.length_nm] * 3 + [1.0, 1.0] + [ac.speed] * (ac.dynamics.n_states - 5)


def _end_bounds(ctx: _Context, end: Event, i: int, lo: list[float], hi: list[float],
                space: tuple[np.ndarray, np.ndarray], guess_heading: float) -> tuple[list[float], list[float]]:
    """Aircraft ``i``'s state bounds at the phase's end: in the hole, level, on the gate's track at its gate
    event; on the runway threshold's state at its landing; else its bounds in the phase."""
    flo, fhi = list(lo), list(hi)
    gate, ac, margins = ctx.gate, ctx.aircraft[i], ctx.margins
    if end.aircraft == i and end.kind == "gate" and gate is not None:
        flo[gate.axis] = fhi[gate.axis] = gate.position
        for (b_lo, b_hi), ax in zip(gate.bounds, gate.other_axes, strict=True):
            inset = margins.gate_inset_nm(b_lo, b_hi)
            flo[ax], fhi[ax] = max(flo[ax], b_lo + inset), min(fhi[ax], b_hi - inset)
        flo[3] = fhi[3] = gate.flight_path_angle
        # the gate's heading is a ground track: the state (air) heading is crabbed into the wind
        flo[4] = fhi[4] = _wrap_near(ac.heading_for_track(gate.heading, gate.flight_path_angle), guess_heading)
    elif end.aircraft == i and end.kind == "land":
        rw = ctx.scenario.runway_state
        flo[:3] = fhi[:3] = list(np.clip(rw[:3], *space))  # the threshold, inside the margin
        flo[3] = fhi[3] = float(rw[3])
        flo[4] = fhi[4] = _wrap_near(ctx.scenario.runway_heading(ac), guess_heading)
        if len(fhi) > 5:  # the airspeed model lands within its type's final approach speeds
            fhi[5] = min(fhi[5], landing_airspeed(ctx.scenario, ac, margins.speed_share))
    return flo, fhi


def phase_guess(who: list[int], aircraft: list[Aircraft], guesses: list[AircraftGuess], span: tuple[float, float],
                samples: int = 25) -> PhaseGuess:
    """The stacked guess of the aircraft ``who`` over the phase's guessed time span."""
    t = np.linspace(span[0], span[1], samples)
    x = np.hstack([guesses[i].model_states(aircraft[i], t) for i in who])
    u = np.hstack([guesses[i].model_controls(aircraft[i], t) for i in who])
    return PhaseGuess(t=t, x=x, u=u)


def phase_guesses(scenario: Scenario, layout: PhaseLayout, guesses: list[AircraftGuess]) -> list[PhaseGuess]:
    """Per-phase guesses for ``layout`` (e.g. to warm-start a cached NLP from shifted trajectories)."""
    aircraft = [scenario.aircraft_by_callsign(cs) for cs in layout.callsigns]
    times = [0.0] + [ev.time_guess for ev in layout.events]
    return [phase_guess(layout.airborne(k), aircraft, guesses, (times[k], times[k + 1]))
            for k in range(layout.n_phases)]
