"""Beasley's OR-Library aircraft landing files (airland1-13) as :class:`SequencingProblem`.

Format (whitespace-separated numbers): the number of planes P and the freeze time; then per plane its
appearance time, earliest, target and latest landing times, the cost per unit of time before and after the
target, and the P separation times S_ij after it (99999 on the diagonal). Appearance and freeze times
belong to the dynamic problem and are not used here.

airland1-8 ship with the package (``importlib.resources``); :data:`PUBLISHED_OPTIMA` are the published
single-runway optima (Beasley et al., Transportation Science 34(2), 2000).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np

from mal_planner.sequencing.problem import SequencingProblem

PUBLISHED_OPTIMA: dict[str, float] = {
    "airland1": 700, "airland2": 1480, "airland3": 820, "airland4": 2520, "airland5": 3100,
    "airland6": 24442, "airland7": 1550, "airland8": 1950,
}
BUNDLED: tuple[str, ...] = tuple(f"airland{k}" for k in range(1, 9))


class ORLibraryError(ValueError):
    """A file that is not an OR-Library aircraft landing instance (one line: file and reason)."""


def parse_airland(text: str, source: str = "<airland>") -> SequencingProblem:
    try:
        values = [float(tok) for tok in text.split()]
    except ValueError as exc:
        raise ORLibraryError(f"{source}: not an OR-Library landing file ({exc})") from None
    if len(values) < 2 or values[0] != int(values[0]) or values[0] < 1:
        raise ORLibraryError(f"{source}: must start with the number of planes and the freeze time")
    n = int(values[0])
    expected = 2 + n * (6 + n)
    if len(values) != expected:
        raise ORLibraryError(f"{source}: {n} planes need {expected} numbers, found {len(values)}")
    rows = np.array(values[2:]).reshape(n, 6 + n)
    _, earliest, target, latest, early, late = rows[:, :6].T
    separation = rows[:, 6:].copy()
    np.fill_diagonal(separation, 0.0)
    names = tuple(str(k + 1) for k in range(n))
    bad = [names[i] for i in range(n) if not earliest[i] <= target[i] <= latest[i]]
    if bad:
        raise ORLibraryError(f"{source}: plane {bad[0]}: target outside [earliest, latest]")
    return SequencingProblem(names, earliest, target, latest, early, late, separation)


def read_airland(path: str | Path) -> SequencingProblem:
    """A file path, or the name of a bundled instance (``airland1`` ... ``airland8``)."""
    p = Path(path)
    if not p.exists() and p.name.removesuffix(".txt") in BUNDLED and len(p.parts) == 1:
        return parse_airland(bundled_text(p.name.removesuffix(".txt")), p.name)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ORLibraryError(f"{path}: cannot read: {getattr(exc, 'strerror', None) or exc}") from None
    return parse_airland(text, str(path))


def bundled_text(name: str) -> str:
    return resources.files("mal_planner.sequencing").joinpath("data", f"{name}.txt").read_text(encoding="utf-8")


def instance_name(path: str | Path) -> str:
    return Path(path).name.removesuffix(".txt")
