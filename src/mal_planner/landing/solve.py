"""Solve the landing problem: initial guess -> phase layout -> OCP -> per-aircraft trajectories."""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence

import numpy as np

from mal_planner.landing.base import LandingOptions, LandingResult
from mal_planner.landing.constraints import Intruder, control_offsets, state_offsets
from mal_planner.landing.guess import AircraftGuess, guess_from_initial_plan, straight_line_guess
from mal_planner.landing.layout import PhaseLayout, plan_layout
from mal_planner.landing.meshes import REFINE_PAD_TURN_TIMES, meshes_after, split_segments
from mal_planner.landing.pairs import (
    SAMPLES_PER_TURN_TIME,
    PhasePairs,
    all_pairs,
    close_unconstrained,
    count,
    screen_pairs,
)
from mal_planner.landing.problem import LandingProblem, build_landing_problem, phase_guesses
from mal_planner.landing.publish import OUTPUT_STEP_TURN_TIMES, published_times, round_step, within_limits
from mal_planner.ocp import OCPOptions, OCPSolution, OCPSolver, PhaseMesh
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.sequencing.schedule import make_schedule
from mal_planner.sequencing.timing import earliest_landing_times
from mal_planner.trajectory import Trajectory

log = logging.getLogger("mal_planner.optimizer")


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
                                        scenario.separation_nm + screen.recheck_nm(self.scales),
                                        [scenario.aircraft_by_callsign(cs).dynamics.n_states
                                         for cs in self.layout.callsigns])
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
        everyone = [self.scenario.aircraft_by_callsign(cs) for cs in lay.callsigns]
        for i, cs in enumerate(lay.callsigns):
            ts, xs, us, ph = [], [], [], []
            model = everyone[i].dynamics
            for k, phase in enumerate(sol.phases):
                if i not in lay.airborne(k):
                    continue
                who = [everyone[m] for m in lay.airborne(k)]
                j = lay.airborne(k).index(i)
                xa, ua = state_offsets(who)[j], control_offsets(who)[j]
                # Dense samples of the solution's own interpolants (states and controls), plus the nodes.
                # A phase boundary appears twice: the end of one phase with the control that applied up
                # to it, then the start of the next with the control that applies from it.
                # The global grid k * output_dt inside the phase, its ends and the nodes.
                controls = slice(ua, ua + model.n_controls)
                t = published_times(phase, controls, self.output_dt, self.options.control_tol)
                x_all, u_all = phase.interpolate(t)
                x = x_all[:, xa:xa + model.n_states]
                # The solution's control interpolant, kept within the aircraft's limits where it overshoots them
                # between the points the NLP constrains (the verification checks what is published).
                u = within_limits(u_all[:, controls], everyone[i].limits)
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
