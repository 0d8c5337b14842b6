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
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from mal_planner.landing.guess import AircraftGuess
from mal_planner.landing.pairs import PairScreen
from mal_planner.landing.problem import Intruder, phase_guesses
from mal_planner.landing.solve import LandingOptimizer, LandingOptions, LandingResult, layout_for, split_segments
from mal_planner.scenario import Scenario

log = logging.getLogger("mal_planner.optimizer")


def closest_approach(a_t: np.ndarray, a_pos: np.ndarray, b_t: np.ndarray, b_pos: np.ndarray) -> float:
    """Smallest distance (nm) between two sampled paths while both fly, on a's sample times."""
    keep = a_t <= min(a_t[-1], b_t[-1])
    if not keep.any():
        return float("inf")
    other = np.column_stack([np.interp(a_t[keep], b_t, b_pos[:, k]) for k in range(3)])
    return float(np.linalg.norm(a_pos[keep] - other, axis=1).min())


class SequentialOptimizer:
    """The :class:`LandingOptimizer` interface (solve, refine_at, accepts) over per-aircraft subproblems."""

    def __init__(self, scenario: Scenario, guesses: list[AircraftGuess], options: LandingOptions) -> None:
        self.scenario = scenario
        self.options = options
        self.layout = layout_for(scenario, guesses)
        self._guesses = guesses
        self.setup_time = 0.0

    @property
    def screen(self) -> PairScreen:
        return self.options.pair_screen or PairScreen(near_nm=float("inf"), recheck_nm=float("inf"))

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
        meshes = []
        for part in previous.parts:
            meshes.append([split_segments(mesh, phase.t0, phase.tf, times)
                           for phase, mesh in zip(part.solution.phases, part.solution.meshes, strict=True)])
        result = self._solve_all(scenario, guesses, list(previous.parts), meshes, deadline, only=callsigns)
        result.solve_time += previous.solve_time
        result.build_time += previous.build_time
        result.nlp_iterations += previous.nlp_iterations
        result.mesh_history = previous.mesh_history + result.mesh_history
        return result

    def _solve_all(self, scenario: Scenario, guesses: Sequence[AircraftGuess], previous: list[LandingResult] | None,
                   meshes: list | None, deadline, only: set[str] | None = None) -> LandingResult:
        options = replace(self.options, pair_screen=None)
        screen = self.screen
        sep = scenario.separation_nm
        parts: list[LandingResult] = []
        before_by_callsign = {p.trajectories[0].callsign: p for p in previous or [] if p.trajectories}
        kept_parts: list[LandingResult] = []
        flown: list[tuple[str, np.ndarray, np.ndarray]] = []  # callsign, t, positions of the planned ones
        t_start = time.perf_counter()
        for i, guess in enumerate(guesses):
            if deadline is not None and deadline.expired():
                break
            kept = before_by_callsign.get(guess.callsign) if only is not None and guess.callsign not in only else None
            if kept is not None:
                kept_parts.append(kept)
                parts.append(kept)
                tr = kept.trajectories[0]
                flown.append((tr.callsign, tr.t, tr.positions))
                continue
            own = scenario.aircraft_by_callsign(guess.callsign)
            sub = replace(scenario, aircraft=(own,))
            near = [k for k, (_, t, pos) in enumerate(flown)
                    if _guess_distance(guess, t, pos) < sep + screen.near_nm]
            earliest = None
            if not options.fixed_landing_times and parts:
                earliest = parts[-1].landing_times[parts[-1].trajectories[0].callsign] + scenario.landing_spacing_s
                if guess.landing_time < earliest:
                    guess = _retimed(guess, earliest)
            part: LandingResult | None = None
            for _ in range(screen.max_rounds + 1):
                intruders = [Intruder.from_trajectory(flown[k][1], flown[k][2], flown[k][0]) for k in near]
                opt = LandingOptimizer(sub, [guess], options, intruders=intruders, earliest_landing=earliest)
                before = before_by_callsign.get(guess.callsign)
                if before is not None and before.layout.signature() != opt.layout.signature():
                    before = None
                params = opt.problem.params(sub, [guess.landing_time])
                if part is not None:  # intruders added: warm, on the mesh already refined
                    sol = opt.solver.solve(params, guess=part.solution, meshes=part.solution.meshes, warm=True,
                                           refine_mesh=False, deadline=deadline)
                elif before is not None and meshes is not None:  # verification-driven refinement
                    sol = opt.solver.solve(params, guess=before.solution, meshes=meshes[i], warm=True,
                                           deadline=deadline)
                elif before is not None:  # a replan: the previous plan shifted in time, on its mesh
                    sol = opt.solver.solve(params, guess=phase_guesses(sub, opt.layout, [guess]),
                                           meshes=before.solution.meshes, warm=True, deadline=deadline)
                else:
                    sol = opt.solver.solve(params, deadline=deadline)
                part = opt._result(sol, sol.solve_time, sum(m.build_time for m in sol.mesh_history),
                                   [guess.landing_time])
                if not part.success:
                    break
                mine = part.trajectories[0]
                close = [k for k, (_, t, pos) in enumerate(flown) if k not in near
                         and closest_approach(mine.t, mine.positions, t, pos) < sep + screen.recheck_nm]
                if not close:
                    break
                log.info("%s: %s came close; re-solving against them too", guess.callsign,
                         ", ".join(flown[k][0] for k in close))
                near += close
            assert part is not None
            parts.append(part)
            if not part.success:
                log.warning("sequential: %s found no plan (%s)", guess.callsign, part.status)
                break
            tr = part.trajectories[0]
            flown.append((tr.callsign, tr.t, tr.positions))
            log.debug("sequential: %s planned against %d of %d earlier aircraft", guess.callsign, len(near), i)
        wall = time.perf_counter() - t_start
        solved = [p for p in parts if all(p is not k for k in kept_parts)]
        return _combine(parts, len(guesses), self.layout, wall, solved=solved)


def _guess_distance(guess: AircraftGuess, t: np.ndarray, pos: np.ndarray) -> float:
    """Smallest distance between a guess (sampled every second) and a planned path while both fly."""
    ts = np.arange(0.0, guess.landing_time + 1.0, 1.0)
    return closest_approach(ts, guess.state_at(ts)[:, :3], t, pos)


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
