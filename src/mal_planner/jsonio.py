"""Strict JSON for every file the project writes: NaN and infinities become ``null``, never the bare ``NaN`` /
``Infinity`` tokens Python's json module writes by default (which are not JSON: other parsers refuse them).

    write(path, doc, indent=1)      # atomically, with a final newline
    text = dumps(doc)

Numpy scalars and arrays are written as numbers and lists. Standard library and numpy only (a bottom module).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["dumps", "strict", "write"]


def strict(value: Any) -> Any:
    """``value`` with every non-finite float (Python or numpy) replaced by None, and numpy values by Python ones;
    containers are copied (tuples become lists), anything else is returned as it is."""
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {key: strict(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [strict(item) for item in value]
    if isinstance(value, np.ndarray):
        return strict(value.tolist())
    if isinstance(value, np.integer | np.bool_):
        return value.item()
    return value


def dumps(doc: Any, *, indent: int | None = None, sort_keys: bool = False, default: Any = None) -> str:
    """Strict JSON text of ``doc`` (see :func:`strict`); ``default`` as for :func:`json.dumps`."""
    return json.dumps(strict(doc), indent=indent, sort_keys=sort_keys, default=default, allow_nan=False)


def write(path: str | Path, doc: Any, *, indent: int | None = 1, sort_keys: bool = False,
          default: Any = None) -> Path:
    """Write ``doc`` as strict JSON (and a newline) to ``path``, atomically: a reader sees the old file or the new
    one, never half of one."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(dumps(doc, indent=indent, sort_keys=sort_keys, default=default) + "\n", encoding="utf-8")
    os.replace(tmp, path)
    return path
