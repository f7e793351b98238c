import pytest
import yaml

from scenes import load_scenario, preset_names, scenario_from_dict, scenario_to_yaml
from scenes.errors import UserInputError

REQUIRED_PRESETS = {"clear_day_quad", "dusk_crossover", "low_elevation_haze", "bird_confuser",
                    "fixed_wing_pass", "swarm_3", "out_of_view"}


def _minimal() -> dict:
    return {
        "name": "t", "duration_s": 1.0,
        "targets": [{"name": "d", "kind": "quadcopter", "size_m": 0.4,
                     "trajectory": {"kind": "hover", "center_m": [0, 100, 20]}}],
        "camera_rig": {"look_at_m": [0, 100, 20]},
    }


def test_required_presets_exist_and_validate():
    assert REQUIRED_PRESETS <= set(preset_names())
    for name in preset_names():
        assert load_scenario(name).name == name


def test_yaml_round_trip_is_identity():
    for name in preset_names():
        scenario = load_scenario(name)
        assert scenario_from_dict(yaml.safe_load(scenario_to_yaml(scenario))) == scenario


def test_error_names_the_field_path_and_value():
    data = _minimal()
    data["targets"][0]["size_m"] = -1
    with pytest.raises(UserInputError, match=r"targets\.0\.size_m: .*greater than 0.*got -1"):
        scenario_from_dict(data)


def test_unknown_field_is_rejected_with_its_name():
    data = _minimal()
    data["camera_rig"]["fov"] = 10
    with pytest.raises(UserInputError, match=r"camera_rig\.fov"):
        scenario_from_dict(data)


def test_unknown_trajectory_kind_is_rejected():
    data = _minimal()
    data["targets"][0]["trajectory"] = {"kind": "teleport"}
    with pytest.raises(UserInputError, match=r"targets\.0\.trajectory"):
        scenario_from_dict(data)


def test_track_target_must_name_a_target():
    data = _minimal()
    data["camera_rig"] = {"track_target": "ghost"}
    with pytest.raises(UserInputError, match="ghost"):
        scenario_from_dict(data)


def test_sun_needs_angles_or_time_and_place():
    data = _minimal()
    data["sky"] = {"sun": {"elevation_deg": 10}}
    with pytest.raises(UserInputError, match="sun"):
        scenario_from_dict(data)


def test_unknown_preset_lists_valid_names():
    with pytest.raises(UserInputError, match="clear_day_quad"):
        load_scenario("no_such_preset")
