"""What pushes simulated aircraft off their plans: wind with gusts, radar noise, the delay before a plan is flown.

Each disturbance draws from its own seeded generator, so a run is reproducible and changing one (say, the
radar noise) leaves the others' draws unchanged.

Gusts are a first-order Gauss-Markov process per aircraft and horizontal axis (the simplest coloured-noise
turbulence model; the Dryden model's longitudinal component is this process): stationary standard deviation
``sigma`` and correlation time ``tau``, updated exactly over any step ``dt`` as
``g <- g e^{-dt/tau} + sigma sqrt(1 - e^{-2 dt/tau}) N(0, 1)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mal_planner.units import kt_to_nm_per_s, m_to_nm

DEFAULT_GUST_TAU_S = 10.0
"""Correlation time of the gusts: L/V of the Dryden model at low altitude (L about 300-600 m, V 60-80 m/s)."""


@dataclass(frozen=True)
class WindSpec:
    """The true wind the simulated aircraft fly in (the planner may know the mean, or not)."""

    mean: tuple[float, float] = (0.0, 0.0)
    """Constant wind (w_x, w_y) in nm/s in the local frame."""
    gust_sigma: float = 0.0
    """Standard deviation of the gusts per horizontal axis in nm/s (0: a steady wind)."""
    gust_tau_s: float = DEFAULT_GUST_TAU_S

    @classmethod
    def from_knots(cls, speed_kt: float, from_heading_rad: float, gust_kt: float = 0.0,
                   gust_tau_s: float = DEFAULT_GUST_TAU_S) -> WindSpec:
        """A wind of ``speed_kt`` blowing from the local heading ``from_heading_rad``, gusts of ``gust_kt`` rms."""
        v = kt_to_nm_per_s(speed_kt)
        towards = from_heading_rad + math.pi
        return cls((v * math.cos(towards), v * math.sin(towards)), kt_to_nm_per_s(gust_kt), gust_tau_s)

    @property
    def speed(self) -> float:
        return math.hypot(*self.mean)


class WindField:
    """The wind each aircraft meets: the mean plus its own gust process (rows: aircraft; columns: x, y)."""

    def __init__(self, spec: WindSpec, n_aircraft: int, seed: int | None) -> None:
        self.spec = spec
        self.rng = np.random.default_rng(seed)
        sigma = spec.gust_sigma
        self.gusts = self.rng.normal(0.0, sigma, (n_aircraft, 2)) if sigma > 0 else np.zeros((n_aircraft, 2))

    def step(self, dt: float) -> None:
        """Advance the gusts by ``dt`` seconds (exact discretisation of the Gauss-Markov process)."""
        sigma = self.spec.gust_sigma
        if sigma <= 0 or dt <= 0:
            return
        decay = math.exp(-dt / self.spec.gust_tau_s)
        self.gusts = self.gusts * decay + sigma * math.sqrt(1.0 - decay * decay) * self.rng.normal(
            0.0, 1.0, self.gusts.shape)

    def current(self) -> np.ndarray:
        """(n_aircraft, 2) wind in nm/s now."""
        return np.asarray(self.spec.mean, float)[None, :] + self.gusts


class RadarNoise:
    """Gaussian position noise of the radar tracks (sigma in metres per axis), from its own seeded generator."""

    def __init__(self, sigma_m: float, seed: int | None) -> None:
        self.sigma_nm = float(m_to_nm(sigma_m))
        self.rng = np.random.default_rng(seed)

    def apply(self, state: np.ndarray) -> np.ndarray:
        out = np.array(state, dtype=float)
        if self.sigma_nm > 0:
            out[:3] += self.rng.normal(0.0, self.sigma_nm, 3)
        return out
