"""Scenario files in a campaign's records: paths relative to the campaign folder, so that committed results
carry no path of the machine they ran on. Tables written before hold absolute paths; both forms are read."""

from __future__ import annotations

import os
from pathlib import Path


def campaign_key(path: Path, out: Path) -> str:
    """A scenario file's key in results.csv and campaign.json: its path relative to the campaign folder ``out``
    (POSIX separators), e.g. ``../traffic/traffic-0001-n6-wall.yaml``."""
    return Path(os.path.relpath(Path(path).resolve(), Path(out).resolve())).as_posix()


def scenario_path(key: str, out: Path) -> Path:
    """The file a key names (relative to the campaign folder ``out``, or absolute in older tables)."""
    path = Path(key)
    return path if path.is_absolute() else Path(os.path.normpath(Path(out).resolve() / path))
