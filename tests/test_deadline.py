"""The plan's time limit covers the initializer: it ends promptly, classed ``timeout``, naming the stage."""

from __future__ import annotations

import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from mal_planner.deadline import Deadline
from mal_planner.errors import TimeLimitReached, classify
from mal_planner.initializer import MultiRRT, PlanningFailed, Sequencer
from mal_planner.initializer.base import InitializerTimeout
from mal_planner.initializer.collision import CollisionChecker
from mal_planner.initializer.ompl_planners import available_ompl_planners
from mal_planner.initializer.planners import make_planner
from mal_planner.options import PlanOptions
from mal_planner.pipeline import Planner
from mal_planner.scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
OVERRUN_S = 10.0
"""How far past its limit a plan may end (the initializer's longest step between two checks is well under a
second; the rest is a loaded CI machine). A bound on promptness, not on speed."""


def expired() -> Deadline:
    deadline = Deadline(1e-6)
    time.sleep(1e-3)
    return deadline


@pytest.fixture(scope="module")
def thesis():
    return load_scenario(SCENARIOS / "thesis.yaml")


@pytest.fixture(scope="module")
def tma():
    return load_scenario(SCENARIOS / "tma_12.yaml")


def test_deadline_check_raises_only_when_expired() -> None:
    Deadline(None).check()
    Deadline(60.0).check()
    with pytest.raises(TimeLimitReached, match="time limit 1e-06 s reached") as caught:
        expired().check()
    assert caught.value.failure_class == "timeout"


def test_rrt_search_stops_at_an_expired_deadline(thesis) -> None:
    checker = CollisionChecker.from_scenario(thesis)
    with pytest.raises(TimeLimitReached):
        MultiRRT().search(checker, thesis.aircraft[2].position, thesis.runway_state[:3], np.random.default_rng(0),
                          expired())


@pytest.mark.skipif("RRTConnect" not in available_ompl_planners(), reason="OMPL not installed")
def test_ompl_query_gets_no_time_past_the_deadline(thesis) -> None:
    checker = CollisionChecker.from_scenario(thesis)
    planner = make_planner("ompl:RRTConnect")
    with pytest.raises(TimeLimitReached):
        planner.plan(checker, thesis.aircraft[2].position, thesis.runway_state[:3], np.random.default_rng(0),
                     expired())


def test_initializer_with_an_expired_deadline_names_the_first_aircraft(thesis) -> None:
    with pytest.raises(InitializerTimeout) as caught:
        Sequencer().plan(thesis, seed=0, deadline=expired())
    exc = caught.value
    assert isinstance(exc, PlanningFailed) and exc.failure_class == "timeout"  # mal-plan and campaigns see both
    assert str(exc) == "time limit 1e-06 s reached in the initializer (multi-rrt path of aircraft A1, 0 of 3 planned)"


def test_plan_whose_limit_runs_out_in_the_initializer_ends_promptly(tma) -> None:
    """tma_12's initializer takes seconds (12 aircraft, 45 nm terminal area); 0.3 s ends it part-way."""
    limit = 0.3
    t0 = time.monotonic()
    with pytest.raises(InitializerTimeout) as caught:
        Planner(PlanOptions(seed=0, time_limit_s=limit)).plan(tma, reuse=False)
    assert time.monotonic() - t0 < limit + OVERRUN_S
    reason = str(caught.value)
    assert reason.startswith("time limit 0.3 s reached in the initializer (") and "of 12 " in reason, reason
    assert classify(error=caught.value).failure_class == "timeout"


def test_fallback_initializer_out_of_time_is_a_timeout_naming_it(thesis, monkeypatch) -> None:
    """A first solve that fails, then the reseeded initializer runs out of time: the failed solve is kept and the
    failure names where the limit stopped the plan."""
    planner = Planner(PlanOptions(seed=0))
    initial = Sequencer().plan(thesis, seed=0)

    def failing_solve(*args: object) -> None:
        raise ValueError("no solve in this test")

    def out_of_time(*args: object, **kwargs: object) -> None:
        raise InitializerTimeout("time limit 60 s reached in the initializer (multi-rrt path of aircraft A2, "
                                 "1 of 3 planned)")

    monkeypatch.setattr(planner, "_cold_attempt", failing_solve)
    monkeypatch.setattr("mal_planner.pipeline.planner.plan_initial", out_of_time)
    result = planner.plan(thesis, reuse=False, initial=initial)
    assert result.timed_out and result.landing is None
    assert result.failure == ("timeout", "time limit 60 s reached in the initializer (multi-rrt path of aircraft A2, "
                                         "1 of 3 planned), in the solve from another initializer seed")


def test_node_reports_the_initializer_timeout_as_a_failed_plan(thesis) -> None:
    """The node's plan step (run on a stand-in for the node: no DDS, its real service core) answers a failure
    carrying the reason."""
    from mal_planner.ros.plan_jobs import PlanJob
    from mal_planner.ros.planner_node import PlannerNode
    from mal_planner.service.core import PlanningService
    from mal_planner.service.rules import ServiceRules
    from mal_planner.service.tracks import Track

    service = PlanningService(thesis, ServiceRules(), PlanOptions(seed=0, time_limit_s=1e-6))
    tracks = {a.callsign: Track(a.callsign, 1.0, a.state0.copy(), a.speed) for a in thesis.aircraft}
    failed: list[tuple[str, str | None]] = []
    node = SimpleNamespace(
        service=service, _now=lambda: 1.0, _clock=time.monotonic,
        _planning=SimpleNamespace(plan=lambda sc, opts, *, reuse, start_time, what_if, traffic: Planner(opts).plan(
            sc, reuse=reuse, start_time=start_time)),  # in this process: the PlanProcess interface
        _failed=lambda request, reason, outcome, latency_s, result=None: failed.append(
            (reason, outcome)) or SimpleNamespace(success=False, message=reason))
    outcome = PlannerNode._plan(node, PlanJob(["test"], explicit=tracks))  # type: ignore[arg-type]
    assert not outcome.success
    assert failed == [(outcome.message, "timeout")]  # error code 6 in the service response and diagnostics
    assert outcome.message.startswith("planning failed: time limit 1e-06 s reached in the initializer ("), failed


def test_mal_plan_exits_4_when_the_limit_runs_out_in_the_initializer(tmp_path: Path) -> None:
    """The documented exit code of a timeout, with one line naming the stage (tma_12's initializer takes ~3 s)."""
    import subprocess
    import sys

    run = subprocess.run([sys.executable, "-m", "mal_planner.cli", "scenarios/tma_12.yaml", "--time-limit", "0.3",
                          "--figures", "none", "--out", str(tmp_path / "out"), "-q"],
                         capture_output=True, text=True, check=False)
    assert run.returncode == 4, run.stderr
    lines = [line for line in run.stderr.splitlines() if line.startswith("mal-plan:")]
    assert len(lines) == 1 and "time limit 0.3 s reached in the initializer (" in lines[0], run.stderr
