"""Helicopter target kind: validation (rotor required), asset (closed parts, span, blades, geared
tail rotor moving rigidly), thermal defaults (exhaust hottest)."""
import numpy as np
import pytest

from scenes import load_scenario, scenario_from_dict
from scenes.assets import build_asset, rotor_count, validate_closed_mesh
from scenes.errors import UserInputError
from simulator.physics.timeline import build_timeline
from simulator.render.geometry import AnimatedAsset


def _data(**target):
    data = load_scenario("helicopter_pass").model_dump(mode="json")
    data["targets"][0].update(target)
    return data


def test_a_helicopter_without_rotor_is_refused_naming_the_field():
    with pytest.raises(UserInputError, match=r"targets\.0: .*rotor: a helicopter needs a main rotor"):
        scenario_from_dict(_data(rotor=None))
    with pytest.raises(UserInputError, match=r"targets\.0\.rotor\.main_blades: .*greater than or equal to 2"):
        scenario_from_dict(_data(rotor={"main_blades": 0}))
    data = load_scenario("clear_day_quad").model_dump(mode="json")
    data["targets"][0]["rotor"] = {"main_blades": 3}
    with pytest.raises(UserInputError, match=r"targets\.0: .*only helicopters take a rotor"):
        scenario_from_dict(data)


@pytest.mark.parametrize("blades", [2, 3, 5])
def test_asset_parts_are_closed_and_span_the_rotor_diameter(blades):
    parts = build_asset("helicopter", 10.0, main_blades=blades)
    for p in parts:
        validate_closed_mesh(p.vertices, p.faces)
    roles = {p.role for p in parts}
    assert {"fuselage", "tail", "engine", "exhaust", "prop", "body"} == roles
    main = next(p for p in parts if p.name == "main_rotor")
    hub = main.vertices.mean(axis=0)
    radius = np.hypot(main.vertices[:, 0] - hub[0], main.vertices[:, 1] - hub[1])
    assert radius.max() == pytest.approx(5.0, rel=0.01)
    # one tip per blade: cluster the outermost vertices by angle
    tips = main.vertices[radius > 4.9]
    angles = np.unique(np.round(np.degrees(np.arctan2(tips[:, 1], tips[:, 0])) / 10.0))
    assert len(angles) >= blades
    assert rotor_count("helicopter") == 1


def test_rotors_move_rigidly_and_the_tail_rotor_is_geared():
    asset = AnimatedAsset("helicopter", 10.0, 4)
    assert asset.exact
    a, b = build_asset("helicopter", 10.0, rotor_angle_rad=0.0), build_asset("helicopter", 10.0, rotor_angle_rad=0.1)
    moved = {p.name for p, q in zip(a, b) if not np.array_equal(p.vertices, q.vertices)}
    assert moved == {"main_rotor", "tail_rotor"}


def test_timeline_rotor_and_temperatures():
    scene = load_scenario("helicopter_pass")
    tl = build_timeline(scene, 5, 10)
    track = tl.targets[0]
    assert (track.n_blades == 4 and np.allclose(track.rotor_rpm, 400.0, rtol=0.03)
            and np.ptp(track.rotor_rpm) == 0)  # governed, 1 % detune
    temps = {r: float(v[0]) for r, v in track.part_temperature_k.items()}
    assert max(temps, key=temps.get) == "exhaust" and temps["exhaust"] > temps["engine"] > temps["fuselage"]
