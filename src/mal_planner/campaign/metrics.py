"""Figures of merit of one plan for the campaign table (planner units: nm, s)."""

from __future__ import annotations

import numpy as np

from mal_planner.obstacles import Superquadric
from mal_planner.pipeline import PlanResult
from mal_planner.report import sequence_document
from mal_planner.scenario import Scenario
from mal_planner.sequencing import SequencingInfeasible, first_come_first_served
from mal_planner.sequencing.schedule import LandingSchedule, sequencing_problem
from mal_planner.verification import LandingGap
from mal_planner.wake import categories as wake_categories


def ray_clearance_nm(obstacle: Superquadric, points: np.ndarray) -> np.ndarray:
    """Distance from each point to the obstacle's surface along the ray from the obstacle's centre (nm).

    With r = (q - c) / semi_axes and ||r||_p its p-norm, the surface point on that ray is c + (q - c)/||r||_p,
    so the distance is |q - c| (1 - 1/||r||_p): negative inside, exact for spheres and for points facing a
    box's face, an upper bound of the true Euclidean distance otherwise. Computed without overflow.
    """
    d = np.asarray(points, float) - np.asarray(obstacle.center)
    r = np.abs(d / np.asarray(obstacle.semi_axes))
    m = np.max(r, axis=-1)
    safe = np.where(m > 0.0, m, 1.0)
    norm = safe * np.sum((r / safe[..., None]) ** obstacle.p, axis=-1) ** (1.0 / obstacle.p)
    return np.linalg.norm(d, axis=-1) * (1.0 - 1.0 / np.where(m > 0.0, norm, 1e-300))


def min_obstacle_clearance_nm(scenario: Scenario, result: PlanResult) -> float | None:
    """Smallest :func:`ray_clearance_nm` of any planned trajectory sample to any obstacle (None: no obstacle)."""
    if not scenario.obstacles:
        return None
    points = np.concatenate([tr.positions for tr in result.trajectories()])
    return float(min(np.min(ray_clearance_nm(ob, points)) for ob in scenario.obstacles))


def min_separation_nm(result: PlanResult) -> float | None:
    """Smallest distance of any pair over the verification's re-integrated flight (None: not verified/one aircraft)."""
    if result.verification is None or not result.verification.pairs:
        return None
    return float(min(p.min_distance_nm for p in result.verification.pairs))


def format_times(times: dict[str, float], order: list[str]) -> str:
    return ";".join(f"{cs}={times[cs]:.2f}" for cs in order if cs in times)


def landing_columns(result: PlanResult) -> dict[str, object]:
    """Planned and initializer landing times and the delay between them (planned minus initializer)."""
    order = result.order
    initial = {t.callsign: float(t.landing_time) for t in result.initial.trajectories}
    columns: dict[str, object] = {"initializer_landing_times_s": format_times(initial, order)}
    if result.optimized:
        planned = result.landing_times()
        delays = np.array([planned[cs] - initial[cs] for cs in order])
        columns.update(landing_times_s=format_times(planned, order), mean_delay_s=float(np.mean(delays)),
                       max_delay_s=float(np.max(delays)))
    return columns


def schedule_margin_s(schedule: LandingSchedule) -> float:
    """The margin (s) the schedule put between a free aircraft's earliest landing and its target (0: all fixed)."""
    free = [cs for cs in schedule.target if cs not in schedule.fixed and cs in schedule.earliest]
    return float(schedule.target[free[0]] - schedule.earliest[free[0]]) if free else 0.0


def fcfs_delay_s(scenario: Scenario, schedule: LandingSchedule) -> float | None:
    """Total delay (s against the targets) of first come, first served on the very problem the schedule solved
    (:func:`~mal_planner.sequencing.schedule.sequencing_problem` from its earliest times and margin): no
    planning, milliseconds. None when first come, first served finds no schedule (fixed times in its way)."""
    problem = sequencing_problem(scenario, schedule.earliest, schedule_margin_s(schedule))
    try:
        return float(first_come_first_served(problem).cost)
    except SequencingInfeasible:
        return None


def sequence_columns(scenario: Scenario, result: PlanResult) -> dict[str, object]:
    """The sequence plan.json reports (strategy, status, total delay of the planned landings against the
    targets), the schedule's own total delay, and first come, first served's on the same problem."""
    schedule = result.initial.schedule
    document = sequence_document(result)
    if schedule is None or document is None:
        return {}
    return {"sequencing_strategy": schedule.strategy, "sequencing_status": schedule.status,
            "total_delay_s": document["total_delay_s"],
            "scheduled_delay_s": float(sum(schedule.delay(cs) for cs in schedule.order)),
            "fcfs_delay_s": fcfs_delay_s(scenario, schedule)}


def landing_gap_columns(scenario: Scenario, result: PlanResult) -> dict[str, object]:
    """From ``verification.landings`` (consecutive landings of the re-flown controls): the smallest ratio of a
    gap to the time the pair needs (its wake minimum, or the scenario's spacing when that is more; >= 1: every
    pair keeps it) and the number of pairs below, counted as the verification does: a wake minimum with no
    tolerance, the scenario's spacing less the verification's landing-time tolerance."""
    report = result.verification
    if report is None or not report.landings:
        return {}
    spacing, tol = scenario.landing_spacing_s, report.tolerances.landing_time_s

    def below(gap: LandingGap) -> bool:
        wake_bound = gap.wake is not None and gap.needed_s > spacing
        return gap.gap_s < gap.needed_s - (0.0 if wake_bound else tol)

    return {"min_landing_gap_ratio": float(min(g.gap_s / g.needed_s for g in report.landings)),
            "landing_pairs_below": sum(below(g) for g in report.landings)}


def plan_columns(scenario: Scenario, result: PlanResult) -> dict[str, object]:
    """Timings, iterations, separation, clearance and landing times of a finished plan."""
    timings = result.timings
    stages = [timings.get(k) for k in ("initializer_s", "optimizer_s", "verification_s")]
    landing = result.landing
    columns: dict[str, object] = {
        "initializer_s": stages[0], "optimizer_s": stages[1], "verification_s": stages[2],
        "total_s": float(sum(s for s in stages if s is not None)),
        "optimizer_status": landing.status if landing is not None else None,
        "ipopt_iterations": landing.nlp_iterations if landing is not None else None,
        "mesh_iterations": len(landing.mesh_history) if landing is not None else None,
        "verified": bool(result.verification is not None and result.verification.verified),
        "min_separation_nm": min_separation_nm(result),
        "min_obstacle_clearance_nm": min_obstacle_clearance_nm(scenario, result) if result.optimized else None,
    }
    columns.update(landing_columns(result))
    columns.update(sequence_columns(scenario, result))
    columns.update(landing_gap_columns(scenario, result))
    return columns


def layout_of(scenario: Scenario) -> str:
    """wall (a gate: a wall with a hole), no-fly-zones (obstacles only) or open."""
    if scenario.gates:
        return "wall"
    return "no-fly-zones" if scenario.obstacles else "open"


def landing_times_mode(scenario: Scenario) -> str:
    """fixed (every aircraft has a landing time), free (none has) or partial."""
    given = [a.landing_time is not None for a in scenario.aircraft]
    return "fixed" if all(given) else ("free" if not any(given) else "partial")


def wake_mix(scenario: Scenario) -> str | None:
    """``"icao:H=1;M=3;L=3"``: the wake table and how many aircraft of each category (None without a table)."""
    if scenario.wake == "none":
        return None
    drawn = [ac.wake_category for ac in scenario.aircraft]
    return f"{scenario.wake}:" + ";".join(f"{c}={drawn.count(c)}" for c in wake_categories(scenario.wake)
                                          if c in drawn)


def scenario_columns(scenario: Scenario) -> dict[str, object]:
    return {"name": scenario.name, "n_aircraft": len(scenario.aircraft), "layout": layout_of(scenario),
            "landing_times": landing_times_mode(scenario), "wake_mix": wake_mix(scenario)}
