"""Export a plan as a BlueSky scenario (``.scn``): each aircraft created at its initial state, then flown along
waypoints of the plan by BlueSky's own autopilot (LNAV/VNAV), its bank limit raised to the plan's, deleted at
landing.

A ``.scn`` file is lines ``HH:MM:SS.ss>COMMAND args``. BlueSky turns at 25 deg of bank by default, so each
aircraft gets ``BANK`` at its plan's limit. Conflict detection is switched on first (``ASAS ON``), then the
protected zone is set (``ZONER`` in nm, ``ZONEDH`` in ft, half the zone's height): the other order resets the
zone. A thesis-style sphere of radius d has no cylinder of its own; the export uses the smallest cylinder
holding it (radius d, half-height d), so BlueSky counts every loss the plan could have, and some it has not.

BlueSky's speeds are calibrated airspeeds (CAS); the plan's constant true airspeed becomes the CAS of the
International Standard Atmosphere at each waypoint's altitude (OpenAP's atmosphere, :mod:`mal_planner.performance`;
BlueSky's is the same model, its speeds agree to 1e-4).
"""

from __future__ import annotations

import contextlib
import io
import math
import os
from pathlib import Path

import numpy as np

from mal_planner.geodesy import GeoFrame
from mal_planner.performance import DEFAULT_TYPE, cas_of_tas, tas_of_cas, tas_of_mach
from mal_planner.scales import Scales
from mal_planner.units import METRES_PER_NM, ft_to_nm, kt_to_nm_per_s, m_to_ft, nm_per_s_to_kt

WAYPOINTS_PER_RADIAN = 4.0
"""Waypoints per turn time (the time to turn one radian at the bank limit): BlueSky flies straight legs between
them and turns at each with its own anticipation, so the legs stay short against the turn radius (thesis: one
waypoint every 1.9 s, 0.075 nm)."""


def tas_to_cas_kt(tas_kt: float, altitude_ft: float) -> float:
    """True to calibrated airspeed (knots) at a pressure altitude (ft), in OpenAP's ISA, which is BlueSky's."""
    return float(nm_per_s_to_kt(cas_of_tas(kt_to_nm_per_s(tas_kt), ft_to_nm(altitude_ft))))


def cas_to_tas_kt(cas_kt: float, altitude_ft: float) -> float:
    """Calibrated to true airspeed (knots): the inverse of :func:`tas_to_cas_kt`."""
    return float(nm_per_s_to_kt(tas_of_cas(kt_to_nm_per_s(cas_kt), ft_to_nm(altitude_ft))))


def mach_to_tas_kt(mach: float, altitude_ft: float) -> float:
    """Mach number to true airspeed (knots) at a pressure altitude (ft)."""
    return float(nm_per_s_to_kt(tas_of_mach(mach, ft_to_nm(altitude_ft))))


def wind_command(frame: GeoFrame, wind: tuple[float, float]) -> str | None:
    """BlueSky's ``WIND`` for a constant local wind (w_x, w_y) nm/s at the threshold (one point: BlueSky blows it
    everywhere): from which true direction, kt; None if calm."""
    speed = math.hypot(*wind)
    if speed == 0.0:
        return None
    towards, _ = frame.direction_to_geodetic([0.0, 0.0, 0.0], math.atan2(wind[1], wind[0]), 0.0)
    return f"WIND {frame.lat_deg:.8f} {frame.lon_deg:.8f} {(towards + 180.0) % 360.0:.4f} {nm_per_s_to_kt(speed):.4f}"


def _clock(t: float) -> str:
    hours, rest = divmod(max(t, 0.0), 3600.0)
    minutes, seconds = divmod(rest, 60.0)
    return f"{int(hours):02d}:{int(minutes):02d}:{seconds:05.2f}"


def detection_commands(scenario) -> list[str]:
    """Conflict detection on, then the protected zone: the scenario's minima as BlueSky's cylinder (``ZONER`` nm,
    ``ZONEDH`` ft, half its height; a sphere of radius d becomes the cylinder holding it)."""
    vertical_ft = m_to_ft((scenario.vertical_separation_nm or scenario.separation_nm) * METRES_PER_NM)
    return ["ASAS ON", f"ZONER {scenario.separation_nm:.6g}", f"ZONEDH {vertical_ft:.6g}"]


def create_commands(callsign: str, frame: GeoFrame, state: np.ndarray, tas_kt: float, bank_angle_max: float,
                    aircraft_type: str = DEFAULT_TYPE) -> list[str]:
    """``CRE`` an aircraft at a local state [x, y, z, gamma, heading] (its heading made true at its position, its
    true airspeed made CAS) and ``BANK`` it at the plan's limit (rad)."""
    lat, lon, alt = frame.to_geodetic(state[:3])
    track, _ = frame.direction_to_geodetic(state[:3], state[4], state[3])
    return [f"CRE {callsign},{aircraft_type},{float(lat):.8f},{float(lon):.8f},{track:.4f},{float(alt):.2f},"
            f"{tas_to_cas_kt(tas_kt, float(alt)):.3f}",
            f"BANK {callsign} {math.degrees(bank_angle_max):.4f}"]


def route_commands(callsign: str, frame: GeoFrame, t: np.ndarray, states: np.ndarray, tas_kt: float, dt: float,
                   after: float | None = None) -> list[str]:
    """``ADDWPT`` one sample of a plan (times ``t``, local states) every ``dt`` seconds after ``after`` (default:
    its start) and its last one, at the true airspeed as CAS (an airspeed-model plan's own airspeed there), then
    ``LNAV``/``VNAV ON``."""
    if not dt > 0.0:
        raise ValueError(f"waypoint_dt_s must be > 0, got {dt}")
    start = float(t[0]) if after is None else max(float(after), float(t[0]))
    marks = np.arange(start + dt, float(t[-1]), dt)
    picks = sorted({int(np.argmin(np.abs(t - m))) for m in marks} | {len(t) - 1})
    lat, lon, alt = frame.to_geodetic(states[picks, :3])
    speeds = nm_per_s_to_kt(states[picks, 5]) if states.shape[1] > 5 else np.full(len(picks), tas_kt)
    lines = [f"ADDWPT {callsign} {la:.8f} {lo:.8f} {al:.2f} {tas_to_cas_kt(float(v), al):.3f}"
             for la, lo, al, v in zip(lat.tolist(), lon.tolist(), alt.tolist(), speeds.tolist(), strict=True)]
    return lines + [f"LNAV {callsign} ON", f"VNAV {callsign} ON"]


def waypoint_interval_s(scenario) -> float:
    """The default time between waypoints: the turn time / :data:`WAYPOINTS_PER_RADIAN`."""
    return Scales.of(scenario).time_s / WAYPOINTS_PER_RADIAN


def scn_lines(result, frame: GeoFrame | None = None, aircraft_type: str | None = None,
              waypoint_dt_s: float | None = None) -> list[str]:
    """The ``.scn`` lines of a plan (a :class:`~mal_planner.pipeline.PlanResult`).

    ``frame`` places a local scenario on the Earth (default: the scenario's own, required when it has none);
    ``aircraft_type`` is BlueSky's type of every aircraft (default: each one's type in the scenario, else
    :data:`~mal_planner.performance.DEFAULT_TYPE`);
    ``waypoint_dt_s`` is the time between waypoints (default: :func:`waypoint_interval_s`).
    """
    scenario = result.scenario
    frame = frame or scenario.geo_frame
    if frame is None:
        raise ValueError(f"{scenario.source}: the scenario is local: give a frame (runway threshold and course) "
                         "to place it on the Earth")
    dt = waypoint_dt_s or waypoint_interval_s(scenario)
    if not dt > 0.0:
        raise ValueError(f"waypoint_dt_s must be > 0, got {waypoint_dt_s}")
    at0 = "00:00:00.00>"
    lines = [f"# mal-planner plan of {scenario.name} ({scenario.source}); frame origin {frame.lat_deg:.8f} "
             f"{frame.lon_deg:.8f} at {frame.elevation_ft:.1f} ft, runway course {frame.course_deg} deg true"]
    lines += [at0 + c for c in detection_commands(scenario)]
    wind = wind_command(frame, scenario.wind)
    lines += [at0 + wind] if wind else []
    landing = result.landing_times()
    deletions = []
    for tr in result.trajectories():
        ac = scenario.aircraft_by_callsign(tr.callsign)
        tas_kt = nm_per_s_to_kt(ac.speed)
        commands = create_commands(tr.callsign, frame, tr.states[0], tas_kt, ac.limits.bank_angle_max,
                                   aircraft_type or scenario.type_of(ac) or DEFAULT_TYPE)
        commands += route_commands(tr.callsign, frame, tr.t, tr.states, tas_kt, dt)
        lines += [at0 + c for c in commands]
        deletions.append((float(landing.get(tr.callsign, tr.t[-1])), tr.callsign))
    lines += [f"{_clock(t)}>DEL {callsign}" for t, callsign in sorted(deletions)]
    return lines


def write_scn(result, path: str | Path, frame: GeoFrame | None = None, **options) -> Path:
    """Write the plan's ``.scn`` file (see :func:`scn_lines`); return its path."""
    path = Path(path)
    path.write_text("\n".join(scn_lines(result, frame, **options)) + "\n", encoding="utf-8")
    return path


_started: Path | None = None
"""BlueSky's working directory once it has been initialised in this process (it keeps global state)."""


def default_workdir() -> Path:
    """Where BlueSky keeps its settings, navigation cache and logs by default: the user's cache folder (its
    navigation data are parsed once, about 7-25 s, then read from the cache in 0.2 s)."""
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "mal-planner" / "bluesky"


def start_bluesky(workdir: str | Path | None = None):
    """BlueSky, headless, ready for a new scenario; returns the ``bluesky`` module (needs bluesky-simulator).

    The first call in a process initialises it in ``workdir`` (default: :func:`default_workdir`) with its
    compiled modules off (1.1.1's compiled conflict detection is wrong); later calls reset it (traffic, clock,
    stack, wind: 0.1 s) and ignore ``workdir``: BlueSky keeps global state, one simulation per process.
    """
    global _started
    import importlib.resources

    import bluesky

    if _started is not None:
        with contextlib.redirect_stdout(io.StringIO()):  # "Loading global navigation database..."
            bluesky.sim.reset()
        return bluesky
    workdir = Path(workdir) if workdir is not None else default_workdir()
    workdir.mkdir(parents=True, exist_ok=True)
    default = importlib.resources.files("bluesky").joinpath("resources", "default.cfg").read_text()
    (workdir / "settings.cfg").write_text(default.replace("prefer_compiled = True", "prefer_compiled = False"))
    with contextlib.redirect_stdout(io.StringIO()):  # its loading messages
        bluesky.init(mode="sim", detached=True, workdir=str(workdir))
    if getattr(bluesky.settings, "prefer_compiled", False):
        raise RuntimeError("BlueSky kept prefer_compiled = True")
    _started = workdir
    return bluesky


def run_commands(bluesky, commands: list[str]) -> None:
    """Process stack commands now (before the next step); RuntimeError with BlueSky's messages if any fails."""
    errors: list[str] = []
    net = bluesky.net

    def capture(topic, data="", to_group=b"") -> None:  # a detached BlueSky drops its echoes: catch the errors
        if topic == "ECHO" and isinstance(data, dict) and data.get("flags"):
            errors.append(str(data.get("text", "")))

    net.send = capture
    try:
        bluesky.stack.process(";".join(commands))
    finally:
        del net.send  # the class's own again
    if errors:
        raise RuntimeError("BlueSky refused: " + " | ".join(" ".join(e.split()) for e in errors))


def replay(scn: str | Path, until_s: float, workdir: str | Path) -> tuple[dict[str, np.ndarray], list[tuple[str, str]]]:
    """Fly a ``.scn`` file in BlueSky, headless, for ``until_s`` simulated seconds (needs bluesky-simulator).

    Returns each aircraft's flown samples, rows (t_s, lat_deg, lon_deg, alt_ft), one per simulation step, and
    BlueSky's own losses of separation (pairs of callsigns). ``workdir`` gets BlueSky's settings (with its
    compiled geodesy off: 1.1.1's compiled conflict detection is wrong), navigation cache and logs, the first
    time in a process (see :func:`start_bluesky`).
    """
    bluesky = start_bluesky(workdir)
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
