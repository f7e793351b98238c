"""Mitsuba backend: a Timeline -> per-frame RGB radiance, thermal radiance and object-id masks.

One scene graph per camera, sharing geometry built from the same procedural meshes:
- RGB: Hosek-Wilkie ``sunsky`` sky (baked once into an environment map, with optional clouds) plus
  a directional sun, path traced. Visible haze is exact per object: reflectance is scaled by the
  transmittance t and the airlight (1 - t) A is added as emission, so L = t L_obj + (1 - t) A.
- Thermal: every part is an emitter of its at-sensor band radiance
  tau (eps L(T) + (1 - eps) L_refl) + L_path (LOWTRAN7 tables) over an LWIR sky map (simulator.physics.sky);
  one bounce suffices because the physics is folded into the emission (no Mitsuba thermal physics).
- Masks: the same scene at 1 spp with a box filter and only direct emission, where each shape emits
  its target id and the sky emits nothing, so a pixel's value is exactly the id it sees (0 = sky).
  (Mitsuba's shape_index AOV does not follow scene.shapes() order, so it is not used.)
Mitsuba is imported lazily (simulator.render.mitsuba_setup) so nothing else depends on it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenes.assets import build_asset
from scenes.defaults import material_for
from simulator.physics import thermal
from simulator.physics.sky import (
    CloudField,
    ThermalSky,
    direction_from_elevation_azimuth,
    sun_elevation_azimuth_deg,
)
from simulator.physics.timeline import CameraTrack, TargetTrack, Timeline
from simulator.seeding import render_seed

ENV_WIDTH = 2048
ENV_HEIGHT = 1024
SUN_SOLID_ANGLE_SR = 6.8e-5
RGB_MAX_DEPTH = 3
EXPOSURE_KEY = 0.45


@dataclass
class FrameBuffers:
    """Raw per-frame outputs (linear, float32) before encoding."""

    rgb_linear: np.ndarray        # (H, W, 3) linear sRGB radiance x exposure
    thermal_radiance: np.ndarray  # (H, W) W sr^-1 m^-2 at the sensor
    thermal_kelvin: np.ndarray    # (H, W) radiometric (brightness) temperature
    mask_rgb: np.ndarray          # (H, W) uint16 target ids, 0 = background
    mask_thermal: np.ndarray      # (H, W) uint16


def _env_directions(width: int, height: int, to_world: np.ndarray) -> np.ndarray:
    """World direction of each texel of a Mitsuba lat-long map (local +y up, phi = atan2(x, -z))."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    uu, vv = np.meshgrid(u, v)
    theta, phi = vv * np.pi, uu * 2 * np.pi
    local = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], -1)
    return local @ to_world.T


class SkyMaps:
    """The sky as seen by each sensor, baked into environment maps once per sequence."""

    def __init__(self, mi, timeline: Timeline):
        import drjit as dr

        scenario = timeline.scenario
        self.to_world = mi.ScalarTransform4f().rotate([1, 0, 0], 90)
        rot = np.array(self.to_world.matrix)[:3, :3]
        dirs = _env_directions(ENV_WIDTH, ENV_HEIGHT, rot)
        flat = dirs.reshape(-1, 3)
        sun_el, sun_az = sun_elevation_azimuth_deg(scenario.sky.sun)
        self.sun_direction = direction_from_elevation_azimuth(sun_el, sun_az)
        sunsky = {"type": "sunsky", "sun_direction": self.sun_direction.tolist(), "turbidity": scenario.sky.turbidity,
                  "albedo": scenario.sky.ground_albedo}
        sky_only = mi.load_dict({**sunsky, "sun_scale": 0.0})
        si = dr.zeros(mi.SurfaceInteraction3f, flat.shape[0])
        si.wi = mi.Vector3f(-flat[:, 0], -flat[:, 1], -flat[:, 2])
        rgb = np.array(sky_only.eval(si)).T.reshape(ENV_HEIGHT, ENV_WIDTH, 3)
        if sun_el > 0:
            sun_only = mi.load_dict({**sunsky, "sky_scale": 0.0})
            si1 = dr.zeros(mi.SurfaceInteraction3f, 1)
            si1.wi = mi.Vector3f(*[float(c) for c in -self.sun_direction])
            self.sun_irradiance = np.array(sun_only.eval(si1)).ravel() * SUN_SOLID_ANGLE_SR
        else:
            self.sun_irradiance = np.zeros(3)
        up = dirs[..., 2]
        texel_solid_angle = (2 * np.pi / ENV_WIDTH) * (np.pi / ENV_HEIGHT) * np.sqrt(np.clip(1 - (dirs[..., 1] * 0) ** 2, 0, 1))
        texel_solid_angle = texel_solid_angle * np.sin((np.arange(ENV_HEIGHT)[:, None] + 0.5) / ENV_HEIGHT * np.pi)
        cos_up = np.clip(up, 0, None)
        sky_irradiance = np.sum(rgb * (cos_up * texel_solid_angle)[..., None], axis=(0, 1))
        sun_cos = max(self.sun_direction[2], 0.0)
        ground = scenario.sky.ground_albedo * (sky_irradiance + self.sun_irradiance * sun_cos) / np.pi
        clouds = scenario.sky.clouds
        if clouds is not None and clouds.coverage > 0:
            cover = CloudField(clouds, timeline.seed).coverage(dirs)[..., None]
            cloud_rgb = 0.75 * (sky_irradiance + self.sun_irradiance * sun_cos) / np.pi
            rgb = (1 - cover) * rgb + cover * cloud_rgb
            self.sun_irradiance = self.sun_irradiance * (1 - 0.8 * clouds.coverage)
        below = (up <= 0)[..., None]
        rgb = np.where(below, ground, rgb)
        self.rgb = rgb.astype(np.float32)
        horizon = (up > 0.01) & (up < 0.06)
        self.airlight_rgb = rgb[horizon].mean(axis=0) if np.any(horizon) else rgb.reshape(-1, 3).mean(axis=0)
        self.thermal_sky = ThermalSky(scenario.sky, scenario.atmosphere, timeline.seed)
        self.thermal = self.thermal_sky.radiance(dirs).astype(np.float32)
        self.reflected_lwir = self.thermal_sky.reflected_radiance()

    def rgb_at(self, direction: np.ndarray) -> np.ndarray:
        """Sky colour in a world direction (nearest texel), used for exposure."""
        local = np.array(self.to_world.inverse().matrix)[:3, :3] @ direction
        u = (np.arctan2(local[0], -local[2]) / (2 * np.pi)) % 1.0
        v = np.arccos(np.clip(local[1], -1, 1)) / np.pi
        return self.rgb[min(int(v * ENV_HEIGHT), ENV_HEIGHT - 1), min(int(u * ENV_WIDTH), ENV_WIDTH - 1)]


def _color(mi, values) -> object:
    return mi.Color3f(*[float(v) for v in values])


def _object_to_world(track: TargetTrack, frame: int, vertices: np.ndarray) -> np.ndarray:
    return vertices @ track.rotation[frame].T + track.position_m[frame]


def _parts_by_role(track: TargetTrack, frame: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Merge an asset's parts per material role (one Mitsuba shape per role and target)."""
    parts = build_asset(track.kind, track.size_m, flap_phase_rad=float(track.flap_phase_rad[frame]),
                        rotor_angle_rad=float(track.rotor_angle_rad[frame]))
    grouped: dict[str, list] = {}
    for part in parts:
        grouped.setdefault(part.role, []).append(part)
    merged = {}
    for role, group in grouped.items():
        offset = 0
        verts, faces = [], []
        for part in group:
            verts.append(part.vertices)
            faces.append(part.faces + offset)
            offset += len(part.vertices)
        merged[role] = (_object_to_world(track, frame, np.vstack(verts)), np.vstack(faces).astype(np.uint32))
    return merged


class SequenceRenderer:
    """Renders every frame of a Timeline; geometry and shape set stay fixed, so Dr.Jit compiles once."""

    def __init__(self, timeline: Timeline):
        from simulator.render.mitsuba_setup import load_mitsuba

        self.mi = mi = load_mitsuba()
        self.timeline = timeline
        scenario = timeline.scenario
        self.sky = SkyMaps(mi, timeline)
        atm = scenario.atmosphere
        self.beta_visible = thermal.visible_extinction_per_m(atm.visibility_m)
        self.air_radiance = float(thermal.band_radiance(atm.air_temperature_k))
        self.rig = scenario.camera_rig
        self._targets = {t.name: t for t in scenario.targets}
        first = {track.target_id: _parts_by_role(track, 0) for track in timeline.targets}
        self._shape_keys: list[tuple[str, int, str]] = []  # (key, target_id, role)
        for track in timeline.targets:
            for role in first[track.target_id]:
                self._shape_keys.append((f"t{track.target_id}_{role}", track.target_id, role))
        self.rgb_scene = self._build_scene("rgb", first)
        self.thermal_scene = self._build_scene("thermal", first)
        self.rgb_params = mi.traverse(self.rgb_scene)
        self.thermal_params = mi.traverse(self.thermal_scene)
        self._mask_integrator = mi.load_dict({"type": "path", "max_depth": 1})
        look = timeline.cameras["rgb"].forward[0]
        luminance = float(np.dot(self.sky.rgb_at(look), [0.2126, 0.7152, 0.0722]))
        self.exposure = EXPOSURE_KEY / max(luminance, 1e-6)

    def _sensor(self, camera: CameraTrack, spp: int) -> dict:
        mi = self.mi
        return {
            "type": "perspective", "fov": camera.hfov_deg, "fov_axis": "x",
            "near_clip": 0.1, "far_clip": 1e6,
            "to_world": mi.ScalarTransform4f().look_at(origin=camera.origin_m[0].tolist(),
                                                      target=(camera.origin_m[0] + camera.forward[0]).tolist(),
                                                      up=camera.up[0].tolist()),
            "film": {"type": "hdrfilm", "width": camera.width_px, "height": camera.height_px,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        }

    def _build_scene(self, which: str, first: dict):
        mi = self.mi
        camera = self.timeline.cameras[which]
        if which == "rgb":
            env_bitmap = mi.Bitmap(self.sky.rgb)
            scene: dict = {"type": "scene", "integrator": {"type": "path", "max_depth": RGB_MAX_DEPTH},
                           "sensor": self._sensor(camera, self.rig.rgb.spp)}
            if np.any(self.sky.sun_irradiance > 0):
                scene["sun"] = {"type": "directional", "direction": (-self.sky.sun_direction).tolist(),
                                "irradiance": {"type": "rgb", "value": self.sky.sun_irradiance.tolist()}}
        else:
            env_bitmap = mi.Bitmap(np.repeat(self.sky.thermal[..., None], 3, axis=-1))
            scene = {"type": "scene", "integrator": {"type": "path", "max_depth": 1},
                     "sensor": self._sensor(camera, self.rig.thermal.spp)}
        scene["sky"] = {"type": "envmap", "bitmap": env_bitmap, "to_world": self.sky.to_world}
        for key, tid, role in self._shape_keys:
            verts, faces = first[tid][role]
            props = mi.Properties()
            props["bsdf"] = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}})
            props["emitter"] = mi.load_dict({"type": "area", "radiance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}})
            mesh = mi.Mesh(key, len(verts), len(faces), props=props)
            params = mi.traverse(mesh)
            params["vertex_positions"] = mi.Float(verts.astype(np.float32).ravel())
            params["faces"] = mi.UInt32(faces.ravel())
            params.update()
            scene[key] = mesh
        return mi.load_dict(scene)

    def _update(self, frame: int) -> None:
        mi = self.mi
        tracks = {t.target_id: t for t in self.timeline.targets}
        geometry = {tid: _parts_by_role(track, frame) for tid, track in tracks.items()}
        for which, params in (("rgb", self.rgb_params), ("thermal", self.thermal_params)):
            camera = self.timeline.cameras[which]
            params["sky.scale"] = 1.0
            params["sensor.to_world"] = mi.ScalarTransform4f().look_at(
                origin=camera.origin_m[frame].tolist(), target=(camera.origin_m[frame] + camera.forward[frame]).tolist(),
                up=camera.up[frame].tolist())
            paths = {}
            for tid, track in tracks.items():  # LWIR path per target (LOWTRAN7 tables, simulator.physics.atmosphere)
                sight = track.position_m[frame] - camera.origin_m[frame]
                paths[tid] = (float(np.linalg.norm(sight)), *self.sky.thermal_sky.lwir.along(sight))
            for key, tid, role in self._shape_keys:
                track = tracks[tid]
                verts, _ = geometry[tid][role]
                params[f"{key}.vertex_positions"] = mi.Float(verts.astype(np.float32).ravel())
                range_m, tau, path_radiance = paths[tid]
                material = material_for(self._targets[track.name], role)
                if which == "rgb":
                    t = float(np.exp(-self.beta_visible * range_m))
                    params[f"{key}.bsdf.reflectance.value"] = _color(mi, t * np.asarray(material.rgb_reflectance))
                    params[f"{key}.emitter.radiance.value"] = _color(mi, (1 - t) * self.sky.airlight_rgb)
                else:
                    temp_k = float(track.part_temperature_k[role][frame])
                    surface = thermal.surface_radiance(temp_k, material.emissivity, self.sky.reflected_lwir)
                    value = float(tau * surface + path_radiance)
                    params[f"{key}.emitter.radiance.value"] = mi.Color3f(value, value, value)
                    params[f"{key}.bsdf.reflectance.value"] = mi.Color3f(0.0, 0.0, 0.0)
            params.update()

    def render_frame(self, frame: int) -> FrameBuffers:
        mi = self.mi
        self._update(frame)
        seed = self.timeline.seed
        rgb = np.array(mi.render(self.rgb_scene, seed=render_seed(seed, frame, 0)), dtype=np.float32)
        th = np.array(mi.render(self.thermal_scene, seed=render_seed(seed, frame, 1)), dtype=np.float32)[..., 0]
        masks = {}
        for idx, (which, scene, params) in enumerate((("rgb", self.rgb_scene, self.rgb_params),
                                                      ("thermal", self.thermal_scene, self.thermal_params))):
            params["sky.scale"] = 0.0
            for key, tid, _ in self._shape_keys:
                params[f"{key}.emitter.radiance.value"] = mi.Color3f(float(tid), float(tid), float(tid))
            params.update()
            ids = np.array(mi.render(scene, integrator=self._mask_integrator, spp=1,
                                     seed=render_seed(seed, frame, 2 + idx)))[..., 0]
            masks[which] = np.rint(ids).astype(np.uint16)
        kelvin = thermal.brightness_temperature(th).astype(np.float32)
        return FrameBuffers(rgb_linear=rgb * np.float32(self.exposure), thermal_radiance=th, thermal_kelvin=kelvin,
                            mask_rgb=masks["rgb"], mask_thermal=masks["thermal"])
