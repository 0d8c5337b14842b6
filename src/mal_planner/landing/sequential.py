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
from dataclasses import dataclass, replace

import numpy as np

from mal_planner.landing.guess import AircraftGuess
from mal_planner.landing.pairs import SAMPLES_PER_TURN_TIME, PairScreen
from mal_planner.landing.problem import Intruder, phase_guesses
from mal_planner.landing.solve import (
    REFINE_PAD_TURN_TIMES,
    LandingOptimizer,
    LandingOptions,
    LandingResult,
    layout_for,
    meshes_after,
    split_segments,
)
from mal_planner.ocp.solver import INFEASIBLE
from mal_planner.scales import Scales
from mal_planner.scenario import Scenario
from mal_planner.sequencing.schedule import planned_spacing
from mal_planner.trajectory import closest_approach
from mal_planner.wake import wake_spacing_s

log = logging.getLogger("mal_planner.optimizer")


Reguess = Callable[[Scenario, str, float, Sequence[tuple[np.ndarray, np.ndarray]], int], "AircraftGuess | None"]
"""(scenario, callsign, landing time, traffic, attempt) -> a new guess of that aircraft that keeps clear of the
traffic (times and positions of the aircraft planned before it), or None (the initializer's
:meth:`~mal_planner.initializer.sequencer.Sequencer.replan_one`, given by the pipeline)."""

RECOVERIES = ("another guess", "later landing", "give way", "swap with the previous")
"""What the sequential strategy tries, in this order, when an aircraft finds no plan against the plans of those
before it (the joint NLP of everyone is the pipeline's last resort):

* *another guess*: the initializer stretches the aircraft's path anew, clear of the plans made so far (the
  first guess only kept clear of the others' guesses);
* *later landing*: where the schedule (not the scenario) set its landing time, it lands as soon as it can after
  it (a free landing time), else later by half a landing spacing, then one, then two (the aircraft after it move
  back as far as their spacing needs);
* *give way*: its plan alone (no intruders) shows which earlier aircraft block it; the last of them is planned
  again with that plan as an intruder, then the aircraft again against everyone;
* *swap with the previous*: it takes the previous aircraft's landing slot, and that one is planned after it.

On a replan (``LandingOptions.replanning``) 'later landing' comes first: there the aircraft that find no plan are
those that fell behind the plan they fly (gusts, the guidance's lag); in the campaigns 'later landing' served 305 of
346 aircraft that tried it, 'another guess' 14 of 389. Such an aircraft's warm solve that IPOPT finds infeasible goes
straight to the recovery: its cold retries never found a plan (ten-aircraft closed loop, seed 0: the cold NLP on the
same mesh 0 of 24 times in the first 12 runs, the solve from the guess 0 of 30 in the first 17) and cost twice the
first solve."""


LATER_BY_SPACINGS = (0.5, 1.0, 2.0)
"""The delays the recovery 'later landing' tries, in landing spacings."""

INACCURATE_ERROR = 100.0
"""A plan whose mesh refinement stopped (a refined mesh found no solution) at an error estimate more than this
many times the mesh tolerance is recovered from like a failed one. The hp error estimate falls by one or more
orders per mesh iteration, so two orders above the tolerance is a mesh still far from resolving the path: in a
thesis-size campaign two plans kept at 1.5e-2 and 2.3e-2 (tolerance 1e-5) flew 0.44 and 1.2 nm off when
re-integrated. Plans that stop just above the tolerance (1.04e-5 was seen) are kept; the verification judges."""


@dataclass
class Recovery:
    callsign: str
    name: str
    success: bool
    seconds: float


class SequentialOptimizer:
    """The :class:`LandingOptimizer` interface (solve, refine_at, accepts) over per-aircraft subproblems."""

    warm_by_aircraft = True
    """A warm start takes each aircraft's previous plan by callsign: any earlier result with those aircraft."""

    def __init__(self, scenario: Scenario, guesses: list[AircraftGuess], options: LandingOptions,
                 reguess: Reguess | None = None) -> None:
        self.scenario = scenario
        self.options = options
        self.layout = layout_for(scenario, guesses)
        self.scales = Scales.of(scenario)
        """The whole scenario's scales: every aircraft's subproblem is scaled and margined alike."""
        self.reguess = reguess
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
        guesses = [_guess_from(part) for part in previous.parts]
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

    def _solve_one(self, scenario: Scenario, guess: AircraftGuess, flown: list[tuple[str, np.ndarray, np.ndarray]],
                   before: LandingResult | None, mesh, deadline, earliest: float | None,
                   options: LandingOptions) -> LandingResult:
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
        order = list(guesses)
        parts: list[LandingResult] = []
        before_by_callsign = {p.trajectories[0].callsign: p for p in previous or [] if p.trajectories}
        kept_parts: list[LandingResult] = []
        flown: list[tuple[str, np.ndarray, np.ndarray]] = []  # callsign, t, positions of the planned ones
        recoveries: list[Recovery] = []
        t_start = time.perf_counter()
        i = 0
        while i < len(order):
            guess = order[i]
            if deadline is not None and deadline.expired():
                break
            kept = before_by_callsign.get(guess.callsign) if only is not None and guess.callsign not in only else None
            if kept is not None:
                kept_parts.append(kept)
                parts.append(kept)
                tr = kept.trajectories[0]
                flown.append((tr.callsign, tr.t, tr.positions))
                i += 1
                continue
            earliest = None
            if not options.fixed_landing_times and parts:
                earliest = self._after(scenario, parts[-1], guess.callsign)
                if guess.landing_time < earliest:
                    guess = order[i] = _retimed(guess, earliest)
            mesh = None if meshes is None else meshes.get(guess.callsign)
            # A refinement re-plans some aircraft with the others' plans fixed: the later ones too, whose plans kept
            # clear of this one's former path only (a refined path came 2.96 nm to a later plan, against 3 nm).
            later = [] if only is None else [
                (cs, p.trajectories[0].t, p.trajectories[0].positions) for cs, p in before_by_callsign.items()
                if cs not in {f[0] for f in flown} and cs != guess.callsign]
            part = self._solve_one(scenario, guess, flown + later, before_by_callsign.get(guess.callsign), mesh,
                                   deadline, earliest, options)
            kept = before_by_callsign.get(guess.callsign) if only is not None else None
            if not part.success and kept is not None:
                # A refinement that finds no plan for this aircraft keeps its previous one; the others of the pair
                # are re-planned around it (an aircraft with a fixed landing time could not move away from a
                # later one passing 2.93 nm from the threshold when it landed; the later one could).
                log.info("%s: the refinement found no plan (%s); keeping its previous plan", guess.callsign,
                         part.status)
                kept_parts.append(kept)
                part = kept
            inaccurate = meshes is None and self._inaccurate(part)
            if (not part.success or inaccurate) and meshes is None:
                if inaccurate:
                    log.warning("sequential: %s found no accurate plan (Mesh_Not_Converged: error %.1e, over %gx the "
                                "tolerance); trying to recover", guess.callsign, part.solution.max_error,
                                INACCURATE_ERROR)
                else:
                    log.warning("sequential: %s found no plan (%s); trying to recover", guess.callsign, part.status)
                step = self._recover(scenario, order, i, parts, flown, recoveries, deadline, options)
                if step == "swap":  # the previous aircraft is planned again, after this one
                    parts.pop()
                    flown.pop()
                    i -= 1
                    continue
                if step is not None:
                    part = step
            parts.append(part)
            if not part.success:
                log.warning("sequential: %s found no plan (%s)", order[i].callsign, part.status)
                break
            tr = part.trajectories[0]
            flown.append((tr.callsign, tr.t, tr.positions))
            i += 1
        wall = time.perf_counter() - t_start
        solved = [p for p in parts if all(p is not k for k in kept_parts)]
        self.layout = layout_for(scenario, order)
        result = _combine(parts, len(order), self.layout, wall, solved=solved)
        result.recoveries = recoveries
        return result

    def _inaccurate(self, part: LandingResult) -> bool:
        """A solved plan whose mesh refinement stopped far above the tolerance (:data:`INACCURATE_ERROR`)."""
        sol = part.solution
        return (part.success and sol is not None and not sol.mesh_converged
                and sol.max_error > INACCURATE_ERROR * self.options.mesh_tol)

    @staticmethod
    def _landed(part: LandingResult) -> float:
        return part.landing_times[part.trajectories[0].callsign]

    @classmethod
    def _after(cls, scenario: Scenario, leader: LandingResult, follower: str) -> float:
        """The earliest landing of ``follower`` right after the aircraft planned in ``leader``: its landing plus the
        spacing the pair needs (:func:`~mal_planner.sequencing.schedule.planned_spacing`, wake included)."""
        lead = leader.trajectories[0].callsign
        return cls._landed(leader) + planned_spacing(scenario, scenario.aircraft_by_callsign(lead),
                                                     scenario.aircraft_by_callsign(follower))

    def _recover(self, scenario: Scenario, order: list[AircraftGuess], i: int, parts: list[LandingResult],
                 flown: list[tuple[str, np.ndarray, np.ndarray]], recoveries: list[Recovery], deadline,
                 options: LandingOptions) -> LandingResult | str | None:
        """Try :data:`RECOVERIES` for the aircraft at ``order[i]``: a plan (``order`` updated), ``"swap"`` (the
        aircraft and the previous one exchanged in ``order``: plan the previous index again) or None."""
        guess = order[i]
        cs = guess.callsign
        schedule_made = scenario.aircraft_by_callsign(cs).landing_time is None
        traffic = [(t, pos) for _, t, pos in flown]
        earliest = self._after(scenario, parts[-1], cs) if parts else None

        def attempt(name: str, run) -> LandingResult | str | None:
            if deadline is not None and deadline.expired():
                return None
            t0 = time.perf_counter()
            outcome = run()
            ok = outcome == "swap" or (isinstance(outcome, LandingResult) and outcome.success
                                       and not self._inaccurate(outcome))
            recoveries.append(Recovery(cs, name, ok, time.perf_counter() - t0))
            log.info("sequential: %s: recovery '%s' %s (%.1f s)", cs, name, "worked" if ok else "failed",
                     time.perf_counter() - t0)
            return outcome if ok else None

        free_earliest = None if options.fixed_landing_times else earliest

        def another_guess() -> LandingResult | None:
            new = self.reguess(scenario, cs, guess.landing_time, traffic, len(recoveries)) if self.reguess else None
            if new is None:
                return None
            part = self._solve_one(scenario, new, flown, None, None, deadline, free_earliest, options)
            if part.success:
                order[i] = new
            return part

        def later_landing() -> LandingResult | None:
            # As little later as it can: its landing time free, no earlier than its slot (nor the spacing behind
            # the previous one). A replan's aircraft that fell behind its plan (gusts) is seconds late, not half a
            # spacing: the fixed delays below pushed everyone behind it back, each re-solved far from its guess.
            soonest = guess.landing_time if earliest is None else max(guess.landing_time, earliest)
            part = self._solve_one(scenario, _retimed(order[i], soonest), flown, None, None, deadline, soonest,
                                   replace(options, fixed_landing_times=False))
            if part.success:  # the time it found is its fixed time from now on (the verification checks it)
                part.required_landing_times = {cs: self._landed(part)}
            if not part.success or self._inaccurate(part):
                for delay in LATER_BY_SPACINGS:  # fixed times a little later: surer than a free-time NLP
                    later = _retimed(order[i], guess.landing_time + delay * scenario.landing_spacing_s)
                    part = self._solve_one(scenario, later, flown, None, None, deadline, None, options)
                    if part.success or (deadline is not None and deadline.expired()):
                        break
            if part is not None and part.success:
                landed = self._landed(part)
                order[i] = _retimed(order[i], landed)
                follows = landed
                for j in range(i + 1, len(order)):  # those after it move back by as much as their spacing needs
                    follows += planned_spacing(scenario, scenario.aircraft_by_callsign(order[j - 1].callsign),
                                               scenario.aircraft_by_callsign(order[j].callsign))
                    if order[j].landing_time < follows and \
                            scenario.aircraft_by_callsign(order[j].callsign).landing_time is None:
                        order[j] = _retimed(order[j], follows)
                    follows = max(follows, order[j].landing_time)
            return part

        def give_way() -> LandingResult | None:
            alone = self._solve_one(scenario, order[i], [], None, None, deadline, free_earliest, options)
            if not alone.success:
                return None
            mine = alone.trajectories[0]
            recheck = scenario.separation_nm + self.screen.recheck_nm(self.scales)
            blockers = [k for k, (_, t, pos) in enumerate(flown)
                        if closest_approach(mine.t, mine.positions, t, pos) < recheck]
            if not blockers:  # its own plan keeps clear of everyone: the failure was the solver's
                return alone
            log.info("sequential: %s: its own plan comes close to %s; they give way (latest first)", cs,
                     ", ".join(flown[b][0] for b in blockers))
            for k in reversed(blockers):
                others = flown[:k] + flown[k + 1:] + [(cs, mine.t, mine.positions)]
                earlier = (self._after(scenario, parts[k - 1], flown[k][0])
                           if k > 0 and not options.fixed_landing_times else None)
                moved = self._solve_one(scenario, _guess_from(parts[k]), others, parts[k], None, deadline, earlier,
                                        options)
                if not moved.success:
                    return None
                parts[k] = moved
                tr = moved.trajectories[0]
                flown[k] = (tr.callsign, tr.t, tr.positions)
            # from its own plan, which the others now keep clear of
            return self._solve_one(scenario, _guess_from(alone), flown, alone, None, deadline, free_earliest, options)

        def swap() -> str | None:
            previous = order[i - 1]
            if scenario.aircraft_by_callsign(previous.callsign).landing_time is not None:
                return None
            slot_early, slot_late = previous.landing_time, guess.landing_time
            swapped = [*order[:i - 1], _retimed(guess, slot_early), _retimed(previous, slot_late), *order[i + 1:]]
            if not _spaced(scenario, swapped[max(i - 2, 0):i + 2]):
                return None  # the exchanged slots would break a pair's spacing (e.g. its wake minimum)
            order[i - 1], order[i] = swapped[i - 1], swapped[i]
            return "swap"

        steps = [("another guess", another_guess)]
        if schedule_made and options.fixed_landing_times:
            steps.insert(0 if options.replanning else 1, ("later landing", later_landing))
        steps.append(("give way", give_way))
        if schedule_made and i > 0 and not any(r.callsign == cs and r.name == "swap with the previous"
                                                 for r in recoveries):
            steps.append(("swap with the previous", swap))
        for name, run in steps:
            outcome = attempt(name, run)
            if outcome is not None:
                return outcome
        return None


def _guess_distance(guess: AircraftGuess, t: np.ndarray, pos: np.ndarray, scales: Scales) -> float:
    """Smallest distance between a guess (sampled as the pair screen does) and a planned path while both fly."""
    dt = scales.seconds(1.0 / SAMPLES_PER_TURN_TIME)
    ts = np.arange(0.0, guess.landing_time + dt, dt)
    return closest_approach(ts, guess.state_at(ts)[:, :3], t, pos)


def _spaced(scenario: Scenario, guesses: Sequence[AircraftGuess]) -> bool:
    """Whether consecutive guesses land at least the scenario's spacing and their wake minimum apart (what the
    verification checks; the slots of a schedule made without a wake table always are)."""
    def minimum(a: AircraftGuess, b: AircraftGuess) -> float:
        lead, follow = scenario.aircraft_by_callsign(a.callsign), scenario.aircraft_by_callsign(b.callsign)
        return wake_spacing_s(scenario.wake, lead.wake_category, follow.wake_category,
                              scenario.final_ground_speed(follow), scenario.separation_nm, scenario.landing_spacing_s)

    return scenario.wake == "none" or all(b.landing_time - a.landing_time >= minimum(a, b)
                                          for a, b in zip(guesses[:-1], guesses[1:], strict=True))


def _retimed(guess: AircraftGuess, landing_time: float) -> AircraftGuess:
    scale = landing_time / guess.landing_time
    return AircraftGuess(guess.callsign, guess.t * scale, guess.states, landing_time,
                         None if guess.gate_time is None else guess.gate_time * scale)


def _guess_from(part: LandingResult) -> AircraftGuess:
    tr = part.trajectories[0]
    t, idx = np.unique(tr.t, return_index=True)
    states = tr.states[idx].copy()
    states[:, 4] = np.unwrap(states[:, 4])
    return AircraftGuess(tr.callsign, t, states, part.landing_times[tr.callsign], part.gate_times[tr.callsign])


def _combine(parts: list[LandingResult], n: int, layout, wall: float, solved: list[LandingResult]) -> LandingResult:
    """One result for all aircraft (failed if any part failed or is missing); the effort counts the parts
    ``solved`` now."""
    success = len(parts) == n and all(p.success for p in parts)
    failed = next((p for p in parts if not p.success), None)
    status = parts[-1].status if success else (
        f"{failed.trajectories[0].callsign if failed.trajectories else '?'}: {failed.status}" if failed is not None
        else f"time limit after {len(parts)} of {n} aircraft")
    merged: dict = {"gate_times": {}, "landing_times": {}, "required_landing_times": {}}
    for p in parts:
        for key in merged:
            merged[key].update(getattr(p, key))
    return LandingResult(
        success=success, status=status, trajectories=[tr for p in parts for tr in p.trajectories],
        gate_times=merged["gate_times"], landing_times=merged["landing_times"],
        objective=sum(p.objective for p in parts), solve_time=wall, build_time=sum(p.build_time for p in solved),
        nlp_iterations=sum(p.nlp_iterations for p in solved),
        mesh_history=[m for p in solved for m in p.mesh_history], layout=layout,
        solution=parts[-1].solution if parts else None,  # type: ignore[arg-type]
        phase_names=[f"{p.trajectories[0].callsign}:{name}" for p in parts for name in p.phase_names],
        required_landing_times=merged["required_landing_times"], parts=parts, strategy="sequential")
