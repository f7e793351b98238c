"""Procedural terrain geometry (renderer-free): the ground disc, tree lines, buildings and masts of a
scene's ``terrain`` as one triangle mesh with per-vertex asset, normal and texture.

World frame as everywhere (ENU metres, +z up); the ground is z = 0 under the camera rig (whose
position_m z is its height above ground). Every random draw comes from the generator passed in
(the caller derives it from the scene seed), so the same seed gives the same terrain.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from scenes.schema import Building, Mast, Scenario, Terrain, TreeLine
from scenes.terrain_assets import TERRAIN_ASSETS

ASSET_NAMES: tuple[str, ...] = tuple(TERRAIN_ASSETS)
GROUND_RINGS = 80
GROUND_SECTORS = 512
GROUND_INNER_M = 0.5
TREE_COLUMN_M = 3.0          # widest spacing of crown columns along a tree line
TREE_COLUMN_PX = 6.0         # ... and at most this many pixels of the sharpest camera (narrow fields of view)
MIN_TREE_COLUMN_M = 0.8
MAX_TREE_COLUMNS = 4000
RELIEF_TAPER_M = (50.0, 250.0)  # relief is zero within the first radius, full beyond the second


@dataclass
class TerrainMesh:
    """One mesh: vertices (N, 3) world metres, faces (M, 3), and per vertex: the asset index into
    ASSET_NAMES, a unit normal, an albedo multiplier and a surface-temperature offset (K)."""

    vertices: np.ndarray
    faces: np.ndarray
    asset: np.ndarray
    normal: np.ndarray
    texture: np.ndarray
    temperature_offset_k: np.ndarray

    @property
    def extent_m(self) -> float:
        """Largest horizontal distance of any vertex from the mesh origin column (the rig)."""
        return float(np.max(np.hypot(self.vertices[:, 0] - self._cx, self.vertices[:, 1] - self._cy)))

    _cx: float = 0.0
    _cy: float = 0.0

    def subset(self, face_mask: np.ndarray) -> tuple["TerrainMesh", np.ndarray]:
        """(the mesh of the masked faces, the original index of each kept vertex)."""
        faces = self.faces[np.asarray(face_mask, bool)]
        keep = np.unique(faces)
        remap = np.full(len(self.vertices), -1, np.int64)
        remap[keep] = np.arange(len(keep))
        m = TerrainMesh(self.vertices[keep], remap[faces], self.asset[keep], self.normal[keep], self.texture[keep],
                        self.temperature_offset_k[keep])
        m._cx, m._cy = self._cx, self._cy
        return m, keep


class _Noise:
    """Seeded smooth 2-D value noise (bilinear on a periodic lattice), sum of octaves, ~unit rms."""

    def __init__(self, rng: np.random.Generator, cells_m: tuple[float, ...], grid: int = 128):
        self.cells_m = cells_m
        self.grids = [rng.standard_normal((grid, grid)) for _ in cells_m]
        self.grid = grid

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        out = np.zeros(np.shape(x))
        for cell, g in zip(self.cells_m, self.grids):
            gx, gy = np.asarray(x) / cell, np.asarray(y) / cell
            i0, j0 = np.floor(gx).astype(np.int64), np.floor(gy).astype(np.int64)
            fx, fy = gx - i0, gy - j0
            fx, fy = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy)   # smoothstep: no creases at cell edges
            n = self.grid
            a, b = g[j0 % n, i0 % n], g[j0 % n, (i0 + 1) % n]
            c, d = g[(j0 + 1) % n, i0 % n], g[(j0 + 1) % n, (i0 + 1) % n]
            out += (a * (1 - fx) + b * fx) * (1 - fy) + (c * (1 - fx) + d * fx) * fy
        return out / math.sqrt(len(self.cells_m)) * 1.6


def _texture_multiplier(noise: np.ndarray | float, texture: float) -> np.ndarray:
    return np.exp(texture * noise)   # lognormal: positive, median 1


class _Relief:
    """Height of gently rolling ground: a few seeded long-wave ripples, zero near the rig."""

    def __init__(self, rng: np.random.Generator, relief_m: float, cx: float, cy: float):
        self.relief_m, self.cx, self.cy = relief_m, cx, cy
        k = 5
        self.wavelength = rng.uniform(250.0, 900.0, k)
        self.direction = rng.uniform(0.0, 2 * np.pi, k)
        self.phase = rng.uniform(0.0, 2 * np.pi, k)

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        if self.relief_m == 0.0:
            return np.zeros(np.shape(x))
        h = np.zeros(np.shape(x))
        for lam, d, p in zip(self.wavelength, self.direction, self.phase):
            h += np.sin(2 * np.pi * ((x - self.cx) * np.cos(d) + (y - self.cy) * np.sin(d)) / lam + p)
        r = np.hypot(x - self.cx, y - self.cy)
        lo, hi = RELIEF_TAPER_M
        taper = np.clip((r - lo) / (hi - lo), 0.0, 1.0)
        return self.relief_m * math.sqrt(2.0 / len(self.wavelength)) * h * taper


def _compass(azimuth_deg: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    a = np.radians(azimuth_deg)
    return np.sin(a), np.cos(a)   # east, north


class _Builder:
    def __init__(self):
        self.v, self.f, self.asset, self.n, self.tex, self.dt = [], [], [], [], [], []
        self.count = 0

    def add(self, vertices, faces, asset: str, normals, texture, dt_k) -> None:
        nv = len(vertices)
        self.v.append(np.asarray(vertices, np.float64))
        self.f.append(np.asarray(faces, np.int64) + self.count)
        self.asset.append(np.full(nv, ASSET_NAMES.index(asset), np.int16))
        self.n.append(np.broadcast_to(np.asarray(normals, np.float64), (nv, 3)))
        self.tex.append(np.broadcast_to(np.asarray(texture, np.float64), (nv,)))
        self.dt.append(np.broadcast_to(np.asarray(dt_k, np.float64), (nv,)))
        self.count += nv

    def mesh(self, cx: float, cy: float) -> TerrainMesh:
        v, f, n = np.vstack(self.v), np.vstack(self.f), np.vstack(self.n)
        # wind every face so its geometric normal agrees with its vertices' normals: a renderer's
        # area emitter emits on the front side only
        geometric = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        flip = np.einsum("ij,ij->i", geometric, n[f].sum(axis=1)) < 0
        f[flip] = f[flip][:, ::-1]
        m = TerrainMesh(v, f, np.concatenate(self.asset), n, np.concatenate(self.tex), np.concatenate(self.dt))
        m._cx, m._cy = cx, cy
        return m


def _ground(b: _Builder, terrain: Terrain, relief: _Relief, noise: _Noise, cx: float, cy: float) -> None:
    asset = TERRAIN_ASSETS[terrain.ground]
    radii = GROUND_INNER_M * (terrain.ground_radius_m / GROUND_INNER_M) ** (np.arange(GROUND_RINGS + 1) / GROUND_RINGS)
    theta = np.arange(GROUND_SECTORS) / GROUND_SECTORS * 2 * np.pi
    rr, tt = np.meshgrid(radii, theta, indexing="ij")
    x, y = cx + rr * np.cos(tt), cy + rr * np.sin(tt)
    z = relief(x, y)
    centre = np.array([[cx, cy, 0.0]])
    verts = np.vstack([centre, np.stack([x, y, z], -1).reshape(-1, 3)])
    # normals from the height field's gradient (central differences, 1 m)
    dzdx = (relief(x + 1, y) - relief(x - 1, y)) / 2
    dzdy = (relief(x, y + 1) - relief(x, y - 1)) / 2
    normals = np.stack([-dzdx, -dzdy, np.ones_like(dzdx)], -1).reshape(-1, 3)
    normals = np.vstack([[0.0, 0.0, 1.0], normals / np.linalg.norm(normals, axis=1, keepdims=True)])
    idx = 1 + np.arange((GROUND_RINGS + 1) * GROUND_SECTORS).reshape(GROUND_RINGS + 1, GROUND_SECTORS)
    nxt = np.roll(idx, -1, axis=1)
    faces = [np.stack([np.zeros(GROUND_SECTORS, np.int64), idx[0], nxt[0]], -1)]
    a, bb, c, d = idx[:-1], nxt[:-1], idx[1:], nxt[1:]
    faces.append(np.stack([a, c, d], -1).reshape(-1, 3))
    faces.append(np.stack([a, d, bb], -1).reshape(-1, 3))
    n = noise(verts[:, 0], verts[:, 1])
    b.add(verts, np.vstack(faces), terrain.ground, normals, _texture_multiplier(n, asset.texture),
          asset.temperature_texture_k * n)


def _tree_line(b: _Builder, line: TreeLine, relief: _Relief, rng: np.random.Generator, cx: float, cy: float,
               pixel_rad: float) -> None:
    asset = TERRAIN_ASSETS[line.asset]
    height = line.height_m if line.height_m is not None else asset.height_m
    a0, a1 = line.azimuth_deg
    arc_m = math.radians(a1 - a0) * line.distance_m
    column_m = float(np.clip(TREE_COLUMN_PX * pixel_rad * line.distance_m, MIN_TREE_COLUMN_M, TREE_COLUMN_M))
    n = int(min(MAX_TREE_COLUMNS, max(2, math.ceil(arc_m / column_m) + 1)))
    az = np.linspace(a0, a1, n)
    e, nn = _compass(az)
    # the tree line's edge is not a perfect arc: its distance wanders by a few per cent
    wander = 1.0 + 0.04 * np.convolve(rng.standard_normal(n + 8), np.ones(9) / 3.0, mode="valid")[:n]
    dist = line.distance_m * wander
    x, y = cx + dist * e, cy + dist * nn
    base = relief(x, y) - 1.0
    # crowns: trees 4-9 m wide along the line, each a rounded (half-ellipse) crown on its own height,
    # the line's top is the highest crown over each column; slow variation along the line on top
    along = np.linspace(0.0, arc_m, n)
    widths = rng.uniform(4.0, 9.0, int(arc_m / 4.0) + 3)
    centres = np.cumsum(widths) - widths / 2 - widths[0]
    tree_h = height * np.clip(1.0 + line.height_jitter * 0.6 * rng.standard_normal(len(widths)), 0.3, 2.0)
    slow = np.convolve(rng.standard_normal(n + 30), np.ones(31) / math.sqrt(31.0), mode="valid")[:n]
    k = np.clip(np.searchsorted(centres, along), 1, len(centres) - 2)
    top = np.zeros(n)
    for shift in (-1, 0, 1):
        j = k + shift
        r = 0.55 * widths[j]
        u = np.clip(1.0 - ((along - centres[j]) / r) ** 2, 0.0, None)
        top = np.maximum(top, np.where(u > 0, tree_h[j] - 0.6 * r + 0.6 * r * np.sqrt(u), 0.0))
    top = np.maximum(top, 0.45 * height) * np.clip(1.0 + line.height_jitter * 0.5 * slow, 0.5, 1.5)
    smooth_top = top
    fractions = (0.0, 0.5, 0.8, 1.0)
    rows = [base + f * (top if f < 0.9 else 0.5 * (top + smooth_top)) for f in fractions]
    rows[2] = base + 0.8 * (0.6 * top + 0.4 * smooth_top)
    n_rows = len(rows)
    verts = np.vstack([np.stack([x, y, r], -1) for r in rows])
    inward = -np.stack([e, nn, np.zeros(n)], -1)   # normals face the rig
    normals = np.vstack([inward] * n_rows)
    faces = []
    for row in range(n_rows - 1):
        i = np.arange(n - 1) + row * n
        faces.append(np.stack([i, i + 1, i + n + 1], -1))
        faces.append(np.stack([i, i + n + 1, i + n], -1))
    column_tex = rng.standard_normal(n)
    leaf_tex = rng.standard_normal((n_rows, n))   # per-vertex speckle: foliage is not a smooth wall
    tex = np.concatenate([column_tex * (0.6 + 0.4 * f) + 0.8 * leaf_tex[j] for j, f in enumerate(fractions)])
    dt = np.concatenate([(f - 0.5) * 0.6 * np.ones(n) for f in fractions]) * asset.temperature_texture_k \
        + asset.temperature_texture_k * (0.5 * np.tile(column_tex, n_rows) + 0.5 * leaf_tex.ravel())
    b.add(verts, np.vstack(faces), line.asset, normals, _texture_multiplier(tex, asset.texture), dt)


def _box(b: _Builder, asset_name: str, centre_xy: np.ndarray, yaw: float, size: tuple[float, float, float],
         base_z: float, texture: float, dt_k: float) -> None:
    """A box with its own 4 vertices per side (walls and roof keep their own normals)."""
    w, d, h = size
    c, s = math.cos(yaw), math.sin(yaw)
    ax, ay = np.array([c, s, 0.0]), np.array([-s, c, 0.0])
    sides = [(ax, ay, w / 2, d / 2), (-ax, ay, w / 2, d / 2), (ay, ax, d / 2, w / 2), (-ay, ax, d / 2, w / 2)]
    verts: list[np.ndarray] = []
    normals: list[np.ndarray] = []
    faces: list[tuple[int, int, int]] = []
    origin = np.array([centre_xy[0], centre_xy[1], base_z])
    for normal, along, half_out, half_along in sides:
        p0 = origin + normal * half_out
        quad = [p0 - along * half_along, p0 + along * half_along,
                p0 - along * half_along + [0, 0, h], p0 + along * half_along + [0, 0, h]]
        k = len(verts)
        verts += quad
        normals += [normal] * 4
        faces += [(k, k + 1, k + 3), (k, k + 3, k + 2)]
    roof = [origin + [0, 0, h] + sx * ax * w / 2 + sy * ay * d / 2 for sx, sy in ((-1, -1), (1, -1), (-1, 1), (1, 1))]
    k = len(verts)
    verts += roof
    normals += [np.array([0.0, 0.0, 1.0])] * 4
    faces += [(k, k + 1, k + 3), (k, k + 3, k + 2)]
    b.add(np.array(verts), np.array(faces), asset_name, np.array(normals), texture, dt_k)


def _structure(b: _Builder, item: Building | Mast, relief: _Relief, rng: np.random.Generator, cx: float,
               cy: float) -> None:
    asset = TERRAIN_ASSETS[item.asset]
    e, n = _compass(item.azimuth_deg)
    centre = np.array([cx + item.distance_m * e, cy + item.distance_m * n])
    size = (item.width_m or asset.width_m, item.depth_m or asset.depth_m, item.height_m or asset.height_m)
    facing = math.atan2(-n, -e) + float(rng.uniform(-0.5, 0.5))   # roughly facing the rig
    base = float(relief(np.array(centre[0]), np.array(centre[1]))) - 0.5
    tex = float(_texture_multiplier(rng.standard_normal(), asset.texture))
    _box(b, item.asset, centre, facing, size, base, tex, asset.temperature_texture_k * float(rng.standard_normal()))


def _procedural(p, rng: np.random.Generator) -> tuple[list[TreeLine], list[Building], list[Mast]]:
    def draw(pair):
        return float(rng.uniform(pair[0], pair[1]))

    def count(pair):
        return int(rng.integers(pair[0], pair[1] + 1))

    trees = []
    for _ in range(count(p.tree_lines)):
        start, span = draw((0.0, 360.0)), draw(p.tree_span_deg)
        trees.append(TreeLine(asset=p.tree_assets[int(rng.integers(len(p.tree_assets)))],
                              distance_m=draw(p.tree_distance_m),
                              azimuth_deg=(start, start + span)))
    buildings = [Building(asset=p.building_assets[int(rng.integers(len(p.building_assets)))],
                          distance_m=draw(p.building_distance_m), azimuth_deg=draw((0.0, 360.0)))
                 for _ in range(count(p.buildings))]
    masts = [Mast(asset=p.mast_assets[int(rng.integers(len(p.mast_assets)))],
                  distance_m=draw(p.mast_distance_m), azimuth_deg=draw((0.0, 360.0)))
             for _ in range(count(p.masts))]
    return trees, buildings, masts


def build_terrain(scenario: Scenario, rng: np.random.Generator) -> TerrainMesh:
    """The scene's terrain as one mesh (the scene must have ``terrain``)."""
    terrain = scenario.terrain
    if terrain is None:
        raise ValueError("scenario has no terrain")
    cx, cy = float(scenario.camera_rig.position_m[0]), float(scenario.camera_rig.position_m[1])
    relief = _Relief(rng, terrain.relief_m, cx, cy)
    noise = _Noise(rng, (160.0, 40.0, 9.0, 2.5))
    trees, buildings, masts = list(terrain.tree_lines), list(terrain.buildings), list(terrain.masts)
    if terrain.procedural is not None:
        t, bl, m = _procedural(terrain.procedural, rng)
        trees, buildings, masts = trees + t, buildings + bl, masts + m
    b = _Builder()
    _ground(b, terrain, relief, noise, cx, cy)
    rig = scenario.camera_rig
    pixel_rad = min(math.radians(rig.rgb.hfov_deg) / rig.rgb.width_px, math.radians(rig.thermal.hfov_deg)
                    / rig.thermal.width_px)
    for line in trees:
        _tree_line(b, line, relief, rng, cx, cy, pixel_rad)
    for item in list(buildings) + list(masts):
        _structure(b, item, relief, rng, cx, cy)
    return b.mesh(cx, cy)
