"""Solve the landing problem: initial guess -> phase layout -> OCP -> per-aircraft trajectories."""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from mal_planner.landing.guess import AircraftGuess, guess_from_initial_plan, straight_line_guess
from mal_planner.landing.layout import PhaseLayout, plan_layout
from mal_planner.landing.pairs import (
    SAMPLES_PER_TURN_TIME,
    PairScreen,
    PhasePairs,
    all_pairs,
    close_unconstrained,
    count,
    screen_pairs,
)
from mal_planner.landing.problem import (
    Intruder,
    LandingProblem,
    SafetyMargins,
    build_landing_problem,
    phase_guesses,
)
from mal_planner.ocp import MeshIteration, OCPOptions, OCPSolution, OCPSolver, PhaseMesh, PhaseSolution
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.sequencing.schedule import make_schedule
from mal_planner.sequencing.timing import earliest_landing_times
from mal_planner.trajectory import Trajectory

log = logging.getLogger("mal_planner.optimizer")


LANDING_IPOPT: dict = {
    # The initial guess is already close (the initializer's obstacle-free paths): start with a small
    # barrier and little push off the bounds. Measured on scenarios/thesis.yaml (benchmarks/bench_landing.py):
    # 61 -> 44 IPOPT iterations. AMD ordering and a smaller MUMPS workspace cut the time per iteration.
    "mu_init": 1e-4,
    "bound_push": 1e-5,
    "bound_frac": 1e-5,
    "mumps_pivot_order": 0,
    "mumps_mem_percent": 100,
}


OUTPUT_STEP_TURN_TIMES = 1.0 / 30.0
"""Default sampling step of the published trajectories, in turn times (thesis: 0.25 s)."""
REFINE_PAD_TURN_TIMES = 1.0 / 7.5
"""A verification-driven refinement cuts a new segment this far around a violation (thesis: 1 s)."""


@dataclass(frozen=True)
class LandingOptions:
    guess: Literal["initializer", "straight"] = "initializer"
    """Initial guess: the initializer's paths (the thesis's method) or naive straight lines."""
    fixed_landing_times: bool = True
    """Fix the landing times at the schedule's (the scenario's where it gives them); False: the optimizer
    chooses them, subject to the minimum spacing."""
    replanning: bool = False
    """The guesses are the previous plan (set by :class:`mal_planner.pipeline.Planner` on replans): an aircraft that
    finds no plan for its slot has most likely fallen behind that plan (gusts), so the sequential strategy's
    recovery 'later landing' comes first."""
    segments: int = 4
    """Initial mesh without ``segment_turn_times``: this many segments per phase ..."""
    degree: int = 6
    """... of this many collocation points each."""
    segment_turn_times: float | None = 4.0
    """About one initial segment per this many turn times of (guessed) phase duration (thesis: one per 20 s);
    None: ``segments`` in every phase. Short phases then start on small meshes (measured: thesis 3.5 -> 2.2 s,
    five aircraft 15 -> 7 s)."""
    mesh_tol: float = 1e-5
    """The hp refinement's tolerance on the relative state error of each segment (states scaled by the turn radius).
    The published paths then deviate from the flown ones by about 5e-5 nm (thesis and terminal area alike), a
    hundredth of the verification's accuracy; at 1e-4 a terminal-area plan drifted 0.018 nm and left the airspace
    by 0.0009 nm (its margin is a fifth of the accuracy), and 1e-6 costs a mesh iteration more (formerly the
    default)."""
    n_min: int = 3
    n_max: int = 10
    max_mesh_iterations: int = 8
    nlp_tol: float = 1e-8
    max_nlp_iterations: int = 3000
    refine: bool = True
    output_dt: float | None = None
    """Sampling step (s) of the output trajectories (dense samples of the solution's interpolants); None: a round
    step near a thirtieth of the scenario's turn time (thesis: 0.25 s)."""
    control_tol: float = 1e-5
    """The published controls, linear between samples, stay this close (load factor) to the solution's control
    interpolant at every midpoint: where they do not, samples are added (see :func:`published_times`)."""
    margins: SafetyMargins = field(default_factory=SafetyMargins)
    """How much stricter than the scenario the NLP is (the verification allows no tolerance)."""
    ipopt: dict = field(default_factory=lambda: dict(LANDING_IPOPT))
    """IPOPT options on top of the engine's defaults (see LANDING_IPOPT)."""
    strategy: Literal["auto", "joint", "sequential"] = "auto"
    """joint: one NLP for all aircraft; sequential: one small NLP per aircraft in landing order against the
    fixed plans of those before it (:mod:`mal_planner.landing.sequential`); auto: sequential from
    ``sequential_from`` aircraft on, joint below (the thesis's 3 aircraft are planned jointly)."""
    sequential_from: int = 4
    sequential_max_iterations: int = 400
    """IPOPT iterations of one aircraft's NLP in the sequential strategy, at most: its solves take 20-100; one that
    runs on is stuck (a terminal-area case took 1,270 for a plan its recovery then found in 60)."""
    pair_screen: PairScreen | None = field(default_factory=PairScreen)
    """Separation constraints only for pairs that can come close (see :mod:`mal_planner.landing.pairs`);
    None: every pair in every phase."""


@dataclass
class LandingResult:
    success: bool
    status: str
    trajectories: list[Trajectory]
    """In landing order, with controls and phase indices."""
    gate_times: dict[str, float | None]
    landing_times: dict[str, float]
    objective: float
    solve_time: float
    build_time: float
    nlp_iterations: int
    mesh_history: list[MeshIteration]
    layout: PhaseLayout
    solution: OCPSolution
    phase_names: list[str] = field(default_factory=list)
    required_landing_times: dict[str, float] = field(default_factory=dict)
    """The landing times the problem was given (fixed mode), relative to the plan start."""
    parts: list[LandingResult] = field(default_factory=list)
    """Sequential decomposition: the per-aircraft results in landing order (empty for a joint solve)."""
    strategy: str = "joint"
    recoveries: list = field(default_factory=list)
    """Sequential decomposition: the recoveries tried (:class:`mal_planner.landing.sequential.Recovery`)."""

    def stats(self) -> dict:
        return {
            "success": self.success,
            "status": self.status,
            "strategy": self.strategy,
            "objective": self.objective,
            "solve_time_s": self.solve_time,
            "build_time_s": self.build_time,
            "nlp_iterations": self.nlp_iterations,
            "recoveries": [{"callsign": r.callsign, "recovery": r.name, "success": r.success, "seconds": r.seconds}
                           for r in self.recoveries],
            "phases": self.phase_names,
            "mesh_iterations": [
                {"iteration": m.iteration, "segments": list(m.segments), "degrees": [list(d) for d in m.degrees],
                 "max_error": m.max_error, "nlp_iterations": m.nlp_iterations, "nlp_time_s": m.nlp_time,
                 "build_time_s": m.build_time, "status": m.status}
                for m in self.mesh_history
            ],
        }


def split_segments(mesh: PhaseMesh, t0: float, tf: float, times: Sequence[float], pad_s: float) -> PhaseMesh:
    """The phase ``[t0, tf]``'s mesh with a new segment (same degree) around the times in each segment that
    contains some: from the first to the last of them, ``pad_s`` wider on each side (a cut closer than
    ``pad_s / 2`` to the segment's end is left out); a segment the times (nearly) cover is halved instead.

    Halving alone was too slow where a path cuts an obstacle's corner between collocation points: three
    rounds left points about 1 s apart at a 20 s segment's centre, and the chord still cut 0.05 nm into a
    no-fly zone (campaign traffic-0128); a short segment at the cut puts all its points there.
    """
    duration = tf - t0
    fractions = [(t - t0) / duration for t in times if t0 <= t <= tf] if duration > 0 else []
    pad = pad_s / duration if duration > 0 else 0.0
    breaks, degrees = [mesh.breaks[0]], []
    for s, n in enumerate(mesh.degrees):
        a, b = mesh.breaks[s], mesh.breaks[s + 1]
        inside = [f for f in fractions if a <= f <= b]
        if inside:
            cuts = [c for c in (min(inside) - pad, max(inside) + pad) if a + pad / 2 < c < b - pad / 2]
            for c in cuts or [0.5 * (a + b)]:
                breaks.append(c)
                degrees.append(n)
        breaks.append(b)
        degrees.append(n)
    return PhaseMesh(tuple(breaks), tuple(degrees))


MERGED_PIECE = 0.25
"""A segment cut by :func:`mesh_after` to less than this share of its width joins the next segment."""


def mesh_after(mesh: PhaseMesh, t0: float, tf: float, t: float) -> PhaseMesh:
    """The mesh of phase ``[t0, tf]`` with the part before ``t`` cut off, over ``[t, tf]``, once a whole segment lies
    before ``t`` (before that: the mesh itself).

    A replan starts on the previous plan's meshes: uncut, the segments of the part already flown squeezed into what
    is left (at ten aircraft the last replans solved 12 segments over 60 s where the first plan had 12 over 250 s).
    """
    duration = tf - t0
    f = (t - t0) / duration if duration > 0 else 0.0
    if f < mesh.breaks[1]:  # not a whole segment flown: the same mesh (a joint NLP on it is cached)
        return mesh
    if f >= 1.0:
        return PhaseMesh.uniform(1, mesh.degrees[-1])
    breaks, degrees = [0.0], []
    for s, n in enumerate(mesh.degrees):
        a, b = mesh.breaks[s], mesh.breaks[s + 1]
        if b <= f:
            continue
        if degrees and a > f:
            breaks.append((a - f) / (1.0 - f))
        if not degrees and a < f and (b - f) < MERGED_PIECE * (b - a) and s + 1 < len(mesh.degrees):
            continue  # a sliver: the next segment starts at the cut
        degrees.append(n)
    breaks.append(1.0)
    return PhaseMesh(tuple(breaks), tuple(degrees))


def meshes_after(solution: OCPSolution, t: float) -> list[PhaseMesh]:
    """:func:`mesh_after` for every phase of ``solution`` (an :class:`~mal_planner.ocp.solution.OCPSolution`)."""
    return [mesh_after(p.layout.mesh, p.t0, p.tf, t) for p in solution.phases]


def scheduled_landings(scenario: Scenario, initial_plan) -> tuple[list[str], list[float]]:
    """Landing order and times: the initializer's schedule, or (no initializer) one made from the
    turn-aware earliest landing times alone."""
    schedule = getattr(initial_plan, "schedule", None)
    if schedule is None:
        schedule = make_schedule(scenario, earliest_landing_times(scenario))
    return list(schedule.order), schedule.time_list()


class LandingOptimizer:
    """Builds the OCP once and re-solves it (new initial states, warm start) without rebuilding.

    Times are relative to the plan start (t = 0 at the scenario's initial states).
    """

    warm_by_aircraft = False
    """A warm start needs the previous result of this very NLP (its meshes are per phase)."""

    def __init__(self, scenario: Scenario, guesses: list[AircraftGuess], options: LandingOptions,
                 intruders: Sequence[Intruder] = (), earliest_landing: float | None = None,
                 scales: Scales | None = None) -> None:
        self.scenario = scenario
        self.scales = scales or Scales.of(scenario)
        self.options = options
        self.intruders = tuple(intruders)
        self.earliest_landing = earliest_landing
        self.layout = layout_for(scenario, guesses)
        self.landing_times = [g.landing_time for g in guesses]
        self._guesses = guesses
        t0 = time.perf_counter()
        screen = options.pair_screen
        self.pairs: PhasePairs = (all_pairs(self.layout) if screen is None else
                                  screen_pairs(self.layout, guesses, self.scales, screen))
        self._build()
        self.setup_time = time.perf_counter() - t0

    def _build(self) -> None:
        options = self.options
        self.problem: LandingProblem = build_landing_problem(
            self.scenario, self.layout, self._guesses, options.fixed_landing_times,
            PhaseMesh.uniform(options.segments, options.degree), margins=options.margins,
            segment_turn_times=options.segment_turn_times, pairs=self.pairs, intruders=self.intruders,
            earliest_landing=self.earliest_landing, scales=self.scales)
        self.solver = OCPSolver(self.problem.problem, OCPOptions(
            tol=options.nlp_tol, max_iter=options.max_nlp_iterations, refine=options.refine,
            mesh_tol=options.mesh_tol, n_min=options.n_min, n_max=options.n_max,
            max_mesh_iterations=options.max_mesh_iterations, ipopt=dict(options.ipopt),
            # The NLP's load-factor bounds are this far inside the aircraft's limits: an interpolant that passes
            # them by more is clipped when published, and the flown path drifts from the plan (campaign
            # traffic-0057: n_v 0.006 past 1.3 for 0.5 s before a gate, 0.002 nm low at touchdown, below the floor).
            control_overshoot_tol=options.margins.load_factor))
        if len(self.layout.callsigns) > 1:
            log.debug("separation constraints on %d of %d phase pairs", count(self.pairs),
                      count(all_pairs(self.layout)))

    @property
    def output_dt(self) -> float:
        """Sampling step of the published trajectories (s): ``options.output_dt``, or the round step (1, 2, 2.5 or 5
        times a power of ten) nearest to a thirtieth of the turn time (thesis: 0.25 s; terminal area: 0.5 s)."""
        return self.options.output_dt or round_step(self.scales.seconds(OUTPUT_STEP_TURN_TIMES))

    @property
    def refine_pad_s(self) -> float:
        """How far around a violation a verification-driven refinement cuts its new segment (s)."""
        return self.scales.seconds(REFINE_PAD_TURN_TIMES)

    def _with_close_pairs(self, result: LandingResult, scenario: Scenario, deadline) -> LandingResult:
        """Re-solve (warm) with every unconstrained pair that came close added, until none does."""
        screen = self.options.pair_screen
        rounds = 0
        while screen is not None and result.success and rounds < screen.max_rounds:
            if deadline is not None and deadline.expired():
                break
            samples = []
            dt = self.scales.seconds(0.5 / SAMPLES_PER_TURN_TIME)
            for phase in result.solution.phases:
                t = np.linspace(phase.t0, phase.tf, max(20, int(np.ceil((phase.tf - phase.t0) / dt)) + 1))
                samples.append((t, phase.interpolate(t)[0]))
            close = close_unconstrained(self.layout, samples, self.pairs,
                                        scenario.separation_nm + screen.recheck_nm(self.scales))
            if not count(close):
                break
            rounds += 1
            self.pairs = [have | new for have, new in zip(self.pairs, close, strict=True)]
            log.info("separation: %d more phase pairs came close; re-solving with %d", count(close), count(self.pairs))
            self._build()
            landing_times = [result.required_landing_times[cs] for cs in self.layout.callsigns]
            params = self.problem.params(scenario, landing_times)
            t0 = time.perf_counter()
            # On the mesh already refined: the added pairs move the solution a little, not its accuracy.
            sol = self.solver.solve(params, guess=result.solution, meshes=result.solution.meshes, warm=True,
                                    refine_mesh=False, deadline=deadline)
            again = self._result(sol, time.perf_counter() - t0, sum(m.build_time for m in sol.mesh_history),
                                 landing_times)
            again.solve_time += result.solve_time
            again.build_time += result.build_time
            again.nlp_iterations += result.nlp_iterations
            again.mesh_history = result.mesh_history + again.mesh_history
            result = again
        return result

    def accepts(self, scenario: Scenario, guesses: list[AircraftGuess]) -> bool:
        """True if the cached NLP fits (same aircraft, obstacles, gates and event order)."""
        return (scenario.obstacles == self.scenario.obstacles and scenario.gates == self.scenario.gates
                and layout_for(scenario, guesses).signature() == self.layout.signature())

    def solve(self, scenario: Scenario | None = None, warm: LandingResult | None = None,
              guesses: list[AircraftGuess] | None = None, deadline=None) -> LandingResult:
        """Solve for ``scenario``'s initial states (default: the one built with).

        ``guesses`` (e.g. the previous plan shifted in time, see :func:`shift_guesses`) replace the
        initial guess and carry the landing times; ``warm`` reuses that result's meshes, so a replan
        normally needs no new NLP at all.
        """
        scenario = scenario or self.scenario
        landing_times = [g.landing_time for g in guesses] if guesses is not None else self.landing_times
        params = self.problem.params(scenario, landing_times)
        t0 = time.perf_counter()
        builds_before = self.solver.n_builds
        phase_init = phase_guesses(scenario, layout_for(scenario, guesses), guesses) if guesses else None
        shift = guesses[0].shifted_by if guesses else 0.0
        meshes = meshes_after(warm.solution, shift) if warm is not None else None
        sol = self.solver.solve(params, guess=phase_init, meshes=meshes, warm=True if warm is not None else None,
                                deadline=deadline)
        wall = time.perf_counter() - t0
        build_time = sum(m.build_time for m in sol.mesh_history)
        log.info("optimizer: %s in %.2f s (%d NLP builds, objective %.4f)", sol.status, wall,
                 self.solver.n_builds - builds_before, sol.objective)
        return self._with_close_pairs(self._result(sol, wall, build_time, landing_times), scenario, deadline)

    def refine_at(self, previous: LandingResult, times: list[float], scenario: Scenario | None = None,
                  deadline=None, callsigns: set[str] | None = None) -> LandingResult:
        """Re-solve with the mesh segments containing ``times`` split in two (warm start).

        ``callsigns`` (the aircraft involved) is for the sequential optimizer; one NLP re-solves them all.

        Path constraints (separation, obstacles) hold only at the collocation points; where the
        independent verification finds the flown trajectory breaking one between them, more points
        there close the gap.
        """
        scenario = scenario or self.scenario
        meshes = []
        for phase, mesh in zip(previous.solution.phases, previous.solution.meshes, strict=True):
            meshes.append(split_segments(mesh, phase.t0, phase.tf, times, self.refine_pad_s))
        landing_times = [previous.required_landing_times[cs] for cs in self.layout.callsigns]
        params = self.problem.params(scenario, landing_times)
        t0 = time.perf_counter()
        sol = self.solver.solve(params, guess=previous.solution, meshes=meshes, deadline=deadline)
        wall = time.perf_counter() - t0
        log.info("optimizer (refined at %d places): %s in %.2f s", len(times), sol.status, wall)
        result = self._result(sol, wall, sum(m.build_time for m in sol.mesh_history), landing_times)
        # Report the whole effort: the previous solves and this one.
        result.solve_time += previous.solve_time
        result.build_time += previous.build_time
        result.nlp_iterations += previous.nlp_iterations
        result.mesh_history = previous.mesh_history + result.mesh_history
        return self._with_close_pairs(result, scenario, deadline)

    def _result(self, sol: OCPSolution, wall: float, build_time: float, required: list[float]) -> LandingResult:
        lay = self.layout
        trajectories: list[Trajectory] = []
        gate_times: dict[str, float | None] = {}
        landing_times: dict[str, float] = {}
        for i, cs in enumerate(lay.callsigns):
            ts, xs, us, ph = [], [], [], []
            for k, phase in enumerate(sol.phases):
                if i not in lay.airborne(k):
                    continue
                j = lay.airborne(k).index(i)
                # Dense samples of the solution's own interpolants (states and controls), plus the nodes.
                # A phase boundary appears twice: the end of one phase with the control that applied up
                # to it, then the start of the next with the control that applies from it.
                # The global grid k * output_dt inside the phase, its ends and the nodes.
                t = published_times(phase, slice(2 * j, 2 * j + 2), self.output_dt, self.options.control_tol)
                x_all, u_all = phase.interpolate(t)
                x = x_all[:, 5 * j:5 * j + 5]
                # The solution's control interpolant, kept within the aircraft's limits where it overshoots them
                # between the points the NLP constrains (the verification checks what is published).
                u = within_limits(u_all[:, 2 * j:2 * j + 2], self.scenario.aircraft_by_callsign(cs).limits)
                ts.append(t)
                xs.append(x)
                us.append(u)
                ph.append(np.full(len(t), k))
            trajectories.append(Trajectory(cs, np.concatenate(ts), np.concatenate(xs), np.concatenate(us),
                                           np.concatenate(ph)))
            gate_times[cs] = sol.phases[lay.event_index("gate", i)].tf if lay.has_gate_event(i) else None
            landing_times[cs] = sol.phases[lay.event_index("land", i)].tf
        return LandingResult(
            success=sol.success, status=sol.status, trajectories=trajectories, gate_times=gate_times,
            landing_times=landing_times, objective=sol.objective, solve_time=wall, build_time=build_time,
            nlp_iterations=sol.iterations, mesh_history=list(sol.mesh_history), layout=lay, solution=sol,
            phase_names=[lay.phase_name(k) for k in range(lay.n_phases)],
            required_landing_times=dict(zip(lay.callsigns, required, strict=True)))


def round_step(step: float) -> float:
    """The one of 1, 2, 2.5 and 5 times a power of ten nearest to ``step`` (by ratio): samples on a round grid."""
    power = 10.0 ** math.floor(math.log10(step))
    return min((m * power for m in (1.0, 2.0, 2.5, 5.0, 10.0)), key=lambda c: abs(math.log(c / step)))


def within_limits(u: np.ndarray, limits) -> np.ndarray:
    """Controls (n_h, n_v) rows moved into the load-factor and bank limits (n_v first, then n_h within
    +-tan(mu) n_v): the interpolant of a solution that rides a limit can pass it by 1e-4 between the points
    where the NLP holds it (campaign: n_v 1.3000x against 1.3, and a verification round to refine it)."""
    out = np.array(u, float, copy=True)
    out[:, 1] = np.clip(out[:, 1], *limits.n_v)
    cap = math.tan(limits.bank_angle_max) * out[:, 1]
    out[:, 0] = np.clip(out[:, 0], np.maximum(-cap, limits.n_h[0]), np.minimum(cap, limits.n_h[1]))
    return out


def published_times(phase: PhaseSolution, controls: slice, dt: float, control_tol: float,
                    max_rounds: int = 8) -> np.ndarray:
    """Sample times of one aircraft in one phase: the global grid ``k * dt``, the phase's ends and nodes, and
    wherever the controls, taken as linear between samples (as a follower flies them), would miss the
    solution's control interpolant by more than ``control_tol`` at an interval's midpoint, its midpoint
    (at most ``max_rounds`` halvings of an interval: where the interpolants of two mesh segments differ at
    their common break, the last interval before it stays 1/256 of its length).

    Where the optimal controls bend sharply (the first seconds of a plan, a turn's entry) a 0.25 s grid
    flown linearly drifted 0.0035 nm from the plan over 290 s and dipped below the floor before landing
    (campaign traffic-0083); 0.05 s everywhere fixed it at five times the samples.
    """
    grid = np.arange(np.floor(phase.t0 / dt) + 1, np.ceil(phase.tf / dt)) * dt
    t = np.union1d(np.concatenate([grid, [phase.t0, phase.tf]]), phase.t)
    u = phase.interpolate(t)[1][:, controls]
    for _ in range(max_rounds):
        mid = 0.5 * (t[:-1] + t[1:])
        u_mid = phase.interpolate(mid)[1][:, controls]
        bad = np.max(np.abs(u_mid - 0.5 * (u[:-1] + u[1:])), axis=1) > control_tol
        if not bad.any():
            break
        t = np.concatenate([t, mid[bad]])
        u = np.concatenate([u, u_mid[bad]])
        order = np.argsort(t, kind="stable")
        t, u = t[order], u[order]
    return t


def layout_for(scenario: Scenario, guesses: list[AircraftGuess]) -> PhaseLayout:
    """Phase layout from guesses; an aircraft already past the gate gets no gate event."""
    gate = scenario.gates[0] if scenario.gates else None
    gate_times: list[float | None] | None = None
    if gate is not None:
        gate_times = []
        for g in guesses:
            past = gate.signed_distance(scenario.aircraft_by_callsign(g.callsign).position) <= 0.0
            gate_times.append(None if past else (g.gate_time if g.gate_time is not None else 0.5 * g.landing_time))
    return plan_layout([g.callsign for g in guesses], [g.landing_time for g in guesses], gate_times)


def shift_guesses(previous: LandingResult, dt: float) -> list[AircraftGuess]:
    """The previous plan seen from ``dt`` seconds later: times shifted, the past cut off."""
    out = []
    for tr in previous.trajectories:
        keep = tr.t >= dt
        t = np.concatenate([[dt], tr.t[keep]]) - dt
        states = np.vstack([tr.state_at(dt)[None, :], tr.states[keep]])
        states[:, 4] = np.unwrap(states[:, 4])
        t, idx = np.unique(t, return_index=True)
        gate = previous.gate_times.get(tr.callsign)
        out.append(AircraftGuess(tr.callsign, t, states[idx], previous.landing_times[tr.callsign] - dt,
                                 None if gate is None or gate - dt <= 0.0 else gate - dt, shifted_by=dt))
    return out


def make_guesses(scenario: Scenario, initial_plan, options: LandingOptions) -> list[AircraftGuess]:
    """Guesses in landing order from the initializer's plan (or straight lines, per ``options.guess``)."""
    order, landing = scheduled_landings(scenario, initial_plan)
    if options.guess == "straight" or initial_plan is None:
        return straight_line_guess(scenario, order, landing)
    return guess_from_initial_plan(scenario, initial_plan.trajectories, landing)


def uses_sequential(options: LandingOptions, n_aircraft: int) -> bool:
    """Whether ``options.strategy`` plans ``n_aircraft`` one at a time."""
    return options.strategy == "sequential" or (options.strategy == "auto" and n_aircraft >= options.sequential_from)


def make_optimizer(scenario: Scenario, guesses: list[AircraftGuess], options: LandingOptions, reguess=None):
    """The optimizer ``options.strategy`` asks for: a :class:`LandingOptimizer` or a SequentialOptimizer (whose
    first recovery, a new guess, comes from ``reguess``; see :data:`mal_planner.landing.sequential.Reguess`)."""
    if uses_sequential(options, len(guesses)):
        from mal_planner.landing.sequential import SequentialOptimizer

        return SequentialOptimizer(scenario, guesses, options, reguess)
    return LandingOptimizer(scenario, guesses, options)


def optimize_landing(scenario: Scenario, initial_plan=None, options: LandingOptions | None = None) -> LandingResult:
    """One-shot: build and solve (see :class:`LandingOptimizer` for re-solving)."""
    options = options or LandingOptions()
    guesses = make_guesses(scenario, initial_plan, options)
    return make_optimizer(scenario, guesses, options).solve()
