"""WHAT is in the world: declarative, renderer-free scenarios (pydantic), presets and procedural assets."""
from scenes.loader import (
    load_scenario,
    preset_names,
    scenario_from_dict,
    scenario_to_yaml,
)
from scenes.schema import SCHEMA_VERSION, Scenario

__all__ = ["SCHEMA_VERSION", "Scenario", "load_scenario", "preset_names", "scenario_from_dict", "scenario_to_yaml"]
