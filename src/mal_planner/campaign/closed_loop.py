"""One closed-loop campaign run: the row ``mal-campaign --closed-loop`` records per scenario.

The mean wind of a scenario is drawn from the campaign seed and the file's name (so a scenario meets the same
wind in every campaign with that seed, whatever the order): a speed uniform in [0, wind_kt_max] kt from a
uniform direction. The planner knows it unless ``knows_wind`` is false.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from mal_planner.campaign.results import FLOWN_RECORD
from mal_planner.closedloop.disturbances import WindSpec
from mal_planner.closedloop.loop import PLAN_TIME_LIMIT_S, ClosedLoopOptions, run_closed_loop
from mal_planner.closedloop.metrics import measure
from mal_planner.closedloop.record import run_record
from mal_planner.closedloop.simulator import SimOptions
from mal_planner.scenario import Scenario
from mal_planner.units import nm_per_s_to_kt


def drawn_wind(source: str, seed: int, options: dict[str, Any]) -> tuple[float, float]:
    """(speed kt, local heading it blows from, deg) of this scenario's mean wind."""
    rng = np.random.default_rng([seed, zlib.crc32(Path(source).name.encode())])
    return float(rng.uniform(0.0, options["wind_kt_max"])), float(rng.uniform(0.0, 360.0))


def closed_loop_row(scenario: Scenario, source: str, options: dict[str, Any]) -> dict[str, Any]:
    """Fly ``scenario`` in closed loop with the campaign's options; the row's columns (status, reason, cl_*)."""
    from mal_planner.campaign.plan_options import to_plan_options

    loop = options["closed_loop"]
    seed = int(options["seed"])
    speed_kt, from_deg = drawn_wind(source, seed, loop)
    slowest = min(nm_per_s_to_kt(a.speed * math.cos(a.state0[3])) for a in scenario.aircraft)
    speed_kt = min(speed_kt, 0.5 * slowest)  # a slow model (rotorcraft) meets at most half its airspeed
    wind = WindSpec.from_knots(speed_kt, math.radians(from_deg), loop["gust_kt"])
    simulator = None
    if loop.get("simulator", "ours") != "ours":
        from mal_planner.closedloop.bluesky_sim import make_simulator

        simulator = make_simulator(loop["simulator"])
    run = run_closed_loop(scenario, ClosedLoopOptions(
        sim=SimOptions(wind=wind, plan_delay_s=loop["delay_s"], seed=seed),
        plan=replace(to_plan_options(options), time_limit_s=options.get("time_limit_s") or PLAN_TIME_LIMIT_S),
        planner_knows_wind=loop["knows_wind"], radar_noise_m=loop["noise_m"],
        extra_plan_delay_s=loop.get("extra_plan_delay_s", 0.0), fail_every=loop.get("fail_every", 0),
        replan_what_changed=loop.get("replan_what_changed", False)), simulator)
    m = measure(run)
    lat = m.replan_latency_s
    row: dict[str, Any] = {
        "status": "ok" if m.success else "failed", "verified": m.success,
        "failure_class": "" if m.success else "verification_failed",
        "reason": "" if m.success else m.failures[0],
        "total_s": m.wall_s, "initializer_s": None, "optimizer_s": None, "verification_s": None,
        "min_separation_nm": m.min_separation_nm if math.isfinite(m.min_separation_nm) else None,
        "landing_times_s": ";".join(f"{cs}={t:.1f}" for cs, t in sorted(m.landing_times_s.items(),
                                                                         key=lambda kv: kv[1])),
        "cl_wind_kt": speed_kt, "cl_wind_from_deg": from_deg, "cl_landed": m.landed,
        "cl_separation_ratio": m.separation_ratio if math.isfinite(m.separation_ratio) else None,
        "cl_losses_of_separation": m.losses_of_separation, "cl_infringements": m.infringements,
        "cl_max_deviation_nm": m.max_deviation_nm, "cl_replans": m.replans, "cl_failed_replans": m.failed_replans,
        "cl_replans_what_changed": m.replans_what_changed,
        "cl_replan_reasons": ";".join(f"{k}={v}" for k, v in m.replan_reasons.items()),
        "cl_replan_median_s": _finite(lat["median"]), "cl_replan_p95_s": _finite(lat["p95"]),
        "cl_replan_max_s": _finite(lat["max"]), "cl_order_changes": m.order_changes,
        "cl_min_landing_spacing_s": _finite(m.min_landing_spacing_s),
        "cl_replan_times_s": ";".join(f"{r.charged_s:.3f}" for r in run.replans),
        "cl_simulator": loop.get("simulator", "ours"),
        "cl_fallback_share": m.fallback_share, "cl_holds": m.holds, "cl_net_alerts": m.net_alerts,
        "cl_net_uses": m.net_uses, "cl_vectors": m.vectors,
        "cl_simulator_losses_of_separation": (None if m.external_losses_of_separation is None
                                              else len(m.external_losses_of_separation)),
    }
    if not m.success:  # the campaign writes it beside the run's log (logs/<name>.closed_loop.json)
        row[FLOWN_RECORD] = run_record(run, m, {**loop, "wind_kt": speed_kt, "wind_from_deg": from_deg})
    return row


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None
