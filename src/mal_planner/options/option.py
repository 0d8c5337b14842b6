"""One option, declared once: its type, default, range, help and its spelling in each interface.

Each :class:`Option` has one value type, default, range and help, and its spelling in each interface that offers
it: a command-line flag (``mal-plan``; the campaigns and ``mal-closed-loop`` use the same flags), a campaign key (as
stored in ``campaign.json``) and a ROS 2 parameter of the node. Where an interface states the opposite of the value
(``--free-landing-times`` for ``fixed_landing_times: false``, ``--no-refine``, ``--initial-only``), ``flag_sets``
is the value its flag sets. Checks, ROS descriptor ranges and help text all derive from it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

INT64_MAX = 2**63 - 1
"""The largest ROS 2 integer parameter: the upper end of an integer range without an upper bound."""


@dataclass(frozen=True)
class Option:
    """One option (see the module docstring)."""

    name: str
    kind: type
    default: Any
    help: str
    lo: float | None = None
    """Inclusive lower bound (numbers)."""
    hi: float | None = None
    """Inclusive upper bound (numbers)."""
    above: float | None = None
    """Exclusive lower bound (numbers), e.g. 0 for "> 0"."""
    below: float | None = None
    """Exclusive upper bound (numbers)."""
    choices: tuple[str, ...] = ()
    validate: Callable[[Any], str | None] | None = None
    """A further check of a valid-looking value: the problem, or None."""
    none_as: Any = None
    """The value that stands for None where an interface cannot say None (a ROS parameter: 0 = no limit)."""
    flag: str | None = None
    flag_sets: Any = None
    """For a boolean flag: the value the flag sets (the opposite of the default)."""
    flag_help: str = ""
    """For a boolean flag: what setting it does (``help`` describes the option's value)."""
    campaign: str | None = None
    campaign_inverted: bool = False
    """The campaign key states the opposite (``free_landing_times`` for ``fixed_landing_times``)."""
    ros: str | None = None
    node_default: Any = None
    """The node's default where it differs (a service needs a time limit; ``mal-plan`` has none by default)."""
    unit: str = ""
    metavar: str | None = None
    coerce: Callable[[Any], Any] | None = None
    """Turns a value of an older spelling into the option's (e.g. the node's ``figures: true`` into ``png``)."""
    read_only: bool = False
    """A node parameter that takes effect at start-up only."""

    def check(self, value: Any) -> Any:
        """The value, converted to the option's type; ValueError with the problem (one line, without the name)."""
        if self.coerce is not None:
            value = self.coerce(value)
        if value is None:
            if self.default is not None:
                raise ValueError("expected a value")
            return None
        if self.kind is bool:
            if not isinstance(value, bool):
                raise ValueError("expected true or false")
            return value
        if self.kind is str:
            if not isinstance(value, str):
                raise ValueError("expected a string")
            if self.choices and value not in self.choices:
                raise ValueError(f"expected one of {', '.join(self.choices)}")
        else:
            value = self._number(value)
        problem = self.validate(value) if self.validate else None
        if problem:
            raise ValueError(problem)
        return value

    def _number(self, value: Any) -> float | int:
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise ValueError("expected a finite number" if self.kind is float else "expected an integer")
        if self.kind is int and int(value) != value:
            raise ValueError("expected an integer")
        value = self.kind(value)
        fmt = "d" if self.kind is int else "g"
        for bound, ok, word in ((self.lo, lambda b: value >= b, ">="), (self.hi, lambda b: value <= b, "<="),
                                (self.above, lambda b: value > b, ">"), (self.below, lambda b: value < b, "<")):
            if bound is not None and not ok(bound):
                raise ValueError(f"must be {word} {bound:{fmt}}")
        return value

    @property
    def value_range(self) -> tuple[float, float] | None:
        """The inclusive range of a number, for a ROS parameter descriptor (an exclusive bound becomes the nearest
        representable value inside it); None for other kinds."""
        if self.kind not in (int, float):
            return None
        if self.kind is int:
            lo = self.lo if self.lo is not None else (self.above + 1 if self.above is not None else -INT64_MAX - 1)
            hi = self.hi if self.hi is not None else (self.below - 1 if self.below is not None else INT64_MAX)
            return int(lo), int(hi)
        lo = self.lo if self.lo is not None else (math.nextafter(self.above, math.inf) if self.above is not None
                                                  else -math.inf)
        if self.none_as is not None and self.none_as < lo:
            lo = self.none_as
        hi = self.hi if self.hi is not None else (math.nextafter(self.below, -math.inf) if self.below is not None
                                                  else math.inf)
        return lo, hi

    def ros_default(self) -> Any:
        """The default as a ROS parameter (which cannot be None)."""
        if self.node_default is not None:
            return self.node_default
        return self.none_as if self.default is None else self.default

    def check_ros(self, value: Any) -> Any:
        """:meth:`check` for a ROS parameter's value: ``none_as`` stands for None; returns the parameter's value."""
        if self.none_as is not None and value == self.none_as and not isinstance(value, bool):
            return type(self.none_as)(value)
        return self.check(value)
