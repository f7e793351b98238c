"""Procedural, watertight triangle-mesh assets: multirotors, a fixed-wing UAV, a bird and an airliner.

Every asset is a list of :class:`MeshPart`, one closed, outward-oriented triangle mesh per part, in the
OBJECT frame (+x forward, +y left, +z up, metres, origin at the approximate centre of mass of the
uniform-density geometry). Parts may intersect each other; a single part may also hold several
disjoint or overlapping closed shells (e.g. an engine nacelle plus its pylon) and is still a closed
2-manifold in the edge sense checked by :func:`validate_closed_mesh`.

Pure numpy; nothing here knows about the renderer. All geometry is built from one primitive,
:func:`loft_mesh` (a stack of planar rings joined by quads, capped by a centroid fan or an apex), from
which boxes, cylinders, frusta, ellipsoids, wings and propeller blades are derived.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from numbers import Real
from typing import Sequence

import numpy as np

__all__ = [
    "ROLES",
    "KINDS",
    "MeshPart",
    "build_asset",
    "rotor_count",
    "rotor_positions_m",
    "rotor_spin_signs",
    "blade_count",
    "validate_closed_mesh",
    "mesh_volume_m3",
    "loft_mesh",
    "box_mesh",
    "cylinder_mesh",
    "frustum_mesh",
    "ellipsoid_mesh",
]

ROLES = ("body", "arm", "motor", "prop", "battery", "camera", "wing", "fuselage", "tail", "engine", "head", "feather",
         "exhaust")
KINDS = ("quadcopter", "hexacopter", "fixed_wing", "bird", "airliner", "helicopter")

#: Peak bird wing dihedral (rad); wing angle = amplitude * sin(flap_phase_rad).
BIRD_FLAP_AMPLITUDE_RAD = math.radians(50.0)

Mesh = tuple[np.ndarray, np.ndarray]


@dataclass(frozen=True, eq=False)
class MeshPart:
    """One closed triangle mesh of an asset with its thermal/material role.

    ``vertices`` (V, 3) float64 metres in the object frame; ``faces`` (F, 3) int32, counter-clockwise seen
    from outside. Arrays are stored read-only (copy before modifying). Equality is identity (arrays make
    field-wise ``==`` ambiguous).
    """

    name: str
    role: str
    vertices: np.ndarray
    faces: np.ndarray

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"MeshPart.name must be a non-empty string, got {self.name!r}")
        if self.role not in ROLES:
            raise ValueError(f"MeshPart.role must be one of {', '.join(ROLES)}; got {self.role!r}")
        v = np.array(self.vertices, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"MeshPart.vertices must have shape (V, 3), got {v.shape}")
        f = np.asarray(self.faces)
        if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
            raise ValueError(f"MeshPart.faces must be an integer array of shape (F, 3), got {f.dtype} {f.shape}")
        f = f.astype(np.int32)
        v.flags.writeable = False
        f.flags.writeable = False
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)


# ----------------------------------------------------------------------------------------------------
# validation and measurement
# ----------------------------------------------------------------------------------------------------

def _as_mesh_arrays(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"vertices must have shape (V, 3), got {v.shape}")
    if not np.issubdtype(v.dtype, np.number):
        raise ValueError(f"vertices must be numeric, got dtype {v.dtype}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces must have shape (F, 3), got {f.shape}")
    if f.size and not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"faces must be an integer array, got dtype {f.dtype}")
    return v.astype(np.float64), f.astype(np.int64)


def mesh_volume_m3(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed enclosed volume (divergence theorem); positive for a closed, outward-oriented mesh."""
    v, f = _as_mesh_arrays(vertices, faces)
    if f.size == 0:
        return 0.0
    if f.min() < 0 or f.max() >= len(v):
        raise ValueError(f"faces index out of range [0, {len(v)})")
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    # Shift by a reference point for numerical robustness far from the origin (volume is shift invariant).
    ref = v[f[0, 0]]
    a, b, c = a - ref, b - ref, c - ref
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def validate_closed_mesh(vertices: np.ndarray, faces: np.ndarray) -> None:
    """Raise ValueError unless the mesh is a closed, consistently outward-oriented triangle 2-manifold.

    Checks: shapes/dtypes, finite vertices, at least 4 faces, indices in range, no degenerate (repeated
    index or ~zero-area) faces, every directed edge used exactly once and its reverse exactly once
    (i.e. each edge shared by exactly two faces with opposite directions), and positive signed volume.
    """
    v, f = _as_mesh_arrays(vertices, faces)
    if not np.all(np.isfinite(v)):
        raise ValueError("vertices contain non-finite values")
    if len(f) < 4:
        raise ValueError(f"a closed triangle mesh needs at least 4 faces, got {len(f)}")
    bad = np.nonzero((f < 0) | (f >= len(v)))
    if bad[0].size:
        i = int(bad[0][0])
        raise ValueError(f"faces[{i}] = {f[i].tolist()} has an index out of range [0, {len(v)})")
    rep = np.nonzero((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0]))[0]
    if rep.size:
        i = int(rep[0])
        raise ValueError(f"degenerate face faces[{i}] = {f[i].tolist()} repeats a vertex")
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    extent = float(np.linalg.norm(np.ptp(v[f].reshape(-1, 3), axis=0)))
    tol = 1e-12 * max(extent, 1e-300) ** 2
    deg = np.nonzero(area2 <= tol)[0]
    if deg.size:
        i = int(deg[0])
        raise ValueError(f"degenerate (zero-area) face faces[{i}] = {f[i].tolist()} ({deg.size} such faces)")
    n = np.int64(len(v))
    src = f.reshape(-1)
    dst = f[:, [1, 2, 0]].reshape(-1)
    code = src * n + dst
    uniq, counts = np.unique(code, return_counts=True)
    dup = np.nonzero(counts > 1)[0]
    if dup.size:
        e = int(uniq[dup[0]])
        raise ValueError(
            f"directed edge ({e // int(n)} -> {e % int(n)}) is used by {int(counts[dup[0]])} faces: "
            f"inconsistent face orientation or non-manifold edge ({dup.size} such edges)"
        )
    rev = dst * n + src
    missing = np.nonzero(~np.isin(rev, uniq))[0]
    if missing.size:
        j = int(missing[0])
        raise ValueError(
            f"edge ({int(src[j])}, {int(dst[j])}) of faces[{j // 3}] has no opposite half-edge: "
            f"mesh is open (boundary edge) or inconsistently oriented ({missing.size} such edges)"
        )
    vol = mesh_volume_m3(v, f)
    if not vol > 0.0:
        raise ValueError(f"signed volume is {vol:.3g} m^3 (<= 0): faces are oriented inward")


# ----------------------------------------------------------------------------------------------------
# primitives
# ----------------------------------------------------------------------------------------------------

def _flip(mesh: Mesh) -> Mesh:
    return mesh[0], mesh[1][:, ::-1].copy()


def loft_mesh(
    rings: Sequence[np.ndarray],
    start_apex: np.ndarray | None = None,
    end_apex: np.ndarray | None = None,
) -> Mesh:
    """Closed mesh through a stack of planar rings (each (n, 3), same n, convex, same winding).

    Consecutive rings are joined by quads (two triangles each); the ends are closed by a fan from the ring
    centroid, or from ``start_apex``/``end_apex`` (a cone tip) if given. Orientation is made outward.
    """
    rs = [np.asarray(r, dtype=np.float64) for r in rings]
    if not rs:
        raise ValueError("rings must contain at least one ring")
    n = rs[0].shape[0]
    if n < 3 or any(r.shape != (n, 3) for r in rs):
        raise ValueError(f"every ring must have shape (n, 3) with the same n >= 3, got {[r.shape for r in rs]}")
    if len(rs) < 2 and start_apex is None and end_apex is None:
        raise ValueError("a single ring needs at least one apex to enclose a volume")
    m = len(rs)
    idx = np.arange(n)
    nxt = (idx + 1) % n
    faces = []
    for k in range(m - 1):
        a, b, c, d = k * n + idx, k * n + nxt, (k + 1) * n + nxt, (k + 1) * n + idx
        faces.append(np.stack([a, b, c], axis=1))
        faces.append(np.stack([a, c, d], axis=1))
    s = rs[0].mean(axis=0) if start_apex is None else np.asarray(start_apex, dtype=np.float64)
    e = rs[-1].mean(axis=0) if end_apex is None else np.asarray(end_apex, dtype=np.float64)
    faces.append(np.stack([np.full(n, m * n), nxt, idx], axis=1))
    last = (m - 1) * n
    faces.append(np.stack([np.full(n, m * n + 1), last + idx, last + nxt], axis=1))
    verts = np.concatenate(rs + [s[None], e[None]])
    mesh = (verts, np.concatenate(faces).astype(np.int64))
    if mesh_volume_m3(*mesh) < 0.0:
        mesh = _flip(mesh)
    return mesh


def _ring(section2d: np.ndarray, origin: np.ndarray | Sequence[float], u: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Place 2-D section points (n, 2) in the plane origin + s0 * u + s1 * w."""
    s = np.asarray(section2d, dtype=np.float64)
    return (np.asarray(origin, float)[None] + s[:, :1] * np.asarray(u, float)[None] + s[:, 1:]
            * np.asarray(w, float)[None])


def _circle(n: int, ra: float, rb: float | None = None, phase: float = 0.0) -> np.ndarray:
    t = phase + 2.0 * np.pi * np.arange(n) / n
    return np.stack([ra * np.cos(t), (ra if rb is None else rb) * np.sin(t)], axis=1)


def _superellipse(n: int, a: float, b: float, p: float = 4.0) -> np.ndarray:
    """Rounded-rectangle-like convex section |x/a|^p + |y/b|^p = 1."""
    t = 2.0 * np.pi * (np.arange(n) + 0.5) / n
    c, s = np.cos(t), np.sin(t)
    return np.stack([a * np.sign(c) * np.abs(c) ** (2.0 / p), b * np.sign(s) * np.abs(s) ** (2.0 / p)], axis=1)


def _airfoil(chord: float, thickness_ratio: float, n_side: int = 6) -> np.ndarray:
    """Symmetric NACA-00xx section, leading edge at 0, trailing edge at -chord; (n, 2) = (along, across)."""
    beta = np.linspace(0.0, np.pi, n_side + 1)[1:]
    xc = 0.5 * (1.0 - np.cos(beta))  # cosine spacing, excludes the leading edge
    yt = 5.0 * thickness_ratio * (0.2969 * np.sqrt(xc) - 0.1260 * xc - 0.3516 * xc**2 + 0.2843 * xc**3 - 0.1015 * xc**4)
    upper = np.stack([-xc[::-1], yt[::-1]], axis=1)  # trailing edge -> leading edge
    lower = np.stack([-xc, -yt], axis=1)  # leading edge -> trailing edge
    return chord * np.concatenate([upper, [[0.0, 0.0]], lower])


def box_mesh(center: Sequence[float], size: Sequence[float]) -> Mesh:
    """Axis-aligned box (12 side triangles + 8 cap-fan triangles)."""
    cx, cy, cz = center
    sx, sy, sz = (0.5 * float(s) for s in size)
    rect = np.array([[sx, sy], [-sx, sy], [-sx, -sy], [sx, -sy]])
    ex, ey = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    return loft_mesh([_ring(rect, (cx, cy, cz - sz), ex, ey), _ring(rect, (cx, cy, cz + sz), ex, ey)])


def frustum_mesh(n: int, r0: float, r1: float, z0: float, z1: float) -> Mesh:
    """Capped n-sided frustum along z from (radius r0 at z0) to (r1 at z1); r1 = 0 makes a cone."""
    ex, ey = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    bottom = _ring(_circle(n, r0), (0, 0, z0), ex, ey)
    if r1 <= 0.0:
        return loft_mesh([bottom], end_apex=np.array([0.0, 0.0, z1]))
    return loft_mesh([bottom, _ring(_circle(n, r1), (0, 0, z1), ex, ey)])


def cylinder_mesh(n: int, radius: float, z0: float, z1: float) -> Mesh:
    """Capped n-sided prism along z (volume n/2 r^2 sin(2 pi / n) (z1 - z0))."""
    return frustum_mesh(n, radius, radius, z0, z1)


def ellipsoid_mesh(center: Sequence[float], radii: Sequence[float], n_around: int = 16, n_rings: int = 9) -> Mesh:
    """UV ellipsoid with poles on the x axis (n_rings - 1 latitude rings plus two apex poles)."""
    rx, ry, rz = (float(r) for r in radii)
    c = np.asarray(center, dtype=np.float64)
    th = np.pi * np.arange(1, n_rings) / n_rings
    ey, ez = np.array([0, 1.0, 0]), np.array([0, 0, 1.0])
    rings = [_ring(_circle(n_around, ry * math.sin(t), rz * math.sin(t)), c + [rx * math.cos(t), 0, 0], ey, ez)
             for t in th]
    return loft_mesh(rings, start_apex=c + [rx, 0, 0], end_apex=c - [rx, 0, 0])


def _rot(axis: str, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _xf(mesh: Mesh, rot: np.ndarray | None = None, shift: np.ndarray | Sequence[float] = (0.0, 0.0, 0.0)) -> Mesh:
    """Apply x -> rot @ x + shift; a reflection (det < 0) also reverses the winding."""
    v, f = mesh
    if rot is not None:
        v = v @ np.asarray(rot, dtype=np.float64).T
        if np.linalg.det(rot) < 0.0:
            f = f[:, ::-1].copy()
    return v + np.asarray(shift, dtype=np.float64), f


_MIRROR_Y = np.diag([1.0, -1.0, 1.0])


def _merge(*meshes: Mesh) -> Mesh:
    vs, fs, off = [], [], 0
    for v, f in meshes:
        vs.append(v)
        fs.append(f + off)
        off += len(v)
    return np.concatenate(vs), np.concatenate(fs)


def _part(name: str, role: str, mesh: Mesh) -> MeshPart:
    return MeshPart(name=name, role=role, vertices=mesh[0], faces=mesh[1])


def _wing_loft(stations: Sequence[tuple[float, float, float, float, float]], n_side: int = 6) -> Mesh:
    """Left (+y) lifting surface from stations (y, x_leading_edge, z, chord, thickness_ratio)."""
    ex, ez = np.array([1.0, 0, 0]), np.array([0, 0, 1.0])
    rings = [_ring(_airfoil(c, t, n_side), (xle, y, z), ex, ez) for (y, xle, z, c, t) in stations]
    return loft_mesh(rings)


def _fin_loft(stations: Sequence[tuple[float, float, float, float]], n_side: int = 6) -> Mesh:
    """Vertical surface from stations (z, x_leading_edge, chord, thickness_ratio) in the x-y plane."""
    ex, ey = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    rings = [_ring(_airfoil(c, t, n_side), (xle, 0.0, z), ex, ey) for (z, xle, c, t) in stations]
    return loft_mesh(rings)


def _prop_blades(radius: float, blade_angle: float, spin: float) -> Mesh:
    """Two-blade propeller spinning about local +z at the origin; blade axis at ``blade_angle``.

    Blade sections are pitched (leading edge up for the given spin sign: +1 counter-clockwise seen from +z)
    and twisted (pitch falls toward the tip).
    """
    es = np.array([math.cos(blade_angle), math.sin(blade_angle), 0.0])
    ec = np.array([-math.sin(blade_angle), math.cos(blade_angle), 0.0])
    ez = np.array([0.0, 0.0, 1.0])
    # (fraction of radius, chord / radius, pitch deg)
    prof = [(0.06, 0.11, 22.0), (0.3, 0.15, 17.0), (0.7, 0.12, 11.0), (0.93, 0.08, 8.0), (1.0, 0.05, 7.0)]
    stations = [(-f, c, p) for f, c, p in prof[::-1]] + [(f, c, p) for f, c, p in prof]
    t = 0.035 * radius  # blade thickness
    rings = []
    for f, c, p in stations:
        phi = spin * math.copysign(1.0, f) * math.radians(p)
        u = math.cos(phi) * ec + math.sin(phi) * ez  # rotation of (ec, ez) about es by phi
        w = -math.sin(phi) * ec + math.cos(phi) * ez
        sec = np.array([[0.5, 0.0], [0.2, 0.5], [-0.25, 0.5], [-0.5, 0.0], [-0.25, -0.5], [0.2, -0.5]])
        sec = sec * [c * radius, t]
        rings.append(_ring(sec, f * radius * es, u, w))
    return loft_mesh(rings)


# ----------------------------------------------------------------------------------------------------
# argument checks
# ----------------------------------------------------------------------------------------------------

def _check_kind(kind: object) -> str:
    if not isinstance(kind, str) or kind not in KINDS:
        raise ValueError(f"unknown kind {kind!r}; valid kinds: {', '.join(KINDS)}")
    return kind


def _check_real(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(float(value)):
        raise ValueError(f"{name} must be a finite real number, got {value!r}")
    return float(value)


def _check_size(size_m: object) -> float:
    s = _check_real("size_m", size_m)
    if s <= 0.0:
        raise ValueError(f"size_m must be > 0 (overall span in metres), got {size_m!r}")
    return s


# ----------------------------------------------------------------------------------------------------
# rotor layout (shared by build_asset and rotor_positions_m)
# ----------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Multirotor:
    n: int
    arm_angles: np.ndarray  # rad, arm i direction in the x-y plane
    arm_r: float  # hub distance from the centre (fraction of span)
    prop_r: float  # prop radius (fraction of span); 2 * (arm_r + prop_r) == 1
    hub_z: float  # hub height (fraction of span)


_QUAD = _Multirotor(4, np.radians([45.0, 135.0, 225.0, 315.0]), 0.30, 0.20, 0.062)
_HEXA = _Multirotor(6, np.radians([30.0, 90.0, 150.0, 210.0, 270.0, 330.0]), 0.35, 0.15, 0.052)
_FW_HUB_X = 0.283  # fixed-wing nose prop hub x (fraction of span)
_FW_PROP_R = 0.075
_HELI_HUB_Z = 0.075          # main rotor hub height above the cabin centre (fraction of rotor diameter)
_HELI_TAIL_X = -0.60         # tail rotor hub x
_HELI_TAIL_R = 0.085         # tail rotor radius
HELI_TAIL_GEAR = 5.5         # tail rotor turns this many times per main rotor turn (typical 5-6)


def rotor_count(kind: str) -> int:
    """Number of rotors/propellers: 4 quadcopter, 6 hexacopter, 1 fixed_wing (nose puller), 0 bird/airliner."""
    return {"quadcopter": 4, "hexacopter": 6, "fixed_wing": 1, "bird": 0, "airliner": 0,
            "helicopter": 1}[_check_kind(kind)]


def blade_count(kind: str) -> int:
    """Blades per rotor: 2 for multirotors and the fixed wing, 0 for kinds without rotors."""
    return 2 if rotor_count(kind) > 0 else 0


def rotor_spin_signs(kind: str) -> np.ndarray:
    """(n_rotors,) +1 = counter-clockwise seen from the thrust side, -1 = clockwise;
    blade angle = base + sign * rotor_angle."""
    n = rotor_count(kind)
    return np.array([1.0 if i % 2 == 0 else -1.0 for i in range(n)])


def rotor_positions_m(kind: str, size_m: float) -> np.ndarray:
    """(n_rotors, 3) hub centres in the object frame, metres (empty (0, 3) for bird and airliner)."""
    kind = _check_kind(kind)
    s = _check_size(size_m)
    if kind in ("quadcopter", "hexacopter"):
        lay = _QUAD if kind == "quadcopter" else _HEXA
        a = lay.arm_angles
        return s * np.stack([lay.arm_r * np.cos(a), lay.arm_r * np.sin(a), np.full(lay.n, lay.hub_z)], axis=1)
    if kind == "fixed_wing":
        return s * np.array([[_FW_HUB_X, 0.0, 0.0]])
    if kind == "helicopter":   # the main rotor hub (the tail rotor turns with it, geared)
        return s * np.array([[0.0, 0.0, _HELI_HUB_Z]])
    return np.zeros((0, 3))


# ----------------------------------------------------------------------------------------------------
# assets (built at unit span, scaled at the end)
# ----------------------------------------------------------------------------------------------------

def _multirotor(lay: _Multirotor, rotor_angle: float, hexa: bool) -> list[tuple[str, str, Mesh]]:
    parts: list[tuple[str, str, Mesh]] = []
    ex, ey = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    if hexa:
        bl, bw, bh, p = 0.20, 0.20, 0.06, 2.6
    else:
        bl, bw, bh, p = 0.24, 0.15, 0.075, 3.5
    # rounded body: superellipse section, chamfered top and bottom
    zs = [(-0.5, 0.72), (-0.3, 1.0), (0.3, 1.0), (0.5, 0.8)]
    body = loft_mesh([_ring(_superellipse(24, 0.5 * bl * k, 0.5 * bw * k, p), (0, 0, z * bh), ex, ey) for z, k in zs])
    parts.append(("body", "body", body))
    arm_w, arm_h, arm_z = 0.028, 0.02, 0.0
    motor_r, motor_top = 0.03, lay.hub_z - 0.008
    for i, a in enumerate(lay.arm_angles):
        r0, r1 = 0.06, lay.arm_r + 0.01
        arm = box_mesh((0.5 * (r0 + r1), 0.0, arm_z), (r1 - r0, arm_w, arm_h))
        parts.append((f"arm_{i}", "arm", _xf(arm, _rot("z", a))))
    spins = rotor_spin_signs("hexacopter" if hexa else "quadcopter")
    for i, a in enumerate(lay.arm_angles):
        hub = (lay.arm_r * math.cos(a), lay.arm_r * math.sin(a), lay.hub_z)
        motor = _merge(
            cylinder_mesh(14, motor_r, arm_z - 0.4 * arm_h, motor_top),
            frustum_mesh(10, 0.35 * motor_r, 0.25 * motor_r, motor_top - 0.002, lay.hub_z),  # shaft/hub
        )
        parts.append((f"motor_{i}", "motor", _xf(motor, None, (hub[0], hub[1], 0.0))))
        blades = _prop_blades(lay.prop_r, float(a) + spins[i] * rotor_angle, spins[i])
        parts.append((f"prop_{i}", "prop", _xf(blades, None, hub)))
    if hexa:
        parts.append(("battery", "battery", box_mesh((0.0, 0.0, -0.5 * bh - 0.022), (0.14, 0.07, 0.045))))
        gimbal = _merge(
            box_mesh((0.075, 0.0, -0.5 * bh - 0.025), (0.025, 0.03, 0.04)),
            box_mesh((0.08, 0.0, -0.5 * bh - 0.062), (0.06, 0.055, 0.045)),
        )
        parts.append(("camera", "camera", gimbal))
    else:
        parts.append(("battery", "battery", box_mesh((-0.01, 0.0, 0.5 * bh + 0.012), (0.15, 0.085, 0.03))))
        gimbal = _merge(
            box_mesh((0.085, 0.0, -0.5 * bh - 0.012), (0.02, 0.025, 0.03)),
            box_mesh((0.09, 0.0, -0.5 * bh - 0.038), (0.045, 0.05, 0.04)),
        )
        parts.append(("camera", "camera", gimbal))
        # landing skids (two thin legs + rails), part of the body shell set
        for side in (1.0, -1.0):
            leg_f = _xf(box_mesh((0.0, 0.0, -0.07), (0.012, 0.012, 0.09)), _rot("x", side * 0.35),
                        (0.05, side * 0.05, 0.0))
            leg_b = _xf(box_mesh((0.0, 0.0, -0.07), (0.012, 0.012, 0.09)), _rot("x", side * 0.35),
                        (-0.05, side * 0.05, 0.0))
            rail = box_mesh((0.0, side * 0.0745, -0.1135), (0.17, 0.012, 0.012))
            parts.append((f"skid_{'left' if side > 0 else 'right'}", "body", _merge(leg_f, leg_b, rail)))
    return parts


def _fixed_wing(rotor_angle: float) -> list[tuple[str, str, Mesh]]:
    ey, ez = np.array([0, 1.0, 0]), np.array([0, 0, 1.0])
    # fuselage stations (x, half-width, half-height, centre z)
    st = [(0.262, 0.012, 0.013, 0.0), (0.252, 0.026, 0.029, 0.0), (0.232, 0.036, 0.040, 0.0),
          (0.19, 0.041, 0.047, 0.002),
          (0.05, 0.042, 0.048, 0.004), (-0.06, 0.036, 0.040, 0.004), (-0.16, 0.017, 0.019, 0.006),
          (-0.33, 0.011, 0.012, 0.008), (-0.40, 0.008, 0.009, 0.008)]
    fus = loft_mesh([_ring(_superellipse(16, hw, hh, 2.4), (x, 0, zc), ey, ez) for x, hw, hh, zc in st])
    parts: list[tuple[str, str, Mesh]] = [("fuselage", "fuselage", fus)]
    dihedral = math.tan(math.radians(3.0))
    c_root, c_tip, z_w = 0.17, 0.11, 0.042
    wing = _wing_loft([(y, 0.25 * c, z_w + y * dihedral, c, 0.12)
                       for y, c in ((0.0, c_root), (0.25, 0.5 * (c_root + c_tip)), (0.5, c_tip))])
    parts.append(("wing_left", "wing", wing))
    parts.append(("wing_right", "wing", _xf(wing, _MIRROR_Y)))
    htp = _wing_loft([(y, -0.305 + 0.01 * y / 0.15, 0.012, c, 0.09) for y, c in ((0.0, 0.075), (0.15, 0.055))])
    parts.append(("tail_h", "tail", _merge(htp, _xf(htp, _MIRROR_Y))))
    fin = _fin_loft([(0.0, -0.30, 0.09, 0.09), (0.12, -0.335, 0.055, 0.09)])
    parts.append(("tail_v", "tail", fin))
    spinner = loft_mesh([_ring(_circle(12, 0.015), (x, 0, 0), ey, ez) for x in (0.255, 0.275)],
                        end_apex=np.array([0.30, 0.0, 0.0]))
    parts.append(("motor", "motor", spinner))
    blades = _prop_blades(_FW_PROP_R, rotor_angle, 1.0)
    # local +z (spin axis) -> +x (thrust forward); local x -> -z
    parts.append(("prop_0", "prop", _xf(blades, _rot("y", math.pi / 2), (_FW_HUB_X, 0.0, 0.0))))
    return parts


def _bird(flap: float) -> list[tuple[str, str, Mesh]]:
    ey, ez = np.array([0, 1.0, 0]), np.array([0, 0, 1.0])
    parts: list[tuple[str, str, Mesh]] = [
        ("body", "body", ellipsoid_mesh((0.0, 0.0, 0.0), (0.14, 0.055, 0.058), 16, 10)),
        ("head", "head", ellipsoid_mesh((0.155, 0.0, 0.03), (0.045, 0.038, 0.04), 12, 7)),
    ]
    beak = loft_mesh([_ring(_circle(8, 0.011, 0.008), (0.19, 0, 0.025), ey, ez)],
                     end_apex=np.array([0.235, 0.0, 0.018]))
    parts.append(("beak", "head", beak))
    # tail fan: flat hexagonal section widening rearward
    tail_st = [(-0.09, 0.035, 0.012), (-0.17, 0.055, 0.007), (-0.25, 0.075, 0.004)]
    fan = loft_mesh([_ring(np.array([[w, 0], [0.5 * w, t], [-0.5 * w, t], [-w, 0], [-0.5 * w, -t], [0.5 * w, -t]]),
                           (x, 0, 0.005 + 0.1 * (x + 0.09)), ey, ez) for x, w, t in tail_st])
    parts.append(("tail", "feather", fan))
    # left wing in the local frame (x, s along the span, z), then rotated about the shoulder x axis
    shoulder = np.array([0.03, 0.04, 0.02])
    length = 0.5 - shoulder[1]
    # (span fraction, x of leading edge rel. shoulder, chord, thickness ratio)
    st = [(0.0, 0.06, 0.15, 0.16), (0.2, 0.065, 0.16, 0.11), (0.45, 0.06, 0.14, 0.09),
          (0.72, 0.03, 0.11, 0.08), (0.92, -0.02, 0.075, 0.07), (1.0, -0.05, 0.035, 0.08)]
    ex = np.array([1.0, 0, 0])
    wing = loft_mesh([_ring(_airfoil(c, t, 5), (xle, f * length, 0.0), ex, ez) for f, xle, c, t in st])
    angle = BIRD_FLAP_AMPLITUDE_RAD * math.sin(flap)
    wing = _xf(wing, _rot("x", angle), shoulder)
    parts.append(("wing_left", "wing", wing))
    parts.append(("wing_right", "wing", _xf(wing, _MIRROR_Y)))
    return parts


def _airliner() -> list[tuple[str, str, Mesh]]:
    ey, ez = np.array([0, 1.0, 0]), np.array([0, 0, 1.0])
    r = 0.056
    # (x, radius fraction, centre z): nose ogive, constant section, upswept tail cone
    nose = [(0.45, 0.14, -0.02), (0.445, 0.38, -0.016), (0.435, 0.56, -0.012), (0.42, 0.72, -0.008),
            (0.40, 0.85, -0.005), (0.375, 0.94, -0.002), (0.345, 0.99, 0.0), (0.32, 1.0, 0.0)]
    mid = [(0.15, 1.0, 0.0), (-0.05, 1.0, 0.0), (-0.25, 1.0, 0.0)]
    tail = [(-0.33, 0.93, 0.004), (-0.41, 0.76, 0.012), (-0.49, 0.52, 0.022), (-0.56, 0.30, 0.031),
            (-0.60, 0.16, 0.036)]
    rings = [_ring(_circle(24, r * k, r * k, math.pi / 2), (x, 0, r * zc / 0.056), ey, ez)
             for x, k, zc in nose + mid + tail]
    parts: list[tuple[str, str, Mesh]] = [("fuselage", "fuselage", loft_mesh(rings))]
    sweep = math.tan(math.radians(27.0))
    dih = math.tan(math.radians(5.0))
    le0, z0 = 0.10, -0.035
    # (y, x leading edge, z, chord, thickness ratio); trailing edge straight (unswept) inboard of the kink
    stations = [(y, le0 - y * sweep, z0 + y * dih, c, t) for y, c, t in (
        (0.0, 0.19, 0.14), (0.05, 0.19 - 0.05 * sweep, 0.135), (0.18, 0.19 - 0.18 * sweep, 0.12), (0.5, 0.045, 0.10))]
    wing = _wing_loft(stations, n_side=7)
    parts.append(("wing_left", "wing", wing))
    parts.append(("wing_right", "wing", _xf(wing, _MIRROR_Y)))
    # engines: nacelle (flat inlet and exhaust faces) plus pylon
    ye = 0.165
    xle_e = le0 - ye * sweep
    zw = z0 + ye * dih
    ze = zw - 0.062
    nac_st = [(xle_e + 0.085, 0.030), (xle_e + 0.07, 0.034), (xle_e + 0.02, 0.034), (xle_e - 0.02, 0.028),
              (xle_e - 0.04, 0.020)]
    nac = loft_mesh([_ring(_circle(16, rr), (x, 0, 0), ey, ez) for x, rr in nac_st])
    pylon = box_mesh((xle_e - 0.005, 0.0, 0.5 * (0.03 + (zw - ze))), (0.07, 0.008, (zw - ze) - 0.03 + 0.01))
    engine = _xf(_merge(nac, pylon), None, (0.0, ye, ze))
    parts.append(("engine_left", "engine", engine))
    parts.append(("engine_right", "engine", _xf(engine, _MIRROR_Y)))
    # horizontal stabiliser and fin
    hsw, hdih = math.tan(math.radians(32.0)), math.tan(math.radians(6.0))
    htp = _wing_loft([(y, -0.43 - y * hsw, 0.012 + y * hdih, c, 0.10) for y, c in ((0.0, 0.10), (0.175, 0.035))])
    parts.append(("stabiliser_left", "tail", htp))
    parts.append(("stabiliser_right", "tail", _xf(htp, _MIRROR_Y)))
    fsw = math.tan(math.radians(38.0))
    fin = _fin_loft([(z, -0.38 - (z - 0.03) * fsw, c, 0.11) for z, c in ((0.03, 0.17), (0.23, 0.065))])
    parts.append(("fin", "tail", fin))
    return parts


def _rotor_blades(radius: float, n_blades: int, angle: float, chord: float) -> Mesh:
    """``n_blades`` flat untwisted blades (root at 0.12 r) spinning about local +z, blade 0 at ``angle``."""
    meshes = []
    t = 0.012 * radius
    for k in range(n_blades):
        a = angle + 2 * math.pi * k / n_blades
        es = np.array([math.cos(a), math.sin(a), 0.0])
        ec = np.array([-math.sin(a), math.cos(a), 0.0])
        sec = np.array([[0.5, 0.0], [0.2, 0.5], [-0.25, 0.5], [-0.5, 0.0], [-0.25, -0.5], [0.2, -0.5]]) * [chord, t]
        meshes.append(loft_mesh([_ring(sec, f * radius * es, ec, np.array([0.0, 0.0, 1.0])) for f in (0.12, 0.6, 1.0)]))
    return _merge(*meshes)


def _helicopter(rotor_angle: float, main_blades: int) -> list[tuple[str, str, Mesh]]:
    """A light single-engine helicopter at unit main-rotor diameter: cabin, tail boom and fin, skids,
    engine with a rearward exhaust on the cabin roof, main rotor and a geared tail rotor (left side)."""
    ey, ez = np.array([0, 1.0, 0]), np.array([0, 0, 1.0])
    # cabin + boom as one loft (x, half-width, half-height, centre z)
    st = [(0.22, 0.02, 0.03, -0.03), (0.20, 0.055, 0.065, -0.02), (0.14, 0.075, 0.085, -0.005), (0.04, 0.08, 0.09, 0.0),
          (-0.07, 0.075, 0.085, 0.0), (-0.13, 0.045, 0.05, 0.01), (-0.2, 0.022, 0.025, 0.02),
          (-0.58, 0.012, 0.014, 0.03)]
    fus = loft_mesh([_ring(_superellipse(16, hw, hh, 2.2), (x, 0, zc), ey, ez) for x, hw, hh, zc in st])
    parts: list[tuple[str, str, Mesh]] = [("fuselage", "fuselage", fus)]
    fin = _fin_loft([(0.02, -0.56, 0.07, 0.1), (0.12, -0.60, 0.04, 0.1)])
    parts.append(("fin", "tail", fin))
    engine = ellipsoid_mesh((-0.04, 0.0, 0.085), (0.085, 0.04, 0.03), 14, 8)
    parts.append(("engine", "engine", engine))
    exhaust = loft_mesh([_ring(_circle(10, 0.016), (x, 0, 0.09), ey, ez) for x in (-0.11, -0.15)])
    parts.append(("exhaust", "exhaust", exhaust))
    mast = cylinder_mesh(8, 0.008, 0.09, _HELI_HUB_Z)
    skids = []
    for side in (1.0, -1.0):
        rail = box_mesh((0.03, side * 0.085, -0.13), (0.3, 0.012, 0.012))
        leg_f = box_mesh((0.1, side * 0.07, -0.105), (0.012, 0.01, 0.05))
        leg_b = box_mesh((-0.05, side * 0.07, -0.105), (0.012, 0.01, 0.05))
        skids.append(_merge(rail, leg_f, leg_b))
    parts.append(("mast_skids", "body", _merge(mast, *skids)))
    main = _xf(_rotor_blades(0.5, main_blades, rotor_angle, 0.05), None, (0.0, 0.0, _HELI_HUB_Z))
    parts.append(("main_rotor", "prop", main))
    tail = _rotor_blades(_HELI_TAIL_R, 2, HELI_TAIL_GEAR * rotor_angle, 0.02)
    # spin axis local +z -> +y (the tail rotor disc stands vertical on the boom's left side)
    parts.append(("tail_rotor", "prop", _xf(tail, _rot("x", -math.pi / 2), (_HELI_TAIL_X, 0.025, 0.07))))
    return parts


def build_asset(kind: str, size_m: float, *, flap_phase_rad: float = 0.0, rotor_angle_rad: float = 0.0,
                main_blades: int = 4) -> list[MeshPart]:
    """Closed, watertight triangle meshes per part for ``kind`` scaled to overall span ``size_m``.

    Span: multirotors = diagonal motor-to-motor distance + 2 prop radii (tip-to-tip of the prop discs);
    fixed_wing / bird / airliner = wingspan (bird: with the wings level, i.e. sin(flap_phase_rad) = 0);
    helicopter = main rotor diameter (``main_blades`` blades; the tail rotor turns HELI_TAIL_GEAR x faster).
    ``rotor_angle_rad`` turns the props (rotor i at base_i + rotor_spin_signs(kind)[i] * rotor_angle_rad);
    ``flap_phase_rad`` sets the bird wing dihedral BIRD_FLAP_AMPLITUDE_RAD * sin(flap_phase_rad).
    """
    kind = _check_kind(kind)
    s = _check_size(size_m)
    flap = _check_real("flap_phase_rad", flap_phase_rad)
    rot = _check_real("rotor_angle_rad", rotor_angle_rad)
    if kind == "quadcopter":
        raw = _multirotor(_QUAD, rot, hexa=False)
    elif kind == "hexacopter":
        raw = _multirotor(_HEXA, rot, hexa=True)
    elif kind == "fixed_wing":
        raw = _fixed_wing(rot)
    elif kind == "bird":
        raw = _bird(flap)
    elif kind == "helicopter":
        if isinstance(main_blades, bool) or not isinstance(main_blades, int) or not 2 <= main_blades <= 8:
            raise ValueError(f"main_blades must be an integer in [2, 8], got {main_blades!r}")
        raw = _helicopter(rot, main_blades)
    else:
        raw = _airliner()
    return [_part(name, role, (v * s, f)) for name, role, (v, f) in raw]
