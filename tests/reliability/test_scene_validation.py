"""The scene boundary (scenes.schema via scenes.loader): names that become paths, NaN/inf, a thermal
scale that would clip, camera poses that see nothing. Each row is a mutation of a valid preset that
must be refused with the field named; valid neighbours must still pass."""
from __future__ import annotations

import copy

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scenes.errors import UserInputError
from scenes.loader import load_scenario, scenario_from_dict

BASE = load_scenario("clear_day_quad").model_dump(mode="json")


def _set(path: str, value):
    def mutate(d):
        keys = path.split(".")
        for k in keys[:-1]:
            d = d[int(k)] if k.isdigit() else d[k]
        d[int(keys[-1]) if keys[-1].isdigit() else keys[-1]] = value
    return mutate


def _fixed_camera(position, look_at):
    def mutate(d):
        d["camera_rig"].update({"position_m": position, "look_at_m": look_at, "track_target": None})
    return mutate


REFUSED = [
    ("absolute name", _set("name", "/abs/victim"), "name"),
    ("dot name", _set("name", "."), "name"),
    ("parent escape", _set("name", "../../x"), "name"),
    ("name with a separator", _set("name", "a/b"), "name"),
    ("hidden name", _set("name", ".hidden"), "name"),
    ("empty name", _set("name", ""), "name"),
    ("NaN position", _set("camera_rig.position_m", [float("nan"), 0.0, 1.5]), "camera_rig.position_m"),
    ("inf position", _set("camera_rig.position_m", [0.0, float("inf"), 1.5]), "camera_rig.position_m"),
    ("NaN size", _set("targets.0.size_m", float("nan")), "targets.0.size_m"),
    ("-inf temperature offset", _set("targets.0.thermal.offsets_k", {"body": float("-inf")}), "offsets_k"),
    ("kelvin_per_count 1e-4 clips everything", _set("camera_rig.thermal.kelvin_per_count", 1e-4), "kelvin_per_count"),
    ("a 1400 K part clips", _set("targets.0.thermal", {"mode": "absolute", "absolute_k": {"body": 1400.0}}),
     "kelvin_per_count"),
    ("camera looking straight up", _fixed_camera([0, 0, 1.5], [0, 0, 500.0]), "straight above"),
    ("camera looking at itself", _fixed_camera([10, 20, 1.5], [10, 20, 1.5]), "is the camera position"),
]


@pytest.mark.parametrize("case,mutate,field", REFUSED, ids=[r[0] for r in REFUSED])
def test_refused_with_the_field_named(case, mutate, field):
    data = copy.deepcopy(BASE)
    mutate(data)
    with pytest.raises(UserInputError) as info:
        scenario_from_dict(data)
    assert field in str(info.value)
    assert len(str(info.value)) < 1500


ACCEPTED = [
    ("plain name with dots and dashes", _set("name", "my-scene_v1.2")),
    ("hot part within range", _set("targets.0.thermal", {"mode": "absolute", "absolute_k": {"body": 600.0}})),
    ("coarse but sufficient scale", _set("camera_rig.thermal.kelvin_per_count", 0.0065)),
    ("camera looking steeply up", _fixed_camera([0, 0, 1.5], [5, 0, 500.0])),
]


@pytest.mark.parametrize("case,mutate", ACCEPTED, ids=[r[0] for r in ACCEPTED])
def test_valid_neighbours_still_pass(case, mutate):
    data = copy.deepcopy(BASE)
    mutate(data)
    scenario_from_dict(data)


@settings(max_examples=60, deadline=None)
@given(st.text(max_size=40))
def test_a_name_that_validates_is_one_safe_path_component(name):
    data = copy.deepcopy(BASE)
    data["name"] = name
    try:
        scenario = scenario_from_dict(data)
    except UserInputError:
        return
    assert "/" not in scenario.name and "\\" not in scenario.name and "\x00" not in scenario.name
    assert scenario.name not in (".", "..") and not scenario.name.startswith((".", "-"))


@settings(max_examples=40, deadline=None)
@given(st.floats(min_value=1e-6, max_value=0.05))
def test_thermal_scale_is_refused_exactly_when_the_ceiling_clips(kpc):
    data = copy.deepcopy(BASE)
    data["camera_rig"]["thermal"]["kelvin_per_count"] = kpc
    hottest = data["atmosphere"]["air_temperature_k"] + max(
        [0.0] + list(data["targets"][0]["thermal"]["offsets_k"].values()))
    clips = 65535 * kpc < hottest + 20.0
    clips |= 65535 * kpc < 400.0  # the camera model's own floor (scenes.schema.ThermalCamera)
    try:
        scenario_from_dict(data)
        assert not clips
    except UserInputError as exc:
        assert clips and "kelvin_per_count" in str(exc)
