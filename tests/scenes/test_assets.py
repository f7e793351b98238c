"""Tests for scenes.assets: closed meshes, validation, volumes, spans, rotors, flapping, errors, determinism."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from scenes.assets import (
    BIRD_FLAP_AMPLITUDE_RAD,
    KINDS,
    ROLES,
    MeshPart,
    blade_count,
    box_mesh,
    build_asset,
    cylinder_mesh,
    ellipsoid_mesh,
    mesh_volume_m3,
    rotor_count,
    rotor_positions_m,
    rotor_spin_signs,
    validate_closed_mesh,
)

MULTIROTORS = ("quadcopter", "hexacopter")
WINGED = ("fixed_wing", "bird", "airliner")
TYPICAL_SIZE = {"quadcopter": 0.45, "hexacopter": 1.0, "fixed_wing": 2.0, "bird": 0.8, "airliner": 35.0,
                "helicopter": 10.0}


def _all_vertices(parts: list[MeshPart]) -> np.ndarray:
    return np.concatenate([p.vertices for p in parts])


def _xy_diameter(points: np.ndarray) -> float:
    xy = points[:, :2]
    hull = xy[ConvexHull(xy).vertices]
    return float(np.sqrt(((hull[:, None] - hull[None]) ** 2).sum(-1)).max())


def _unit_cube() -> tuple[np.ndarray, np.ndarray]:
    return box_mesh((0.5, 0.5, 0.5), (1.0, 1.0, 1.0))


# ---------------------------------------------------------------------------------------------- meshes


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize(
    "size_m, flap, rotor",
    [(0.05, 0.0, 0.0), (0.45, 0.7, 1.3), (2.0, -1.2, -2.5), (35.0, math.pi / 2, 10.0), (1000.0, 3.0, 0.1)],
)
def test_every_part_is_a_closed_outward_mesh(kind: str, size_m: float, flap: float, rotor: float) -> None:
    parts = build_asset(kind, size_m, flap_phase_rad=flap, rotor_angle_rad=rotor)
    names = [p.name for p in parts]
    assert len(set(names)) == len(names), f"duplicate part names {names}"
    n_tri = 0
    for p in parts:
        assert p.role in ROLES
        assert p.vertices.dtype == np.float64 and p.vertices.shape[1] == 3
        assert p.faces.dtype == np.int32 and p.faces.shape[1] == 3
        validate_closed_mesh(p.vertices, p.faces)
        assert mesh_volume_m3(p.vertices, p.faces) > 0.0
        n_tri += len(p.faces)
    assert 300 <= n_tri <= 3000, f"{kind}: {n_tri} triangles"


@pytest.mark.parametrize("kind", KINDS)
def test_part_roles_per_kind(kind: str) -> None:
    roles = {p.role for p in build_asset(kind, 1.0)}
    expected = {
        "quadcopter": {"body", "arm", "motor", "prop", "battery", "camera"},
        "hexacopter": {"body", "arm", "motor", "prop", "battery", "camera"},
        "fixed_wing": {"fuselage", "wing", "tail", "prop", "motor"},
        "bird": {"body", "head", "wing", "feather"},
        "airliner": {"fuselage", "wing", "tail", "engine"},
        "helicopter": {"fuselage", "tail", "engine", "exhaust", "body", "prop"},
    }[kind]
    assert roles == expected


def test_meshpart_arrays_are_read_only_and_role_checked() -> None:
    part = build_asset("quadcopter", 0.4)[0]
    with pytest.raises(ValueError):
        part.vertices[0, 0] = 1.0
    v, f = _unit_cube()
    with pytest.raises(ValueError, match="role"):
        MeshPart("x", "laser", v, f)
    with pytest.raises(ValueError, match="faces"):
        MeshPart("x", "body", v, f.astype(float))


# ------------------------------------------------------------------------------------------ validation


def test_validate_accepts_primitives() -> None:
    for v, f in (_unit_cube(), cylinder_mesh(7, 0.2, -1.0, 2.0), ellipsoid_mesh((1, 2, 3), (0.5, 0.2, 0.1))):
        validate_closed_mesh(v, f)


def test_validate_rejects_missing_face() -> None:
    v, f = _unit_cube()
    with pytest.raises(ValueError, match="open"):
        validate_closed_mesh(v, f[1:])


def test_validate_rejects_one_flipped_face() -> None:
    v, f = _unit_cube()
    f = f.copy()
    f[3] = f[3, ::-1]
    with pytest.raises(ValueError, match="orientation"):
        validate_closed_mesh(v, f)


def test_validate_rejects_all_faces_flipped_as_negative_volume() -> None:
    v, f = _unit_cube()
    with pytest.raises(ValueError, match="volume"):
        validate_closed_mesh(v, f[:, ::-1])


def test_validate_rejects_index_out_of_range() -> None:
    v, f = _unit_cube()
    f = f.copy()
    f[5, 1] = len(v)
    with pytest.raises(ValueError, match="out of range"):
        validate_closed_mesh(v, f)
    f[5, 1] = -1
    with pytest.raises(ValueError, match="out of range"):
        validate_closed_mesh(v, f)


def test_validate_rejects_degenerate_triangles() -> None:
    # zero-area face from collinear vertices: a tetrahedron whose apex lies on an edge's line is still
    # edge-closed, so only the area check can catch it.
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]])
    f = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    with pytest.raises(ValueError, match="degenerate"):
        validate_closed_mesh(v, f)
    cv, cf = _unit_cube()
    cf = cf.copy()
    cf[0, 1] = cf[0, 0]
    with pytest.raises(ValueError, match="degenerate"):
        validate_closed_mesh(cv, cf)


def test_validate_rejects_bad_shapes_and_nan() -> None:
    v, f = _unit_cube()
    with pytest.raises(ValueError, match="vertices"):
        validate_closed_mesh(v[:, :2], f)
    with pytest.raises(ValueError, match="faces"):
        validate_closed_mesh(v, f[:, :2])
    bad = v.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        validate_closed_mesh(bad, f)


@settings(max_examples=25, deadline=None)
@given(
    quat=st.tuples(*[st.floats(-1, 1) for _ in range(4)]).filter(lambda q: sum(x * x for x in q) > 0.1),
    shift=st.tuples(*[st.floats(-100, 100) for _ in range(3)]),
    drop=st.integers(0, 10_000),
)
def test_rigid_motion_keeps_validity_and_volume_and_any_removed_face_is_caught(quat, shift, drop) -> None:
    v, f = cylinder_mesh(9, 0.3, 0.0, 1.5)
    rot = Rotation.from_quat(quat).as_matrix()
    v2 = v @ rot.T + np.asarray(shift)
    validate_closed_mesh(v2, f)
    assert mesh_volume_m3(v2, f) == pytest.approx(mesh_volume_m3(v, f), rel=1e-9)
    with pytest.raises(ValueError):
        validate_closed_mesh(v2, np.delete(f, drop % len(f), axis=0))


# ------------------------------------------------------------------------------------------- volumes


def test_unit_cube_volume_is_one() -> None:
    assert mesh_volume_m3(*_unit_cube()) == pytest.approx(1.0, abs=1e-12)
    v, f = box_mesh((10.0, -3.0, 7.0), (2.0, 3.0, 0.5))
    assert mesh_volume_m3(v, f) == pytest.approx(3.0, abs=1e-12)


def test_cylinder_volume_matches_inscribed_polygon_and_pi_r2_h() -> None:
    n, r, h = 64, 0.3, 2.0
    v, f = cylinder_mesh(n, r, -0.5, -0.5 + h)
    # inscribed 64-gon area = n/2 r^2 sin(2 pi / n) = 0.998394 * pi r^2
    polygon = 0.5 * n * r * r * math.sin(2 * math.pi / n) * h
    assert mesh_volume_m3(v, f) == pytest.approx(polygon, rel=1e-12)
    assert mesh_volume_m3(v, f) == pytest.approx(math.pi * r * r * h, rel=2e-3)
    assert mesh_volume_m3(v, f) < math.pi * r * r * h


def test_ellipsoid_volume_close_to_analytic() -> None:
    v, f = ellipsoid_mesh((0, 0, 0), (0.5, 0.3, 0.2), 32, 24)
    assert mesh_volume_m3(v, f) == pytest.approx(4 / 3 * math.pi * 0.5 * 0.3 * 0.2, rel=0.02)


# ------------------------------------------------------------------------------------- size and rotors


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("size_m", [0.3, 2.0, 35.0])
def test_span_matches_size(kind: str, size_m: float) -> None:
    verts = _all_vertices(build_asset(kind, size_m))
    if kind in MULTIROTORS:
        span = _xy_diameter(verts)  # blades lie along the arms at rotor angle 0
    else:
        span = float(np.ptp(verts[:, 1]))  # wingspan (bird at phase 0 has level wings)
    assert span == pytest.approx(size_m, rel=0.10)
    # a helicopter is longer than its rotor (tail rotor behind the disc: Bell 206 11.8 m over a 10.2 m rotor)
    assert np.ptp(verts, axis=0).max() <= (1.25 if kind == "helicopter" else 1.1) * size_m


@pytest.mark.parametrize("kind", MULTIROTORS)
def test_multirotor_prop_disc_span_is_size_for_all_rotor_angles(kind: str) -> None:
    size = 0.5
    hubs = rotor_positions_m(kind, size)
    for angle in np.linspace(0.0, math.pi, 5):
        parts = build_asset(kind, size, rotor_angle_rad=angle)
        props = [p for p in parts if p.role == "prop"]
        radius = max(np.linalg.norm(p.vertices[:, :2] - h[:2], axis=1).max() for p, h in zip(props, hubs))
        disc_span = 2 * np.linalg.norm(hubs[:, :2], axis=1).max() + 2 * radius
        assert disc_span == pytest.approx(size, rel=0.01)
        assert _xy_diameter(_all_vertices(parts)) <= size * 1.001


@pytest.mark.parametrize("kind", KINDS)
def test_rotor_positions_inside_bounds_and_symmetric(kind: str) -> None:
    size = TYPICAL_SIZE[kind]
    pos = rotor_positions_m(kind, size)
    assert pos.shape == (rotor_count(kind), 3)
    assert rotor_spin_signs(kind).shape == (rotor_count(kind),)
    verts = _all_vertices(build_asset(kind, size))
    lo, hi = verts.min(0), verts.max(0)
    assert np.all(pos >= lo - 1e-9) and np.all(pos <= hi + 1e-9)
    np.testing.assert_allclose(rotor_positions_m(kind, 2 * size), 2 * pos)
    if kind in MULTIROTORS:
        np.testing.assert_allclose(pos[:, :2].sum(0), 0.0, atol=1e-12 * size)
        radii = np.linalg.norm(pos[:, :2], axis=1)
        np.testing.assert_allclose(radii, radii[0])
        assert rotor_spin_signs(kind).sum() == 0


@pytest.mark.parametrize("kind", ("quadcopter", "hexacopter", "fixed_wing"))
def test_props_are_centred_on_rotor_positions_and_turn_with_alternating_spin(kind: str) -> None:
    size, angle = 1.0, 0.3
    hubs = rotor_positions_m(kind, size)
    spins = rotor_spin_signs(kind)
    props0 = [p for p in build_asset(kind, size) if p.role == "prop"]
    props1 = [p for p in build_asset(kind, size, rotor_angle_rad=angle) if p.role == "prop"]
    assert len(props0) == len(hubs)
    axis = np.array([0, 0, 1.0]) if kind in MULTIROTORS else np.array([1.0, 0, 0])
    for p0, p1, hub, spin in zip(props0, props1, hubs, spins):
        centre = 0.5 * (p0.vertices.min(0) + p0.vertices.max(0))
        assert np.linalg.norm(centre - hub) < 0.01 * size
        # blade direction = farthest vertex from the hub, projected onto the rotor plane
        def blade_dir(p: MeshPart) -> np.ndarray:
            d = p.vertices - hub
            d = d - np.outer(d @ axis, axis)
            return d[np.argmax(np.linalg.norm(d, axis=1))]
        a, b = blade_dir(p0), blade_dir(p1)
        turned = math.atan2(np.cross(a, b) @ axis, a @ b)
        # two-blade props are symmetric under a half turn: compare modulo pi
        err = (turned - spin * angle + math.pi / 2) % math.pi - math.pi / 2
        assert abs(err) < 0.05, (turned, spin * angle)


def test_rotor_and_blade_counts() -> None:
    assert [rotor_count(k) for k in KINDS] == [4, 6, 1, 0, 0, 1]
    assert [blade_count(k) for k in KINDS] == [2, 2, 2, 0, 0, 2]
    assert rotor_positions_m("airliner", 35.0).shape == (0, 3)


@pytest.mark.parametrize("kind", KINDS)
def test_origin_near_centre_of_mass(kind: str) -> None:
    size = TYPICAL_SIZE[kind]
    total, moment = 0.0, np.zeros(3)
    for p in build_asset(kind, size):
        a, b, c = (p.vertices[p.faces[:, i]] for i in range(3))
        w = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
        total += w.sum()
        moment += (w[:, None] * (a + b + c) / 4.0).sum(0)
    assert np.linalg.norm(moment / total) < 0.05 * size


# ---------------------------------------------------------------------------------------------- bird


def _wing_tip(parts: list[MeshPart], name: str) -> np.ndarray:
    wing = next(p for p in parts if p.name == name)
    return wing.vertices[np.argmax(np.abs(wing.vertices[:, 1]))]


def test_bird_wing_tips_move_up_and_down_with_flap_phase() -> None:
    size = 0.8
    phases = [-math.pi / 2, -math.pi / 4, 0.0, math.pi / 4, math.pi / 2]
    tips = [_wing_tip(build_asset("bird", size, flap_phase_rad=ph), "wing_left") for ph in phases]
    z = [t[2] for t in tips]
    assert all(z1 > z0 for z0, z1 in zip(z, z[1:])), z
    body_top = next(p for p in build_asset("bird", size) if p.name == "body").vertices[:, 2].max()
    assert z[-1] > body_top + 0.2 * size  # wings clearly up: visible in silhouette
    assert z[0] < -0.2 * size
    # analytic: the tip rotates about the shoulder by amplitude * sin(phase)
    assert math.degrees(BIRD_FLAP_AMPLITUDE_RAD) == pytest.approx(50.0)
    up = build_asset("bird", size, flap_phase_rad=math.pi / 2)
    left, right = _wing_tip(up, "wing_left"), _wing_tip(up, "wing_right")
    np.testing.assert_allclose(right, left * [1, -1, 1])
    # flapping moves only the wings
    for a, b in zip(build_asset("bird", size), up):
        if a.role != "wing":
            np.testing.assert_array_equal(a.vertices, b.vertices)


# -------------------------------------------------------------------------------------------- errors


@pytest.mark.parametrize(
    "call",
    [
        lambda k: build_asset(k, 1.0),
        rotor_count,
        blade_count,
        lambda k: rotor_positions_m(k, 1.0),
    ],
)
@pytest.mark.parametrize("kind", ["gyrocopter", "Quadcopter", "", None])
def test_unknown_kind_lists_valid_kinds(call, kind) -> None:
    with pytest.raises(ValueError) as exc:
        call(kind)
    for k in KINDS:
        assert k in str(exc.value)


@pytest.mark.parametrize("size_m", [0.0, -1.0, float("nan"), float("inf"), True, "1.0"])
def test_bad_size_names_size_m(size_m) -> None:
    with pytest.raises(ValueError, match="size_m"):
        build_asset("quadcopter", size_m)
    with pytest.raises(ValueError, match="size_m"):
        rotor_positions_m("hexacopter", size_m)


def test_bad_angles_are_named() -> None:
    with pytest.raises(ValueError, match="flap_phase_rad"):
        build_asset("bird", 1.0, flap_phase_rad=float("nan"))
    with pytest.raises(ValueError, match="rotor_angle_rad"):
        build_asset("quadcopter", 1.0, rotor_angle_rad=float("inf"))


# ------------------------------------------------------------------------------------------- determinism


@pytest.mark.parametrize("kind", KINDS)
def test_deterministic(kind: str) -> None:
    kw = dict(flap_phase_rad=0.9, rotor_angle_rad=1.7)
    a = build_asset(kind, 3.0, **kw)
    b = build_asset(kind, 3.0, **kw)
    assert [(p.name, p.role) for p in a] == [(p.name, p.role) for p in b]
    for pa, pb in zip(a, b):
        np.testing.assert_array_equal(pa.vertices, pb.vertices)
        np.testing.assert_array_equal(pa.faces, pb.faces)
    c = build_asset(kind, 3.0, flap_phase_rad=0.2, rotor_angle_rad=0.4)
    changed = any(not np.array_equal(pa.vertices, pc.vertices) for pa, pc in zip(a, c))
    assert changed == (kind != "airliner")
