"""The arrival procedures a controller holds a plan to (``procedures:`` in a scenario file), in planner units.

A scenario at a real airport names them; the thesis's small airspace has none. The defaults are the rules of
issue 33, as a controller would check an arrival: at or below 250 kt below 10,000 ft (ICAO Annex 11, Appendix
4: 250 kt IAS below 3,050 m for IFR flights in classes D to G, and common in terminal areas), at or below 180 kt
inside 4 nm of the threshold (the usual speed-control instruction to the outer marker), vertical speed within
-3,500 / +1,500 ft/min and within the type's envelope (:mod:`mal_planner.performance`), no climb of more than
1,000 ft, at least 1,000 ft above the threshold beyond 4 nm (a minimum vectoring altitude), and no turning away
from the runway below 1,000 ft.

Altitudes are the threshold's elevation plus the height above it, taken as pressure altitudes in the ISA (no QNH
correction: at CDG's 392 ft, a QNH 20 hPa off standard moves FL100 by about 550 ft).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pydantic import Field

from mal_planner.scenario.quantities import Strict, quantity
from mal_planner.units import ft_to_nm, kt_to_nm_per_s


@dataclass(frozen=True)
class Procedures:
    """The rules of :mod:`mal_planner.scenario.procedures` in planner units (nm, s; speeds CAS)."""

    default_type: str
    """The ICAO type of an aircraft that names none (its performance: :mod:`mal_planner.performance`)."""
    speed_limit: float
    speed_limit_below_nm: float
    """Pressure altitude below which :attr:`speed_limit` holds."""
    final_speed: float
    final_distance_nm: float
    """Ground distance from the threshold inside which :attr:`final_speed` holds."""
    max_descent_rate: float
    max_climb_rate: float
    max_climb_nm: float
    """The most an arrival may climb above the lowest altitude it has flown."""
    min_height_nm: float
    """Height above the threshold to keep beyond :attr:`final_distance_nm` (or the aircraft's first height, if
    lower)."""
    turn_away_below_nm: float
    """Below this height above the threshold, the aircraft does not fly away from the threshold."""

    def final_approach_height(self, glide_path_rad: float) -> float:
        """The height (nm above the threshold) below which an aircraft inside the final distance is on the final
        approach, where :attr:`final_speed` holds: the glide path's at the final distance plus the minimum height
        (an aircraft higher up overflies the airport)."""
        return self.final_distance_nm * math.tan(abs(glide_path_rad)) + self.min_height_nm


class ProceduresConfig(Strict):
    """``procedures:``: the rules a plan at a real airport keeps (see the module docstring for their sources)."""

    aircraft_type: str = Field("A320", pattern=r"^[A-Za-z0-9]{2,4}$")
    """The ICAO type designator of an aircraft that gives none."""
    speed_limit_kt: float = quantity("kt", 250.0, gt=0.0)
    speed_limit_below_ft: float = quantity("ft", 10000.0, gt=0.0)
    final_speed_kt: float = quantity("kt", 180.0, gt=0.0)
    final_distance_nm: float = quantity("nm", 4.0, gt=0.0)
    max_descent_fpm: float = quantity("ft/min", 3500.0, gt=0.0)
    max_climb_fpm: float = quantity("ft/min", 1500.0, ge=0.0)
    max_climb_ft: float = quantity("ft", 1000.0, ge=0.0)
    min_height_ft: float = quantity("ft", 1000.0, ge=0.0)
    turn_away_below_ft: float = quantity("ft", 1000.0, ge=0.0)

    def to_procedures(self) -> Procedures:
        per_min = 1.0 / 60.0
        return Procedures(
            default_type=self.aircraft_type.upper(), speed_limit=kt_to_nm_per_s(self.speed_limit_kt),
            speed_limit_below_nm=ft_to_nm(self.speed_limit_below_ft), final_speed=kt_to_nm_per_s(self.final_speed_kt),
            final_distance_nm=self.final_distance_nm, max_descent_rate=ft_to_nm(self.max_descent_fpm) * per_min,
            max_climb_rate=ft_to_nm(self.max_climb_fpm) * per_min, max_climb_nm=ft_to_nm(self.max_climb_ft),
            min_height_nm=ft_to_nm(self.min_height_ft), turn_away_below_nm=ft_to_nm(self.turn_away_below_ft))
