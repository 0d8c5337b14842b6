"""Aircraft performance by ICAO type designator, from OpenAP, in planner units (nm, s).

OpenAP (J. Sun, J. M. Hoekstra, J. Ellerbroek, "OpenAP: An open-source aircraft performance model for air
transportation studies and simulations", Aerospace 7(8):104, 2020; https://github.com/TUDelft-CNS-ATM/openap) is the
open performance model BlueSky flies with. Its aircraft properties give a type's structural limits (VMO, MMO,
ceiling); its WRAP kinematic model, fitted to ADS-B flights, gives the speeds and vertical rates of each flight phase,
each as the default and the range of the flights observed. Nothing here is typed by hand: a type OpenAP does not know
is an error naming it, and every number says which OpenAP parameter it is.

OpenAP (and pandas under it) takes seconds to import: it is imported on the first type asked for, not before.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache, lru_cache
from importlib.metadata import version

import numpy as np

from mal_planner.errors import InvalidInput
from mal_planner.units import METRES_PER_NM, kt_to_nm_per_s, m_per_s_to_nm_per_s

DEFAULT_TYPE = "A320"
"""The type of an aircraft whose type is not known (the most common airliner at European airports)."""


class UnknownAircraftType(InvalidInput):
    """A type designator OpenAP has no performance for."""


@dataclass(frozen=True)
class Band:
    """One WRAP parameter: its default and the range of the flights OpenAP was fitted to (planner units)."""

    default: float
    low: float
    high: float


@dataclass(frozen=True)
class Performance:
    """One type's performance (nm, s; speeds are calibrated airspeeds, rates positive up)."""

    type_code: str
    vmo: float
    """Maximum operating speed, CAS (OpenAP ``vmo``)."""
    mmo: float
    """Maximum operating Mach number (OpenAP ``mmo``)."""
    ceiling_nm: float
    """Certified ceiling, pressure altitude (OpenAP ``ceiling``)."""
    final_approach_cas: Band
    """Speed on the final approach (WRAP ``finalapp_vcas``)."""
    landing_speed: Band
    """Speed at touchdown (WRAP ``landing_speed``)."""
    descent_cas: Band
    """Speed of the constant-CAS descent below the crossover altitude (WRAP ``descent_const_vcas``)."""
    descent_rate: Band
    """Vertical speed of the constant-CAS descent (WRAP ``descent_vs_concas``; negative: down)."""
    final_descent_rate: Band
    """Vertical speed on the final approach (WRAP ``finalapp_vs``)."""
    climb_rate: Band
    """Vertical speed of the constant-CAS climb (WRAP ``climb_vs_concas``)."""
    longitudinal: Band
    """Longitudinal load factor (thrust - drag) / weight (dimensionless): low at idle thrust with the landing gear
    down (which an airliner may lower from about 250 kt; on the final approach it is down), high at climb thrust
    clean, both the weakest of :data:`LONGITUDINAL_CONDITIONS_FT` (OpenAP's drag polar and thrust model, at the mean
    of the operating empty and the maximum landing mass); default 0. Speed brakes and flaps, which OpenAP's polar
    barely models, slow a real aircraft more: the low end is what it can always do."""
    source: str
    """Where the numbers come from, with the library's version (e.g. 'OpenAP 2.6.2: A320')."""

    def max_cas(self, altitude_nm) -> np.ndarray:
        """The highest calibrated airspeed (nm/s) at pressure altitude ``altitude_nm`` (nm): VMO below the
        crossover altitude, MMO above it (ISA)."""
        aero = _aero()
        h_m = np.asarray(altitude_nm, dtype=float) * METRES_PER_NM
        mmo_cas = m_per_s_to_nm_per_s(aero.mach2cas(self.mmo, h_m))
        return np.minimum(self.vmo, mmo_cas)


def cas_of_tas(tas, altitude_nm):
    """Calibrated airspeed (nm/s) of the true airspeed ``tas`` (nm/s) at pressure altitude ``altitude_nm`` (ISA,
    OpenAP's atmosphere)."""
    aero = _aero()
    tas_m_s = np.asarray(tas, dtype=float) * METRES_PER_NM
    return aero.tas2cas(tas_m_s, np.asarray(altitude_nm, dtype=float) * METRES_PER_NM) / METRES_PER_NM


def tas_of_cas(cas, altitude_nm):
    """True airspeed (nm/s) of the calibrated airspeed ``cas`` (nm/s) at pressure altitude ``altitude_nm``."""
    aero = _aero()
    cas_m_s = np.asarray(cas, dtype=float) * METRES_PER_NM
    return aero.cas2tas(cas_m_s, np.asarray(altitude_nm, dtype=float) * METRES_PER_NM) / METRES_PER_NM


def tas_of_mach(mach, altitude_nm):
    """True airspeed (nm/s) of the Mach number ``mach`` at pressure altitude ``altitude_nm`` (ISA)."""
    return _aero().mach2tas(np.asarray(mach, dtype=float), np.asarray(altitude_nm, dtype=float) * METRES_PER_NM
                            ) / METRES_PER_NM


@cache
def performance_of(type_code: str | None = None) -> Performance:
    """The performance of ICAO type ``type_code`` (None: :data:`DEFAULT_TYPE`); synonyms OpenAP knows (e.g. A20N
    flies as A320neo) resolve. Raises :class:`UnknownAircraftType` naming the type."""
    code = (type_code or DEFAULT_TYPE).strip().upper()
    props, wrap = _openap_type(code)
    return Performance(
        type_code=code,
        vmo=kt_to_nm_per_s(float(props["vmo"])),
        mmo=float(props["mmo"]),
        ceiling_nm=float(props["ceiling"]) / METRES_PER_NM,
        final_approach_cas=_band(wrap.finalapp_vcas()),
        landing_speed=_band(wrap.landing_speed()),
        descent_cas=_band(wrap.descent_const_vcas()),
        descent_rate=_band(wrap.descent_vs_concas()),
        final_descent_rate=_band(wrap.finalapp_vs()),
        climb_rate=_band(wrap.climb_vs_concas()),
        longitudinal=_longitudinal(code, props, wrap),
        source=f"OpenAP {version('openap')}: {code}",
    )


def known_type(type_code: str) -> str:
    """``type_code`` in capitals if OpenAP has its performance; else :class:`UnknownAircraftType`."""
    return performance_of(type_code).type_code


def _openap_type(code: str):
    """OpenAP's aircraft properties and WRAP model of ``code`` (synonyms resolved)."""
    from openap import WRAP, prop  # seconds to import: only when a type is asked for

    known = {c.upper() for c in prop.available_aircraft(use_synonym=True)}
    if code not in known:
        raise UnknownAircraftType(f"aircraft type {code!r} is not in OpenAP {version('openap')} (known: "
                                  f"{', '.join(sorted(known))})")
    return prop.aircraft(code, use_synonym=True), WRAP(code, use_synonym=True)


LONGITUDINAL_CONDITIONS_FT = (1000.0, 10000.0, 20000.0)
"""Pressure altitudes (ft) at which :attr:`Performance.longitudinal` is evaluated: on the final approach at its
speed, and in the constant-CAS descent at its speed (WRAP defaults)."""


def _longitudinal(code: str, props: dict, wrap) -> Band:
    """(thrust - drag) / weight in level flight at idle thrust with the landing gear down and at climb thrust clean,
    the weakest over the conditions."""
    from openap import Drag, Thrust, aero

    drag, thrust = Drag(code, use_synonym=True), Thrust(code, use_synonym=True)
    mass = 0.5 * (float(props["oew"]) + float(props["mlw"]))
    weight = mass * aero.g0
    idle, climb = [], []
    for alt_ft in LONGITUDINAL_CONDITIONS_FT:
        cas = wrap.finalapp_vcas()["default"] if alt_ft == LONGITUDINAL_CONDITIONS_FT[0] else \
            wrap.descent_const_vcas()["default"]
        tas_kt = aero.cas2tas(cas, alt_ft * aero.ft) / aero.kts
        gear_down = float(drag.nonclean(mass=mass, tas=tas_kt, alt=alt_ft, flap_angle=0.0, landing_gear=True))
        idle.append((float(thrust.descent_idle(tas=tas_kt, alt=alt_ft)) - gear_down) / weight)
        climb.append((float(thrust.climb(tas=tas_kt, alt=alt_ft, roc=0.0)) - drag.clean(mass=mass, tas=tas_kt,
                                                                                       alt=alt_ft)) / weight)
    return Band(0.0, max(idle), min(climb))


def _band(parameter: dict) -> Band:
    """A WRAP parameter in planner units: speeds and rates are m/s in WRAP."""
    to_planner = 1.0 / METRES_PER_NM
    return Band(parameter["default"] * to_planner, parameter["minimum"] * to_planner,
                parameter["maximum"] * to_planner)


@lru_cache(maxsize=1)
def _aero():
    from openap import aero  # OpenAP's ISA atmosphere and airspeed conversions

    return aero

