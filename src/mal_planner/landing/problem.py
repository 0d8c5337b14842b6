"""Build the landing problem as a multi-phase OCP (see :mod:`mal_planner.landing.layout`).

Per phase: the stacked states (x, y, z, gamma, heading) and controls (n_h, n_v) of the aircraft
airborne in it; path constraints: the thesis's log p-norm obstacle functions (>= 0), the linear bank
limit, and the squared distance of every pair that can come close in it (>= separation^2; see
:mod:`mal_planner.landing.pairs`). Events: initial states (parameters,
so a replan with new radar states reuses the NLP), continuity of each aircraft between phases (linkage),
gate conditions (in the hole, level, ground track set) at its gate event, runway state at its landing event
and the landing times (parameters when fixed, spacing constraints when free). Cost, as in the thesis:
-sum t_obs + sum of integrals of gamma'^2 + heading'^2; with free landing times, +sum t_land instead
of -sum t_obs (maximising t_obs is only meaningful when t_land is fixed).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from mal_planner.dynamics import STATE_NAMES, bank_limit_residuals
from mal_planner.landing.guess import AircraftGuess
from mal_planner.landing.layout import PhaseLayout
from mal_planner.landing.pairs import PhasePairs, all_pairs
from mal_planner.obstacles import Gate
from mal_planner.ocp import Phase, PhaseGuess, PhaseMesh, Problem
from mal_planner.scales import Scales
from mal_planner.scenario import Aircraft, Scenario
from mal_planner.sequencing.schedule import planned_spacing

GAMMA_BOUND = math.radians(30.0)
HEADING_BOUND = 4.0 * math.pi


@dataclass(frozen=True)
class SafetyMargins:
    """How much stricter than the scenario's minima the NLP is (the verifier allows no tolerance at all).

    Path constraints hold at the collocation points; between them, and after re-integrating the published
    controls, a trajectory that rides a constraint can cross it by a little. These margins keep that
    little on the safe side; where it is not enough the verification finds it and the mesh is refined.
    Lengths are in units of the scenario's path accuracy (:attr:`mal_planner.scales.Scales.accuracy_nm`,
    the verification's largest deviation between the published and the flown path: L / 60, 0.005 nm in the
    thesis, where these were tuned in nm); :meth:`in_nm` resolves them for one scenario.
    """

    separation: float = 2.0
    """Added to the minimum separation: each of the two published paths may be the accuracy off the flown one
    (thesis: 0.01 nm, about 18 m)."""
    obstacle: float = 2.0
    """Obstacles are inflated by this in every semi-axis (thesis: 0.01 nm)."""
    clearance: float = 1e-4
    """Lower bound of ln ||r||_p of the inflated obstacles at the collocation points (dimensionless)."""
    gate: float = 0.4
    """The gate event stays this far inside the hole's edges, beyond the obstacle margin (the wall pieces
    are rounded p-norm shapes; thesis: 0.002 nm)."""
    airspace: float = 0.2
    """The airspace is shrunk by this (thesis: 0.001 nm, about 2 m); the runway threshold is crossed this high
    above the floor (real approaches cross it at about 15 m), so the flown path never touches the ground early."""
    bank_rad: float = math.radians(0.5)
    """Taken off the bank-angle limit (the control interpolant overshoots a riding limit between its
    collocation points by up to about this; campaigns measured 0.2 deg past a 0.25 deg margin)."""
    load_factor: float = 1e-3
    """Taken off both ends of the load-factor limits (dimensionless)."""
    airspace_bulge: float | None = None
    """How far a path may pass the airspace less ``airspace`` (and the gate's plane, where a phase keeps it on one
    side) between its collocation points before the mesh refinement splits the segment; None: unchecked (open loop:
    the margin absorbs it, and the verification refines where the airspace itself is crossed). Plans that are flown
    keep the rest of the margin for the aircraft's stray (:func:`mal_planner.closedloop.loop.tracking_margins`)."""

    def in_nm(self, scales: Scales) -> Margins:
        unit = scales.accuracy_nm
        return Margins(self.separation * unit, self.obstacle * unit, self.clearance, self.gate * unit,
                       self.airspace * unit, self.bank_rad, self.load_factor,
                       None if self.airspace_bulge is None else self.airspace_bulge * unit)


@dataclass(frozen=True)
class Margins:
    """:class:`SafetyMargins` of one scenario, lengths in nm."""

    separation_nm: float
    obstacle_nm: float
    clearance: float
    gate_nm: float
    airspace_nm: float
    bank_rad: float
    load_factor: float
    airspace_bulge_nm: float | None = None

    @property
    def hole_nm(self) -> float:
        """How far inside the hole's edges the gate event is kept."""
        return self.obstacle_nm + self.gate_nm


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
    event_times = [ev.time_guess for ev in layout.events]
    ctx = _Context(scenario, layout, aircraft, guesses, gate, horizon, (margins or SafetyMargins()).in_nm(scales),
                   scales, tuple(intruders))
    pairs = pairs if pairs is not None else all_pairs(layout)
    phases: list[Phase] = []
    members: list[list[int]] = []
    for k in range(layout.n_phases):
        who = layout.airborne(k)
        members.append(who)
        span = (event_times[k - 1] if k else 0.0, event_times[k])
        phase_mesh = mesh if segment_turn_times is None else _scaled_mesh(
            mesh, span[1] - span[0], scales.seconds(segment_turn_times))
        phases.append(_phase(ctx, k, who, phase_mesh, span, sorted(pairs[k])))
    n_states = len(STATE_NAMES)

    def index_of(k: int, i: int) -> int:
        return members[k].index(i)

    def events(E, p):
        out = []
        # Initial states of every aircraft (all are airborne in phase 0).
        for i in range(n):
            j = index_of(0, i)
            out.append(E[0].x0[j * n_states:(j + 1) * n_states] - p[i * n_states:(i + 1) * n_states])
        # Landing times.
        for i in range(n):
            t_land = E[layout.event_index("land", i)].tf
            if fixed_landing_times:
                out.append(t_land - p[n * n_states + i])
        if not fixed_landing_times:
            for i in range(n - 1):
                out.append(E[layout.event_index("land", i + 1)].tf - E[layout.event_index("land", i)].tf)
            if earliest_landing is not None:
                out.append(E[layout.event_index("land", 0)].tf)
        return ca.vertcat(*out)

    n_eq = n * n_states + (n if fixed_landing_times else 0)
    # Free landing times: each consecutive pair at least the spacing it needs (wake turbulence included).
    spacing = [] if fixed_landing_times else [planned_spacing(scenario, aircraft[i], aircraft[i + 1])
                                              for i in range(n - 1)]
    if not fixed_landing_times and earliest_landing is not None:
        spacing.append(earliest_landing)
    lb = [0.0] * n_eq + spacing
    ub = [0.0] * n_eq + [math.inf] * len(spacing)

    gated = [i for i in range(n) if layout.has_gate_event(i)]

    def mayer(E, p):
        if fixed_landing_times:
            return -sum(E[layout.event_index("gate", i)].tf for i in gated) if gated else 0.0
        return sum(E[layout.event_index("land", i)].tf for i in range(n))

    length, seconds = scales.length_nm, scales.time_s
    state_scale = [length, length, length, 1.0, 1.0]
    problem = Problem(phases=phases, n_params=n * n_states + n, mayer=mayer, events=events,
                      events_lb=lb, events_ub=ub, objective_scale=seconds,
                      events_scale=state_scale * n + [seconds] * (len(lb) - n * n_states))
    for k in range(layout.n_phases - 1):
        linked = []
        for i in members[k + 1]:
            cs = layout.callsigns[i]
            linked += [f"{cs}.{s}" for s in STATE_NAMES]
        problem.link(phases[k].name, phases[k + 1].name, linked, time=True)
    return LandingProblem(problem, layout, n, fixed_landing_times, tuple(float(g.states[0, 4]) for g in guesses))


MIN_DEGREE = 3
HORIZON_TURN_TIMES = 8.0
"""The phases' times are bounded by twice the last guessed landing plus this many turn times (thesis: 60 s)."""
MIN_DURATION_TURN_TIMES = 1e-3
"""A phase lasts at least this many turn times (thesis: 0.01 s)."""
LANDED_DISTANCE2 = 1e2
"""The squared distance (in separations^2) a separation constraint sees once the intruder has landed: far away."""
CYLINDER_P = 50
"""Exponent of the smooth cylinder: ||(h / H, dz / V)||_p >= 2^(1/p) implies max(h / H, |dz| / V) >= 1, so the
optimizer keeps 2^(1/50) - 1 = 1.4 % more than the minima where one of them alone separates (the wall's p)."""


@dataclass(frozen=True)
class ProtectedZone:
    """The separation constraint of one pair, as the NLP sees it.

    A sphere (the thesis): the squared distance >= (S + margin)^2, scaled by that. A cylinder (ATC: separated
    horizontally by H OR vertically by V): ln(A^(p/2) + B^(p/2)) / p >= ln(2) / p with A = h^2 / H'^2 and
    B = dz^2 / V'^2, H' and V' the minima plus the margin; a smooth, conservative form of max(A, B) >= 1 (see
    :data:`CYLINDER_P`), dimensionless like the obstacles' ln of the p-norm.
    """

    horizontal_nm: float
    vertical_nm: float | None

    @classmethod
    def of(cls, scenario: Scenario, margins: Margins) -> ProtectedZone:
        vertical = scenario.vertical_separation_nm
        return cls(scenario.separation_nm + margins.separation_nm,
                   None if vertical is None else vertical + margins.separation_nm)

    def measure(self, d):
        """The constrained expression of a relative position ``d`` (3 rows)."""
        if self.vertical_nm is None:
            return ca.sumsqr(d)
        a = (d[0] ** 2 + d[1] ** 2) / self.horizontal_nm**2
        b = d[2] ** 2 / self.vertical_nm**2
        return ca.log(a ** (CYLINDER_P // 2) + b ** (CYLINDER_P // 2)) / CYLINDER_P

    @property
    def lower(self) -> float:
        return self.horizontal_nm**2 if self.vertical_nm is None else math.log(2.0) / CYLINDER_P

    @property
    def scale(self) -> float:
        return self.horizontal_nm**2 if self.vertical_nm is None else 1.0

    @property
    def landed(self) -> float:
        """What a constraint sees once the intruder has landed: far away."""
        return LANDED_DISTANCE2 * self.lower if self.vertical_nm is None else self.lower + 1.0


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


@dataclass(frozen=True)
class Intruder:
    """An aircraft whose trajectory is fixed (planned before): the others keep separated from it while it flies."""

    callsign: str
    position: ca.Function
    """t (s) -> (x, y, z) nm, a smooth interpolant of the planned path."""
    t_end: float
    """It has landed after this time."""

    @classmethod
    def from_trajectory(cls, t: np.ndarray, positions: np.ndarray, callsign: str, dt: float) -> Intruder:
        """A B-spline through the path sampled every ``dt`` seconds."""
        grid = np.append(np.arange(t[0], t[-1] - 0.5 * dt, dt), t[-1])
        values = np.column_stack([np.interp(grid, t, positions[:, k]) for k in range(3)])
        return cls(callsign, ca.interpolant(f"{callsign}_path", "bspline", [grid], values.ravel()), float(t[-1]))


def _phase(ctx: _Context, k: int, who: list[int], mesh: PhaseMesh, guess_span: tuple[float, float],
           separated: list[tuple[int, int]]) -> Phase:
    """Phase ``k`` with the aircraft ``who`` (landing-order indices) airborne in it, keeping the pairs
    ``separated`` (landing-order indices) apart."""
    scenario, layout, aircraft, guesses, gate = ctx.scenario, ctx.layout, ctx.aircraft, ctx.guesses, ctx.gate
    horizon, margins, scales = ctx.horizon, ctx.margins, ctx.scales
    space_lo, space_hi = scenario.airspace[:, 0] + margins.airspace_nm, scenario.airspace[:, 1] - margins.airspace_nm
    obstacles = [ob.inflated(margins.obstacle_nm) for ob in scenario.obstacles]
    states, controls = [], []
    x_lb, x_ub, u_lb, u_ub = [], [], [], []
    xf_lb, xf_ub = [], []
    end = layout.events[k]
    for i in who:
        ac, cs = aircraft[i], layout.callsigns[i]
        states += [f"{cs}.{s}" for s in STATE_NAMES]
        controls += [f"{cs}.n_h", f"{cs}.n_v"]
        lo = [*space_lo, -GAMMA_BOUND, -HEADING_BOUND]
        hi = [*space_hi, GAMMA_BOUND, HEADING_BOUND]
        if gate is not None:  # keep each aircraft on its side of the gate plane in this phase
            if layout.approaching(k, i):
                (lo if gate.direction < 0 else hi)[gate.axis] = gate.position
            else:
                (hi if gate.direction < 0 else lo)[gate.axis] = gate.position
        x_lb += lo
        x_ub += hi
        flo, fhi = list(lo), list(hi)
        guess_heading = float(guesses[i].state_at(np.array([guess_span[1]]))[0, 4])
        if end.aircraft == i and end.kind == "gate" and gate is not None:
            flo[gate.axis] = fhi[gate.axis] = gate.position
            for (b_lo, b_hi), ax in zip(gate.bounds, gate.other_axes, strict=True):
                flo[ax], fhi[ax] = max(flo[ax], b_lo + margins.hole_nm), min(fhi[ax], b_hi - margins.hole_nm)
            flo[3] = fhi[3] = gate.flight_path_angle
            # the gate's heading is a ground track: the state (air) heading is crabbed into the wind
            flo[4] = fhi[4] = _wrap_near(ac.heading_for_track(gate.heading, gate.flight_path_angle), guess_heading)
        elif end.aircraft == i and end.kind == "land":
            rw = scenario.runway_state
            flo[:3] = fhi[:3] = list(np.clip(rw[:3], space_lo, space_hi))  # the threshold, inside the margin
            flo[3] = fhi[3] = float(rw[3])
            flo[4] = fhi[4] = _wrap_near(scenario.runway_heading(ac), guess_heading)
        xf_lb += flo
        xf_ub += fhi
        u_lb += [ac.limits.n_h[0] + margins.load_factor, ac.limits.n_v[0] + margins.load_factor]
        u_ub += [ac.limits.n_h[1] - margins.load_factor, ac.limits.n_v[1] - margins.load_factor]
    n_ac = len(who)
    models = [aircraft[i].dynamics for i in who]
    limits = [aircraft[i].limits for i in who]
    # An obstacle matters to an aircraft in this phase only if it overlaps the box the state bounds allow
    # (e.g. the wall, which lies on the approach side of its gate, is irrelevant after the gate).
    relevant = [
        [ob for ob in obstacles if _overlaps(ob.bounding_box(), x_lb[5 * j:5 * j + 3], x_ub[5 * j:5 * j + 3])]
        for j in range(len(who))
    ]
    pairs = [(who.index(a), who.index(b)) for a, b in separated]
    zone = ProtectedZone.of(scenario, margins)

    def dynamics(x, u, t, p):
        return ca.vertcat(*[m.rhs(x[5 * j:5 * j + 5], u[2 * j:2 * j + 2]) for j, m in enumerate(models)])

    def lagrange(x, u, t, p):
        total = 0
        for j, m in enumerate(models):
            g_rate, h_rate = m.angle_rates(x[5 * j:5 * j + 5], u[2 * j:2 * j + 2])
            total += g_rate**2 + h_rate**2
        return total

    def separations(x, t) -> list:
        out = [zone.measure(x[5 * a:5 * a + 3] - x[5 * b:5 * b + 3]) for a, b in pairs]
        for j in range(n_ac):
            for other in ctx.intruders:  # once it has landed, an intruder no longer counts
                row = zone.measure(x[5 * j:5 * j + 3] - other.position(t))
                out.append(ca.if_else(t <= other.t_end, row, zone.landed))
        return out

    def path(x, u, t, p):
        out = []
        for j in range(n_ac):
            px, py, pz = x[5 * j], x[5 * j + 1], x[5 * j + 2]
            # ln(F)/p = ln of the p-norm: the thesis's constraint divided by p, the same feasible set with
            # p times smaller derivatives (p = 50 for the wall).
            out += [ob.log_pnorm(px, py, pz) / ob.p for ob in relevant[j]]
        return ca.vertcat(*out, *separations(x, t))

    # The obstacles with some volume and the separations again at the middle of every chord between two nodes (a
    # thin wall is crossed only at its gate event, where its phase ends: the state bounds keep each side of its
    # plane).
    bulky = [[ob for ob in relevant[j] if min(ob.semi_axes) >= scales.length_nm] for j in range(n_ac)]

    def midpoint(x, t, p):
        return ca.vertcat(*[ob.log_pnorm(x[5 * j], x[5 * j + 1], x[5 * j + 2]) / ob.p
                            for j in range(n_ac) for ob in bulky[j]], *separations(x, t))

    n_bulky = sum(len(b) for b in bulky)

    def bank(u):  # linear in the controls: enforced at the collocation points and between them
        return ca.vertcat(*[bank_limit_residuals(u[2 * j], u[2 * j + 1], limits[j].bank_angle_max - margins.bank_rad)
                            for j in range(n_ac)])

    p_lb, p_ub = [], []
    for j in range(n_ac):
        p_lb += [margins.clearance] * len(relevant[j])
        p_ub += [math.inf] * len(relevant[j])
    n_sep = len(pairs) + n_ac * len(ctx.intruders)
    p_lb += [zone.lower] * n_sep
    p_ub += [math.inf] * n_sep
    # Obstacle rows are dimensionless already; squared distances are scaled by the squared separation.
    p_scale = [1.0] * (len(p_lb) - n_sep) + [zone.scale] * n_sep
    # Between the points, a bulky obstacle's row may pass its bound only while the path keeps half the obstacle
    # margin (on the largest semi-axis: the smallest ln-norm change per nm); thin pieces and separations: unchecked.
    p_tol = [margins.clearance - math.log1p(-0.5 * margins.obstacle_nm / max(ob.semi_axes)) if ob in bulky[j]
             else math.inf for j in range(n_ac) for ob in relevant[j]] + [math.inf] * n_sep

    return Phase(
        name=layout.phase_name(k),
        states=states,
        controls=controls,
        dynamics=dynamics,
        lagrange=lagrange,
        path=path,
        path_lb=p_lb,
        path_ub=p_ub,
        path_overshoot_tol=p_tol,
        state_overshoot_tol=None if margins.airspace_bulge_nm is None else
        [v for _ in who for v in (*[margins.airspace_bulge_nm] * 3, math.inf, math.inf)],
        state_lb=x_lb,
        state_ub=x_ub,
        final_state_lb=xf_lb,
        final_state_ub=xf_ub,
        control_lb=u_lb,
        control_ub=u_ub,
        # The initial states are given (radar): they may lie on the airspace boundary, inside the margin.
        initial_state_lb=[v for _ in who for v in (*scenario.airspace[:, 0], -GAMMA_BOUND, -HEADING_BOUND)]
        if k == 0 else None,
        initial_state_ub=[v for _ in who for v in (*scenario.airspace[:, 1], GAMMA_BOUND, HEADING_BOUND)]
        if k == 0 else None,
        t0_bounds=(0.0, 0.0) if k == 0 else (0.0, horizon),
        tf_bounds=(0.0, horizon),
        min_duration=scales.seconds(MIN_DURATION_TURN_TIMES),
        guess=phase_guess(who, aircraft, guesses, guess_span),
        mesh=mesh,
        bound_controls_between=True,
        control_path=bank,
        control_path_ub=0.0,
        midpoint_path=midpoint if n_bulky + n_sep else None,
        midpoint_path_lb=[margins.clearance] * n_bulky + [zone.lower] * n_sep,
        midpoint_path_scale=[1.0] * n_bulky + [zone.scale] * n_sep,
        state_scale=[v for _ in who for v in (scales.length_nm, scales.length_nm, scales.length_nm, 1.0, 1.0)],
        time_scale=scales.time_s,
        path_scale=p_scale,
    )


def phase_guess(who: list[int], aircraft: list[Aircraft], guesses: list[AircraftGuess], span: tuple[float, float],
                samples: int = 25) -> PhaseGuess:
    """The stacked guess of the aircraft ``who`` over the phase's guessed time span."""
    t = np.linspace(span[0], span[1], samples)
    x = np.hstack([guesses[i].state_at(t) for i in who])
    u = np.hstack([_clip_controls(guesses[i], aircraft[i], t) for i in who])
    return PhaseGuess(t=t, x=x, u=u)


def phase_guesses(scenario: Scenario, layout: PhaseLayout, guesses: list[AircraftGuess]) -> list[PhaseGuess]:
    """Per-phase guesses for ``layout`` (e.g. to warm-start a cached NLP from shifted trajectories)."""
    aircraft = [scenario.aircraft_by_callsign(cs) for cs in layout.callsigns]
    times = [0.0] + [ev.time_guess for ev in layout.events]
    return [phase_guess(layout.airborne(k), aircraft, guesses, (times[k], times[k + 1]))
            for k in range(layout.n_phases)]


def _clip_controls(guess: AircraftGuess, ac: Aircraft, t: np.ndarray) -> np.ndarray:
    u_all = guess.controls(ac.dynamics.gravity, ac.speed)
    u = np.column_stack([np.interp(t, guess.t, u_all[:, k]) for k in range(2)])
    u[:, 1] = np.clip(u[:, 1], max(ac.limits.n_v[0], 1e-3), ac.limits.n_v[1])
    cap = np.tan(ac.limits.bank_angle_max) * u[:, 1]
    u[:, 0] = np.clip(u[:, 0], np.maximum(-cap, ac.limits.n_h[0]), np.minimum(cap, ac.limits.n_h[1]))
    return u


def _overlaps(box: np.ndarray, lo: list[float], hi: list[float]) -> bool:
    """True if the (3, 2) box and the bounds [lo, hi] share a volume (not just a face)."""
    return all(box[k, 0] < hi[k] and box[k, 1] > lo[k] for k in range(3))
