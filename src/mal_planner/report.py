"""Outputs of a plan: the JSON result (schema in the README), a validation report, figures."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np

from mal_planner import jsonio
from mal_planner.errors import outcome_code
from mal_planner.performance import cas_of_tas, performance_of
from mal_planner.pipeline import PlanResult
from mal_planner.scenario import Scenario
from mal_planner.units import nm_per_s_to_kt, nm_to_ft

SCHEMA = "mal-planner/plan"
SCHEMA_VERSION = 1
SEQUENCE_FIGURE = ("![landing sequence: who lands when, each gap against the spacing it needs](sequence.png)\n\n"
                   "`sequence.png` (written with the PNG figures): a row per aircraft in landing order, its landing "
                   "(▼), target (|) and delay (shaded); between consecutive landings the gap got against the spacing "
                   "needed (grey band), red where short.")
"""The landing-sequence section's figure (report.md sits beside the PNGs)."""


def _num(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else float(value)


def _scenario(result: PlanResult) -> dict:
    """Name, source and the geometry the figures draw (planner units)."""
    sc = result.scenario
    return {"name": sc.name, "source": sc.source, "airspace": sc.airspace.tolist(),
            "runway": sc.runway_state.tolist(), "separation_nm": sc.separation_nm,
            "obstacles": [asdict(ob) for ob in sc.obstacles], "gates": [asdict(g) for g in sc.gates],
            "geo_frame": None if sc.geo_frame is None else sc.geo_frame.describe(), "wind": wind_summary(sc),
            "elevation_nm": sc.elevation_nm, "procedures": _procedures(sc)}


def _procedures(sc: Scenario) -> dict | None:
    """The speed and height rules the profile figure draws (planner units: nm, nm/s CAS); None without any."""
    pr = sc.procedures
    if pr is None:
        return None
    return {"speed_limit": pr.speed_limit, "speed_limit_below_nm": pr.speed_limit_below_nm,
            "final_speed": pr.final_speed, "final_distance_nm": pr.final_distance_nm,
            "min_height_nm": pr.min_height_nm}


def wind_summary(sc: Scenario) -> dict:
    """The scenario's wind: speed (kt), where it blows from (local heading; true direction on the Earth, deg) and
    the local vector (nm/s); directions None in still air."""
    wx, wy = (float(v) for v in sc.wind)
    speed = math.hypot(wx, wy)
    from_local = from_true = None
    if speed > 0.0:  # rounded to 1e-9 deg: the vector's round-off (cos 90 deg = 6e-17) is not a direction
        from_local = round(math.degrees(math.atan2(-wy, -wx)), 9) + 0.0
        if sc.geo_frame is not None:
            towards, _ = sc.geo_frame.direction_to_geodetic(np.zeros(3), math.atan2(wy, wx), 0.0)
            from_true = round((towards + 180.0) % 360.0, 9) % 360.0
    return {"speed_kt": float(nm_per_s_to_kt(speed)), "from_heading_deg": from_local, "from_deg": from_true,
            "vector_nm_s": [wx, wy]}


def _trajectory(result: PlanResult, columns: dict) -> dict:
    """A trajectory's columns, with ``lat_deg``, ``lon_deg``, ``alt_ft`` per sample when the scenario is on the
    Earth."""
    sc = result.scenario
    if "airspeed" in columns:  # the airspeed model: its calibrated airspeed at its pressure altitude as well
        altitude = sc.elevation_nm + np.asarray(columns["z"], float)
        columns = {**columns, "cas": cas_of_tas(np.asarray(columns["airspeed"], float), altitude).tolist()}
    frame = sc.geo_frame
    if frame is None:
        return columns
    lat, lon, alt = frame.to_geodetic(np.column_stack([columns["x"], columns["y"], columns["z"]]))
    return {**columns, "lat_deg": lat.tolist(), "lon_deg": lon.tolist(), "alt_ft": alt.tolist()}


def _limits(result: PlanResult, callsign: str) -> dict:
    ac = result.scenario.aircraft_by_callsign(callsign)
    lim = ac.limits
    thrust = {"n_x": list(lim.n_x)} if ac.dynamics.variable_airspeed else {}
    kind = result.scenario.type_of(ac)
    if kind is not None and ac.dynamics.variable_airspeed:
        perf = performance_of(kind)
        thrust |= {"type": kind, "vmo": perf.vmo, "final_approach_cas": [perf.final_approach_cas.low,
                                                                          perf.final_approach_cas.high]}
    return {"n_h": list(lim.n_h), "n_v": list(lim.n_v), "bank_angle_max": lim.bank_angle_max, **thrust}


def sequence_document(result: PlanResult) -> dict | None:
    """Who lands when: each aircraft's slot, target, landing time and delay, from the schedule."""
    schedule = getattr(result.initial, "schedule", None)
    if schedule is None:
        return None
    landing = result.landing_times()
    rows = []
    for slot, cs in enumerate(result.order, start=1):
        t = landing.get(cs, schedule.times.get(cs))
        target = schedule.target.get(cs)
        category = result.scenario.aircraft_by_callsign(cs).wake_category
        rows.append({"callsign": cs, "slot": slot, "wake_category": category,
                     "fixed": cs in schedule.fixed, "earliest_s": _num(schedule.earliest.get(cs)),
                     "target_s": _num(target), "scheduled_s": _num(schedule.times.get(cs)), "landing_time_s": _num(t),
                     "delay_s": None if t is None or target is None else _num(t - target)})
    return {"strategy": schedule.strategy, "status": schedule.status, "gap": _num(schedule.gap),
            "wake": result.scenario.wake, "total_delay_s": _num(sum(r["delay_s"] or 0.0 for r in rows)),
            "aircraft": rows}


def _outcome(result: PlanResult) -> dict:
    """How the plan ended, as every interface reports it (:data:`mal_planner.errors.OUTCOMES`)."""
    failure = result.failure
    code = outcome_code(failure[0] if failure else None)
    return {"name": code.name, "reason": failure[1] if failure else "", "error_code": code.error_code,
            "exit_code": code.exit_code}


def result_to_dict(result: PlanResult) -> dict:
    """The JSON document (planner units: nm, s, rad)."""
    initial = result.initial
    trajectories = {t.callsign: t for t in result.trajectories()}
    landing, gates = result.landing_times(), result.gate_times()
    aircraft = []
    for tr in initial.trajectories:
        aircraft.append({
            "callsign": tr.callsign,
            "order": tr.order,
            "gate_time_s": _num(gates.get(tr.callsign)),
            "landing_time_s": _num(landing.get(tr.callsign)),
            "initial": {
                "path_length_nm": tr.path_length,
                "landing_time_s": tr.landing_time,
                "gate_times_s": {k: _num(v) for k, v in tr.gate_times.items()},
                "waypoint": None if tr.waypoint is None else np.asarray(tr.waypoint).tolist(),
                "waypoint_index": tr.waypoint_index,
                "waypoints": {"t": np.asarray(tr.times).tolist(),
                              **{k: np.asarray(tr.waypoints)[:, i].tolist() for i, k in enumerate("xyz")}},
                "direct_path": np.asarray(tr.direct_path).tolist(),
            },
            "limits": _limits(result, tr.callsign),
            "trajectory": _trajectory(result, trajectories[tr.callsign].to_dict()),
        })
    status = "optimal" if result.optimized else ("failed" if result.landing is not None else "initial_guess")
    return {
        "schema": SCHEMA,
        "version": SCHEMA_VERSION,
        "units": {"length": "nm", "time": "s", "angle": "rad", "speed": "nm/s"},
        "scenario": _scenario(result),
        "status": status,
        "verified": bool(result.verification.verified) if result.verification else False,
        "outcome": _outcome(result),
        "landing_order": result.order,
        "sequence": sequence_document(result),
        "initializer": {"planner": initial.planner, "seed": initial.seed, "timings_s": initial.timings,
                        "collision_checks": initial.collision_checks},
        "optimizer": result.landing.stats() if result.landing is not None else None,
        "verification": result.verification.to_dict() if result.verification else None,
        "timings_s": result.timings,
        "aircraft": aircraft,
    }


def summary_table(result: PlanResult) -> str:
    """Short text table: order, path length, gate and landing time per aircraft, and the outcome."""
    landing, gates = result.landing_times(), result.gate_times()
    rows = [f"{'order':>5}  {'callsign':<8} {'path (nm)':>9} {'t_gate (s)':>10} {'t_land (s)':>10}"]
    for tr in result.initial.trajectories:
        gate = gates.get(tr.callsign)
        rows.append(f"{tr.order:>5}  {tr.callsign:<8} {tr.path_length:>9.3f} "
                    f"{'-' if gate is None else f'{gate:.2f}':>10} {landing[tr.callsign]:>10.2f}")
    if result.landing is None:
        rows.append("initial trajectories only (optimizer not run)")
    else:
        lr = result.landing
        verdict = "n/a"
        if result.verification is not None:
            verdict = "verified" if result.verification.verified else "NOT verified: " + "; ".join(
                result.verification.reasons[:3])
        rows.append(f"optimizer: {lr.status}, objective {lr.objective:.4f}, {lr.nlp_iterations} NLP iterations, "
                    f"{lr.solve_time:.2f} s; {verdict}")
    return "\n".join(rows)


def validation_report(result: PlanResult) -> str:
    """Chapter-6 style validation tables (Table 6-1 analog, separation, bank, events)."""
    lines = [f"# Validation report: {result.scenario.name}", ""]
    if result.landing is None or result.verification is None:
        lines.append("No optimized trajectories to validate.")
        return "\n".join(lines)
    rep = result.verification
    lines += ["## Mayer cost (Table 6-1 analog)", "", "| aircraft | t_obs (s) | t_f (s) |", "|---|---|---|"]
    for cs in result.order:
        g = result.landing.gate_times[cs]
        lines.append(f"| {cs} | {'-' if g is None else f'{g:.2f}'} | {result.landing.landing_times[cs]:.2f} |")
    wind = wind_summary(result.scenario)
    if wind["speed_kt"] > 0.0:
        true = "" if wind["from_deg"] is None else f", {wind['from_deg']:.1f} deg true"
        lines += ["", f"Wind: {wind['speed_kt']:.1f} kt from heading {wind['from_heading_deg']:.1f} deg{true} "
                      "(gate and runway headings are ground tracks: the aircraft crab)"]
    lines += ["", f"Objective: {result.landing.objective:.6f}", "", "## Separation (minimum over the flight)", "",
              "| pair | minimum distance (nm) | at t (s) |", "|---|---|---|"]
    lines += [f"| {p.pair} | {p.min_distance_nm:.4f} | {p.at_time_s:.2f} |" for p in rep.pairs]
    sc = result.scenario
    required = f"{sc.separation_nm} nm" if sc.vertical_separation_nm is None else (
        f"{sc.separation_nm} nm horizontally or {nm_to_ft(sc.vertical_separation_nm):.0f} ft vertically (a cylinder; "
        "the distance column is the horizontal minimum times the smallest max(h / H, |dz| / V))")
    lines += ["", f"Required: {required}", "", "## Bank angle and re-integration", "",
              "| aircraft | bank min (deg) | bank max (deg) | max deviation (nm) | runway error (nm) |",
              "|---|---|---|---|---|"]
    for a in rep.aircraft:
        runway = a.runway_error.get("position_error_nm", float("nan"))
        lines.append(f"| {a.callsign} | {a.bank_min_deg:.2f} | {a.bank_max_deg:.2f} | "
                     f"{a.max_position_deviation_nm:.2e} | {runway:.2e} |")
    lines += ["", "## Gate events", "", "| aircraft | t (s) | x (nm) | z (nm) | gamma (deg) | heading (deg) |",
              "|---|---|---|---|---|---|"]
    for a in rep.aircraft:
        for ev in a.gate_events:
            x, _, z = ev["position"]
            lines.append(f"| {a.callsign} | {ev['time_s']:.2f} | {x:.4f} | {z:.4f} | "
                         f"{math.degrees(ev['gamma']):.3f} | {math.degrees(ev['heading']):.3f} |")
    sequence = sequence_document(result)
    if sequence is not None:
        lines += ["", f"## Landing sequence ({sequence['strategy']}, wake table {sequence['wake']})", "",
                  SEQUENCE_FIGURE, "", "| slot | aircraft | wake | target (s) | lands (s) | delay (s) |",
                  "|---|---|---|---|---|---|"]
        for r in sequence["aircraft"]:
            cells = ["-" if r[k] is None else f"{r[k]:.2f}" for k in ("target_s", "landing_time_s", "delay_s")]
            lines.append(f"| {r['slot']} | {r['callsign']} | {r['wake_category'] or '-'} | {' | '.join(cells)} |")
        lines += ["", f"Total delay against the targets: {sequence['total_delay_s']:.1f} s"]
    if rep.landings:
        lines += ["", "## Landing spacing (consecutive pairs)", ""]
        lines += [SEQUENCE_FIGURE, ""] if sequence is None else []
        lines += ["| pair | wake | table (nm) | needs (s) | got (s) |", "|---|---|---|---|---|"]
        for g in rep.landings:
            lines.append(f"| {g.pair} | {g.wake or '-'} | {'-' if g.wake_nm is None else f'{g.wake_nm:g}'} | "
                         f"{g.needed_s:.2f} | {g.gap_s:.3f} |")
    lines += ["", f"**verified: {str(rep.verified).lower()}**"]
    lines += [f"- {r}" for r in rep.reasons]
    return "\n".join(lines) + "\n"


def write_figures(result: PlanResult | dict | Path, out_dir: Path, figures: str | bool = "all") -> list[Path]:
    """Figures of a plan (a PlanResult, a plan.json document or its path): PNGs and/or plan.html.

    ``figures`` is none, png, html or all (True means png, False none). Everything is drawn from the
    plan.json document, so a saved plan renders the same as a live one.
    """
    from mal_planner.figures import render, want

    kinds = want(figures)
    if not kinds:
        return []
    if isinstance(result, PlanResult):
        result = result_to_dict(result)
    elif not isinstance(result, dict):
        result = json.loads(Path(result).read_text(encoding="utf-8"))
    return render(result, Path(out_dir), kinds)


def _write_text(path: Path, text: str) -> Path:
    """Write atomically (a reader in another process never sees a partial file)."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)
    return path


def write_outputs(result: PlanResult, out_dir: Path, figures: str | bool = "all") -> list[Path]:
    """Write plan.json, report.md, plan.scn (BlueSky; geodetic scenarios), then the figures (see
    :func:`write_figures`) into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    doc = result_to_dict(result)
    written = [jsonio.write(out_dir / "plan.json", doc, indent=1),
               _write_text(out_dir / "report.md", validation_report(result))]
    if result.scenario.geo_frame is not None:  # on the Earth: the plan as a BlueSky scenario too
        from mal_planner.geo.bluesky import scn_lines

        written.append(_write_text(out_dir / "plan.scn", "\n".join(scn_lines(result)) + "\n"))
    return written + write_figures(doc, out_dir, figures)


def start_figures(out_dir: Path, figures: str, running: subprocess.Popen | None = None) -> subprocess.Popen | None:
    """Render the figures of ``out_dir/plan.json`` in a background process; return at once.

    At most one renderer runs: while ``running`` (the previous call's process) is busy, it is left to
    finish, and with ``--follow`` it renders again when plan.json changed meanwhile. Returns the process
    the caller passes back next time.
    """
    if running is not None and running.poll() is None:
        return running
    log_path = Path(out_dir) / "figures.log"
    with open(log_path, "ab") as log_file:
        return subprocess.Popen([sys.executable, "-m", "mal_planner.figures", str(Path(out_dir) / "plan.json"),
                                 "--figures", figures, "--follow", "-q"], stdout=log_file, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, start_new_session=True)
