"""The node plans in a child process (mal_planner.ros.plan_process): same plans, exceptions and deaths reported."""

from __future__ import annotations

import os
import signal
import threading
from dataclasses import replace

import pytest

from mal_planner.errors import InfeasibleRequest
from mal_planner.options import PlanOptions
from mal_planner.pipeline import Planner
from mal_planner.ros.plan_process import PlanningProcessDied, PlanProcess
from mal_planner.scenario import load_scenario


@pytest.fixture(scope="module")
def planning():
    process = PlanProcess()
    yield process
    process.close()


def test_the_child_plans_what_this_process_would(planning: PlanProcess) -> None:
    sc = load_scenario("scenarios/thesis.yaml")
    options = PlanOptions(seed=0, refinement_rounds=0)
    here = Planner(options).plan(sc, reuse=False, start_time=0.0)
    there = planning.plan(sc, options, reuse=True, start_time=0.0)
    assert there.landing_times() == pytest.approx(here.landing_times(), abs=1e-9)
    assert there.verified == here.verified and there.order == here.order
    what_if = planning.plan(sc, options, reuse=False, start_time=0.0, what_if=True)
    assert what_if.landing_times() == pytest.approx(here.landing_times(), abs=1e-9)


def test_the_child_replans_what_changed_among_the_others(planning: PlanProcess) -> None:
    import numpy as np

    from mal_planner.scenario.traffic import FixedPath, Traffic

    sc = load_scenario("scenarios/thesis.yaml")
    options = PlanOptions(seed=0, refinement_rounds=0)
    whole = Planner(options).plan(sc, reuse=False, start_time=0.0)
    paths = {}
    for tr in whole.landing.trajectories:
        t, idx = np.unique(tr.t, return_index=True)
        paths[tr.callsign] = FixedPath.cut(sc.aircraft_by_callsign(tr.callsign), t, tr.states[idx], 5.0, lands=True)
    last = whole.order[-1]
    mine = replace(sc.aircraft_by_callsign(last), state0=paths[last].states[0].copy(), landing_time=None)
    traffic = Traffic((paths[last],), tuple(p for cs, p in paths.items() if cs != last))
    there = planning.plan(replace(sc, aircraft=(mine,)), options, reuse=True, start_time=5.0, traffic=traffic)
    assert there.verified, there.failure
    assert [tr.callsign for tr in there.landing.trajectories] == [last]
    assert len(there.verification.pairs) == len(sc.aircraft) - 1  # checked against each fixed path


def test_the_childs_exception_is_raised_here(planning: PlanProcess) -> None:
    sc = load_scenario("scenarios/thesis.yaml")
    a1 = sc.aircraft[0]
    close = replace(sc, aircraft=(a1, replace(sc.aircraft[1], state0=a1.state0.copy()), sc.aircraft[2]))
    with pytest.raises(InfeasibleRequest, match="apart at the start"):
        planning.plan(close, PlanOptions(seed=0), reuse=False, start_time=0.0)


def test_a_dead_child_fails_the_plan_and_is_started_again() -> None:
    planning = PlanProcess()
    try:
        pid = planning.pid
        killer = threading.Timer(2.0, lambda: os.kill(pid, signal.SIGKILL))  # while it plans (tma_12: ~10 s)
        killer.start()
        with pytest.raises(PlanningProcessDied, match="exit -9"):
            planning.plan(load_scenario("scenarios/tma_12.yaml"), PlanOptions(seed=0, time_limit_s=120.0),
                          reuse=False, start_time=0.0)
        killer.join()
        sc = load_scenario("scenarios/thesis.yaml")
        result = planning.plan(sc, PlanOptions(seed=0, optimize=False), reuse=False, start_time=0.0)
        assert set(result.landing_times()) == {"A1", "A2", "A3"}
    finally:
        planning.close()


def test_the_child_dies_with_its_node() -> None:
    """A node killed by SIGKILL leaves no planning process behind (PR_SET_PDEATHSIG; Linux)."""
    import subprocess
    import sys
    import time

    node = subprocess.Popen([sys.executable, "-c", "from mal_planner.ros.plan_process import PlanProcess\n"
                             "import time\np = PlanProcess()\nprint(p.pid, flush=True)\ntime.sleep(60)\n"],
                            stdout=subprocess.PIPE, text=True)
    child = int(node.stdout.readline())
    time.sleep(1.0)  # the child is importing or idle
    node.kill()
    node.wait()
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline and _alive(child):
        time.sleep(0.05)
    assert not _alive(child)


def _alive(pid: int) -> bool:
    """Running (not a zombie waiting for its parent)."""
    from pathlib import Path

    try:
        return "zombie" not in Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return False
