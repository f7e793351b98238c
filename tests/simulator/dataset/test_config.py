"""Generation configs: field-named validation errors, split determinism, seeded randomisation."""
import math

import pytest

from scenes.errors import UserInputError
from scenes.loader import validate_mapping
from simulator.dataset.config import (
    GenerationConfig,
    Splits,
    load_generation_config,
    randomised_scenario,
    sequence_seed,
    split_assignment,
)

BASE = {"name": "t", "mixture": [{"scenario": "clear_day_quad"}]}


def _bad(update, field):
    with pytest.raises(UserInputError) as info:
        load_generation_config({**BASE, **update})
    assert field in str(info.value), str(info.value)
    return str(info.value)


def test_config_errors_name_the_field():
    _bad({"sequences": 0}, "sequences")
    _bad({"randomise": {"range_m": [400, 80]}}, "randomise.range_m")
    _bad({"randomise": {"range_m": [0, 80]}}, "randomise")
    _bad({"randomise": {"target_kinds": ["blimp"]}}, "randomise.target_kinds.0")
    _bad({"splits": {"train": 0.9, "val": 0.2, "test": 0.1}}, "splits")
    _bad({"mixture": [{"scenario": "clear_day_quad", "weight": -1}]}, "mixture.0.weight")
    _bad({"image_size": [8, 8]}, "image_size.0")
    msg = _bad({"colour": "red"}, "colour")
    assert "Extra inputs" in msg


def test_unknown_scenario_in_mixture_is_a_user_error():
    config = load_generation_config({**BASE, "mixture": [{"scenario": "no_such_preset"}]})
    with pytest.raises(UserInputError, match="no_such_preset"):
        randomised_scenario(config, 0, 0)


def test_scene_preset_name_gets_default_randomisation_and_trident_config_gets_a_hint():
    config = load_generation_config("dusk_crossover")
    assert [m.scenario for m in config.mixture] == ["dusk_crossover"]
    assert config.randomise.air_temperature_k is not None and config.randomise.range_m is None
    assert load_generation_config("mixed_small").sequences == 50
    with pytest.raises(UserInputError, match="--format trident"):
        load_generation_config("trident_mini")


def test_split_counts_are_exact_and_deterministic():
    splits = Splits(train=0.7, val=0.15, test=0.15, seed=3)
    a = split_assignment(splits, 50)
    assert a == split_assignment(splits, 50)
    assert (a.count("train"), a.count("val"), a.count("test")) == (35, 8, 7)
    assert a != split_assignment(Splits(train=0.7, val=0.15, test=0.15, seed=4), 50)
    assert a[:10] != ["train"] * 10 or a[10:20] != ["train"] * 10  # shuffled, not blocks
    assert split_assignment(Splits(train=1.0, val=0.0, test=0.0), 3) == ["train"] * 3


def test_randomised_scenario_is_seeded_and_respects_ranges():
    config = validate_mapping(GenerationConfig, {**BASE, "randomise": {
        "range_m": [100, 120], "trajectory_kinds": ["hover"], "air_temperature_k": [280, 281],
        "sun_elevation_deg": [20, 21], "distractors": [2, 2], "target_kinds": ["hexacopter"]},
        "frames": 5, "image_size": [96, 80], "spp": 1}, "test")
    src, a = randomised_scenario(config, 11, 2)
    _, b = randomised_scenario(config, 11, 2)
    _, c = randomised_scenario(config, 12, 2)
    assert a == b and a != c and src == "clear_day_quad"
    assert a.name == "seq000003" and a.n_frames == 5
    assert a.camera_rig.rgb.width_px == 96 and a.camera_rig.thermal.height_px == 80 and a.camera_rig.rgb.spp == 1
    assert a.targets[0].kind == "hexacopter" and a.camera_rig.track_target == a.targets[0].name
    centre = a.targets[0].trajectory.center_m
    rng_m = math.dist(centre, a.camera_rig.position_m)
    assert 99.0 < rng_m < 121.0
    assert 280.0 <= a.atmosphere.air_temperature_k <= 281.0
    assert 20.0 <= a.sky.sun.elevation_deg <= 21.0
    assert [t.kind for t in a.targets[1:]] == ["bird", "bird"]
    assert sequence_seed(11, 2) == sequence_seed(11, 2) != sequence_seed(11, 3)


def test_time_of_day_sets_the_sun_by_date_and_place():
    config = load_generation_config("dusk_timeofday")
    _, s = randomised_scenario(config, 0, 0)
    assert s.sky.sun.datetime_utc is not None and s.sky.sun.elevation_deg is None
    assert 16 <= s.sky.sun.datetime_utc.hour <= 20
