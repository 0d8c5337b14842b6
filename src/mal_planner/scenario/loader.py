"""Scenario files (YAML): validated on load, converted to the planner's units (nm, s, rad).

The file gives angles in degrees; everything returned by :func:`load_scenario` is in radians. Any
problem is reported as a :class:`ScenarioError` whose message is one line naming the file, the field
and the reason.

A file is local (the default: the runway frame in nm, speeds in nm/s) or places its runway on the Earth
(``runway: {threshold: {lat, lon, elevation_ft}, course_deg}``); then aircraft may be given in lat/lon/ft
with true tracks and speeds in kt. :func:`localize` converts such a file to the local frame (the one place,
through :class:`mal_planner.geo.GeoFrame`) before anything else sees it; airspace, obstacles and gates
stay in the runway frame (nm) in both kinds of file.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pydantic import ValidationError

from mal_planner.dynamics import make_dynamics
from mal_planner.geodesy import GeoFrame
from mal_planner.obstacles import Gate, Superquadric
from mal_planner.performance import UnknownAircraftType, known_type, performance_of
from mal_planner.scenario.model import Aircraft, Scenario, ScenarioError
from mal_planner.scenario.obstacle_schema import WallConfig
from mal_planner.scenario.quantities import field_unit
from mal_planner.scenario.schema import (
    GEODETIC_ROUND_OFF,
    GeoAircraftConfig,
    GeoRunwayConfig,
    RunwayConfig,
    ScenarioConfig,
)
from mal_planner.units import ft_to_nm


def _format_location(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif part in ("superquadric", "wall_with_hole", "local", "geodetic"):
            continue  # pydantic's discriminator tag, not a field of the file
        else:
            out += f".{part}" if out else str(part)
    return out


_BOUNDS = {"greater_than": ("gt", ">"), "greater_than_equal": ("ge", ">="), "less_than": ("lt", "<"),
           "less_than_equal": ("le", "<=")}
"""pydantic's error types of a number outside its range: the constraint's key and its sign."""


def _number(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _error_message(err: Any) -> str:
    """One validation error as one line: a number out of range as ``must be > 0 nm/s, got -0.1``; any other
    error on a field with a unit names the unit and the value given, e.g. ``Input should be a valid number
    (nm/s), got 'fast'``."""
    unit = field_unit(tuple(err["loc"]), ScenarioConfig)
    with_unit = f" {unit}" if unit else ""
    if err["type"] in _BOUNDS and "input" in err:
        key, sign = _BOUNDS[err["type"]]
        return f"must be {sign} {_number(err['ctx'][key])}{with_unit}, got {_number(err['input'])}"
    msg = err["msg"].removeprefix("Value error, ")
    if unit and err["type"] == "value_error":  # our own checks name the values already
        msg += f" ({unit})"
    elif unit and err["type"] != "missing":
        msg += f" ({unit}), got {err['input']!r}"
    return msg


def localize(config: ScenarioConfig) -> tuple[ScenarioConfig, GeoFrame | None]:
    """The config in the local frame and the runway's frame on the Earth (None for a local file).

    The one place where geodetic inputs become local: the runway's threshold is the origin, its landing
    direction the heading -90 deg; aircraft given in lat/lon/ft/kt are converted by :class:`GeoFrame`.
    """
    if not isinstance(config.runway, GeoRunwayConfig):
        return config, None
    frame = config.runway.frame()
    runway = RunwayConfig(position=(0.0, 0.0, 0.0), flight_path_angle_deg=config.runway.flight_path_angle_deg,
                          heading_deg=-90.0)
    airspace = np.array([config.airspace.x, config.airspace.y, config.airspace.z], dtype=float)
    # A position given on the airspace's boundary converts to within the conversion's round-off of it (about
    # 1e-12 of its distance from the threshold): put it back on the boundary, so the file means what it says.
    snap = GEODETIC_ROUND_OFF * float(np.max(airspace[:, 1] - airspace[:, 0]))
    aircraft = []
    for ac in config.aircraft:
        if isinstance(ac, GeoAircraftConfig):
            ac = ac.to_local(frame)
            p = np.array(ac.position)
            near = (np.abs(p - airspace[:, 0]) <= snap) | (np.abs(p - airspace[:, 1]) <= snap)
            p[near] = np.clip(p, airspace[:, 0], airspace[:, 1])[near]
            ac = ac.model_copy(update={"position": tuple(float(v) for v in p)})
        aircraft.append(ac)
    return config.model_copy(update={"runway": runway, "aircraft": aircraft}), frame


def _obstacles_and_gates(config: ScenarioConfig) -> tuple[list[Superquadric], list[Gate]]:
    """The obstacles (a wall expanded into its pieces) and the gates (a wall's hole among them)."""
    obstacles: list[Superquadric] = []
    gates = [g.to_gate() for g in config.gates]
    for spec in config.obstacles:
        if isinstance(spec, WallConfig):
            pieces, gate = spec.expand()
            obstacles.extend(pieces)
            gates.append(gate.to_gate())
        else:
            obstacles.append(Superquadric(spec.name, spec.center, spec.semi_axes, spec.p))
    return obstacles, gates


def build_scenario(config: ScenarioConfig, source: str = "<scenario>") -> Scenario:
    """Convert a validated config to planner units and check the geometry (raises ScenarioError)."""
    given = config
    config, frame = localize(config)
    obstacles, gates = _obstacles_and_gates(config)
    airspace = np.array([config.airspace.x, config.airspace.y, config.airspace.z], dtype=float)
    wind = (0.0, 0.0) if config.wind is None else config.wind.velocity(frame)
    aircraft = []
    for i, ac in enumerate(config.aircraft):
        dyn = make_dynamics(ac.model, ac.speed, gravity=config.gravity, wind_x=wind[0], wind_y=wind[1])
        state0 = dyn.initial_state(ac.position, np.radians(ac.flight_path_angle_deg), np.radians(ac.heading_deg))
        if math.hypot(*wind) >= ac.speed * math.cos(state0[3]):
            raise ScenarioError(source, "wind.speed_kt", f"{config.wind.speed_kt:g} kt is not below aircraft[{i}] "
                                f"{ac.callsign}'s airspeed: it could not make way against it")
        limits = ac.limits.to_limits() if ac.limits else (
            config.limits.to_limits() if "limits" in config.model_fields_set else dyn.default_limits)
        type_code = _known_type(ac.aircraft_type, source, f"aircraft[{i}].aircraft_type")
        if dyn.variable_airspeed:  # the airspeed model: its thrust and drag from the type's performance
            thrust = performance_of(type_code or (config.procedures.aircraft_type if config.procedures else None))
            limits = replace(limits, n_x=(thrust.longitudinal.low, thrust.longitudinal.high))
        aircraft.append(Aircraft(ac.callsign, state0, dyn, limits, ac.wake_category, ac.landing_time,
                                 ac.target_time, ac.latest_time, ac.cost_early, ac.cost_late, type_code))
        where, what = f"aircraft[{i}].position", str(list(ac.position))
        if isinstance(geo := given.aircraft[i], GeoAircraftConfig):
            where = f"aircraft[{i}].lat/lon/alt_ft"
            what = (f"lat {geo.lat}, lon {geo.lon}, alt {geo.alt_ft} ft (local "
                    f"{[round(float(v), 3) for v in state0[:3]]} nm)")
        if not np.all((state0[:3] >= airspace[:, 0]) & (state0[:3] <= airspace[:, 1])):
            raise ScenarioError(source, where, f"{what} is outside the airspace")
        for ob in obstacles:
            if ob.contains(state0[:3]):
                raise ScenarioError(source, where, f"{what} is inside obstacle {ob.name!r}")
    runway = np.array([*config.runway.position, np.radians(config.runway.flight_path_angle_deg),
                       np.radians(config.runway.heading_deg)])
    if not np.all((runway[:3] >= airspace[:, 0]) & (runway[:3] <= airspace[:, 1])):
        raise ScenarioError(source, "runway.position", "is outside the airspace")
    return Scenario(
        name=config.name,
        description=config.description,
        aircraft=tuple(aircraft),
        runway_state=runway,
        airspace=airspace,
        obstacles=tuple(obstacles),
        gates=tuple(gates),
        separation_nm=config.separation.distance_nm,
        vertical_separation_nm=None if (ft := config.separation.vertical_ft) is None else ft_to_nm(ft),
        landing_spacing_s=config.separation.landing_spacing_s,
        max_landing_spacing_s=config.separation.max_landing_spacing_s,
        wake=config.separation.wake,
        sequencing=config.sequencing.options(),
        gravity=config.gravity,
        config=config,
        source=source,
        geo_frame=frame,
        wind=wind,
        procedures=None if config.procedures is None else replace(
            config.procedures.to_procedures(),
            default_type=_known_type(config.procedures.aircraft_type, source, "procedures.aircraft_type")),
    )


def _known_type(type_code: str | None, source: str, where: str) -> str | None:
    """``type_code`` in capitals, checked against OpenAP (its first use imports OpenAP: seconds)."""
    if type_code is None:
        return None
    try:
        return known_type(type_code)
    except UnknownAircraftType as exc:
        raise ScenarioError(source, where, str(exc).split(" (known:")[0]) from None


def parse_scenario(data: Any, source: str = "<scenario>") -> Scenario:
    """Validate an already-parsed mapping (e.g. from YAML) and build the scenario."""
    if not isinstance(data, dict):
        raise ScenarioError(source, "", "the top level must be a mapping")
    try:
        config = ScenarioConfig.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        raise ScenarioError(source, _format_location(err["loc"]), _error_message(err)) from None
    return build_scenario(config, source)


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario YAML file."""
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(source, "", f"cannot read file ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise ScenarioError(source, "", f"not a text (UTF-8) file: byte {exc.start} is 0x{exc.object[exc.start]:02x}"
                            ) from None
    return scenario_from_text(text, source)


def scenario_from_text(text: str, source: str = "<scenario>") -> Scenario:
    """Validate a scenario file's text (``source`` names it in errors), as :func:`load_scenario` does."""
    if "\x00" in text:
        raise ScenarioError(source, "", "not a text file (it contains NUL bytes)")
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark is not None else ""
        raise ScenarioError(source, where, f"invalid YAML ({getattr(exc, 'problem', None) or exc})") from None
    return parse_scenario(data, source)
