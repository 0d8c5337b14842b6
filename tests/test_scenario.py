"""Scenario files: every bundled file loads; each kind of invalid file gives its one-line error."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

from mal_planner.scenario import ScenarioError, load_scenario, parse_scenario

SCENARIOS = sorted(Path("scenarios").glob("*.yaml"))


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_bundled_scenarios_load(path: Path) -> None:
    sc = load_scenario(path)
    assert sc.aircraft and sc.name == path.stem


def test_bundled_set_covers_the_issue() -> None:
    names = {p.stem for p in SCENARIOS}
    assert {"thesis", "five_aircraft", "no_fly_zones"} <= names
    assert len(load_scenario("scenarios/five_aircraft.yaml").aircraft) == 5
    nfz = load_scenario("scenarios/no_fly_zones.yaml")
    assert not nfz.gates and {ob.p for ob in nfz.obstacles} == {2, 50}


def _base() -> dict:
    return yaml.safe_load(Path("scenarios/thesis.yaml").read_text())


def _mutate(edit) -> dict:
    data = copy.deepcopy(_base())
    edit(data)
    return data


CASES = [
    ("missing-airspace", lambda d: d.pop("airspace"), "airspace", "Field required"),
    ("negative-speed", lambda d: d["aircraft"][1].update(speed=-0.04), "aircraft[1].speed",
     "must be > 0 nm/s, got -0.04"),
    ("odd-p", lambda d: d["obstacles"][0].update(p=7), "obstacles[0].p", "even integer"),
    ("zero-semi-axis", lambda d: d["obstacles"][2].update(semi_axes=[1, 0, 1]), "obstacles[2].semi_axes", "> 0"),
    ("bad-interval", lambda d: d["airspace"].update(x=[3, -3]), "airspace.x", "below upper bound"),
    ("unknown-model", lambda d: d["aircraft"][0].update(model="blimp"), "aircraft[0].model", "unknown dynamics"),
    ("duplicate-callsign", lambda d: d["aircraft"][2].update(callsign="A1"), "aircraft[2].callsign", "duplicate"),
    ("unknown-field", lambda d: d["aircraft"][0].update(colour="red"), "aircraft[0].colour", "Extra inputs"),
    ("outside-airspace", lambda d: d["aircraft"][0].update(position=[9, 5, 0.2]), "aircraft[0].position", "outside"),
    ("inside-obstacle", lambda d: d["aircraft"][0].update(position=[-2, 3.0005, 0.15]), "aircraft[0].position",
     "inside obstacle"),
    ("bank-limit", lambda d: d["limits"].update(bank_angle_deg=95), "limits.bank_angle_deg",
     "must be < 90 deg, got 95"),
    ("negative-nv", lambda d: d["limits"].update(n_v=[-1, 2]), "limits.n_v", ">= 0"),
    ("gate-axes", lambda d: d["gates"][0].update(bounds={"x": [-1, 1]}), "gates[0]", "exactly the axes"),
    ("no-aircraft", lambda d: d.update(aircraft=[]), "aircraft", "at least 1"),
    ("spacing-order", lambda d: d["separation"].update(max_landing_spacing_s=5), "separation", "must exceed"),
    ("wrong-type", lambda d: d["aircraft"][0].update(position="north"), "aircraft[0].position",
     "valid tuple (nm), got 'north'"),
    ("wall-hole", lambda d: d["obstacles"].append({"type": "wall_with_hole", "position": 2.0, "thickness": 0.01,
                                                   "span": {"x": [-3, 3], "z": [0, 0.3]},
                                                   "hole": {"x": [-1, 1], "z": [0.1, 0.5]}}),
     "obstacles[4]", "strictly inside"),
]


@pytest.mark.parametrize(("name", "edit", "field", "reason"), CASES, ids=[c[0] for c in CASES])
def test_invalid_scenarios_give_one_line_errors(name, edit, field, reason) -> None:
    with pytest.raises(ScenarioError) as info:
        parse_scenario(_mutate(edit), source=f"{name}.yaml")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{name}.yaml: {field}"), message
    assert reason in message, message


def test_file_level_errors(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match=r"missing\.yaml: cannot read file"):
        load_scenario(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\naircraft: [\n")
    with pytest.raises(ScenarioError, match=r"bad\.yaml: line \d+: invalid YAML"):
        load_scenario(bad)
    scalar = tmp_path / "scalar.yaml"
    scalar.write_text("42\n")
    with pytest.raises(ScenarioError, match="top level must be a mapping"):
        load_scenario(scalar)


GEODETIC = Path("scenarios/thesis_geodetic.yaml")
UNIT_CASES = [
    ("speed", _base, lambda d: d["aircraft"][0].update(speed=-0.1), "aircraft[0].speed: must be > 0 nm/s, got -0.1"),
    ("speed-too-fast", _base, lambda d: d["aircraft"][2].update(speed=1.5),
     "aircraft[2].speed: must be <= 1 nm/s, got 1.5"),
    ("alt-ft", lambda: yaml.safe_load(GEODETIC.read_text()), lambda d: d["aircraft"][1].update(alt_ft=70000),
     "aircraft[1].alt_ft: must be <= 60000 ft, got 70000"),
    ("heading", _base, lambda d: d["aircraft"][0].update(heading_deg=-400.5),
     "aircraft[0].heading_deg: must be >= -360 deg, got -400.5"),
    ("not-a-number", _base, lambda d: d["aircraft"][0].update(speed="fast"),
     "aircraft[0].speed: Input should be a valid number, unable to parse string as a number (nm/s), got 'fast'"),
    ("separation-ft", _base, lambda d: d["separation"].update(vertical_ft=0), "separation.vertical_ft: must be > 0 ft, "
                                                                              "got 0"),
    ("no-unit", _base, lambda d: d.update(sequencing={"max_shift": -2}), "sequencing.max_shift: must be >= 0, got -2"),
]


@pytest.mark.parametrize(("name", "load", "edit", "message"), UNIT_CASES, ids=[c[0] for c in UNIT_CASES])
def test_errors_name_the_fields_unit_and_the_value_given(name, load, edit, message) -> None:
    """The unit is declared once per field (quantities.quantity); the loader's one formatter writes it into the
    line."""
    data = load()
    edit(data)
    with pytest.raises(ScenarioError) as info:
        parse_scenario(data, source=f"{name}.yaml")
    assert str(info.value) == f"{name}.yaml: {message}"


def test_units_are_declared_on_the_fields() -> None:
    from mal_planner.scenario.quantities import field_unit
    from mal_planner.scenario.schema import ScenarioConfig

    assert field_unit(("aircraft", 0, "local", "speed"), ScenarioConfig) == "nm/s"
    assert field_unit(("aircraft", 3, "geodetic", "speed_kt"), ScenarioConfig) == "kt"
    assert field_unit(("runway", "geodetic", "threshold", "elevation_ft"), ScenarioConfig) == "ft"
    assert field_unit(("obstacles", 1, "wall_with_hole", "hole", "x", 0), ScenarioConfig) == "nm"
    assert field_unit(("aircraft", 0, "local", "callsign"), ScenarioConfig) is None
