"""Mitsuba backend: a Timeline -> per-frame RGB radiance, thermal radiance, coverage masks.

One scene graph per camera, sharing geometry built from the same procedural meshes:
- RGB: Hosek-Wilkie ``sunsky`` sky (baked once into an environment map, with optional clouds) plus
  a directional sun, path traced. Visible haze is exact per object: reflectance is scaled by the
  transmittance t and the airlight (1 - t) A is added as emission, so L = t L_obj + (1 - t) A.
- Thermal: every part is an emitter of its at-sensor band radiance
  tau (eps L(T) + (1 - eps) L_refl) + L_path (LOWTRAN7 tables) over an LWIR sky map (simulator.physics.sky);
  one bounce suffices because the physics is folded into the emission (no Mitsuba thermal physics).
- Batched: many frames per launch (Mitsuba's ``batch`` sensor, one sub-sensor per tile; each frame's
  world is its own copy, see simulator.render.plan). Small frames are whole tiles; on large frames
  only a tile around each target is traced and the rest is the sky evaluated at pixel centres.
- Coverage (exact labels): a regular 8 x 8 grid of rays per pixel over each target's projected box,
  intersected with the same scene after the radiance launch; the shape each ray hits gives the
  target and part. Deterministic (no random samples), so identically placed cameras get identical
  masks and boxes; the pixel's coverage is the fraction of its rays that hit the target.
Mitsuba is imported lazily (simulator.render.mitsuba_setup) so nothing else depends on it.
"""
from __future__ import annotations

import warnings
import weakref
from collections.abc import Generator
from concurrent.futures import Future, ThreadPoolExecutor, wait
from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np

from scenes.defaults import material_for
from simulator.physics import thermal
from simulator.physics.sky import (
    CloudField,
    ThermalSky,
    direction_from_elevation_azimuth,
    sun_elevation_azimuth_deg,
)
from simulator.physics.timeline import Timeline
from simulator.render import scalar
from simulator.render.geometry import TrackGeometry
from simulator.render.plan import (
    BATCH_FRAMES,
    BATCH_PIXEL_BUDGET,
    COVERAGE_SUBSAMPLES,
    CameraPlan,
    Tile,
    pixel_box,
    place_tile,
    plan_camera,
    projected_boxes,
)
from simulator.seeding import render_seed, rng_for

if TYPE_CHECKING:
    from scenes.terrain import TerrainMesh

ENV_WIDTH = 2048
ENV_HEIGHT = 1024
SUN_SOLID_ANGLE_SR = 6.8e-5
RGB_MAX_DEPTH = 3
EXPOSURE_KEY = 0.45
PASS_INDEX = {"rgb": 0, "thermal": 1}  # render_seed pass index per camera
SCENE_BOUND_M = 1.0e6  # half-size of the fixed scene box (see _View: pins the kernels' bounding sphere)
JITTER_FRAME = 2**31 - 1  # render_seed "frame" of the per-camera primary-sample jitter seed


@dataclass
class TargetCoverage:
    """Where one target is in one camera's frame, from the coverage rays (exact labels).

    ``coverage`` holds, for the pixels ``[y0:y1, x0:x1]``, the fraction of each pixel covered by the
    target's visible silhouette (occlusion by other targets included). ``role_px`` is the covered
    area per part role in pixels; for the thermal camera ``role_radiance`` is each part's at-sensor
    band radiance and ``sky_radiance`` the sky behind the target (coverage-weighted), both
    W sr^-1 m^-2, for label contrast from the target's radiance rather than from partial pixels.
    """

    target_id: int
    region: tuple[int, int, int, int]       # x0, y0, x1, y1 (pixels, end exclusive)
    coverage: np.ndarray                    # (y1 - y0, x1 - x0) float32 in [0, 1]
    role_px: dict[str, float]
    role_radiance: dict[str, float] | None = None
    sky_radiance: float | None = None

    @property
    def visible_px(self) -> float:
        return float(self.coverage.sum())


@dataclass
class FrameBuffers:
    """Raw per-frame outputs (linear, float32) before encoding."""

    rgb_linear: np.ndarray | None        # (H, W, 3) linear sRGB radiance x exposure
    thermal_radiance: np.ndarray | None  # (H, W) W sr^-1 m^-2 at the sensor
    mask_rgb: np.ndarray | None          # (H, W) uint16 id of the target covering >= half the pixel, 0 = none
    mask_thermal: np.ndarray | None      # (H, W) uint16
    coverage: dict[str, list[TargetCoverage]] | None = None  # per camera, one entry per visible target

    @cached_property
    def thermal_kelvin(self) -> np.ndarray | None:
        """(H, W) float32 radiometric (brightness) temperature; computed on first use (by the
        writer threads, off the render loop)."""
        if self.thermal_radiance is None:
            return None
        return thermal.brightness_temperature(self.thermal_radiance).astype(np.float32)


@lru_cache(maxsize=2)
def _env_directions_cached(width: int, height: int, to_world_bytes: bytes) -> np.ndarray:
    out = _env_directions(width, height, np.frombuffer(to_world_bytes).reshape(3, 3))
    out.flags.writeable = False
    return out


@lru_cache(maxsize=2)
def _neg_directions_f32(width: int, height: int, to_world_bytes: bytes) -> np.ndarray:
    """(3, n) float32 of minus the upper-hemisphere texel directions (the ``wi`` of a sky lookup)."""
    top = _env_directions_cached(width, height, to_world_bytes)[: height // 2]
    out = np.ascontiguousarray(-top.reshape(-1, 3).T.astype(np.float32))
    out.flags.writeable = False
    return out


@lru_cache(maxsize=2)
def _sky_weights(width: int, height: int, to_world_bytes: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Per upper-hemisphere texel: the irradiance weight cos(zenith) x solid angle (flattened) and
    the near-horizon band the airlight is averaged over (``up`` in (0.01, 0.06))."""
    half = height // 2
    up = _env_directions_cached(width, height, to_world_bytes)[:half, :, 2]
    # texel solid angle depends on the row only: (2 pi / W)(pi / H) sin(theta_row)
    row_sa = (2 * np.pi / width) * (np.pi / height) * np.sin((np.arange(half) + 0.5) / height * np.pi)
    weight = (up * row_sa[:, None]).ravel()
    horizon = (up > 0.01) & (up < 0.06)
    weight.flags.writeable = horizon.flags.writeable = False
    return weight, horizon


def _env_directions(width: int, height: int, to_world: np.ndarray) -> np.ndarray:
    """World direction of each texel of a Mitsuba lat-long map (local +y up, phi = atan2(x, -z))."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    uu, vv = np.meshgrid(u, v)
    theta, phi = vv * np.pi, uu * 2 * np.pi
    local = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], -1)
    return local @ to_world.T


SKY_CACHE_SIZE = 2          # bakes kept per process, ~25 MB each (+8 MB with the LWIR map): a clip and its twin


@dataclass
class _SkyBake:
    """What SkyMaps computes from the sky parameters (and the cloud seed): shared between sequences."""

    sun_direction: np.ndarray
    sun_irradiance: np.ndarray
    sun_elevation_deg: float
    sky_irradiance: np.ndarray
    rgb: np.ndarray                          # a read-only view of rgb_bitmap's pixels
    rgb_bitmap: object                       # mi.Bitmap of the RGB map (the envmap plugin only reads it)
    airlight_rgb: np.ndarray
    thermal: np.ndarray | None = None        # the LWIR map, filled when a thermal camera first needs it
    thermal_sky: ThermalSky | None = None    # the LWIR sky model, made on first use


_SKY_BAKES: dict[tuple, _SkyBake] = {}      # insertion-ordered: the oldest is dropped first


def _sky_key(mi, timeline: Timeline) -> tuple:
    """Everything a sky bake depends on: variant, sky and atmosphere parameters, and the seed only
    when clouds (the one seeded part) are present."""
    scenario = timeline.scenario
    clouds = scenario.sky.clouds is not None and scenario.sky.clouds.coverage > 0
    return (mi.variant(), scenario.sky.model_dump_json(), scenario.atmosphere.model_dump_json(),
            int(timeline.seed) if clouds else None)


class SkyMaps:
    """The sky as seen by each sensor, baked into environment maps; the bake is memoised by the sky
    parameters (``_sky_key``, SKY_CACHE_SIZE bakes per process), so a clip's counterfactual twin or
    any clip under the same sky reuses it. The maps are read-only."""

    def __init__(self, mi, timeline: Timeline):
        scenario = timeline.scenario
        self.to_world = mi.ScalarTransform4f().rotate([1, 0, 0], 90)
        self._scenario, self._seed = scenario, timeline.seed
        key = _sky_key(mi, timeline)
        bake = _SKY_BAKES.get(key)
        if bake is None:
            bake = self._bake(mi, timeline)
            _SKY_BAKES[key] = bake
            while len(_SKY_BAKES) > SKY_CACHE_SIZE:
                _SKY_BAKES.pop(next(iter(_SKY_BAKES)))
        else:
            # the two helper emitters are created (and freed) on a hit too: the scene's own emitters
            # then get the same Dr.Jit registry ids as after a bake, so compiled kernels are reused
            sunsky = self._sunsky_dict(scenario)
            helpers = [mi.load_dict({**sunsky, "sun_scale": 0.0}), mi.load_dict({**sunsky, "sky_scale": 0.0})]
            del helpers
        self._bake_state = bake
        self.sun_direction = bake.sun_direction
        self.sun_irradiance = bake.sun_irradiance
        self.sun_elevation_deg = bake.sun_elevation_deg
        self.sky_irradiance = bake.sky_irradiance
        self.rgb = bake.rgb
        self.rgb_bitmap = bake.rgb_bitmap
        self.airlight_rgb = bake.airlight_rgb

    @staticmethod
    def _sunsky_dict(scenario) -> dict:
        sun_el, sun_az = sun_elevation_azimuth_deg(scenario.sky.sun)
        direction = direction_from_elevation_azimuth(sun_el, sun_az)
        return {"type": "sunsky", "sun_direction": direction.tolist(), "turbidity": scenario.sky.turbidity,
                "albedo": scenario.sky.ground_albedo}

    def _bake(self, mi, timeline: Timeline) -> _SkyBake:
        import drjit as dr

        scenario = timeline.scenario
        rot = np.ascontiguousarray(np.array(self.to_world.matrix, dtype=np.float64)[:3, :3])
        dirs = _env_directions_cached(ENV_WIDTH, ENV_HEIGHT, rot.tobytes())  # same for every sequence
        # rows [0, H/2) are exactly the texels above the horizon: the sky is evaluated there only,
        # the lower half is the ground (one colour)
        half = ENV_HEIGHT // 2
        top = dirs[:half]
        sun_el, sun_az = sun_elevation_azimuth_deg(scenario.sky.sun)
        sun_direction = direction_from_elevation_azimuth(sun_el, sun_az)
        sunsky = self._sunsky_dict(scenario)
        sky_only = mi.load_dict({**sunsky, "sun_scale": 0.0})
        wi = _neg_directions_f32(ENV_WIDTH, ENV_HEIGHT, rot.tobytes())
        sun_wi = -sun_direction
        # the map is written straight into the Bitmap the scenes' envmaps read (made once per bake;
        # the plugin copies it) and kept as a view of its pixels: one copy of the map in memory
        bitmap = mi.Bitmap(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, [ENV_WIDTH, ENV_HEIGHT])
        full = np.asarray(bitmap)
        rgb = full[:half]
        if is_scalar(mi):  # one direction per call (simulator.render.scalar)
            rgb[...] = scalar.eval_emitter(mi, sky_only, wi).reshape(half, ENV_WIDTH, 3)
            sun_only = mi.load_dict({**sunsky, "sky_scale": 0.0})
            sun_value = (scalar.eval_emitter(mi, sun_only, sun_wi[:, None]).astype(np.float64).ravel()
                         * SUN_SOLID_ANGLE_SR)
        else:
            si = dr.zeros(mi.SurfaceInteraction3f, wi.shape[1])
            si.wi = mi.Vector3f(wi[0], wi[1], wi[2])
            rgb.reshape(-1, 3)[...] = np.array(sky_only.eval(si), dtype=np.float32).T
            # both helper emitters are always created (and freed) in the same order, so the scene's
            # own emitters get the same Dr.Jit registry ids in every sequence and the compiled
            # kernels are reused instead of rebuilt per sequence
            sun_only = mi.load_dict({**sunsky, "sky_scale": 0.0})
            si1 = dr.zeros(mi.SurfaceInteraction3f, 1)
            si1.wi = mi.Vector3f(*[float(c) for c in sun_wi])
            sun_value = np.array(sun_only.eval(si1)).ravel() * SUN_SOLID_ANGLE_SR
            del si, si1
        sun_irradiance = sun_value if sun_el > 0 else np.zeros(3)
        del sky_only, sun_only
        weight, horizon = _sky_weights(ENV_WIDTH, ENV_HEIGHT, rot.tobytes())
        sky_irradiance = weight @ rgb.reshape(-1, 3).astype(np.float64)
        sun_cos = max(sun_direction[2], 0.0)
        ground = scenario.sky.ground_albedo * (sky_irradiance + sun_irradiance * sun_cos) / np.pi
        clouds = scenario.sky.clouds
        if clouds is not None and clouds.coverage > 0:
            cover = CloudField(clouds, timeline.seed).coverage(top).astype(np.float32)[..., None]
            cloud_rgb = (0.75 * (sky_irradiance + sun_irradiance * sun_cos) / np.pi).astype(np.float32)
            rgb += cover * (cloud_rgb - rgb)  # (1 - cover) rgb + cover cloud_rgb
            sun_irradiance = sun_irradiance * (1 - 0.8 * clouds.coverage)
        full[half:] = ground
        airlight = rgb[horizon].astype(np.float64).mean(axis=0)
        for a in (full, sun_direction, sun_irradiance, sky_irradiance, airlight):
            a.flags.writeable = False
        return _SkyBake(sun_direction, sun_irradiance, float(sun_el), sky_irradiance, full, bitmap, airlight)

    @property
    def thermal_sky(self) -> ThermalSky:
        """The LWIR sky model (kept with the bake: it depends on the same parameters)."""
        bake = self._bake_state
        if bake.thermal_sky is None:
            bake.thermal_sky = ThermalSky(self._scenario.sky, self._scenario.atmosphere, self._seed)
        return bake.thermal_sky

    @property
    def thermal(self) -> np.ndarray:
        """LWIR band radiance map (computed only when a thermal camera renders; kept with the bake)."""
        bake = self._bake_state
        if bake.thermal is None:
            rot = np.ascontiguousarray(np.array(self.to_world.matrix, dtype=np.float64)[:3, :3])
            directions = _env_directions_cached(ENV_WIDTH, ENV_HEIGHT, rot.tobytes())
            bake.thermal = self.thermal_sky.radiance(directions).astype(np.float32)
            bake.thermal.flags.writeable = False
        return bake.thermal

    @cached_property
    def reflected_lwir(self) -> float:
        return self.thermal_sky.reflected_radiance()

    def rgb_at(self, direction: np.ndarray) -> np.ndarray:
        """Sky colour in a world direction (nearest texel), used for exposure."""
        local = np.array(self.to_world.inverse().matrix)[:3, :3] @ direction
        u = (np.arctan2(local[0], -local[2]) / (2 * np.pi)) % 1.0
        v = np.arccos(np.clip(local[1], -1, 1)) / np.pi
        return self.rgb[min(int(v * ENV_HEIGHT), ENV_HEIGHT - 1), min(int(u * ENV_WIDTH), ENV_WIDTH - 1)]


def finite_radiance(image: np.ndarray) -> np.ndarray:
    """``image`` with every non-finite pixel (a NaN/inf path sample; seen on one pixel of a far airliner
    over terrain) replaced by the median of the finite values of its 3x3 neighbourhood (0 when there
    are none), as a film that rejects such samples would show it. Frames without one are returned
    unchanged (the same array, the same bytes)."""
    with np.errstate(over="ignore", invalid="ignore"):
        if np.isfinite(np.sum(image, dtype=np.float32)):    # NaN and inf reach the sum; all finite then
            return image
    finite = np.isfinite(image)
    if finite.all():                                      # finite values whose sum overflowed
        return image
    bad = ~finite.all(axis=-1) if image.ndim == 3 else ~finite
    out = np.where(finite, image, np.float32(np.nan)).astype(np.float32)
    for y, x in zip(*np.nonzero(bad)):
        window = out[max(0, y - 1):y + 2, max(0, x - 1):x + 2].reshape(-1, *image.shape[2:])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)   # an all-NaN window: 0 below
            out[y, x] = np.nan_to_num(np.nanmedian(window, axis=0), nan=0.0)
    out[~np.isfinite(out)] = 0.0
    warnings.warn(f"renderer: {int(bad.sum())} non-finite pixel(s) replaced by their neighbourhood median",
                  RuntimeWarning, stacklevel=2)
    return out


def is_scalar(mi) -> bool:
    """True on Mitsuba's scalar variants (one ray per call; see simulator.render.scalar)."""
    return mi.variant().startswith("scalar")


class _View:
    """One camera's batched Mitsuba scene and our own ray generation.

    The scene holds ONE mesh: ``batch_frames`` slot copies of every target part, faces ordered by
    (slot, target, role), with per-face reflectance/emission attributes (a single shape and emitter,
    so no per-part virtual calls and no light-selection dilution). Rays are generated here, per
    tile pixel and sample, with a pinhole matching Mitsuba's perspective sensor; the sub-pixel
    position of sample ``s`` of pixel ``(x, y)`` is a hash of (camera seed, pixel, s) only, so a
    pixel gets the same primary rays in ROI and full mode, in any batch slot and in every frame.
    """

    def __init__(self, owner: "SequenceRenderer", which: str, plan: CameraPlan):
        import drjit as dr

        self.dr = dr
        # a proxy, not a reference: no renderer <-> view cycle, so a dropped renderer frees its
        # Mitsuba scenes at once instead of at the next garbage collection
        self.owner, self.which, self.plan = weakref.proxy(owner), which, plan
        self.mi = mi = owner.mi
        self.camera = owner.timeline.cameras[which]
        rig = owner.rig
        self.spp = rig.rgb.spp if which == "rgb" else rig.thermal.spp
        self.jitter_seed = render_seed(owner.timeline.seed, JITTER_FRAME, PASS_INDEX[which])
        self.keys: list[tuple[int, int, str]] = []  # (slot, target index, role), in face order
        face_counts, vert_counts = [], []
        for slot in range(plan.batch_frames):
            for ti, geo in enumerate(owner.geometry):
                for role in geo.roles:
                    self.keys.append((slot, ti, role))
                    face_counts.append(len(geo.faces(role)))
                    vert_counts.append(len(geo.world(0)[role]))
        self.terrain: TerrainMesh | None = owner.terrain_seen[which][0] if owner.terrain is not None else None
        if self.terrain is not None:
            # terrain: one copy per slot plus one in the background slot (index batch_frames), which
            # holds no targets and serves the ROI background (self.sky)
            for slot in range(plan.batch_frames + 1):
                self.keys.append((slot, -1, "terrain"))
                face_counts.append(len(self.terrain.faces))
                vert_counts.append(len(self.terrain.vertices))
        self.vert_counts = np.array(vert_counts)
        self.face_counts = np.array(face_counts)
        self.face_key = np.repeat(np.arange(len(self.keys)), self.face_counts)
        self._key_slot = np.array([k[0] for k in self.keys])
        self._key_target = np.array([k[1] for k in self.keys])
        self._key_role = [k[2] for k in self.keys]
        faces, offset = [], 0
        for (_slot, ti, role), nv in zip(self.keys, vert_counts):
            faces.append((self._terrain_mesh.faces if ti < 0 else owner.geometry[ti].faces(role)) + offset)
            offset += nv
        # one zero-area face spanning a fixed box (never hit) pins the scene's bounding sphere, which
        # Mitsuba bakes into the emitter kernels as literals: without it every sequence compiled its
        # own kernels (~2.5 s per clip on 2 cores, measured); with it one compile serves all scenes
        faces.append(np.array([[offset, offset + 1, offset + 1]]))
        self.faces = np.vstack(faces).astype(np.uint32)
        self.n_vertices = offset + 2
        self.scene = self._build()
        self.params = mi.traverse(self.scene)
        self.environment = self.scene.environment()
        self.integrator = mi.load_dict({"type": "path", "max_depth": RGB_MAX_DEPTH}) if which == "rgb" else None
        self._sky_cache: tuple[tuple, np.ndarray] | None = None
        # a camera that never turns keeps one cached sky (copied per frame before compositing);
        # a turning camera gets a fresh sky per frame that the composite may overwrite in place
        self.static = bool(np.all(self.camera.forward == self.camera.forward[0])
                           and np.all(self.camera.up == self.camera.up[0]))

    # ---- scene construction -------------------------------------------------------------------
    def _build(self):
        mi, owner = self.mi, self.owner
        if self.which == "rgb":
            scene: dict = {"type": "scene"}
            bitmap = owner.sky.rgb_bitmap         # shared with the bake (read-only)
            if np.any(owner.sky.sun_irradiance > 0):
                scene["sun"] = {"type": "directional", "direction": (-owner.sky.sun_direction).tolist(),
                                "irradiance": {"type": "rgb", "value": owner.sky.sun_irradiance.tolist()}}
        else:
            scene = {"type": "scene"}
            bitmap = mi.Bitmap(np.repeat(owner.sky.thermal[..., None], 3, axis=-1))
        scene["sky"] = {"type": "envmap", "bitmap": bitmap, "to_world": owner.sky.to_world}
        props = mi.Properties()
        props["bsdf"] = mi.load_dict({"type": "diffuse",
                                      "reflectance": {"type": "mesh_attribute", "name": f"{self.attr}_albedo"}})
        # the airlight/thermal emission is seen directly; it is not a light worth sampling (weight 0)
        props["emitter"] = mi.load_dict({"type": "area", "sampling_weight": 0.0,
                                         "radiance": {"type": "mesh_attribute", "name": f"{self.attr}_emission"}})
        mesh = mi.Mesh("targets", self.n_vertices, len(self.faces), props=props)
        n_faces = len(self.faces)
        n_attr = self.n_vertices if self.terrain is not None else n_faces
        mesh.add_attribute(f"{self.attr}_albedo", 3, [0.5] * (3 * n_attr))
        mesh.add_attribute(f"{self.attr}_emission", 3, [0.0] * (3 * n_attr))
        params = mi.traverse(mesh)
        params["vertex_positions"] = self._floats(self._vertices([0] * self.plan.batch_frames).ravel())
        params["faces"] = self._uints(self.faces.ravel())
        params.update()
        scene["targets"] = mesh
        return mi.load_dict(scene)

    @property
    def attr(self) -> str:
        """Mesh attributes are per face (targets only) or per vertex (with terrain: smooth texture)."""
        return "face" if self.terrain is None else "vertex"

    @property
    def _terrain_mesh(self) -> TerrainMesh:
        """The terrain this view sees; used only with terrain (its keys have target index -1)."""
        if self.terrain is None:
            raise RuntimeError("terrain mesh requested for a scene without terrain")
        return self.terrain

    def _floats(self, values: np.ndarray):
        """A mesh buffer (Dr.Jit Float array) from numpy."""
        return self.mi.Float(values)

    def _uints(self, values: np.ndarray):
        return self.mi.UInt32(values)

    def _vertices(self, slot_frames: list[int]) -> np.ndarray:
        """(n_vertices, 3) float32: each slot's frame geometry relative to its camera, at the slot."""
        cam, plan, owner = self.camera, self.plan, self.owner
        blocks = []
        for slot, ti, role in self.keys:
            if ti < 0:   # terrain; the background slot is set for frame 0's camera origin
                frame = slot_frames[slot] if slot < len(slot_frames) else 0
                blocks.append(self._terrain_mesh.vertices - cam.origin_m[frame] + plan.slot_offset_m(slot))
                continue
            frame = slot_frames[slot]
            rel = owner.geometry[ti].world(frame)[role] - cam.origin_m[frame]
            blocks.append(rel + plan.slot_offset_m(slot))
        blocks.append(np.array([[-SCENE_BOUND_M] * 3, [SCENE_BOUND_M] * 3]))
        return np.vstack(blocks).astype(np.float32)

    # ---- per batch ----------------------------------------------------------------------------
    def place(self, slot_frames: list[int]) -> dict[tuple[int, int], Tile]:
        """Put frame ``slot_frames[s]`` into slot ``s``: geometry and per-face materials; returns tiles."""
        plan, cam, owner = self.plan, self.camera, self.owner
        tiles: dict[tuple[int, int], Tile] = {}
        for slot, frame in enumerate(slot_frames):
            for ti in range(plan.tiles_per_frame):
                box = owner.boxes[self.which][frame][ti] if plan.mode == "roi" else None
                tiles[(slot, ti)] = place_tile(plan, box, cam.width_px, cam.height_px)
        albedo = np.zeros((len(self.keys), 3), np.float32)
        emission = np.zeros((len(self.keys), 3), np.float32)
        for k, (slot, ti, role) in enumerate(self.keys):
            if ti < 0:
                continue
            frame = slot_frames[slot]
            if self.which == "rgb":
                albedo[k], emission[k] = owner.rgb_material(ti, role, frame, "rgb")
            else:
                emission[k] = owner.thermal_radiance(ti, role, frame, "thermal")
        self.params["targets.vertex_positions"] = self._floats(self._vertices(slot_frames).ravel())
        if self.terrain is None:
            pin = np.zeros((1, 3), np.float32)  # the bounding face's attributes (never hit)
            self.params["targets.face_albedo"] = self._floats(
                np.vstack([np.repeat(albedo, self.face_counts, axis=0), pin]).ravel())
            self.params["targets.face_emission"] = self._floats(
                np.vstack([np.repeat(emission, self.face_counts, axis=0), pin]).ravel())
        else:
            self.params["targets.vertex_albedo"] = self._floats(self._per_vertex(albedo, None).ravel())
            seen = owner.terrain_seen[self.which][1]
            self.params["targets.vertex_emission"] = self._floats(
                self._per_vertex(emission, owner.terrain_emission(self.which)[seen]).ravel())
        self.params.update()
        self._slot_frames = list(slot_frames)
        return tiles

    def _per_vertex(self, per_key: np.ndarray, terrain_values: np.ndarray | None) -> np.ndarray:
        """(n_vertices, 3) float32: each target key's value on its vertices, the terrain's own
        per-vertex values (zero albedo: terrain is pre-lit emission), and the two pin vertices."""
        target_keys = self._key_target >= 0
        blocks = [np.repeat(per_key[target_keys], self.vert_counts[target_keys], axis=0)]
        n_terrain = int(np.sum(~target_keys))
        tv = np.zeros((len(self._terrain_mesh.vertices), 3), np.float32) if terrain_values is None else terrain_values
        blocks += [tv] * n_terrain
        blocks.append(np.zeros((2, 3), np.float32))
        return np.vstack(blocks).astype(np.float32)

    def _camera_arrays(self, slot_frames: list[int]) -> list[Any] | np.ndarray:
        """Per-slot camera origin, forward, right and up as Dr.Jit arrays (for gathers)."""
        cam, plan, mi = self.camera, self.plan, self.mi
        rows = []
        for slot, frame in enumerate(slot_frames):
            fwd, up = cam.forward[frame], cam.up[frame]
            rows.append(np.concatenate([plan.slot_offset_m(slot), fwd, np.cross(fwd, up), up]))
        table = np.asarray(rows + rows[:1], np.float64)  # >= 2 rows: size-1 arrays become kernel literals
        return [mi.Float(table[:, c].astype(np.float32)) for c in range(12)]

    def _opaque(self, kind, value):
        """A kernel input that is not baked into the kernel source: values that change between
        sequences (sizes, seeds, focal length) would otherwise recompile the kernels every time."""
        return self.dr.opaque(kind, value)

    def _rays(self, slot, px, py, cams):
        """World rays of slot ``slot`` (UInt32 per lane) through image positions (px, py)."""
        dr, mi, cam = self.dr, self.mi, self.camera
        g = [dr.gather(mi.Float, c, slot) for c in cams]
        o = mi.Point3f(g[0], g[1], g[2])
        fwd, right, up = mi.Vector3f(g[3], g[4], g[5]), mi.Vector3f(g[6], g[7], g[8]), mi.Vector3f(g[9], g[10], g[11])
        f = self._opaque(mi.Float, cam.focal_px)
        cx, cy = self._opaque(mi.Float, cam.width_px / 2), self._opaque(mi.Float, cam.height_px / 2)
        d = fwd * f + right * (px - cx) - up * (py - cy)
        ray = mi.Ray3f(o, dr.normalize(d))
        ray.maxt = self._opaque(mi.Float, self.plan.far_clip_m)
        return ray

    def _jitter(self, x, y, s):
        """Sub-pixel sample position in [0, 1)^2: a hash of (camera seed, pixel, sample) only."""
        mi = self.mi
        pid = y * self._opaque(mi.UInt32, self.camera.width_px) + x
        key = self._opaque(mi.UInt32, self.jitter_seed) + s * 2
        return mi.sample_tea_float32(pid, key), mi.sample_tea_float32(pid, key + 1)

    def _tile_lanes(self, tiles: dict, n_tiles: int):
        """Lane -> (tile, image x, image y, sample) for every sample of every tile."""
        dr, mi, plan = self.dr, self.mi, self.plan
        n = n_tiles * plan.tile_height * plan.tile_width * self.spp
        tw, th = self._opaque(mi.UInt32, plan.tile_width), self._opaque(mi.UInt32, plan.tile_height)
        spp = self._opaque(mi.UInt32, self.spp)
        idx = dr.arange(mi.UInt32, n)
        s = idx % spp
        pix = idx // spp
        u, v, t = pix % tw, (pix // tw) % th, pix // (tw * th)
        order = sorted(tiles)
        order = order + order[:1]  # >= 2 entries (size-1 arrays become literals)
        x0 = mi.UInt32(np.array([tiles[k].x0 for k in order], np.uint32))
        y0 = mi.UInt32(np.array([tiles[k].y0 for k in order], np.uint32))
        x = dr.gather(mi.UInt32, x0, t) + u
        y = dr.gather(mi.UInt32, y0, t) + v
        slot = t // self._opaque(mi.UInt32, plan.tiles_per_frame)
        return slot, x, y, s

    def render_tiles(self, seed: int, tiles: dict) -> np.ndarray:
        """(tiles_per_batch, tile_h, tile_w, 3) radiance of the placed batch."""
        dr, mi, plan = self.dr, self.mi, self.plan
        n_tiles = plan.tiles_per_batch
        slot, x, y, s = self._tile_lanes(tiles, n_tiles)
        jx, jy = self._jitter(x, y, s)
        ray = self._rays(slot, mi.Float(x) + jx, mi.Float(y) + jy, self._camera_arrays(self._slot_frames))
        if self.integrator is not None:
            sampler = mi.load_dict({"type": "independent"})
            sampler.seed(seed, dr.width(ray.o))
            value = self.integrator.sample(self.scene, sampler, ray)[0]
        else:
            si = self.scene.ray_intersect(ray)
            value = si.emitter(self.scene).eval(si)
        img = np.array(dr.block_sum(value, self.spp) / self.spp, dtype=np.float32).T
        return img.reshape(n_tiles, plan.tile_height, plan.tile_width, 3)

    def sky(self, frame: int, region: tuple[int, int, int, int] | None = None) -> np.ndarray:
        """(H, W, 3) sky radiance at pixel centres (thermal: (H, W, 1)) (ROI mode's background; the sky
        behind a target for label contrast), cached while the camera does not turn. Pixels smaller
        than a sky texel make this the pixel's mean to well below the 8-bit step (tested against a
        full render). Only a static camera's sky is cached (a turning camera's is composited over in
        place)."""
        cam = self.camera
        pose = (cam.forward[frame].tobytes(), cam.up[frame].tobytes())
        if self._sky_cache is not None and self._sky_cache[0] == pose:
            whole = self._sky_cache[1]
            return whole if region is None else whole[region[1]:region[3], region[0]:region[2]]
        if region is not None and self.plan.mode == "roi" and self.static:
            return self.sky(frame)[region[1]:region[3], region[0]:region[2]]
        x0, y0, x1, y1 = region if region is not None else (0, 0, cam.width_px, cam.height_px)
        image = self._background([frame], x0, y0, y1 - y0, x1 - x0)[0]
        if region is None and self.static:
            self._sky_cache = (pose, image)
        return image

    def backgrounds(self, frames: list[int]) -> list[np.ndarray]:
        """Each frame's whole (H, W, 3) (thermal: (H, W, 1)) ROI background, private to the caller (it composites the
        tiles over it): a copy of the cached sky for a camera that does not turn, else evaluated for
        several frames per launch (each pixel's value does not depend on the launch it is in)."""
        if self.static:
            return [self.sky(frame).copy() for frame in frames]
        cam = self.camera
        per_launch = max(1, BATCH_PIXEL_BUDGET // (cam.width_px * cam.height_px))
        out: list[np.ndarray] = []
        for start in range(0, len(frames), per_launch):
            out += list(self._background(frames[start:start + per_launch], 0, 0, cam.height_px, cam.width_px))
        return out

    def _background(self, frames: list[int], x0: int, y0: int, h: int, w: int) -> np.ndarray:
        """(len(frames), h, w, 3) background at the centres of pixels [y0:y0+h, x0:x0+w] of each
        frame: the sky, or with terrain the background slot's sky and terrain; one launch. Thermal:
        (len(frames), h, w, 1), the first channel only (the LWIR map's three are equal; the frame
        keeps only the first)."""
        dr, mi = self.dr, self.mi
        n = h * w
        idx = dr.arange(mi.UInt32, n * len(frames))
        no, wo = self._opaque(mi.UInt32, n), self._opaque(mi.UInt32, w)
        which = idx // no            # lane -> index into ``frames``
        pix = idx % no
        x = mi.Float(pix % wo + self._opaque(mi.UInt32, x0)) + 0.5
        y = mi.Float(pix // wo + self._opaque(mi.UInt32, y0)) + 0.5
        if self.terrain is not None:
            value = self._terrain_background(which, x, y, frames)
        else:
            value = self._sky_pixels(which, x, y, frames)
        if self.which == "thermal":
            return np.array(value.x, dtype=np.float32).reshape(len(frames), h, w, 1)
        return np.array(value, dtype=np.float32).T.reshape(len(frames), h, w, 3)

    def _sky_pixels(self, which, x, y, frames: list[int]):
        """Environment radiance through image positions (x, y) of frame ``frames[which]`` (per lane)."""
        dr, mi = self.dr, self.mi
        # camera vectors go in as arrays (Python floats would become kernel literals and recompile
        # the kernel for every camera pose); the origin (the slot's) does not change a sky lookup
        ray = self._rays(which, x, y, self._camera_arrays(frames))
        si = dr.zeros(mi.SurfaceInteraction3f, dr.width(x))
        si.wi = -ray.d
        return self.environment.eval(si)

    def _terrain_background(self, which, x, y, frames: list[int]):
        """Background (sky and terrain, no targets) through image positions (x, y) of frame
        ``frames[which]`` (per lane): one ray per pixel centre from the background slot, which
        holds the terrain and no targets. Smooth terrain (per-vertex emission) matches the tiles'
        jittered samples to well below a grey level; an edge of the terrain crossing a tile border
        can differ by its anti-aliasing (measured: 10x cheaper than the tiles' spp samples per
        pixel, which a turning camera pays every frame)."""
        mi, cam, plan = self.mi, self.camera, self.plan
        rows = [np.concatenate([plan.slot_offset_m(plan.batch_frames), cam.forward[f],
                                np.cross(cam.forward[f], cam.up[f]), cam.up[f]]) for f in frames]
        table = np.asarray(rows + rows[:1], np.float64)  # >= 2 rows: size-1 arrays become kernel literals
        cams = [mi.Float(table[:, c].astype(np.float32)) for c in range(12)]
        si = self.scene.ray_intersect(self._rays(which, x, y, cams))
        return si.emitter(self.scene).eval(si)

    def coverage(self, slot_frames: list[int], tiles: dict[tuple[int, int], Tile], wanted: set[int]) -> dict:
        """Coverage rays (regular k x k grid per pixel) over each target's projected box in each
        wanted slot: {(slot, target): (region, (h, w, n_keys) hit counts)}."""
        cam = self.camera
        k = COVERAGE_SUBSAMPLES
        sub = (np.arange(k) + 0.5) / k
        xs_all, ys_all, slots_all, regions = [], [], [], []
        for slot, frame in enumerate(slot_frames):
            if slot not in wanted:
                continue
            for ti in range(len(self.owner.geometry)):
                box = self.owner.boxes[self.which][frame][ti]
                if box is None:
                    continue
                region = pixel_box(box, cam.width_px, cam.height_px, pad_px=1)
                x0, y0, x1, y1 = region
                px = np.arange(x0, x1)[None, :, None, None] + sub[None, None, None, :]
                py = np.arange(y0, y1)[:, None, None, None] + sub[None, None, :, None]
                px, py = np.broadcast_arrays(px, py)
                xs_all.append(px.ravel())
                ys_all.append(py.ravel())
                slots_all.append(np.full(px.size, slot, np.uint32))
                regions.append(((slot, ti), region))
        if not regions:
            return {}
        prim, valid = self._hits(np.concatenate(slots_all), np.concatenate(xs_all).astype(np.float32),
                                 np.concatenate(ys_all).astype(np.float32), slot_frames)
        n_keys = len(self.keys)
        key = np.where(valid, self.face_key[np.clip(prim, 0, len(self.face_key) - 1)], n_keys)
        out, start = {}, 0
        for slot_ti, region in regions:
            x0, y0, x1, y1 = region
            n = (x1 - x0) * (y1 - y0) * k * k
            hits = key[start:start + n].reshape(-1, k * k)
            start += n
            # hit counts per (pixel, key): a histogram of pixel x (n_keys + 1) + key
            cell = hits + (np.arange(hits.shape[0]) * (n_keys + 1))[:, None]
            counts = np.bincount(cell.ravel(), minlength=hits.shape[0] * (n_keys + 1)).astype(np.int32)
            counts = counts.reshape(hits.shape[0], n_keys + 1)
            out[slot_ti] = (region, counts[:, :n_keys].reshape(y1 - y0, x1 - x0, n_keys))
        return out

    def _hits(self, slots: np.ndarray, xs: np.ndarray, ys: np.ndarray, slot_frames: list[int]) -> tuple:
        """(primitive index, hit) of the rays of slots ``slots`` through image positions (xs, ys)."""
        mi = self.mi
        ray = self._rays(mi.UInt32(slots), mi.Float(xs), mi.Float(ys), self._camera_arrays(slot_frames))
        si = self.scene.ray_intersect(ray)
        return np.array(si.prim_index, dtype=np.int64), np.array(si.is_valid(), dtype=bool)


class _ScalarView(_View):
    """A camera view on Mitsuba's scalar variant: the same lanes (tiles, samples, jitter hash,
    pinhole rays) computed with numpy in float32, each ray traced by one scalar Mitsuba call
    (simulator.render.scalar). Sky, coverage and thermal emission equal the llvm variant's to float
    rounding; path-traced RGB differs by Monte Carlo noise only (another sampler stream)."""

    def _floats(self, values: np.ndarray):
        return self.dr.scalar.ArrayXf(np.ascontiguousarray(values, np.float32))

    def _uints(self, values: np.ndarray):
        return self.dr.scalar.ArrayXu(np.ascontiguousarray(values, np.uint32))

    def _camera_arrays(self, slot_frames: list[int]) -> np.ndarray:
        """(slots, 12) float32 per-slot camera origin, forward, right and up."""
        cam, plan = self.camera, self.plan
        rows = [np.concatenate([plan.slot_offset_m(s), cam.forward[f], np.cross(cam.forward[f], cam.up[f]), cam.up[f]])
                for s, f in enumerate(slot_frames)]
        return np.asarray(rows, np.float64).astype(np.float32)

    def _rays(self, slot, px, py, cams) -> tuple[np.ndarray, np.ndarray]:
        """(origins, unit directions), each (n, 3) float32, as the llvm variant's ``_rays``."""
        cam = self.camera
        g = cams[np.asarray(slot, np.int64)]
        f = np.float32(cam.focal_px)
        cx, cy = np.float32(cam.width_px / 2), np.float32(cam.height_px / 2)
        dx = (np.asarray(px, np.float32) - cx)[:, None]
        dy = (np.asarray(py, np.float32) - cy)[:, None]
        d = g[:, 3:6] * f + g[:, 6:9] * dx - g[:, 9:12] * dy
        d = d / np.sqrt(np.sum(d * d, axis=1, keepdims=True, dtype=np.float32))
        return g[:, 0:3], d.astype(np.float32)

    def _tile_lanes(self, tiles: dict, n_tiles: int):
        plan = self.plan
        idx = np.arange(n_tiles * plan.tile_height * plan.tile_width * self.spp, dtype=np.uint32)
        s, pix = idx % self.spp, idx // self.spp
        u, v = pix % plan.tile_width, (pix // plan.tile_width) % plan.tile_height
        t = pix // (plan.tile_width * plan.tile_height)
        order = sorted(tiles)
        x = np.array([tiles[k].x0 for k in order], np.uint32)[t] + u
        y = np.array([tiles[k].y0 for k in order], np.uint32)[t] + v
        return t // np.uint32(plan.tiles_per_frame), x, y, s

    def _jitter(self, x, y, s):
        with np.errstate(over="ignore"):
            pid = y * np.uint32(self.camera.width_px) + x
            key = np.uint32(self.jitter_seed) + s * np.uint32(2)
            return scalar.tea_float32(pid, key), scalar.tea_float32(pid, key + np.uint32(1))

    def render_tiles(self, seed: int, tiles: dict) -> np.ndarray:
        plan = self.plan
        n_tiles = plan.tiles_per_batch
        slot, x, y, s = self._tile_lanes(tiles, n_tiles)
        jx, jy = self._jitter(x, y, s)
        o, d = self._rays(slot, x.astype(np.float32) + jx, y.astype(np.float32) + jy,
                          self._camera_arrays(self._slot_frames))
        far = float(np.float32(plan.far_clip_m))
        if self.integrator is not None:
            value = scalar.path_trace(self.mi, self.scene, self.integrator, seed, o, d, far)
        else:
            value = scalar.emitted(self.mi, self.scene, o, d, far)
        img = value.reshape(-1, self.spp, 3).sum(axis=1, dtype=np.float32) / np.float32(self.spp)
        return img.reshape(n_tiles, plan.tile_height, plan.tile_width, 3)

    def _background(self, frames: list[int], x0: int, y0: int, h: int, w: int) -> np.ndarray:
        if self.terrain is not None:
            return super()._background(frames, x0, y0, h, w)
        idx = np.arange(h * w)
        x = (idx % w + x0).astype(np.float32) + np.float32(0.5)
        y = (idx // w + y0).astype(np.float32) + np.float32(0.5)
        images = []
        for frame in frames:
            _, d = self._rays(np.zeros(h * w, np.int64), x, y, self._camera_arrays([frame]))
            images.append(scalar.eval_emitter(self.mi, self.environment, -d.T).reshape(h, w, 3))
        return np.stack(images)

    def _hits(self, slots: np.ndarray, xs: np.ndarray, ys: np.ndarray, slot_frames: list[int]) -> tuple:
        o, d = self._rays(slots, xs, ys, self._camera_arrays(slot_frames))
        return scalar.intersect(self.mi, self.scene, o, d, float(np.float32(self.plan.far_clip_m)))


def _layout_geometry(timeline: Timeline, layout: Timeline, cameras: tuple[str, ...]) -> list[TrackGeometry]:
    """The geometry that shapes the launch layout: ``layout``'s targets, checked to start with
    ``timeline``'s own (same names and paths) and to be seen by the same cameras."""
    own, other = timeline.targets, layout.targets
    if layout.n_frames != timeline.n_frames or len(other) < len(own):
        raise ValueError("layout timeline must have the same frames and at least the scene's own targets")
    for a, b in zip(own, other):
        if a.name != b.name or not np.array_equal(a.position_m, b.position_m):
            raise ValueError(f"layout timeline differs in target {a.name!r}: its targets must start with the scene's")
    for which in cameras:
        ca, cb = timeline.cameras[which], layout.cameras[which]
        if not (np.array_equal(ca.origin_m, cb.origin_m) and np.array_equal(ca.forward, cb.forward)
                and np.array_equal(ca.up, cb.up) and ca.focal_px == cb.focal_px and ca.width_px == cb.width_px
                and ca.height_px == cb.height_px):
            raise ValueError(f"layout timeline has a different {which} camera")
    return [TrackGeometry(track) for track in other]


def _faces_in_view(mesh, cam, margin_px: float = 4.0) -> np.ndarray:
    """(n_faces,) bool: faces whose projection touches some frame's image (plus a margin), or that
    cross the camera plane (kept, conservatively). A triangle with every vertex in front projects to
    the triangle of its projected vertices, so the test is exact for those. Culled faces cannot be
    hit by any primary or coverage ray; only indirect light from them is lost (the RGB path tracer's
    bounce to the ground then sees the sky map's ground colour instead)."""
    keep = np.zeros(len(mesh.faces), bool)
    poses: set[bytes] = set()
    for i in range(len(cam.forward)):
        pose = cam.origin_m[i].tobytes() + cam.forward[i].tobytes() + cam.up[i].tobytes()
        if pose in poses:
            continue
        poses.add(pose)
        px, depth = cam.project(i, mesh.vertices)
        front = depth > 1e-3
        fx, fy, fd = px[mesh.faces, 0], px[mesh.faces, 1], front[mesh.faces]
        all_front = fd.all(axis=1)
        inside = ((fx.max(axis=1) >= -margin_px) & (fx.min(axis=1) <= cam.width_px + margin_px)
                  & (fy.max(axis=1) >= -margin_px) & (fy.min(axis=1) <= cam.height_px + margin_px))
        keep |= (all_front & inside) | (fd.any(axis=1) & ~all_front)
    return keep


class SequenceRenderer:
    """Renders every frame of a Timeline in batched launches; geometry and shape set stay fixed, so
    Dr.Jit compiles once per camera. ``cameras`` limits the work (e.g. RGB only for small video);
    ``labels=False`` skips the coverage rays (no masks)."""

    def __init__(self, timeline: Timeline, cameras: tuple[str, ...] = ("rgb", "thermal"), labels: bool = True,
                 batch_frames: int = BATCH_FRAMES, roi: bool = True, layout: Timeline | None = None):
        from simulator.render.mitsuba_setup import load_mitsuba

        self.mi = mi = load_mitsuba()
        self.timeline = timeline
        self.labels = labels
        scenario = timeline.scenario
        self.sky = SkyMaps(mi, timeline)
        atm = scenario.atmosphere
        self.beta_visible = thermal.visible_extinction_per_m(atm.visibility_m)
        self.air_radiance = float(thermal.band_radiance(atm.air_temperature_k))
        self.rig = scenario.camera_rig
        self._targets = {t.name: t for t in scenario.targets}
        self.geometry = [TrackGeometry(track) for track in timeline.targets]
        self.terrain: TerrainMesh | None = None
        # per camera: (the faces any frame sees, their vertex index)
        self.terrain_seen: dict[str, tuple[TerrainMesh, np.ndarray]] = {}
        self._terrain_emission: dict[str, np.ndarray] = {}
        # at-sensor LWIR radiance per (target, role, frame, camera) and (transmission, path radiance)
        # per sight line: the LOWTRAN look-up is ~1 ms of Python per call
        self._thermal_radiance: dict[tuple[int, str, int, str], float] = {}
        self._sight_lwir: dict[tuple[int, int, str], tuple[float, float]] = {}
        if scenario.terrain is not None:
            from scenes.terrain import build_terrain

            self.terrain = build_terrain(scenario, rng_for(timeline.seed, "terrain"))
        # the launch layout (tiles, batch, clip distance) comes from ``layout`` when given: a scene
        # with the same cameras and these targets first (a counterfactual twin renders with its drone
        # clip's layout, so every lane, and so every random number, of the shared pixels is the same)
        layout_geometry = self.geometry if layout is None else _layout_geometry(timeline, layout, cameras)
        n = timeline.n_frames
        self.boxes: dict[str, list[list[tuple | None]]] = {}
        self.plans: dict[str, CameraPlan] = {}
        for which in cameras:
            cam = timeline.cameras[which]
            frames_boxes, max_range = [], 1.0
            for i in range(n):
                row = []
                for geo in layout_geometry:
                    verts = geo.all_vertices(i)
                    px, depth = cam.project(i, verts)
                    row.append(projected_boxes(px, depth, cam.width_px, cam.height_px))
                    max_range = max(max_range, float(np.linalg.norm(verts - cam.origin_m[i], axis=1).max()))
                frames_boxes.append(row)
            if self.terrain is not None:   # only the terrain some frame can see; rays must reach its farthest point
                self.terrain_seen[which] = self.terrain.subset(_faces_in_view(self.terrain, cam))
                seen = self.terrain_seen[which][0]
                if len(seen.faces):
                    max_range = max(max_range, float(np.linalg.norm(seen.vertices - cam.origin_m[0], axis=1).max())
                                    + 10.0)
            self.boxes[which] = frames_boxes
            self.plans[which] = plan_camera(frames_boxes, cam.width_px, cam.height_px, max_range,
                                            batch_frames=batch_frames, roi=roi)
        if len(cameras) == 2 and self.plans["rgb"].batch_frames != self.plans["thermal"].batch_frames:
            b = min(p.batch_frames for p in self.plans.values())
            self.plans = {w: CameraPlan(**{**p.__dict__, "batch_frames": b}) for w, p in self.plans.items()}
        self.batch_frames = min(p.batch_frames for p in self.plans.values())
        view_class = _ScalarView if is_scalar(mi) else _View
        self.views = {which: view_class(self, which, self.plans[which]) for which in cameras}
        look = timeline.cameras["rgb"].forward[0]
        luminance = float(np.dot(self.sky.rgb_at(look), [0.2126, 0.7152, 0.0722]))
        self.exposure = EXPOSURE_KEY / max(luminance, 1e-6)
        self._cached: dict[int, FrameBuffers] = {}

    # ---- materials (shared with labels) --------------------------------------------------------
    def _range_m(self, ti: int, frame: int, which: str) -> float:
        track = self.timeline.targets[ti]
        return float(np.linalg.norm(track.position_m[frame] - self.timeline.cameras[which].origin_m[frame]))

    def rgb_material(self, ti: int, role: str, frame: int, which: str) -> tuple[np.ndarray, np.ndarray]:
        """(reflectance, airlight emission) of a part: L = t L_obj + (1 - t) A."""
        track = self.timeline.targets[ti]
        material = material_for(self._targets[track.name], role)
        t = float(np.exp(-self.beta_visible * self._range_m(ti, frame, which)))
        return t * np.asarray(material.rgb_reflectance), (1 - t) * self.sky.airlight_rgb

    def thermal_radiance(self, ti: int, role: str, frame: int, which: str) -> float:
        """At-sensor LWIR band radiance of a part: tau (eps L(T) + (1 - eps) L_refl) + L_path
        (memoised: asked when the batch is placed and again for the labels; the sight line's
        transmission and path radiance are looked up once per target and frame for all its parts)."""
        key = (ti, role, frame, which)
        if key not in self._thermal_radiance:
            track = self.timeline.targets[ti]
            material = material_for(self._targets[track.name], role)
            temp_k = float(track.part_temperature_k[role][frame])
            surface = thermal.surface_radiance(temp_k, material.emissivity, self.sky.reflected_lwir)
            sight_key = (ti, frame, which)
            if sight_key not in self._sight_lwir:
                sight = track.position_m[frame] - self.timeline.cameras[which].origin_m[frame]
                self._sight_lwir[sight_key] = self.sky.thermal_sky.lwir.along(sight)  # LOWTRAN7 tables
            tau, path_radiance = self._sight_lwir[sight_key]
            self._thermal_radiance[key] = float(tau * surface + path_radiance)
        return self._thermal_radiance[key]

    def terrain_emission(self, which: str) -> np.ndarray:
        """(n_terrain_vertices, 3) float32 emitted radiance of the terrain seen by camera ``which``
        (at frame 0's camera origin). RGB: the pre-lit surface, L = t rho (E_sun max(n.s, 0) +
        E_sky (1 + n_z) / 2) / pi + (1 - t) A (Lambertian, isotropic sky; no cast shadows). Thermal:
        tau (eps L(T) + (1 - eps) L_refl) + L_path with T from simulator.physics.terrain_thermal."""
        if which in self._terrain_emission:
            return self._terrain_emission[which]
        from scenes.terrain import ASSET_NAMES
        from scenes.terrain_assets import TERRAIN_ASSETS
        from simulator.physics.terrain_thermal import surface_offset_k

        mesh, scenario = self.terrain, self.timeline.scenario
        if mesh is None or scenario.terrain is None:
            raise RuntimeError("terrain_emission needs a scene with terrain")
        rel = mesh.vertices - self.timeline.cameras[which].origin_m[0]
        dist = np.maximum(np.linalg.norm(rel, axis=1), 1e-3)
        if which == "rgb":
            albedo = np.array([TERRAIN_ASSETS[n].rgb_albedo for n in ASSET_NAMES])[mesh.asset] * mesh.texture[:, None]
            sun = np.asarray(self.sky.sun_irradiance, np.float64)
            cos_sun = np.clip(mesh.normal @ self.sky.sun_direction, 0.0, None)[:, None]
            irradiance = sun[None, :] * cos_sun + self.sky.sky_irradiance[None, :] * (1 + mesh.normal[:, 2:3]) / 2
            t = np.exp(-self.beta_visible * dist)[:, None]
            out = t * np.clip(albedo, 0.0, 1.0) * irradiance / np.pi + (1 - t) * self.sky.airlight_rgb[None, :]
        else:
            atm, terrain = scenario.atmosphere, scenario.terrain
            cover = scenario.sky.clouds.coverage if scenario.sky.clouds is not None else 0.0
            eps_of = {n: terrain.emissivity.get(n, TERRAIN_ASSETS[n].emissivity) for n in ASSET_NAMES}
            offset = np.array([surface_offset_k(TERRAIN_ASSETS[n], self.sky.sun_elevation_deg, atm.air_temperature_k,
                                                atm.relative_humidity, cover, eps_of[n]) for n in ASSET_NAMES])
            temp_k = atm.air_temperature_k + offset[mesh.asset] + mesh.temperature_offset_k
            eps = np.array([eps_of[n] for n in ASSET_NAMES])[mesh.asset]
            surface = eps * thermal.band_radiance(temp_k) + (1 - eps) * self.sky.reflected_lwir
            el = np.arcsin(np.clip(rel[:, 2] / dist, -1.0, 1.0))
            lwir = self.sky.thermal_sky.lwir
            value = lwir.transmission(dist, el) * surface + lwir.path_radiance(dist, el)
            out = np.repeat(np.asarray(value, np.float64)[:, None], 3, axis=1)
        self._terrain_emission[which] = out.astype(np.float32)
        return self._terrain_emission[which]

    def record(self) -> dict:
        """The launch layout per camera (recorded in the metadata: it shapes the sample pattern)."""
        return {which: plan.record() for which, plan in self.plans.items()}

    # ---- rendering -----------------------------------------------------------------------------
    @property
    def n_batches(self) -> int:
        return -(-self.timeline.n_frames // self.batch_frames)

    def batch_frames_of(self, batch: int) -> list[int]:
        b = self.batch_frames
        return list(range(batch * b, min((batch + 1) * b, self.timeline.n_frames)))

    def render_batch(self, batch: int, only: list[int] | None = None) -> dict[int, FrameBuffers]:
        """Render the frames of launch ``batch`` (or only some of them: the others' slots get a copy
        of the first wanted frame; a frame's pixels do not depend on what the other slots hold)."""
        frames = self.batch_frames_of(batch)
        wanted = [f for f in frames if only is None or f in only]
        b = self.batch_frames
        slot_frames = [(batch * b + s) if (batch * b + s) in wanted else wanted[0] for s in range(b)]
        out: dict[int, dict] = {f: {} for f in wanted}
        for which, view in self.views.items():
            tiles = view.place(slot_frames)
            radiance = view.render_tiles(render_seed(self.timeline.seed, batch, PASS_INDEX[which]), tiles)
            slots = {f - batch * b for f in wanted}
            cover = view.coverage(slot_frames, tiles, slots) if self.labels else {}
            backgrounds = view.backgrounds(wanted) if view.plan.mode == "roi" else [None] * len(wanted)
            for frame, background in zip(wanted, backgrounds):
                out[frame][which] = self._assemble(view, frame, frame - batch * b, tiles, radiance, cover, background)
        return {f: self._buffers(parts) for f, parts in out.items()}

    def _assemble(self, view: _View, frame: int, slot: int, tiles, radiance, cover,
                  background: np.ndarray | None) -> tuple:
        """One frame's image (ROI mode: the tiles composited in place over ``background``, the
        frame's own copy), coverage records and mask."""
        plan, cam = view.plan, view.camera
        skies: dict[tuple[int, int], np.ndarray] | None = None
        h, w = cam.height_px, cam.width_px
        if plan.mode == "full":
            image = radiance[slot][: h, : w].copy()
        else:
            if background is None:
                raise ValueError("ROI frames are composited over their background: none given")
            image = background
            if self.labels and view.which == "thermal":   # the sky behind each target, before the tiles cover it
                skies = {key: image[y0:y1, x0:x1, 0].copy()
                         for key, ((x0, y0, x1, y1), _) in cover.items() if key[0] == slot}
            for ti in range(plan.tiles_per_frame):
                if self.boxes[view.which][frame][ti] is None:
                    continue
                tile = tiles[(slot, ti)]
                image[tile.y0:tile.y0 + tile.height, tile.x0:tile.x0
                      + tile.width] = radiance[slot * plan.tiles_per_frame + ti][..., :image.shape[-1]]
        coverage, mask = None, None
        if self.labels:
            coverage, mask = self._coverage_records(view, frame, slot, cover, skies)
        return image, coverage, mask

    def _coverage_records(self, view: _View, frame: int, slot: int, cover: dict,
                          skies: dict[tuple[int, int], np.ndarray] | None = None) -> tuple[list, np.ndarray]:
        """Per target: coverage record (thermal: with its radiance and the sky behind it, taken from
        ``skies`` (the ROI background's pixels under each coverage region) when given, else evaluated
        for the region) and the frame's id mask. A pixel's sky does not depend on the launch."""
        cam = view.camera
        k2 = COVERAGE_SUBSAMPLES ** 2
        mask = np.zeros((cam.height_px, cam.width_px), np.uint16)
        best = np.zeros((cam.height_px, cam.width_px), np.float32)
        records = []
        key_target, key_role, key_slot = view._key_target, view._key_role, view._key_slot
        for ti, track in enumerate(self.timeline.targets):
            entry = cover.get((slot, ti))
            if entry is None:
                continue
            region, counts = entry
            own = (key_target == ti) & (key_slot == slot)
            cov = counts[..., own].sum(axis=-1).astype(np.float32) / k2
            if not cov.any():
                continue
            roles = [key_role[i] for i in np.flatnonzero(own)]
            role_px: dict[str, float] = {}
            for i, role in zip(np.flatnonzero(own), roles):
                role_px[role] = role_px.get(role, 0.0) + float(counts[..., i].sum()) / k2
            record = TargetCoverage(track.target_id, region, cov, role_px)
            if view.which == "thermal":
                record.role_radiance = {r: self.thermal_radiance(ti, r, frame, "thermal") for r in role_px}
                x0, y0, x1, y1 = region
                sky = skies[(slot, ti)] if skies is not None else view.sky(frame, region)[..., 0]
                record.sky_radiance = float(np.sum(sky * cov) / cov.sum())
            records.append(record)
            x0, y0, x1, y1 = region
            win_best, win_mask = best[y0:y1, x0:x1], mask[y0:y1, x0:x1]
            take = (cov >= 0.5) & (cov > win_best)
            win_mask[take] = track.target_id
            win_best[take] = cov[take]
        return records, mask

    def _buffers(self, parts: dict) -> FrameBuffers:
        rgb = th = mask_rgb = mask_th = None
        coverage = {}
        if "rgb" in parts:
            image, coverage["rgb"], mask_rgb = parts["rgb"]
            rgb = finite_radiance(np.multiply(image, np.float32(self.exposure), out=image))  # image is private
        if "thermal" in parts:
            image, coverage["thermal"], mask_th = parts["thermal"]
            th = finite_radiance(np.ascontiguousarray(image[..., 0]))
        return FrameBuffers(rgb_linear=rgb, thermal_radiance=th, mask_rgb=mask_rgb,
                            mask_thermal=mask_th, coverage=coverage if self.labels else None)

    def iter_frames(self, ahead: bool = False) -> Generator[tuple[int, Any], None, None]:
        """(frame index, FrameBuffers) for every frame in order, one launch per batch (typed Any: which
        buffers are set depends on the cameras and labels asked for).

        ``ahead``: render batch ``b + 1`` on a worker thread while the caller consumes batch ``b``
        (the camera model, PNG queueing: numpy that overlaps the render's Dr.Jit launches and its
        own Python). The same frames in the same order (a batch's pixels do not depend on when or
        on which thread it is rendered); at most two batches are held. Close the iterator (or
        exhaust it) before ``close()``: closing waits for the batch in flight; a render error is
        raised in the caller when it reaches that batch.
        """
        if not ahead:
            for batch in range(self.n_batches):
                yield from sorted(self.render_batch(batch).items())
            return
        with ThreadPoolExecutor(max_workers=1, thread_name_prefix="evids-render") as pool:
            pending: Future | None = pool.submit(self.render_batch, 0) if self.n_batches else None
            try:
                for batch in range(self.n_batches):
                    if pending is None:
                        raise RuntimeError("render-ahead lost a batch")
                    rendered = pending.result()
                    pending = pool.submit(self.render_batch, batch + 1) if batch + 1 < self.n_batches else None
                    yield from sorted(rendered.items())
            finally:
                if pending is not None:   # the caller stopped early: let the batch in flight finish
                    pending.cancel()
                    wait([pending])

    def close(self) -> None:
        """Free the Mitsuba scenes now (views point back at the renderer, a cycle Python would
        only collect later, so each sequence kept ~250 MB alive) and return Dr.Jit's cached memory."""
        import drjit as dr

        self.views.clear()
        self._cached = {}
        dr.flush_malloc_cache()

    def render_frame(self, frame: int) -> FrameBuffers:
        """One frame (renders and caches its whole batch; identical to rendering it alone)."""
        if frame not in self._cached:
            self._cached = self.render_batch(frame // self.batch_frames)
        return self._cached[frame]
