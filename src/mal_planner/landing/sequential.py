"""Sequential decomposition: plan the aircraft one at a time in landing order, each against the fixed plans
of the aircraft before it.

The joint NLP couples every aircraft in every phase: its size grows as N^2 and its cost per IPOPT iteration
faster (README, "Where the time goes"). Here aircraft i solves its own small two-phase problem (to the gate,
to the runway) in which the aircraft planned before it are *intruders*: fixed paths (smooth interpolants of
their planned samples) that it keeps the separation from, with the optimizer's margin. Each subproblem is
the size of a one-aircraft plan, so the total grows about linearly with N. With fixed landing times the
objective (-sum t_gate + smoothness) is a sum over aircraft, so the decomposition is optimal whenever the
separation is not active between aircraft; where it is, the later aircraft gives way (the loss against the
joint solve is measured in the README). Intruders are screened like the joint problem's pairs (only those
the guess brings near) and re-checked after each solve. The joint plan is verified as a whole by the same
independent check as always; a failed decomposition falls back to the joint solve (see the Planner).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from mal_planner.landing.aircraft_plans import combine, earliest_after, guess_from, retimed
from mal_planner.landing.base import LandingOptions, LandingResult
from mal_planner.landing.constraints import Intruder
from mal_planner.landing.guess import AircraftGuess
from mal_planner.landing.meshes import REFINE_PAD_TURN_TIMES, meshes_after, split_segments
from mal_planner.landing.pairs import SAMPLES_PER_TURN_TIME, PairScreen
from mal_planner.landing.problem import phase_guesses
from mal_planner.landing.recovery import Flown, Recovery, Stuck, recover
from mal_planner.landing.solve import LandingOptimizer, layout_for
from mal_planner.ocp.solver import INFEASIBLE
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.scenario.traffic import FixedPath
from mal_planner.sequencing.schedule import planned_spacing
from mal_planner.trajectory import closest_approach

log = logging.getLogger("mal_planner.optimizer")


Reguess = Callable[[Scenario, str, float, Sequence[tuple[np.ndarray, np.ndarray]], int], "AircraftGuess | None"]
"""(scenario, callsign, landing time, traffic, attempt) -> a new guess of that aircraft that keeps clear of the
traffic (times and positions of the aircraft planned before it), or None (the initializer's
:meth:`~mal_planner.initializer.sequencer.Sequencer.replan_one`, given by the pipeline)."""

INACCURATE_ERROR = 100.0
"""A plan whose mesh refinement stopped (a refined mesh found no solution) at an error estimate more than this
many times the mesh tolerance is recovered from like a failed one. The hp error estimate falls by one or more
orders per mesh iteration, so two orders above the tolerance is a mesh still far from resolving the path: in a
thesis-size campaign two plans kept at 1.5e-2 and 2.3e-2 (tolerance 1e-5) flew 0.44 and 1.2 nm off when
re-integrated. Plans that stop just above the tolerance (1.04e-5 was seen) are kept; the verification judges."""


@dataclass
class _Pass:
    """One pass over the landing order: the plans made so far."""

    order: list[AircraftGuess]
    before: dict[str, LandingResult]
    """The previous plans by callsign (a warm start or a refinement)."""
    parts: list[LandingResult] = field(default_factory=list)
    kept_parts: list[LandingResult] = field(default_factory=list)
    """The previous plans kept as they were (their effort is not counted again)."""
    flown: Flown = field(default_factory=list)
    recoveries: list[Recovery] = field(default_factory=list)
    left_out: list[str] = field(default_factory=list)
    """Aircraft that found no plan and were left out (:attr:`LandingOptions.leave_out_failed`)."""

    def fly(self, part: LandingResult) -> None:
        """``part``'s aircraft is planned: the later ones keep clear of it."""
        tr = part.trajectories[0]
        self.flown.append((tr.callsign, tr.t, tr.positions))


class SequentialOptimizer:
    """The :class:`LandingOptimizer` interface (solve, refine_at, accepts) over per-aircraft subproblems."""

    warm_by_aircraft = True
    """A warm start takes each aircraft's previous plan by callsign: any earlier result with those aircraft."""

    def __init__(self, scenario: Scenario, guesses: list[AircraftGuess], options: LandingOptions,
                 reguess: Reguess | None = None, fixed: Sequence[FixedPath] = (), recover_among_fixed: bool = False
                 ) -> None:
        """``fixed``: paths of other aircraft that every aircraft keeps clear of, as of the ones planned before it
        (a replan of what changed); the recoveries are not tried then (that replan gives way to a whole one), unless
        ``recover_among_fixed`` (aircraft without a plan joining the others: a later landing and another guess)."""
        self.scenario = scenario
        self.fixed: Flown = [(f.callsign, f.t, f.positions) for f in fixed]
        self._fixed_landings = [(f.landing_time, f.aircraft) for f in fixed if f.landing_time is not None]
        self.options = options
        self.layout = layout_for(scenario, guesses)
        self.scales = Scales.of(scenario)
        """The whole scenario's scales: every aircraft's subproblem is scaled and margined alike."""
        self.reguess = reguess
        self.recover_among_fixed = recover_among_fixed
        self._guesses = guesses
        self.setup_time = 0.0

    @property
    def screen(self) -> PairScreen:
        return self.options.pair_screen or PairScreen(near=float("inf"), recheck=float("inf"))

    def accepts(self, scenario: Scenario, guesses: list[AircraftGuess]) -> bool:
        """Same obstacles, gates and landing order: each aircraft's own NLP (whose events may have moved
        against the others') is then warm-started from its previous plan."""
        return (scenario.obstacles == self.scenario.obstacles and scenario.gates == self.scenario.gates
                and [g.callsign for g in guesses] == list(self.layout.callsigns))

    def solve(self, scenario: Scenario | None = None, warm: LandingResult | None = None,
              guesses: list[AircraftGuess] | None = None, deadline=None) -> LandingResult:
        scenario = scenario or self.scenario
        guesses = guesses if guesses is not None else self._guesses
        self.layout = layout_for(scenario, guesses)
        return self._solve_all(scenario, guesses, list(warm.parts) if warm is not None else None, None, deadline)

    def refine_at(self, previous: LandingResult, times: list[float], scenario: Scenario | None = None,
                  deadline=None, callsigns: set[str] | None = None) -> LandingResult:
        """Re-solve the aircraft ``callsigns`` (default: all; warm, in landing order against the others'
        plans) with their mesh segments containing ``times`` split; the others keep their plans. The
        margins absorb the small change a refinement makes to an intruder's path, and the verification
        that follows checks every pair again."""
        scenario = scenario or self.scenario
        guesses = [guess_from(part) for part in previous.parts]
        pad = self.scales.seconds(REFINE_PAD_TURN_TIMES)
        meshes = {part.trajectories[0].callsign: [split_segments(mesh, phase.t0, phase.tf, times, pad)
                                                  for phase, mesh in zip(part.solution.phases, part.solution.meshes,
                                                                         strict=True)]
                  for part in previous.parts}
        self.layout = layout_for(scenario, guesses)
        result = self._solve_all(scenario, guesses, list(previous.parts), meshes, deadline, only=callsigns)
        result.solve_time += previous.solve_time
        result.build_time += previous.build_time
        result.nlp_iterations += previous.nlp_iterations
        result.mesh_history = previous.mesh_history + result.mesh_history
        result.recoveries = previous.recoveries + result.recoveries
        return result

    def solve_one(self, scenario: Scenario, guess: AircraftGuess, flown: Flown, before: LandingResult | None, mesh,
                  deadline, earliest: float | None, options: LandingOptions) -> LandingResult:
        """One aircraft's plan against the plans ``flown`` before it (those its guess brings near, then any its
        plan comes close to)."""
        scales, screen, sep = self.scales, self.screen, scenario.separation_nm
        intruder_dt = scales.seconds(0.5 / SAMPLES_PER_TURN_TIME)
        sub = replace(scenario, aircraft=(scenario.aircraft_by_callsign(guess.callsign),))
        near = [k for k, (_, t, pos) in enumerate(flown)
                if _guess_distance(guess, t, pos, scales) < sep + screen.near_nm(scales)]
        part: LandingResult | None = None
        for _ in range(screen.max_rounds + 1):
            intruders = [Intruder.from_trajectory(flown[k][1], flown[k][2], flown[k][0], intruder_dt) for k in near]
            opt = LandingOptimizer(sub, [guess], options, intruders=intruders, earliest_landing=earliest,
                                   scales=scales)
            if before is not None and before.layout.signature() != opt.layout.signature():
                before = None
            params = opt.problem.params(sub, [guess.landing_time])
            if part is not None:  # intruders added: warm, on the mesh already refined; else from the guess
                sol = opt.solver.solve(params, guess=part.solution, meshes=part.solution.meshes, warm=True,
                                       refine_mesh=False, deadline=deadline)
                if not sol.success:
                    log.info("%s: the warm re-solve against them failed (%s); solving from the guess", guess.callsign,
                             sol.status)
                    sol = opt.solver.solve(params, deadline=deadline)
            elif before is not None and mesh is not None:  # verification-driven refinement
                sol = opt.solver.solve(params, guess=before.solution, meshes=mesh, warm=True, deadline=deadline)
            elif before is not None:  # a replan: the previous plan shifted in time, on its mesh
                sol = opt.solver.solve(params, guess=phase_guesses(sub, opt.layout, [guess]),
                                       meshes=meshes_after(before.solution, guess.shifted_by), warm=True,
                                       deadline=deadline, retry_infeasible=not options.replanning)
            else:
                sol = opt.solver.solve(params, deadline=deadline)
            fell_behind = options.replanning and mesh is None and sol.status == INFEASIBLE
            if not sol.success and part is None and before is not None and not fell_behind:
                log.info("%s: the warm start failed (%s); solving from the guess", guess.callsign, sol.status)
                sol = opt.solver.solve(params, meshes=mesh, deadline=deadline)
            part = opt._result(sol, sol.solve_time, sum(m.build_time for m in sol.mesh_history),
                               [guess.landing_time])
            if not part.success:
                break
            mine = part.trajectories[0]
            close = [k for k, (_, t, pos) in enumerate(flown) if k not in near
                     and closest_approach(mine.t, mine.positions, t, pos) < sep + screen.recheck_nm(scales)]
            if not close:
                break
            log.info("%s: %s came close; re-solving against them too", guess.callsign,
                     ", ".join(flown[k][0] for k in close))
            near += close
        assert part is not None
        log.debug("sequential: %s planned against %d of %d earlier aircraft", guess.callsign, len(near), len(flown))
        return part

    def _solve_all(self, scenario: Scenario, guesses: Sequence[AircraftGuess], previous: list[LandingResult] | None,
                   meshes: dict | None, deadline, only: set[str] | None = None) -> LandingResult:
        options = replace(self.options, pair_screen=None,
                          max_nlp_iterations=min(self.options.max_nlp_iterations,
                                                 self.options.sequential_max_iterations))
        run = _Pass(list(guesses), {p.trajectories[0].callsign: p for p in previous or [] if p.trajectories})
        run.flown.extend(self.fixed)
        t_start = time.perf_counter()
        i = 0
        while i < len(run.order):
            guess = run.order[i]
            if deadline is not None and deadline.expired():
                break
            kept = run.before.get(guess.callsign) if only is not None and guess.callsign not in only else None
            if kept is not None:
                run.kept_parts.append(kept)
                run.parts.append(kept)
                run.fly(kept)
                i += 1
                continue
            part = self._plan_next(scenario, run, i, meshes, deadline, only, options)
            if meshes is None and (not self.fixed or self.recover_among_fixed):
                step = self._recover_if_stuck(scenario, run, i, part, deadline, options)
                if step == "swap":  # the previous aircraft is planned again, after this one
                    run.parts.pop()
                    run.flown.pop()
                    i -= 1
                    continue
                if step is not None:
                    part = step
            if not part.success and options.leave_out_failed and meshes is None and only is None:
                log.warning("sequential: %s found no plan (%s); left out, the others planned without it",
                            run.order[i].callsign, part.status)
                run.left_out.append(run.order.pop(i).callsign)
                continue
            run.parts.append(part)
            if not part.success:
                log.warning("sequential: %s found no plan (%s)", run.order[i].callsign, part.status)
                break
            run.fly(part)
            i += 1
        return self._combined(scenario, run, time.perf_counter() - t_start)

    def _combined(self, scenario: Scenario, run: _Pass, wall: float) -> LandingResult:
        """The pass's plans as one result: failed when an aircraft was left out (its parts the plans of the others,
        which :func:`~mal_planner.landing.aircraft_plans.planned_prefix` hands out)."""
        solved = [p for p in run.parts if all(p is not k for k in run.kept_parts)]
        self.layout = layout_for(scenario, run.order)
        result = combine(run.parts, len(run.order), self.layout, wall, solved=solved)
        result.recoveries = run.recoveries
        if run.left_out and result.success:
            result = replace(result, success=False, status=f"{', '.join(run.left_out)}: left out (no plan)",
                             left_out=tuple(run.left_out))
        return result

    def _plan_next(self, scenario: Scenario, run: _Pass, i: int, meshes: dict | None, deadline,
                   only: set[str] | None, options: LandingOptions) -> LandingResult:
        """The plan of the aircraft at ``run.order[i]`` against those planned before it (with free landing times,
        no earlier than the spacing behind the previous one allows); a refinement's that finds none: its previous
        plan."""
        guess = run.order[i]
        earliest = None
        if not options.fixed_landing_times and (run.parts or self._fixed_landings):
            earliest = self._earliest(scenario, run, guess)
            if guess.landing_time < earliest:
                guess = run.order[i] = retimed(guess, earliest)
        mesh = None if meshes is None else meshes.get(guess.callsign)
        # A refinement re-plans some aircraft with the others' plans fixed: the later ones too, whose plans kept
        # clear of this one's former path only (a refined path came 2.96 nm to a later plan, against 3 nm).
        later = [] if only is None else [
            (cs, p.trajectories[0].t, p.trajectories[0].positions) for cs, p in run.before.items()
            if cs not in {f[0] for f in run.flown} and cs != guess.callsign]
        part = self.solve_one(scenario, guess, run.flown + later, run.before.get(guess.callsign), mesh,
                              deadline, earliest, options)
        kept = run.before.get(guess.callsign) if only is not None else None
        if not part.success and kept is not None:
            # A refinement that finds no plan for this aircraft keeps its previous one; the others of the pair
            # are re-planned around it (an aircraft with a fixed landing time could not move away from a
            # later one passing 2.93 nm from the threshold when it landed; the later one could).
            log.info("%s: the refinement found no plan (%s); keeping its previous plan", guess.callsign,
                     part.status)
            run.kept_parts.append(kept)
            part = kept
        return part

    def _earliest(self, scenario: Scenario, run: _Pass, guess: AircraftGuess) -> float:
        """The earliest landing of ``guess``'s aircraft with free landing times: the spacing after the one planned
        before it and after every fixed path landing before its slot (0: none lands before it)."""
        follower = scenario.aircraft_by_callsign(guess.callsign)
        times = [earliest_after(scenario, run.parts[-1], guess.callsign)] if run.parts else []
        times += [t + planned_spacing(scenario, leader, follower) for t, leader in self._fixed_landings
                  if t <= guess.landing_time]
        return max(times, default=0.0)

    def _recover_if_stuck(self, scenario: Scenario, run: _Pass, i: int, part: LandingResult, deadline,
                          options: LandingOptions) -> LandingResult | str | None:
        """None if ``part`` is a plan accurate enough; else what :func:`~mal_planner.landing.recovery.recover`
        finds for the aircraft at ``run.order[i]``."""
        inaccurate = self.inaccurate(part)
        if part.success and not inaccurate:
            return None
        guess = run.order[i]
        if inaccurate:
            log.warning("sequential: %s found no accurate plan (Mesh_Not_Converged: error %.1e, over %gx the "
                        "tolerance); trying to recover", guess.callsign, part.solution.max_error,
                        INACCURATE_ERROR)
        else:
            log.warning("sequential: %s found no plan (%s); trying to recover", guess.callsign, part.status)
        return recover(self, Stuck(scenario, run.order, i, run.parts, run.flown, run.recoveries, deadline, options))

    def inaccurate(self, part: LandingResult) -> bool:
        """A solved plan whose mesh refinement stopped far above the tolerance (:data:`INACCURATE_ERROR`)."""
        sol = part.solution
        return (part.success and sol is not None and not sol.mesh_converged
                and sol.max_error > INACCURATE_ERROR * self.options.mesh_tol)


def _guess_distance(guess: AircraftGuess, t: np.ndarray, pos: np.ndarray, scales: Scales) -> float:
    """Smallest distance between a guess (sampled as the pair screen does) and a planned path while both fly."""
    dt = scales.seconds(1.0 / SAMPLES_PER_TURN_TIME)
    ts = np.arange(0.0, guess.landing_time + dt, dt)
    return closest_approach(ts, guess.state_at(ts)[:, :3], t, pos)
