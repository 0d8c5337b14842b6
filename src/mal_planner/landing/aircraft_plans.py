"""One aircraft's plan in the sequential strategy: when it lands, the guesses made from it, and the plans of all
aircraft combined into one result."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from mal_planner.landing.base import LandingResult
from mal_planner.landing.guess import AircraftGuess
from mal_planner.scenario import Scenario
from mal_planner.sequencing.schedule import planned_spacing
from mal_planner.wake import wake_spacing_s


def landed(part: LandingResult) -> float:
    """The landing time of the aircraft planned in ``part``."""
    return part.landing_times[part.trajectories[0].callsign]


def earliest_after(scenario: Scenario, leader: LandingResult, follower: str) -> float:
    """The earliest landing of ``follower`` right after the aircraft planned in ``leader``: its landing plus the
    spacing the pair needs (:func:`~mal_planner.sequencing.schedule.planned_spacing`, wake included)."""
    lead = leader.trajectories[0].callsign
    return landed(leader) + planned_spacing(scenario, scenario.aircraft_by_callsign(lead),
                                            scenario.aircraft_by_callsign(follower))


def spaced(scenario: Scenario, guesses: Sequence[AircraftGuess]) -> bool:
    """Whether consecutive guesses land at least the scenario's spacing and their wake minimum apart (what the
    verification checks; the slots of a schedule made without a wake table always are)."""
    def minimum(a: AircraftGuess, b: AircraftGuess) -> float:
        lead, follow = scenario.aircraft_by_callsign(a.callsign), scenario.aircraft_by_callsign(b.callsign)
        return wake_spacing_s(scenario.wake, lead.wake_category, follow.wake_category,
                              scenario.final_ground_speed(follow), scenario.separation_nm, scenario.landing_spacing_s)

    return scenario.wake == "none" or all(b.landing_time - a.landing_time >= minimum(a, b)
                                          for a, b in zip(guesses[:-1], guesses[1:], strict=True))


def retimed(guess: AircraftGuess, landing_time: float) -> AircraftGuess:
    """``guess`` stretched in time to land at ``landing_time``."""
    scale = landing_time / guess.landing_time
    return AircraftGuess(guess.callsign, guess.t * scale, guess.states, landing_time,
                         None if guess.gate_time is None else guess.gate_time * scale)


def guess_from(part: LandingResult) -> AircraftGuess:
    """A guess of the aircraft planned in ``part``: its plan."""
    tr = part.trajectories[0]
    t, idx = np.unique(tr.t, return_index=True)
    states = tr.states[idx].copy()
    states[:, 4] = np.unwrap(states[:, 4])
    return AircraftGuess(tr.callsign, t, states, part.landing_times[tr.callsign], part.gate_times[tr.callsign])


def combine(parts: list[LandingResult], n: int, layout, wall: float, solved: list[LandingResult]) -> LandingResult:
    """One result for all aircraft (failed if any part failed or is missing); the effort counts the parts
    ``solved`` now."""
    success = bool(parts) and len(parts) == n and all(p.success for p in parts)  # none: every aircraft left out
    failed = next((p for p in parts if not p.success), None)
    status = parts[-1].status if success else "no aircraft planned" if not parts else (
        f"{failed.trajectories[0].callsign if failed.trajectories else '?'}: {failed.status}" if failed is not None
        else f"time limit after {len(parts)} of {n} aircraft")
    merged = _merged_times(parts)
    return LandingResult(
        success=success, status=status, trajectories=[tr for p in parts for tr in p.trajectories],
        gate_times=merged["gate_times"], landing_times=merged["landing_times"],
        objective=sum(p.objective for p in parts), solve_time=wall, build_time=sum(p.build_time for p in solved),
        nlp_iterations=sum(p.nlp_iterations for p in solved),
        mesh_history=[m for p in solved for m in p.mesh_history], layout=layout,
        solution=parts[-1].solution if parts else None,  # type: ignore[arg-type]
        phase_names=[f"{p.trajectories[0].callsign}:{name}" for p in parts for name in p.phase_names],
        required_landing_times=merged["required_landing_times"], parts=parts, strategy="sequential")


def planned_prefix(landing: LandingResult) -> LandingResult | None:
    """The plan of the aircraft a sequential solve planned before it stopped (the successful parts before the first
    failed or missing one), as one successful result; None when there is none (or the solve was joint)."""
    parts = []
    for part in landing.parts or []:
        if not part.success:
            break
        parts.append(part)
    if not parts:
        return None
    return replace(landing, success=True, status=f"partial: {len(parts)} aircraft ({landing.status})",
                   trajectories=[tr for p in parts for tr in p.trajectories], **_merged_times(parts), parts=parts)


def _merged_times(parts: list[LandingResult]) -> dict[str, dict[str, float]]:
    """The parts' gate, landing and required landing times, by callsign, as LandingResult's fields."""
    return {key: {k: v for p in parts for k, v in getattr(p, key).items()}
            for key in ("gate_times", "landing_times", "required_landing_times")}
