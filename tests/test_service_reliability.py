"""Service reliability under faults (issue 22): lost tracks withdraw their plans, failed replans say how old
the kept plan is, bursts of new callsigns, implausible radar input, a killed recorder or launcher.

Real processes on real DDS (loopback), once per backend where the node is involved.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from dds_support import Snippet, coarse_params, dds_env, snippet  # noqa: F401  (fixtures)
from test_planner_node import SCENARIO, dump_on_failure, start_planner, wait_for

pytestmark = pytest.mark.usefixtures("dds_env")


# Radar: the scenario's aircraft flown straight on at 5 Hz with wall-clock stamps; an aircraft whose
# callsign is named in the file ``stop`` is no longer published.
RADAR = """
import os, time
from mal_planner.ros.transport import create_node
from mal_planner.ros.convert import planner_to_aircraft_state
from mal_planner.ros.state_store import extrapolate
from mal_planner.scenario import load_scenario
node = create_node("radar")
pub = node.create_publisher("mal_msgs/msg/AircraftState", "radar/tracks", 100)
deadline = time.monotonic() + 20
while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
    time.sleep(0.05)
sc = load_scenario(%(scenario)r)
t0 = time.time()
print("radar on", flush=True)
stopped = set()
while True:
    if os.path.exists(%(stop)r) and not stopped:
        stopped = set(open(%(stop)r).read().split())
        print("STOPPED " + repr(time.time()), flush=True)
    now = time.time()
    for a in sc.aircraft:
        if a.callsign not in stopped:
            state = extrapolate(a.state0, a.speed, min(now - t0, 20.0))
            pub.publish(planner_to_aircraft_state(node.types, a.callsign, now, state, a.speed))
    time.sleep(0.2)
"""

# Listener: prints every landing_plan (callsigns) and every path (callsign, number of poses) with the time.
LISTENER = """
import time
from mal_planner.ros.transport import QOS_LATCHED, create_node
node = create_node("listener")
def plan(m):
    print("PLAN " + repr(time.time()) + " " + ",".join(sorted(a.callsign for a in m.aircraft)), flush=True)
def diag(m):
    kv = {v.key: v.value for v in m.status[0].values}
    print("DIAG " + repr(time.time()) + " " + m.status[0].message + " | " + repr(kv), flush=True)
node.create_subscription("mal_msgs/msg/LandingPlan", "landing_plan", plan, QOS_LATCHED)
node.create_subscription("diagnostic_msgs/msg/DiagnosticArray", "diagnostics", diag, QOS_LATCHED)
for cs in ("A1", "A2", "A3"):
    node.create_subscription("nav_msgs/msg/Path", f"aircraft/{cs}/path",
        lambda m, cs=cs: print("PATH " + repr(time.time()) + " " + cs + " " + str(len(m.poses)), flush=True),
        QOS_LATCHED)
print("listening", flush=True)
node.spin()
"""


def test_lost_track_withdraws_its_plan(backend_snippet, snippet, tmp_path: Path) -> None:  # noqa: F811
    """A2's radar stops after the first plan: within track_timeout_s (+ a tick) its path is an empty Path, its
    entry leaves landing_plan and a diagnostic names it; A1 and A3 keep their plans."""
    timeout_s = 2.0
    params = tmp_path / "planner.params.yaml"
    params.write_text(coarse_params(f"    deviation_threshold_m: 0.0\n    figures: false\n"
                                    f"    track_timeout_s: {timeout_s}\n"), encoding="utf-8")
    planner = start_planner(backend_snippet, params)
    with dump_on_failure(planner=planner):
        wait_for(planner, "planner ready", 30)
        listener = snippet(LISTENER)
        listener.wait_for_line("listening")
        stop = tmp_path / "stop"
        radar = snippet(RADAR % {"scenario": str(SCENARIO), "stop": str(stop)})
        radar.wait_for_line("radar on", 30)
        wait_for(planner, "plan #1", 150)
        assert listener.wait_for_line("PLAN ", 30).endswith(" A1,A2,A3")
        stop.write_text("A2", encoding="utf-8")
        stopped = float(radar.wait_for_line("STOPPED ", 10).split()[1])
        seen: dict[str, float] = {}
        deadline = time.monotonic() + timeout_s + 10.0
        while time.monotonic() < deadline and not {"path", "plan", "diag"} <= set(seen):
            line = listener.wait_for_line("", deadline - time.monotonic())
            kind, t, rest = line.split(" ", 2)
            if kind == "PATH" and rest == "A2 0":
                seen["path"] = float(t)
            elif kind == "PLAN" and rest == "A1,A3":
                seen["plan"] = float(t)
            elif kind == "DIAG" and "plan of A2 withdrawn: track lost" in rest:
                seen["diag"] = float(t)
            elif kind == "PATH" and rest.endswith(" 0"):
                pytest.fail(f"another aircraft's plan was withdrawn: {line}")
        assert {"path", "plan", "diag"} <= set(seen), listener.output
        delays = {k: v - stopped for k, v in seen.items()}
        print("withdrawal delays after the last A2 message [s]:", delays)
        assert all(d <= timeout_s + 1.0 for d in delays.values()), delays
        assert planner.proc.poll() is None
