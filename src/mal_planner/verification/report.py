"""What the verification reports, and the accuracy tolerances it allows."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from mal_planner.scales import Scales
from mal_planner.scenario import Scenario


@dataclass(frozen=True)
class Tolerances:
    """Accuracy tolerances, in planner units (nm, s, rad). None of them relaxes a safety minimum.

    The defaults are the thesis's; :meth:`for_scenario` gives every scenario its own, relative to its turn
    radius and turn time (:class:`mal_planner.scales.Scales`), which is what :func:`verify` uses by default.
    """

    sample_dt: float = 0.05
    """Sampling step of the flown trajectory (the issue asked for <= 0.1 s; T / 150)."""
    deviation_nm: float = 0.005
    """Largest position difference between the published and the re-integrated trajectory (about 9 m in the
    thesis; the scenario's path accuracy L / 60: the optimizer's separation margin is twice this, so the
    published paths keep the separation as well)."""
    deviation_angle: float = math.radians(1.0)
    position_nm: float = 1e-3
    """How close to the runway threshold the flown trajectory must end (a fifth of the path accuracy)."""
    attitude: float = math.radians(0.5)
    """Slack on the flown gate and runway attitudes (the flown path drifts from the plan a little)."""
    landing_time_s: float = 1e-3
    """How closely a flown landing meets a fixed landing time (T / 7500)."""
    integration_step_s: float = 0.25
    """Longest step of the fixed-step integration in :func:`fly` (the plan's sample intervals are split to it; T / 15
    for a scenario: its error at 0.5 s steps is 1.4e-12 nm, see :func:`fly`)."""
    rtol: float = 1e-9
    atol: float = 1e-11
    """Tolerances of :func:`fly_reference`, the adaptive SciPy integration kept as a cross-check."""

    @classmethod
    def for_scenario(cls, scenario: Scenario) -> Tolerances:
        """The tolerances of ``scenario``: the thesis's values as fractions of its turn radius L and turn time T
        (thesis: L = 0.302 nm, T = 7.55 s)."""
        scales = Scales.of(scenario)
        return cls(sample_dt=scales.seconds(1.0 / 150.0), deviation_nm=scales.accuracy_nm,
                   position_nm=0.2 * scales.accuracy_nm, landing_time_s=scales.seconds(1.0 / 7500.0),
                   integration_step_s=scales.seconds(1.0 / 15.0))


@dataclass
class AircraftCheck:
    callsign: str
    landing_time: float
    max_position_deviation_nm: float
    max_angle_deviation: float
    bank_min_deg: float
    bank_max_deg: float
    n_v_min: float
    airspace_violation_nm: float
    obstacle_hits: list[str] = field(default_factory=list)
    obstacle_hit_times_s: list[float] = field(default_factory=list)
    gate_events: list[dict] = field(default_factory=list)
    runway_error: dict = field(default_factory=dict)
    limit_violation_times_s: list[float] = field(default_factory=list)
    """Times at which the controls break a limit, the flown path leaves the airspace or misses the hole, or (for
    refining the mesh) the flown path drifts fastest from the published one when it drifts too far."""
    slowest_airspeed: float | None = None
    """The slowest airspeed flown (nm/s; the airspeed model), None: the model's constant airspeed."""


@dataclass
class PairCheck:
    pair: str
    min_distance_nm: float
    at_time_s: float
    violation_times_s: list[float] = field(default_factory=list)
    """Times of the local minima of the distance below the required separation."""


@dataclass
class LandingGap:
    """Two consecutive landings: the time between them against the time they need."""

    pair: str
    """leader->follower."""
    gap_s: float
    needed_s: float
    """The scenario's landing spacing, or the wake minimum at the follower's speed when that is more."""
    wake: str | None = None
    """leader->follower categories when a wake table applies."""
    wake_nm: float | None = None
    """The table's distance (the radar minimum where the table lists none)."""


@dataclass
class VerificationReport:
    verified: bool
    reasons: list[str]
    aircraft: list[AircraftCheck]
    pairs: list[PairCheck]
    tolerances: Tolerances
    by_aircraft: dict[str, list[str]] = field(default_factory=dict)
    """The reasons that concern each aircraft (a separation failure concerns both)."""
    landings: list[LandingGap] = field(default_factory=list)
    """Consecutive landings in landing order."""

    def aircraft_verified(self, callsign: str) -> bool:
        return not self.by_aircraft.get(callsign)

    def to_dict(self) -> dict:
        return asdict(self)

    def violating_callsigns(self) -> set[str]:
        """The aircraft with a violation time (both of a pair that comes too close)."""
        out = {cs for p in self.pairs if p.violation_times_s for cs in p.pair.split("-")}
        return out | {a.callsign for a in self.aircraft if a.obstacle_hit_times_s or a.limit_violation_times_s}

    def violation_times(self) -> list[float]:
        """Times at which a safety minimum is broken (for refining the mesh there)."""
        times = [t for p in self.pairs for t in p.violation_times_s]
        times += [t for a in self.aircraft for t in a.obstacle_hit_times_s + a.limit_violation_times_s]
        return sorted(times)
