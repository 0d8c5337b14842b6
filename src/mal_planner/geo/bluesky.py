"""Export a plan as a BlueSky scenario (``.scn``): each aircraft created at its initial state, then flown along
waypoints of the plan by BlueSky's own autopilot (LNAV/VNAV), its bank limit raised to the plan's, deleted at
landing.

A ``.scn`` file is lines ``HH:MM:SS.ss>COMMAND args``. BlueSky turns at 25 deg of bank by default, so each
aircraft gets ``BANK`` at its plan's limit. Conflict detection is switched on first (``ASAS ON``), then the
protected zone is set (``ZONER`` in nm, ``ZONEDH`` in ft, half the zone's height): the other order resets the
zone. A thesis-style sphere of radius d has no cylinder of its own; the export uses the smallest cylinder
holding it (radius d, half-height d), so BlueSky counts every loss the plan could have, and some it has not.

BlueSky's speeds are calibrated airspeeds (CAS); the plan's constant true airspeed becomes the CAS of the
International Standard Atmosphere at each waypoint's altitude (BlueSky's own atmosphere, troposphere only).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from mal_planner.geo.frame import GeoFrame
from mal_planner.scales import Scales
from mal_planner.units import METRES_PER_NM, ft_to_m, m_to_ft, nm_per_s_to_kt

# The International Standard Atmosphere below the tropopause (ICAO Doc 7488), as BlueSky's tools.aero uses it.
ISA_P0, ISA_RHO0, ISA_T0 = 101325.0, 1.225, 288.15
"""Sea-level pressure (Pa), density (kg/m^3), temperature (K)."""
ISA_LAPSE, ISA_R, ISA_G0 = -0.0065, 287.05287, 9.80665
"""Temperature gradient (K/m), gas constant of air (J/(kg K)), gravity (m/s^2)."""
TROPOPAUSE_M = 11000.0

WAYPOINTS_PER_RADIAN = 4.0
"""Waypoints per turn time (the time to turn one radian at the bank limit): BlueSky flies straight legs between
them and turns at each with its own anticipation, so the legs stay short against the turn radius (thesis: one
waypoint every 1.9 s, 0.075 nm)."""


def tas_to_cas_kt(tas_kt: float, altitude_ft: float) -> float:
    """True to calibrated airspeed (knots) in the ISA troposphere (compressible flow, as BlueSky's tas2cas)."""
    h = ft_to_m(altitude_ft)
    if h >= TROPOPAUSE_M:
        raise ValueError(f"altitude {altitude_ft:.0f} ft is above the tropopause (the export's atmosphere ends there)")
    temperature = ISA_T0 + ISA_LAPSE * h
    pressure = ISA_P0 * (temperature / ISA_T0) ** (-ISA_G0 / (ISA_LAPSE * ISA_R))
    density = pressure / (ISA_R * temperature)
    tas = tas_kt * METRES_PER_NM / 3600.0
    impact = pressure * ((1.0 + density * tas * tas / (7.0 * pressure)) ** 3.5 - 1.0)
    cas = math.sqrt(7.0 * ISA_P0 / ISA_RHO0 * ((impact / ISA_P0 + 1.0) ** (2.0 / 7.0) - 1.0))
    return cas * 3600.0 / METRES_PER_NM


def _clock(t: float) -> str:
    hours, rest = divmod(max(t, 0.0), 3600.0)
    minutes, seconds = divmod(rest, 60.0)
    return f"{int(hours):02d}:{int(minutes):02d}:{seconds:05.2f}"


def scn_lines(result, frame: GeoFrame | None = None, aircraft_type: str = "A320",
              waypoint_dt_s: float | None = None) -> list[str]:
    """The ``.scn`` lines of a plan (a :class:`~mal_planner.pipeline.PlanResult`).

    ``frame`` places a local scenario on the Earth (default: the scenario's own, required when it has none);
    ``waypoint_dt_s`` is the time between waypoints (default: the turn time / :data:`WAYPOINTS_PER_RADIAN`).
    """
    scenario = result.scenario
    frame = frame or scenario.geo_frame
    if frame is None:
        raise ValueError(f"{scenario.source}: the scenario is local: give a frame (runway threshold and course) "
                         "to place it on the Earth")
    dt = waypoint_dt_s or Scales.of(scenario).time_s / WAYPOINTS_PER_RADIAN
    if not dt > 0.0:
        raise ValueError(f"waypoint_dt_s must be > 0, got {waypoint_dt_s}")
    vertical_ft = m_to_ft((scenario.vertical_separation_nm or scenario.separation_nm) * METRES_PER_NM)
    lines = [f"# mal-planner plan of {scenario.name} ({scenario.source}); frame origin {frame.lat_deg:.8f} "
             f"{frame.lon_deg:.8f} at {frame.elevation_ft:.1f} ft, runway course {frame.course_deg} deg true",
             "00:00:00.00>ASAS ON",
             f"00:00:00.00>ZONER {scenario.separation_nm:.6g}",
             f"00:00:00.00>ZONEDH {vertical_ft:.6g}"]
    landing = result.landing_times()
    deletions = []
    for tr in result.trajectories():
        ac = scenario.aircraft_by_callsign(tr.callsign)
        tas_kt = nm_per_s_to_kt(ac.speed)
        lat, lon, alt = frame.to_geodetic(tr.states[:, :3])
        track, _ = frame.direction_to_geodetic(tr.states[0, :3], tr.states[0, 4], tr.states[0, 3])
        t0, t_end = float(tr.t[0]), float(tr.t[-1])
        lines.append(f"00:00:00.00>CRE {tr.callsign},{aircraft_type},{lat[0]:.8f},{lon[0]:.8f},{track:.4f},"
                     f"{alt[0]:.2f},{tas_to_cas_kt(tas_kt, alt[0]):.3f}")
        lines.append(f"00:00:00.00>BANK {tr.callsign} {math.degrees(ac.limits.bank_angle_max):.4f}")
        marks = np.arange(t0 + dt, t_end, dt)
        picks = sorted({int(np.argmin(np.abs(tr.t - m))) for m in marks} | {len(tr.t) - 1})
        for k in picks:
            lines.append(f"00:00:00.00>ADDWPT {tr.callsign} {lat[k]:.8f} {lon[k]:.8f} {alt[k]:.2f} "
                         f"{tas_to_cas_kt(tas_kt, alt[k]):.3f}")
        lines += [f"00:00:00.00>LNAV {tr.callsign} ON", f"00:00:00.00>VNAV {tr.callsign} ON"]
        deletions.append((float(landing.get(tr.callsign, t_end)), tr.callsign))
    lines += [f"{_clock(t)}>DEL {callsign}" for t, callsign in sorted(deletions)]
    return lines


def write_scn(result, path: str | Path, frame: GeoFrame | None = None, **options) -> Path:
    """Write the plan's ``.scn`` file (see :func:`scn_lines`); return its path."""
    path = Path(path)
    path.write_text("\n".join(scn_lines(result, frame, **options)) + "\n", encoding="utf-8")
    return path


def replay(scn: str | Path, until_s: float, workdir: str | Path) -> tuple[dict[str, np.ndarray], list[tuple[str, str]]]:
    """Fly a ``.scn`` file in BlueSky, headless, for ``until_s`` simulated seconds (needs bluesky-simulator).

    Returns each aircraft's flown samples, rows (t_s, lat_deg, lon_deg, alt_ft), one per simulation step, and
    BlueSky's own losses of separation (pairs of callsigns). ``workdir`` gets BlueSky's settings (with its
    compiled geodesy off: 1.1.1's compiled conflict detection is wrong), navigation cache and logs. BlueSky
    keeps global state: call this once per process.
    """
    import importlib.resources

    import bluesky

    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    default = importlib.resources.files("bluesky").joinpath("resources", "default.cfg").read_text()
    (workdir / "settings.cfg").write_text(default.replace("prefer_compiled = True", "prefer_compiled = False"))
    bluesky.init(mode="sim", detached=True, workdir=str(workdir))
    if getattr(bluesky.settings, "prefer_compiled", False):
        raise RuntimeError("BlueSky kept prefer_compiled = True")
    bluesky.stack.stack(f"IC {Path(scn).resolve()}")
    flown: dict[str, list[tuple[float, float, float, float]]] = {}
    traf, sim = bluesky.traf, bluesky.sim
    while sim.simt < until_s:
        sim.step()
        for k, acid in enumerate(traf.id):
            flown.setdefault(acid, []).append((float(sim.simt), float(traf.lat[k]), float(traf.lon[k]),
                                               float(m_to_ft(traf.alt[k]))))
    pairs = sorted(tuple(sorted(p)) for p in traf.cd.lospairs_all)
    return {acid: np.array(rows) for acid, rows in flown.items()}, pairs
