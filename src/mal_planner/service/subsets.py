"""A replan of what changed: which aircraft it replans, and the traffic it replans them among.

An aircraft that strays from its plan (and any other that strays by half the threshold,
:data:`~mal_planner.service.policy.STRAYING_SHARE`) is replanned with the aircraft it can affect: those whose
instructions come within :data:`AFFECT_SEPARATIONS` separations of its plan at the same times. Everyone else keeps
what they fly (plans, holds, vectors): their paths are fixed in the replan (:mod:`mal_planner.pipeline.among`). A
whole replan is made instead when the change is not local: an aircraft tracked flies nothing or has flown past its
plan's end, an aircraft was left out of the plan's inputs, the replan before failed, the aircraft affected are
all those that fly plans, or a fallback (a vector) ends before the replanned aircraft land.

Aircraft that fly no plan (new, holding, vectored, left out of a partial plan) join the others the same way: they
are planned to land after everyone flying a plan, clear of those plans, which stay as they are
(:func:`joining_traffic`; :func:`mal_planner.pipeline.among.plan_joining`). A whole plan of twenty aircraft takes
minutes; a plan of the few without one takes seconds, so they stop holding sooner.
"""

from __future__ import annotations

from collections.abc import Mapping, Set
from dataclasses import replace

from mal_planner.scenario import Scenario
from mal_planner.scenario.traffic import FixedPath, Traffic
from mal_planner.trajectory import Reference, closest_approach

AFFECT_SEPARATIONS = 2.0
"""An aircraft whose instruction comes within this many separations of the straying aircraft's plan (at the same
times, from the replan's start) is replanned with it (a terminal area 6 nm): a replan moves the straying aircraft
by about what it strayed, a fraction of a separation, and the plans keep a separation plus their margins apart, so
an aircraft farther than two separations cannot come into conflict with the new plan; nearer ones can, and may
have to give way."""


def fixed_paths(scenario: Scenario, instructions: Mapping[str, Reference], flying: Mapping[str, Reference],
                start: float) -> dict[str, FixedPath] | None:
    """Every aircraft's instruction from ``start`` on (``scenario``: the aircraft tracked, their states at
    ``start``); None when one flies nothing or past its instruction's end (a whole replan is due)."""
    paths = {}
    for aircraft in scenario.aircraft:
        ref = instructions.get(aircraft.callsign)
        path = None if ref is None else FixedPath.cut(aircraft, ref.t, ref.states(aircraft.dynamics.n_states), start,
                                                       lands=aircraft.callsign in flying)
        if path is None:
            return None
        paths[aircraft.callsign] = path
    return paths


def affected(straying: Set[str], paths: Mapping[str, FixedPath], flying: Mapping[str, Reference],
             separation_nm: float) -> set[str]:
    """The ``straying`` aircraft and those flying plans whose paths come within :data:`AFFECT_SEPARATIONS`
    separations of one's path at the same times."""
    reach = AFFECT_SEPARATIONS * separation_nm
    out = set(straying)
    for cs in straying:
        mine = paths[cs]
        out |= {other for other, p in paths.items() if other not in out and other in flying
                and closest_approach(mine.t, mine.positions, p.t, p.positions) < reach}
    return out


def traffic_for(straying: Set[str], scenario: Scenario, instructions: Mapping[str, Reference],
                flying: Mapping[str, Reference], start: float) -> Traffic | None:
    """The traffic of a replan of what changed for the ``straying`` aircraft (see the module docstring), or None:
    a whole replan is due."""
    if not straying or not straying <= set(flying):
        return None
    paths = fixed_paths(scenario, instructions, flying, start)
    if paths is None or not straying <= set(paths):
        return None
    replanned = affected(straying, paths, flying, scenario.separation_nm)
    if replanned >= {cs for cs in paths if cs in flying}:
        return None
    last = max(paths[cs].landing_time or 0.0 for cs in replanned)
    if any(p.landing_time is None and p.t[-1] < last for p in paths.values()):
        return None  # a fallback that ends first (a vector): where the aircraft flies then is nobody's path yet
    return Traffic(tuple(paths[cs] for cs in sorted(replanned)),
                   tuple(p for cs, p in sorted(paths.items()) if cs not in replanned))


def joining_traffic(joining: Set[str], scenario: Scenario, flying: Mapping[str, Reference], start: float
                    ) -> Traffic | None:
    """The traffic the ``joining`` aircraft (those of ``scenario`` that fly no plan) are planned among: everyone
    else's plan from ``start`` on, fixed; None when a whole plan is due (nobody else flies a plan, an aircraft not
    joining flies none, or a plan ends by ``start``)."""
    others = [a for a in scenario.aircraft if a.callsign not in joining]
    if not joining or not others or not joining <= {a.callsign for a in scenario.aircraft}:
        return None
    if any(a.callsign not in flying for a in others):
        return None
    paths = fixed_paths(replace(scenario, aircraft=tuple(others)), flying, flying, start)
    if paths is None:
        return None
    return Traffic((), tuple(p for _, p in sorted(paths.items())), tuple(sorted(joining)))
