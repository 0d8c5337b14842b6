"""Which aircraft fly in which phase: phases run between consecutive events (gate passages, landings).

The thesis (chapter 5) splits the problem into 2N overlapping phases: before the gate, phases with
shrinking sets of aircraft, then one landing phase per aircraft. Separation there is only enforced in
the phases before the gate, because the landing phases run on separate time grids. Here the 2N phase
boundaries are the same 2N events (each aircraft passes the gate, each aircraft lands) but every
phase carries every aircraft airborne during it, so the separation of EVERY pair of aircraft airborne
at the same time is enforced at every collocation point, also on the shared final approach. Each
aircraft is either *approaching* (before its gate event: kept on the near side of the gate plane) or
*landing* (after it: kept on the far side), which also stops a trajectory from jumping through the
thin wall between two collocation points. The order of the events is taken from the initial guess.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

EventKind = Literal["gate", "land"]


@dataclass(frozen=True)
class Event:
    kind: EventKind
    aircraft: int
    """Index in landing order."""
    time_guess: float


@dataclass(frozen=True)
class PhaseLayout:
    """Events in time order; phase k runs from event k-1 (or t = 0) to event k."""

    callsigns: tuple[str, ...]
    """In landing order."""
    events: tuple[Event, ...]
    has_gate: bool

    @property
    def n_phases(self) -> int:
        return len(self.events)

    def event_index(self, kind: EventKind, aircraft: int) -> int:
        for k, ev in enumerate(self.events):
            if ev.kind == kind and ev.aircraft == aircraft:
                return k
        raise KeyError((kind, aircraft))

    def airborne(self, phase: int) -> list[int]:
        """Aircraft (landing-order indices) flying during ``phase``."""
        return [i for i in range(len(self.callsigns)) if self.event_index("land", i) >= phase]

    def has_gate_event(self, aircraft: int) -> bool:
        return any(ev.kind == "gate" and ev.aircraft == aircraft for ev in self.events)

    def approaching(self, phase: int, aircraft: int) -> bool:
        """True while ``aircraft`` has not passed its gate by the end of ``phase``."""
        return self.has_gate_event(aircraft) and self.event_index("gate", aircraft) >= phase

    def signature(self) -> tuple:
        """What the NLP's structure depends on (event kinds and aircraft, in order)."""
        return self.callsigns, tuple((ev.kind, ev.aircraft) for ev in self.events), self.has_gate

    def phase_name(self, phase: int) -> str:
        ev = self.events[phase]
        return f"P{phase + 1}_{ev.kind}_{self.callsigns[ev.aircraft]}"


def plan_layout(callsigns: list[str], landing_times: list[float],
                gate_times: list[float | None] | None) -> PhaseLayout:
    """Order the events by their guessed times, keeping gates and landings each in landing order.

    ``gate_times`` is None without a gate; an entry is None for an aircraft already past the gate (a
    replan), which then has no gate event. Gate passages follow the landing order, each aircraft passes
    its gate before it lands; guesses that contradict these rules are resolved by the rules.
    """
    n = len(callsigns)
    lands = list(landing_times)
    for i in range(1, n):  # monotone in landing order
        lands[i] = max(lands[i], lands[i - 1] + 1e-3)
    events = [Event("land", i, lands[i]) for i in range(n)]
    if gate_times is not None:
        previous = 0.0
        for i in range(n):
            if gate_times[i] is None:
                continue
            t_gate = min(max(gate_times[i], previous + 1e-3), lands[i] - 1e-3)
            events.append(Event("gate", i, t_gate))
            previous = t_gate
    # Sort by time; at equal times a gate comes before a landing, lower landing order first.
    events.sort(key=lambda e: (e.time_guess, e.kind != "gate", e.aircraft))
    return PhaseLayout(tuple(callsigns), tuple(events), gate_times is not None)
