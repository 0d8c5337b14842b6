"""An IPOPT intermediate callback that stops a solve at a deadline and logs the progress of long solves."""

from __future__ import annotations

import logging
import time
from typing import Any

import casadi as ca

_log = logging.getLogger("mal_planner.ocp")


class IterationWatch:
    """Sees every IPOPT iteration: stops the solve at a deadline and logs progress on long solves.

    One watch serves every NLP of a solver (they are cached); :attr:`deadline` is set per solve.
    """

    def __init__(self, log_every_s: float = 5.0) -> None:
        self.deadline: Any = None
        """An object with ``expired()`` (e.g. :class:`mal_planner.deadline.Deadline`), or None."""
        self.log_every_s = log_every_s
        self.iterations = 0
        self._started = 0.0
        self._last_log = 0.0
        self.stopped = False

    def start(self, deadline: Any) -> None:
        self.deadline, self.iterations, self.stopped = deadline, 0, False
        self._started = self._last_log = time.perf_counter()

    def __call__(self, objective: float) -> int:
        """0 to go on, 1 to stop IPOPT (it then returns User_Requested_Stop)."""
        self.iterations += 1
        now = time.perf_counter()
        if now - self._last_log >= self.log_every_s:
            _log.info("IPOPT: iteration %d, objective %.6g, %.0f s", self.iterations, objective, now - self._started)
            self._last_log = now
        if self.deadline is not None and self.deadline.expired():
            self.stopped = True
            return 1
        return 0

    def function(self, nx: int, ng: int, n_params: int) -> ca.Function:
        return _WatchCallback(self, nx, ng, n_params)


class _WatchCallback(ca.Callback):
    """CasADi's form of an IPOPT intermediate callback (inputs: nlpsol's outputs)."""

    def __init__(self, watch: IterationWatch, nx: int, ng: int, n_params: int) -> None:
        ca.Callback.__init__(self)
        self._watch, self._nx, self._ng, self._np = watch, nx, ng, n_params
        self.construct("watch", {})

    def get_n_in(self) -> int:
        return ca.nlpsol_n_out()

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return ca.nlpsol_out(i)

    def get_name_out(self, i: int) -> str:
        return "ret"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        name = ca.nlpsol_out(i)
        sizes = {"f": 1, "x": self._nx, "lam_x": self._nx, "g": self._ng, "lam_g": self._ng, "p": self._np,
                 "lam_p": self._np}
        return ca.Sparsity.dense(sizes.get(name, 0), 1) if name in sizes else ca.Sparsity(0, 0)

    def eval(self, arg: list) -> list:
        return [self._watch(float(arg[ca.nlpsol_out().index("f")]))]
