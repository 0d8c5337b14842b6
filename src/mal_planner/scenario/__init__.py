"""Scenario files (YAML) and the scenario in planner units: the one definition of a planning problem.

:mod:`.schema` validates a file (every field, its unit and range), :mod:`.loader` converts it to planner units (nm,
s, rad; a geodetic file through :class:`~mal_planner.geodesy.GeoFrame`), :mod:`.model` holds the result.
"""

from mal_planner.scenario.loader import build_scenario, load_scenario, localize, parse_scenario, scenario_from_text
from mal_planner.scenario.model import Aircraft, Scenario, ScenarioError
from mal_planner.scenario.schema import GeoAircraftConfig, ScenarioConfig
from mal_planner.scenario.sequencing import OBJECTIVES, STRATEGIES, SequencingOptions

__all__ = ["OBJECTIVES", "STRATEGIES", "Aircraft", "GeoAircraftConfig", "Scenario", "ScenarioConfig", "ScenarioError",
           "SequencingOptions", "build_scenario", "load_scenario", "localize", "parse_scenario", "scenario_from_text"]
