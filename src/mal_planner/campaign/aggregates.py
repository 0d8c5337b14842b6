"""Aggregates of a campaign's results.csv rows that the summary and its figures both show: success per N, median
time per stage against N and its growth, failure classes."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mal_planner.campaign.results import as_float
from mal_planner.errors import FAILURE_CLASSES

STAGES = ("initializer_s", "optimizer_s", "verification_s", "total_s")


@dataclass(frozen=True)
class Growth:
    """median time ~ c N^exponent, least squares on log median against log N."""

    exponent: float
    coefficient: float


def fit_growth(ns: Sequence[int], medians: Sequence[float]) -> Growth | None:
    pairs = [(n, m) for n, m in zip(ns, medians, strict=True) if n > 0 and m is not None and m > 0]
    if len({n for n, _ in pairs}) < 2:
        return None
    slope, intercept = np.polyfit(np.log([n for n, _ in pairs]), np.log([m for _, m in pairs]), 1)
    return Growth(float(slope), float(math.exp(intercept)))


def n_of(row: dict[str, str]) -> int | None:
    value = as_float(row.get("n_aircraft", ""))
    return int(value) if value is not None else None


def success_by_n(rows: Sequence[dict[str, str]]) -> dict[int, tuple[int, int]]:
    """N -> (verified, scenarios); rows whose N is unknown (unreadable files) are left out."""
    out: dict[int, list[int]] = {}
    for row in rows:
        n = n_of(row)
        if n is not None:
            counts = out.setdefault(n, [0, 0])
            counts[0] += row["status"] == "ok"
            counts[1] += 1
    return {n: (ok, total) for n, (ok, total) in sorted(out.items())}


def stage_medians(rows: Sequence[dict[str, str]], stage: str) -> dict[int, float]:
    """N -> median seconds of ``stage`` over the rows where it ran."""
    values: dict[int, list[float]] = {}
    for row in rows:
        n, t = n_of(row), as_float(row.get(stage, ""))
        if n is not None and t is not None:
            values.setdefault(n, []).append(t)
    return {n: float(np.median(v)) for n, v in sorted(values.items())}


def failure_counts(rows: Sequence[dict[str, str]]) -> dict[str, int]:
    counts = Counter(row["failure_class"] for row in rows if row["failure_class"])
    return {cls: counts.get(cls, 0) for cls in FAILURE_CLASSES}
