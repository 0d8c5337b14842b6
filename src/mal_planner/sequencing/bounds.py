"""Narrowing the MILP by cost before branching: a heuristic schedule, reduced-cost fixing, independent blocks.

Any schedule at least as good as a known one (cost UB) keeps every variable v within (UB - z) / r of its
bound, where z is the LP relaxation's value and r >= 0 the variable's reduced cost (LP duality: the objective
is at least z + r (v - bound)). Applied to the landing times, earliness and tardiness this narrows each
aircraft's window; applied to a pair's binary it fixes the order. Narrower windows fix more pairs by the
windows alone and shrink the big-Ms, which raises z: a few rounds of this leave HiGHS a fraction of the
binaries. The narrowed windows often split the aircraft into blocks no separation links (every aircraft of
a block lands at least its separation after every aircraft of the blocks before): each is its own MILP.

The incumbent comes from the same MILP with constrained position shifting (one place from first come), which
fixes all but neighbouring pairs; none of this is a branch and bound of its own: HiGHS does the searching.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np
from scipy.optimize import linprog
from scipy.sparse import vstack

from mal_planner.sequencing.formulation import CostCut, Model, Pair, build_model, pair_relations, run_milp
from mal_planner.sequencing.problem import SequencingInfeasible, SequencingOptions, SequencingProblem

HEURISTIC_SHARE = 0.25
"""Share of the time limit the position-shifting incumbent may take (it needs about a tenth on airland8)."""
HEURISTIC_SHIFT = 1
"""Places from first come the incumbent may shift each aircraft (1: only neighbouring pairs are binaries)."""
NARROWING_ROUNDS = 12
"""LP rounds at most; each one that still narrows costs one LP of the (shrinking) model."""
COST_TOL = 1e-6
"""Relative tolerance on UB - z (of UB): keeps schedules within round-off of the incumbent's cost."""
CUT_SHARE = 0.25
"""Share of the time left after narrowing that the segment cuts may take (about 0.3 s on airland8)."""
SEGMENT_WIDTH = 6
"""Aircraft per segment cut, consecutive in first-come order (6 lifts airland8's LP bound from 83 % to 99 %)."""
SEGMENT_TIME_S = 1.0
"""Time limit of one segment's MILP (6 aircraft: milliseconds; its bound counts even if it stops early)."""
REDUCED_COST_MIN = 1e-9
"""Reduced costs below this (per unit of the variable) are treated as zero: they bound nothing."""


def solve_narrowed(problem: SequencingProblem, options: SequencingOptions, deadline: float
                   ) -> tuple[np.ndarray | None, bool, float | None]:
    """(times or None, proven optimal, lower bound) within ``deadline`` (a ``time.perf_counter`` instant)."""
    earliest, latest = problem.earliest.astype(float), problem.bounded_latest()
    incumbent = None
    if options.objective == "cost" and (options.max_shift is None or options.max_shift > HEURISTIC_SHIFT):
        incumbent = _position_shift_incumbent(problem, options, earliest, latest, deadline)
    if incumbent is None:
        fixed, free = pair_relations(problem, latest, options.max_shift, earliest)
        model = build_model(problem, earliest, latest, options, fixed, free)
        outcome = run_milp(model, deadline - time.perf_counter(), options.mip_rel_gap)
        if outcome.infeasible:
            raise SequencingInfeasible("no landing sequence meets every time window")
        return outcome.times, outcome.optimal, outcome.bound
    ub = problem.cost(incumbent)
    narrowed = narrow(problem, options, Narrowed.initial(problem, options, earliest, latest), ub)
    if narrowed.lower_bound < ub - _tol(ub):
        cut_deadline = time.perf_counter() + CUT_SHARE * (deadline - time.perf_counter())
        cuts = segment_cuts(problem, options, narrowed, cut_deadline)
        narrowed = narrow(problem, options, dataclasses.replace(narrowed, cuts=cuts), ub)
    if narrowed.lower_bound >= ub - _tol(ub):
        return incumbent, True, ub
    return _solve_blocks(problem, options, narrowed, incumbent, deadline)


@dataclasses.dataclass(frozen=True)
class Narrowed:
    """Windows, forced orders and pair relations that keep every schedule costing at most the incumbent."""

    earliest: np.ndarray
    latest: np.ndarray
    forced: frozenset[Pair]
    fixed: list[Pair]
    free: list[Pair]
    lower_bound: float
    """The last LP relaxation's value: a lower bound on the optimum."""
    cuts: tuple[CostCut, ...] = ()

    @classmethod
    def initial(cls, problem: SequencingProblem, options: SequencingOptions, earliest: np.ndarray,
                latest: np.ndarray) -> Narrowed:
        fixed, free = pair_relations(problem, latest, options.max_shift, earliest)
        return cls(earliest, latest, frozenset(), fixed, free, 0.0)


def narrow(problem: SequencingProblem, options: SequencingOptions, start: Narrowed, ub: float) -> Narrowed:
    """Rounds of LP relaxation and reduced-cost narrowing against the incumbent cost ``ub``."""
    earliest, latest, forced, fixed, free = start.earliest, start.latest, set(start.forced), start.fixed, start.free
    integral = _integral_data(problem, latest)
    z = start.lower_bound
    for _ in range(NARROWING_ROUNDS):
        model = build_model(problem, earliest, latest, options, fixed, free, None, start.cuts)
        lp = _lp_relaxation(model)
        if lp is None:
            break
        z, lower_rc, upper_rc = max(lp[0], z), lp[1], lp[2]
        if z >= ub - _tol(ub):
            break
        new_e, new_l, new_forced = _reduced_cost_limits(problem, model, earliest, latest, ub - z + _tol(ub),
                                                        lower_rc, upper_rc)
        if integral:
            new_e, new_l = np.ceil(new_e - 1e-6), np.floor(new_l + 1e-6)
        new_e, new_l = np.maximum(new_e, earliest), np.minimum(new_l, latest)
        if np.any(new_e > new_l):
            break  # round-off at the incumbent: keep the last consistent windows
        changed = bool(np.any(new_e > earliest + 1e-6) or np.any(new_l < latest - 1e-6) or new_forced - forced)
        if not changed:
            break
        try:
            relations = pair_relations(problem, new_l, options.max_shift, new_e, frozenset(forced | new_forced))
        except SequencingInfeasible:
            break
        earliest, latest, forced = new_e, new_l, forced | new_forced
        fixed, free = relations
    return Narrowed(earliest, latest, frozenset(forced), fixed, free, z, start.cuts)


def segment_cuts(problem: SequencingProblem, options: SequencingOptions, narrowed: Narrowed, deadline: float
                 ) -> tuple[CostCut, ...]:
    """For every run of SEGMENT_WIDTH aircraft in first-come order that cannot all land on target, the least
    cost of that run alone (its own small MILP under the same windows and pair relations, a relaxation of
    the whole): the LP cannot spread it thin over fractional orders, as it does with the pairwise big-Ms."""
    order = problem.first_come_order()
    cuts = []
    for start in range(max(problem.n - SEGMENT_WIDTH + 1, 1)):
        members = sorted(order[start:start + SEGMENT_WIDTH])
        budget = deadline - time.perf_counter()
        if budget <= 0:
            break
        if _on_target(problem, narrowed, members):
            continue
        model = build_model(problem, narrowed.earliest, narrowed.latest, options, narrowed.fixed, narrowed.free,
                            members)
        outcome = run_milp(model, min(budget, SEGMENT_TIME_S), options.mip_rel_gap)
        if outcome.bound is not None and outcome.bound > 0:
            cuts.append(CostCut(tuple(members), outcome.bound))
    return tuple(cuts)


def _on_target(problem: SequencingProblem, narrowed: Narrowed, members: list[int]) -> bool:
    """Every member can land on its target in target order (no cost to bound)."""
    T, S = problem.target, problem.separation
    ranked = sorted(members, key=lambda i: T[i])
    inside = all(narrowed.earliest[i] <= T[i] <= narrowed.latest[i] for i in members)
    forced_ok = all((j, i) not in narrowed.forced for a, i in enumerate(ranked) for j in ranked[a + 1:])
    return inside and forced_ok and all(T[j] - T[i] >= S[i, j] for a, i in enumerate(ranked) for j in ranked[a + 1:])


def _reduced_cost_limits(problem: SequencingProblem, model: Model, earliest: np.ndarray, latest: np.ndarray,
                         slack: float, lower_rc: np.ndarray, upper_rc: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray, set[Pair]]:
    """Windows and pair orders implied by v within slack / r of its bound, for x, a (earliness), b (tardiness)
    and the pair binaries."""
    n, T = model.n, problem.target
    with np.errstate(divide="ignore"):
        reach_lo = np.where(lower_rc > REDUCED_COST_MIN, slack / np.maximum(lower_rc, REDUCED_COST_MIN), np.inf)
        reach_hi = np.where(-upper_rc > REDUCED_COST_MIN, slack / np.maximum(-upper_rc, REDUCED_COST_MIN), np.inf)
    x_lo, a_lo, b_lo = model.lo[:n], model.lo[n:2 * n], model.lo[2 * n:3 * n]
    new_l = np.minimum.reduce([latest, x_lo + reach_lo[:n], T + b_lo + reach_lo[2 * n:3 * n]])
    new_e = np.maximum.reduce([earliest, model.hi[:n] - reach_hi[:n], T - a_lo - reach_lo[n:2 * n]])
    forced: set[Pair] = set()
    for k, (i, j) in enumerate(model.free):
        col = model.d0 + k
        if reach_lo[col] < 1.0:  # d cannot reach 1: j lands first
            forced.add((j, i))
        elif reach_hi[col] < 1.0:  # d cannot leave 1: i lands first
            forced.add((i, j))
    return new_e, new_l, forced


def _lp_relaxation(model: Model) -> tuple[float, np.ndarray, np.ndarray] | None:
    """(value, reduced costs at the lower bounds (>= 0), at the upper bounds (<= 0)) or None if unsolved."""
    eq = model.row_lo == model.row_hi
    has_lo = ~eq & np.isfinite(model.row_lo)
    has_hi = ~eq & np.isfinite(model.row_hi)
    a_ub = vstack([-model.a[has_lo], model.a[has_hi]]).tocsr()
    b_ub = np.concatenate([-model.row_lo[has_lo], model.row_hi[has_hi]])
    res = linprog(model.c, A_ub=a_ub, b_ub=b_ub, A_eq=model.a[eq], b_eq=model.row_lo[eq],
                  bounds=np.column_stack([model.lo, model.hi]), method="highs")
    if res.status != 0:
        return None
    return float(res.fun), np.asarray(res.lower.marginals, float), np.asarray(res.upper.marginals, float)


def _solve_blocks(problem: SequencingProblem, options: SequencingOptions, narrowed: Narrowed,
                  incumbent: np.ndarray, deadline: float) -> tuple[np.ndarray | None, bool, float | None]:
    """Each block's MILP in turn, time shared by binaries; the incumbent's times where a block finds none."""
    blocks = independent_blocks(problem, narrowed.earliest, narrowed.latest) if options.max_shift is None else [
        list(range(problem.n))]
    block_of = {i: k for k, block in enumerate(blocks) for i in block}
    pairs_in = [0] * len(blocks)
    for i, j in narrowed.free:
        pairs_in[block_of[i]] += block_of[i] == block_of[j]
    times = incumbent.copy()
    all_optimal, bound, left = True, 0.0, sum(pairs_in)
    for k in sorted(range(len(blocks)), key=lambda k: pairs_in[k]):
        budget = (deadline - time.perf_counter()) * (pairs_in[k] / left if left else 1.0)
        left -= pairs_in[k]
        model = build_model(problem, narrowed.earliest, narrowed.latest, options, narrowed.fixed, narrowed.free,
                            blocks[k], narrowed.cuts)
        outcome = run_milp(model, budget, options.mip_rel_gap)
        if outcome.times is not None:
            times[blocks[k]] = outcome.times
        all_optimal = all_optimal and outcome.optimal
        bound += outcome.bound if outcome.bound is not None else 0.0
    bound = max(bound, narrowed.lower_bound)
    ub = problem.cost(incumbent)
    if problem.violations(times) or problem.cost(times) > ub:
        times, all_optimal = incumbent, False  # a block kept incumbent times outside its narrowed windows
    cost = problem.cost(times)
    return times, all_optimal or bound >= cost - _tol(cost), min(bound, cost)


def independent_blocks(problem: SequencingProblem, earliest: np.ndarray, latest: np.ndarray) -> list[list[int]]:
    """Aircraft split (in order of earliest time) where every one before the cut lands, even at its latest,
    at least its separation before the earliest time of every one after it."""
    order = np.argsort(earliest, kind="stable")
    reach = latest[order][:, None] + problem.separation[np.ix_(order, order)]  # reach[k, j]: L_k + S_kj
    running = np.maximum.accumulate(reach, axis=0)
    starts = [0] + [p + 1 for p in range(problem.n - 1)
                    if np.all(running[p, p + 1:] <= earliest[order][p + 1:])]
    return [sorted(int(i) for i in order[a:b]) for a, b in zip(starts, [*starts[1:], problem.n], strict=True)]


def _position_shift_incumbent(problem: SequencingProblem, options: SequencingOptions, earliest: np.ndarray,
                              latest: np.ndarray, deadline: float) -> np.ndarray | None:
    """A good schedule fast: the MILP with each aircraft within one place of first come (None if none found)."""
    shifted = dataclasses.replace(options, max_shift=HEURISTIC_SHIFT)
    try:
        fixed, free = pair_relations(problem, latest, shifted.max_shift, earliest)
    except SequencingInfeasible:
        return None
    model = build_model(problem, earliest, latest, shifted, fixed, free)
    outcome = run_milp(model, HEURISTIC_SHARE * (deadline - time.perf_counter()), shifted.mip_rel_gap)
    if outcome.times is None or problem.violations(outcome.times):
        return None
    return outcome.times


def _integral_data(problem: SequencingProblem, latest: np.ndarray) -> bool:
    """Integer windows, targets and separations: some optimal schedule lands on whole seconds."""
    off = problem.separation[~np.eye(problem.n, dtype=bool)]
    return all(np.array_equal(v, np.round(v)) for v in (problem.earliest, problem.target, latest, off))


def _tol(ub: float) -> float:
    return COST_TOL * max(1.0, abs(ub))
