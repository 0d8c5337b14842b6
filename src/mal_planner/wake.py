"""Wake-turbulence separation on final approach: distance minima by (leader, follower) category, as times.

Tables (distance minima in nm; a pair that is not listed needs only the radar minimum, the scenario's
horizontal separation):

* ``icao``: ICAO Doc 4444 (PANS-ATM), 8.7.3.4 "Wake turbulence separation minima based on ATS surveillance
  systems" on approach, categories J (SUPER, A380), H (HEAVY), M (MEDIUM), L (LIGHT): H behind H 4 nm, M behind
  H 5, L behind H 6, L behind M 5; J ahead of H 6, of M 7, of L 8 nm.
* ``recat-eu``: EUROCONTROL, "RECAT-EU: European Wake Turbulence Categorisation and Separation Minima on
  Approach and Departure", Edition 1.1, 15 July 2015 (released issue; authors F. Rooseleer, V. Treve),
  arrival distance table, categories A (super heavy) to F (light). The values are those of issue 18, which
  match the published table as we know it; the search tool found the document (scribd.com 375966575,
  pdfslide.us) but only its front matter as text, so the table itself was not re-read from it.

A distance becomes a time at the follower's approach speed (time-based separation: the follower must be that
far out when the leader lands). The scenario's ``landing_spacing_s`` stays the floor (:func:`wake_spacing_s`).
"""

from __future__ import annotations

from typing import Literal

WakeTableName = Literal["icao", "recat-eu", "none"]
WAKE_TABLES: tuple[str, ...] = WakeTableName.__args__  # type: ignore[attr-defined]

ICAO_CATEGORIES: tuple[str, ...] = ("J", "H", "M", "L")
RECAT_EU_CATEGORIES: tuple[str, ...] = ("A", "B", "C", "D", "E", "F")

ICAO_DISTANCE_NM: dict[tuple[str, str], float] = {
    ("J", "H"): 6.0, ("J", "M"): 7.0, ("J", "L"): 8.0,
    ("H", "H"): 4.0, ("H", "M"): 5.0, ("H", "L"): 6.0,
    ("M", "L"): 5.0,
}
"""(leader, follower) -> nm; pairs not listed: the radar minimum."""


def _recat_eu() -> dict[tuple[str, str], float]:
    rows = {  # leader: distances behind it for followers A..F (None: radar minimum)
        "A": (3.0, 4.0, 5.0, 5.0, 6.0, 8.0),
        "B": (None, 3.0, 4.0, 4.0, 5.0, 7.0),
        "C": (None, None, 3.0, 3.0, 4.0, 6.0),
        "D": (None, None, None, None, None, 5.0),
        "E": (None, None, None, None, None, 4.0),
        "F": (None, None, None, None, None, 3.0),
    }
    return {(lead, follow): nm for lead, row in rows.items()
            for follow, nm in zip(RECAT_EU_CATEGORIES, row, strict=True) if nm is not None}


RECAT_EU_DISTANCE_NM: dict[tuple[str, str], float] = _recat_eu()
"""(leader, follower) -> nm; pairs not listed: the radar minimum."""

TABLES: dict[str, tuple[tuple[str, ...], dict[tuple[str, str], float]]] = {
    "icao": (ICAO_CATEGORIES, ICAO_DISTANCE_NM),
    "recat-eu": (RECAT_EU_CATEGORIES, RECAT_EU_DISTANCE_NM),
}


def categories(table: str) -> tuple[str, ...]:
    """The categories a table knows (none for ``none``)."""
    return TABLES[table][0] if table in TABLES else ()


def wake_distance_nm(table: str, leader: str | None, follower: str | None, radar_nm: float) -> float:
    """The distance the follower must be behind the leader when the leader lands (nm), at least ``radar_nm``.

    An unknown category (None: e.g. a radar track that carries none) is the worst case in its role: the
    heaviest leader, the lightest follower. A category the table does not know is an error.
    """
    if table == "none":
        return radar_nm
    known, distances = TABLES[table]
    for role, category in (("leader", leader), ("follower", follower)):
        if category is not None and category not in known:
            raise ValueError(f"wake table {table}: {role} category {category!r} is not one of {', '.join(known)}")
    return max([radar_nm] + [nm for (lead, follow), nm in distances.items()
                             if leader in (None, lead) and follower in (None, follow)])


def wake_spacing_s(table: str, leader: str | None, follower: str | None, follower_speed_nm_s: float,
                   radar_nm: float, floor_s: float) -> float:
    """Seconds from the leader's landing to the follower's: the wake distance flown at the follower's approach
    speed, at least ``floor_s`` (the scenario's landing spacing). ``none``: ``floor_s``."""
    if table == "none":
        return floor_s
    if not follower_speed_nm_s > 0:
        raise ValueError(f"follower approach speed must be > 0 nm/s, got {follower_speed_nm_s}")
    return max(floor_s, wake_distance_nm(table, leader, follower, radar_nm) / follower_speed_nm_s)
