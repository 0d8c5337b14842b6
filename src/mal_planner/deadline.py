"""A wall-clock time limit shared by the stages of one plan (initializer, optimizer, verification)."""

from __future__ import annotations

import math
import time

from mal_planner.errors import TimeLimitReached


class Deadline:
    """``Deadline(None)`` never expires; ``Deadline(10.0)`` expires 10 s after it was made."""

    def __init__(self, seconds: float | None) -> None:
        if seconds is not None and not (math.isfinite(seconds) and seconds > 0):
            raise ValueError(f"time limit must be a positive number of seconds, got {seconds}")
        self.seconds = seconds
        self._end = math.inf if seconds is None else time.monotonic() + seconds

    def remaining(self) -> float:
        return max(self._end - time.monotonic(), 0.0)

    def expired(self) -> bool:
        return time.monotonic() >= self._end

    def check(self) -> None:
        """Raise :class:`TimeLimitReached` ("time limit 60 s reached") once the limit has run out; cheap enough
        for every iteration of a planner's loop (no clock read without a limit)."""
        if self.seconds is not None and time.monotonic() >= self._end:
            raise TimeLimitReached(f"time limit {self.seconds:g} s reached")


NO_DEADLINE = Deadline(None)
"""The deadline of a call made without one: it never expires."""
