"""Problem description: phases, endpoints, events and linkages.

Everything here is plain data plus user callbacks that receive CasADi ``SX`` column
vectors.  Nothing is transcribed here, so a problem can be solved on many meshes and
with many parameter values without being rebuilt.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

SXFun = Callable[[ca.SX, ca.SX, ca.SX, ca.SX], object]
INF = float("inf")


@dataclass(frozen=True)
class PhaseMesh:
    """Segment breaks as fractions of the phase (0 = t0, 1 = tf) and LGR points per segment."""

    breaks: tuple[float, ...]
    degrees: tuple[int, ...]

    def __post_init__(self) -> None:
        b = np.asarray(self.breaks, dtype=float)
        if len(b) != len(self.degrees) + 1 or abs(b[0]) > 1e-12 or abs(b[-1] - 1.0) > 1e-12:
            raise ValueError("breaks must start at 0, end at 1 and have one more entry than degrees")
        if np.any(np.diff(b) <= 0.0):
            raise ValueError("breaks must be strictly increasing")
        if min(self.degrees) < 1:
            raise ValueError("degrees must be >= 1")
        object.__setattr__(self, "breaks", tuple(float(x) for x in b))
        object.__setattr__(self, "degrees", tuple(int(n) for n in self.degrees))

    @classmethod
    def uniform(cls, segments: int = 4, degree: int = 6) -> PhaseMesh:
        return cls(tuple(np.linspace(0.0, 1.0, segments + 1)), (degree,) * segments)

    @property
    def n_segments(self) -> int:
        return len(self.degrees)

    def key(self) -> tuple[tuple[float, ...], tuple[int, ...]]:
        """Hashable identity used for NLP caching and cycle detection."""
        return tuple(round(b, 12) for b in self.breaks), self.degrees


@dataclass
class PhaseGuess:
    """Initial guess samples; linearly interpolated onto the transcription nodes."""

    t: np.ndarray  # (K,)
    x: np.ndarray  # (K, nx)
    u: np.ndarray  # (K, nu)

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float).reshape(-1)
        k = self.t.size
        self.x = np.asarray(self.x, dtype=float).reshape(k, -1)
        self.u = np.asarray(self.u, dtype=float).reshape(k, -1)


def _vec(values: Sequence[float] | float | None, n: int, default: float) -> np.ndarray:
    if values is None:
        return np.full(n, default)
    arr = np.broadcast_to(np.asarray(values, dtype=float), (n,))
    return arr.copy()


@dataclass(kw_only=True)
class Phase:
    """One phase of a multi-phase optimal control problem.

    Callbacks take ``(x, u, t, p)`` as CasADi SX column vectors (t scalar) and return SX
    (or a list of SX, vertcat'ed).  ``p`` is the problem's parameter vector whose values
    are only given at solve time.  Bounds left as ``None`` are unbounded; the initial and
    final state bounds default to the state bounds.  ``state_scale``/``control_scale``
    may be a vector or ``"auto"`` (from finite bounds); decision variables are the
    physical values divided by the scale. ``time_scale`` does the same for the phase's times,
    and ``path_scale`` divides the path constraints (and their bounds), so that a problem posed in
    physical units reaches the NLP solver with numbers of order one (GPOPS-II and dymos scale the
    same way: by a characteristic value of each variable and constraint).
    """

    name: str
    states: Sequence[str]
    controls: Sequence[str]
    dynamics: SXFun
    lagrange: SXFun | None = None
    path: SXFun | None = None
    path_lb: Sequence[float] | float | None = None
    path_ub: Sequence[float] | float | None = None
    path_overshoot_tol: Sequence[float] | float | None = None
    """How far each ``path`` value may pass its bounds between the points where the NLP holds it, on the
    solution's interpolants (path units; None or inf: not checked). Segments that pass by more are halved in
    the mesh refinement: a path that rides an obstacle's corner cuts it between the points, and the cut only
    shrinks with the points' spacing."""
    state_overshoot_tol: Sequence[float] | float | None = None
    """How far each state's polynomial may pass ``state_lb``/``state_ub`` between the points where the NLP holds
    them (state units; None or inf: not checked); segments that pass by more are halved in the mesh refinement."""
    state_lb: Sequence[float] | float | None = None
    state_ub: Sequence[float] | float | None = None
    control_lb: Sequence[float] | float | None = None
    control_ub: Sequence[float] | float | None = None
    initial_state_lb: Sequence[float] | float | None = None
    initial_state_ub: Sequence[float] | float | None = None
    final_state_lb: Sequence[float] | float | None = None
    final_state_ub: Sequence[float] | float | None = None
    t0_bounds: tuple[float, float] = (-INF, INF)
    tf_bounds: tuple[float, float] = (-INF, INF)
    min_duration: float = 1e-6
    max_duration: float = INF
    guess: PhaseGuess | None = None
    mesh: PhaseMesh = field(default_factory=PhaseMesh.uniform)
    bound_controls_between: bool = False
    """Also keep the control interpolant of each segment within the control bounds, and ``control_path``
    within its bounds, halfway between its collocation points and at the segment end: a solution whose
    controls ride a limit otherwise overshoots it there, and that interpolant is what gets published and
    flown (a 7-aircraft campaign plan banked 45.28 deg against 45 between two points)."""
    control_path: Callable[[ca.SX], object] | None = None
    """Constraints on the controls alone ``c(u)`` (e.g. a bank-angle limit), in [control_path_lb,
    control_path_ub] at every collocation point, and between them with ``bound_controls_between``."""
    control_path_lb: Sequence[float] | float | None = None
    control_path_ub: Sequence[float] | float | None = None
    midpoint_path: Callable[[ca.SX, ca.SX, ca.SX], object] | None = None
    """Constraints ``c(x, t, p)`` on the states (e.g. obstacles and separations, also given in ``path``) held at the
    middle of the chord between every two consecutive nodes too (x the chord's middle, t the time between the
    nodes'): a path that rides a convex obstacle otherwise cuts its corner between two collocation points, and two
    aircraft passing each other come closer between them than at either (real-size traffic: a no-fly zone entered
    by 2 m, separations of 2.97 nm against 3, and verification rounds that could not mend them)."""
    midpoint_path_lb: Sequence[float] | float | None = None
    midpoint_path_ub: Sequence[float] | float | None = None
    midpoint_path_scale: Sequence[float] | float | None = None
    state_scale: Sequence[float] | str | None = None
    control_scale: Sequence[float] | str | None = None
    time_scale: float = 1.0
    path_scale: Sequence[float] | float | None = None

    def __post_init__(self) -> None:
        if self.min_duration <= 0.0:
            raise ValueError("min_duration must be > 0")
        if not self.time_scale > 0.0:
            raise ValueError("time_scale must be > 0")

    @property
    def nx(self) -> int:
        return len(self.states)

    @property
    def nu(self) -> int:
        return len(self.controls)

    def bounds(self) -> dict[str, np.ndarray]:
        """All bound vectors as numpy arrays with defaults resolved."""
        nx, nu = self.nx, self.nu
        xlb, xub = _vec(self.state_lb, nx, -INF), _vec(self.state_ub, nx, INF)
        return {
            "x_lb": xlb,
            "x_ub": xub,
            "x0_lb": xlb if self.initial_state_lb is None else _vec(self.initial_state_lb, nx, -INF),
            "x0_ub": xub if self.initial_state_ub is None else _vec(self.initial_state_ub, nx, INF),
            "xf_lb": xlb if self.final_state_lb is None else _vec(self.final_state_lb, nx, -INF),
            "xf_ub": xub if self.final_state_ub is None else _vec(self.final_state_ub, nx, INF),
            "u_lb": _vec(self.control_lb, nu, -INF),
            "u_ub": _vec(self.control_ub, nu, INF),
        }

    def scales(self) -> tuple[np.ndarray, np.ndarray]:
        """State and control scale factors (ones unless configured)."""
        b = self.bounds()
        return (
            _scale(self.state_scale, b["x_lb"], b["x_ub"]),
            _scale(self.control_scale, b["u_lb"], b["u_ub"]),
        )


def _scale(spec: Sequence[float] | str | None, lb: np.ndarray, ub: np.ndarray) -> np.ndarray:
    if spec is None:
        return np.ones(lb.size)
    if isinstance(spec, str):
        if spec != "auto":
            raise ValueError(f"unknown scale spec {spec!r}")
        mag = np.fmax(np.where(np.isfinite(lb), np.abs(lb), 0.0), np.where(np.isfinite(ub), np.abs(ub), 0.0))
        return np.where(mag > 0.0, mag, 1.0)
    s = _vec(spec, lb.size, 1.0)
    if np.any(s <= 0.0):
        raise ValueError("scale factors must be positive")
    return s


@dataclass
class Endpoint:
    """Symbolic endpoint data of one phase, as seen by ``mayer`` and ``events``."""

    t0: ca.SX
    tf: ca.SX
    x0: ca.SX
    xf: ca.SX
    q: ca.SX


class Endpoints(list):
    """List of :class:`Endpoint` that can also be indexed by phase name."""

    def __init__(self, items: Sequence[Endpoint], names: Sequence[str]) -> None:
        super().__init__(items)
        self._names = {n: i for i, n in enumerate(names)}

    def __getitem__(self, key):  # type: ignore[override]
        if isinstance(key, str):
            key = self._names[key]
        return super().__getitem__(key)


EndpointFun = Callable[[Endpoints, ca.SX], object]


@dataclass(frozen=True)
class Linkage:
    """``xf[a][states_a] == x0[b][states_b]`` and optionally ``tf[a] == t0[b]``."""

    phase_a: str
    phase_b: str
    pairs: tuple[tuple[str, str], ...]
    time: bool = True


@dataclass(kw_only=True)
class Problem:
    """Multi-phase problem: J = mayer(E, p) + sum of phase integrals (if ``lagrange_in_cost``).

    ``events(E, p)`` returns a vector constrained to ``[events_lb, events_ub]``; linkages
    added with :meth:`link` become extra equality events. The NLP minimises J / ``objective_scale``
    and sees the events divided by ``events_scale`` (a scalar or one entry per event); linkage rows are
    divided by the scales of the second phase's states and time. Solutions are reported unscaled.
    """

    phases: list[Phase]
    n_params: int = 0
    mayer: EndpointFun | None = None
    events: EndpointFun | None = None
    events_lb: Sequence[float] | float | None = None
    events_ub: Sequence[float] | float | None = None
    lagrange_in_cost: bool = True
    linkages: list[Linkage] = field(default_factory=list)
    objective_scale: float = 1.0
    events_scale: Sequence[float] | float | None = None

    def __post_init__(self) -> None:
        names = [ph.name for ph in self.phases]
        if len(set(names)) != len(names):
            raise ValueError("phase names must be unique")

    def phase_index(self, name: str) -> int:
        for i, ph in enumerate(self.phases):
            if ph.name == name:
                return i
        raise KeyError(name)

    def link(
        self,
        phase_a: str,
        phase_b: str,
        states: Sequence[str | tuple[str, str]] | None = None,
        time: bool = True,
    ) -> Linkage:
        """Constrain the end of ``phase_a`` to the start of ``phase_b``.

        ``states`` lists names present in both phases, or ``(name_in_a, name_in_b)``
        pairs; ``None`` links every state of a that has the same name in b.
        """
        pa, pb = self.phases[self.phase_index(phase_a)], self.phases[self.phase_index(phase_b)]
        if states is None:
            pairs = tuple((s, s) for s in pa.states if s in pb.states)
        else:
            pairs = tuple((s, s) if isinstance(s, str) else (s[0], s[1]) for s in states)
        for sa, sb in pairs:
            if sa not in pa.states or sb not in pb.states:
                raise KeyError(f"unknown state in linkage {sa!r} -> {sb!r}")
        lk = Linkage(phase_a, phase_b, pairs, time)
        self.linkages.append(lk)
        return lk
