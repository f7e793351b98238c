"""Terrain schema (field-named errors) and the procedural terrain mesh (determinism, winding, counts)."""
import numpy as np
import pytest

from scenes import load_scenario, scenario_from_dict
from scenes.errors import UserInputError
from scenes.terrain import ASSET_NAMES, build_terrain


def _scene(**terrain):
    data = load_scenario("horizon_treeline").model_dump(mode="json")
    data["terrain"] = terrain
    return data


def test_unknown_terrain_asset_is_refused_naming_the_field():
    with pytest.raises(UserInputError, match=r"terrain\.ground: .*unknown terrain asset 'lava'"):
        scenario_from_dict(_scene(ground="lava"))
    with pytest.raises(UserInputError, match=r"terrain\.tree_lines\.0\.asset: .*unknown terrain asset 'palm'"):
        scenario_from_dict(_scene(tree_lines=[{"asset": "palm", "distance_m": 200, "azimuth_deg": [0, 10]}]))
    with pytest.raises(UserInputError, match=r"terrain\.masts\.0\.asset"):
        scenario_from_dict(_scene(masts=[{"asset": "house", "distance_m": 200, "azimuth_deg": 0}]))


def test_negative_emissivity_is_refused_naming_the_field():
    with pytest.raises(UserInputError, match=r"terrain\.emissivity\.grass: .*greater than 0"):
        scenario_from_dict(_scene(emissivity={"grass": -0.5}))


def test_terrain_is_off_by_default_in_existing_presets():
    for name in ("clear_day_quad", "dusk_crossover", "out_of_view", "det_control_a"):
        assert load_scenario(name).terrain is None


def test_terrain_mesh_is_deterministic_and_front_faces_face_the_vertex_normals():
    scene = scenario_from_dict(_scene(ground="field", relief_m=3.0,
                                      procedural={"tree_lines": [2, 4], "buildings": [1, 3], "masts": [1, 1]}))
    a = build_terrain(scene, np.random.default_rng(5))
    b = build_terrain(scene, np.random.default_rng(5))
    c = build_terrain(scene, np.random.default_rng(6))
    assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)
    assert not np.array_equal(a.vertices, c.vertices)
    v, f = a.vertices, a.faces
    geometric = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    assert np.all(np.einsum("ij,ij->i", geometric, a.normal[f].sum(axis=1)) >= 0)
    used = {ASSET_NAMES[i] for i in np.unique(a.asset)}
    assert "field" in used and ("lattice_mast" in used or "pole" in used)
    # the ground is z = 0 under the rig (relief tapers to zero within 50 m)
    near = np.hypot(v[:, 0], v[:, 1]) < 40
    assert np.all(v[near & (a.asset == ASSET_NAMES.index("field")), 2] == 0)


def test_tree_line_stands_where_it_was_put():
    scene = scenario_from_dict(_scene(tree_lines=[{"asset": "conifer", "distance_m": 500, "azimuth_deg": [80, 100],
                                                   "height_m": 20, "height_jitter": 0.0}]))
    mesh = build_terrain(scene, np.random.default_rng(0))
    trees = mesh.vertices[mesh.asset == ASSET_NAMES.index("conifer")]
    rig = np.asarray(scene.camera_rig.position_m)
    r = np.hypot(trees[:, 0] - rig[0], trees[:, 1] - rig[1])
    assert np.all(np.abs(r - 500) < 0.2 * 500)
    azimuth = np.degrees(np.arctan2(trees[:, 0] - rig[0], trees[:, 1] - rig[1]))   # clockwise from north
    assert azimuth.min() >= 79.9 and azimuth.max() <= 100.1
    assert np.isclose(trees[:, 2].max(), 20.0 - 1.0)   # crown top = height above the base (1 m sunk)
