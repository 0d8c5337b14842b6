"""Beasley's aircraft landing problem as a mixed-integer programme (Beasley et al., Transportation Science 34(2),
2000, section 2), tightened so that HiGHS proves the published optima in about a second rather than a minute:

* **Pair fixing from the windows.** If j cannot land before i (E_j + S_ji > L_i), the pair needs no binary:
  x_j >= x_i + S_ij is a plain linear constraint, and none at all when L_i + S_ij <= E_j (the windows keep it).
* **Tight big-Ms.** For an undecided pair with d_ij = 1 when i lands first,
  x_j >= x_i + S_ij - (L_i + S_ij - E_j)(1 - d_ij): the smallest M that leaves the constraint slack when j
  lands first (x_i <= L_i, x_j >= E_j).
* **Constrained position shifting** (``max_shift`` = k): i's position 1 + #(aircraft before i) stays within k
  of its first-come position; two aircraft 2k or more places apart keep their first-come order (fixed pair).

The objective is the weighted earliness and tardiness (x_i = T_i - a_i + b_i) or the last landing time.
:func:`build_model` builds one model (of all aircraft or a block, within given windows), :func:`run_milp` solves it
on HiGHS (SciPy's milp); :mod:`.bounds` narrows the windows and :mod:`.milp` drives the solve.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp
from scipy.sparse import coo_array, csr_array

from mal_planner.sequencing.problem import SequencingInfeasible, SequencingOptions, SequencingProblem

Pair = tuple[int, int]


class _Rows:
    """Sparse constraint rows lb <= A v <= ub, collected one at a time."""

    def __init__(self) -> None:
        self.r: list[int] = []
        self.c: list[int] = []
        self.v: list[float] = []
        self.lb: list[float] = []
        self.ub: list[float] = []

    def add(self, terms: list[tuple[int, float]], lb: float, ub: float = np.inf) -> None:
        k = len(self.lb)
        for col, val in terms:
            self.r.append(k)
            self.c.append(col)
            self.v.append(val)
        self.lb.append(lb)
        self.ub.append(ub)

    def matrix(self, n_vars: int) -> csr_array:
        return coo_array((self.v, (self.r, self.c)), shape=(len(self.lb), n_vars)).tocsr()


@dataclass(frozen=True)
class CostCut:
    """The aircraft ``members`` together cost at least ``bound``: their own MILP's bound, a relaxation."""

    members: tuple[int, ...]
    bound: float


@dataclass(frozen=True)
class Model:
    """One MILP: variables x (n), earliness a (n), tardiness b (n), a binary per free pair, [makespan z]."""

    n: int
    free: list[Pair]
    c: np.ndarray
    integrality: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    a: csr_array
    row_lo: np.ndarray
    row_hi: np.ndarray

    @property
    def d0(self) -> int:
        """Column of the first pair binary (d = 1: the pair's first aircraft lands first)."""
        return 3 * self.n


def interchangeable(problem: SequencingProblem, i: int, j: int) -> bool:
    """Same separations to and from every other aircraft and between them, same costs per second."""
    S = problem.separation
    others = np.ones(problem.n, dtype=bool)
    others[[i, j]] = False
    return bool(S[i, j] == S[j, i] and np.array_equal(S[i, others], S[j, others])
                and np.array_equal(S[others, i], S[others, j])
                and problem.cost_early[i] == problem.cost_early[j] and problem.cost_late[i] == problem.cost_late[j])


def dominates(problem: SequencingProblem, i: int, j: int) -> bool:
    """i's window and target are nowhere later than j's: some optimal schedule lands i first."""
    return bool(problem.earliest[i] <= problem.earliest[j] and problem.target[i] <= problem.target[j]
                and problem.latest[i] <= problem.latest[j])


def pair_relations(problem: SequencingProblem, latest: np.ndarray, max_shift: int | None,
                   earliest: np.ndarray | None = None, forced: frozenset[Pair] = frozenset()
                   ) -> tuple[list[Pair], list[Pair]]:
    """(fixed, free): ordered pairs (i, j) where i must land before j, and unordered pairs (i < j) left open.

    ``earliest``/``latest`` are the (possibly narrowed) windows; ``forced`` holds orders (i, j) already
    proven for some optimal schedule. Dominance always compares the problem's own windows: it is a property of
    the problem, not of the narrowed windows.
    """
    E = problem.earliest if earliest is None else earliest
    S = problem.separation
    position = {i: p for p, i in enumerate(problem.first_come_order())}
    fixed, free = [], []
    for i in range(problem.n):
        for j in range(i + 1, problem.n):
            i_first = E[i] + S[i, j] <= latest[j] and (j, i) not in forced
            j_first = E[j] + S[j, i] <= latest[i] and (i, j) not in forced
            if max_shift is not None:
                gap = position[j] - position[i]
                i_first = i_first and gap > -2 * max_shift
                j_first = j_first and gap < 2 * max_shift
            if i_first and j_first and interchangeable(problem, i, j):
                first, second = (i, j) if position[i] < position[j] else (j, i)
                if dominates(problem, first, second):
                    i_first, j_first = first == i, first == j
            if not i_first and not j_first:
                raise SequencingInfeasible(f"{problem.names[i]} and {problem.names[j]}: their windows leave no "
                                           f"order that keeps the separation", (problem.names[i], problem.names[j]))
            if i_first and j_first:
                free.append((i, j))
            else:
                fixed.append((i, j) if i_first else (j, i))
    return fixed, free


def build_model(problem: SequencingProblem, earliest: np.ndarray, latest: np.ndarray, options: SequencingOptions,
                fixed: list[Pair], free: list[Pair], members: list[int] | None = None,
                cuts: tuple[CostCut, ...] = ()) -> Model:
    """The MILP of the aircraft ``members`` (default all) within the windows [earliest, latest] (finite, indexed
    like the problem), with the pair relations of :func:`pair_relations` (pairs outside ``members`` are ignored).
    Variables are indexed by position in ``members``."""
    members = list(range(problem.n)) if members is None else members
    local = {g: k for k, g in enumerate(members)}
    n = len(members)
    E, L = earliest[members], latest[members]
    T, S = problem.target[members], problem.separation[np.ix_(members, members)]
    fixed = [(local[i], local[j]) for i, j in fixed if i in local and j in local]
    free = [(local[i], local[j]) for i, j in free if i in local and j in local]
    X, A, B, D = 0, n, 2 * n, 3 * n
    makespan = options.objective == "makespan"
    n_vars = 3 * n + len(free) + (1 if makespan else 0)
    Z = n_vars - 1
    lo = np.zeros(n_vars)
    hi = np.full(n_vars, np.inf)
    lo[X:X + n], hi[X:X + n] = E, L
    lo[A:A + n], hi[A:A + n] = np.maximum(T - L, 0.0), np.maximum(T - E, 0.0)
    lo[B:B + n], hi[B:B + n] = np.maximum(E - T, 0.0), np.maximum(L - T, 0.0)
    hi[D:D + len(free)] = 1.0
    integrality = np.zeros(n_vars)
    integrality[D:D + len(free)] = 1
    c = np.zeros(n_vars)
    if makespan:
        lo[Z], hi[Z] = float(np.min(E)), float(np.max(L))
        c[Z] = 1.0
    else:
        c[A:A + n] = problem.cost_early[members]
        c[B:B + n] = problem.cost_late[members]
    rows = _Rows()
    for i in range(n):
        rows.add([(X + i, 1.0), (A + i, 1.0), (B + i, -1.0)], T[i], T[i])  # x = T - a + b
        if makespan:
            rows.add([(Z, 1.0), (X + i, -1.0)], 0.0)
    for i, j in fixed:
        if L[i] + S[i, j] > E[j]:  # otherwise the windows already keep it
            rows.add([(X + j, 1.0), (X + i, -1.0)], S[i, j])
    for k, (i, j) in enumerate(free):
        m_ij = L[i] + S[i, j] - E[j]
        m_ji = L[j] + S[j, i] - E[i]
        rows.add([(X + j, 1.0), (X + i, -1.0), (D + k, -m_ij)], S[i, j] - m_ij)  # d = 1: i first
        rows.add([(X + i, 1.0), (X + j, -1.0), (D + k, m_ji)], S[j, i])           # d = 0: j first
        # Target-conflict cuts: if i lands first, i early plus j late cover what the targets lack of S_ij.
        need_ij, need_ji = S[i, j] + T[i] - T[j], S[j, i] + T[j] - T[i]
        if need_ij > 0:
            rows.add([(A + i, 1.0), (B + j, 1.0), (D + k, -need_ij)], 0.0)
        if need_ji > 0:
            rows.add([(A + j, 1.0), (B + i, 1.0), (D + k, need_ji)], need_ji)
    if options.max_shift is not None:
        _position_shift_rows(problem, rows, fixed, free, D, options.max_shift)
    if not makespan:
        for cut in cuts:
            if all(i in local for i in cut.members):
                rows.add([(A + local[i], problem.cost_early[i]) for i in cut.members]
                         + [(B + local[i], problem.cost_late[i]) for i in cut.members], cut.bound)
    return Model(n, free, c, integrality, lo, hi, rows.matrix(n_vars), np.array(rows.lb), np.array(rows.ub))


@dataclass(frozen=True)
class MilpOutcome:
    """What HiGHS returned: times (None if no schedule), whether proven optimal, its dual bound."""

    times: np.ndarray | None
    optimal: bool
    bound: float | None
    infeasible: bool = False


def run_milp(model: Model, time_limit_s: float, mip_rel_gap: float) -> MilpOutcome:
    res = milp(model.c, integrality=model.integrality, bounds=Bounds(model.lo, model.hi),
               constraints=[LinearConstraint(model.a, model.row_lo, model.row_hi)],
               options={"time_limit": max(time_limit_s, 1e-3), "mip_rel_gap": mip_rel_gap, "disp": False})
    bound = getattr(res, "mip_dual_bound", None)
    bound = None if bound is None or not np.isfinite(bound) else float(bound)
    times = None if res.x is None else np.asarray(res.x[:model.n], float)
    return MilpOutcome(times, res.status == 0 and times is not None, bound, res.status == 2)


def _position_shift_rows(problem: SequencingProblem, rows: _Rows, fixed: list[Pair],
                         free: list[Pair], D: int, k: int) -> None:
    """|position_i - first-come position_i| <= k, position_i = #(aircraft before i) (0-based)."""
    position = {i: p for p, i in enumerate(problem.first_come_order())}
    before_fixed = np.zeros(problem.n)
    for _i, j in fixed:
        before_fixed[j] += 1
    terms: list[list[tuple[int, float]]] = [[] for _ in range(problem.n)]
    constant = before_fixed.copy()
    for col, (i, j) in enumerate(free):
        terms[j].append((D + col, 1.0))   # d = 1: i before j
        terms[i].append((D + col, -1.0))  # d = 0: j before i, counted as 1 - d
        constant[i] += 1
    for i in range(problem.n):
        p = position[i]
        rows.add(terms[i], p - k - constant[i], p + k - constant[i])
