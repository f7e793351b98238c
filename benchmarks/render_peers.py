"""Peer benchmark: the same scene rendered by Blender Cycles (CPU) and by our paired renderer.

Scene: preset `clear_day_quad` (a small quadcopter against the sky, sun), 640x512, equal samples
per pixel (the preset's 4), no denoising, no adaptive sampling, box-like pixel filter as close as
Cycles allows (its default filter, 1.5 px Blackman-Harris, is kept: it costs nothing extra).
What each side renders per frame:
- Blender 5 (Cycles, CPU, all cores): RGB (the same baked sky as an equirectangular world texture, a sun lamp of
  the same irradiance, the drone's meshes of that frame with the same diffuse albedos, 3 bounces) and
  thermal as an emission pass (the LWIR sky map as the world, each part an emitter of its
  at-sensor band radiance, no bounces). Mesh vertices and camera are updated per frame with
  persistent data on (no scene rebuild); only `bpy.ops.render.render()` is timed, nothing is
  written.
- Ours (`SequenceRenderer`): RGB + thermal radiance + coverage masks for both cameras + labels
  of the same frames, batched as in `evids render`.
Blender runs in a subprocess: `bpy` (PyPI, Python 3.11 only) pins numpy 1.26, so it usually lives
in its own environment: `--blender-python /path/to/python-with-bpy` (default: this interpreter).
Without bpy the benchmark says so and exits 0. The load average is printed (shared machine).

    .venv/bin/python benchmarks/render_peers.py [--frames 6] [--blender-python PY]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SCENE = "clear_day_quad"


# ------------------------------------------------------------------------------------------
# Export of our scene for Blender (runs in the project environment)


def _blender_equirect(env: np.ndarray, to_world: np.ndarray, width: int = 1024, height: int = 512) -> np.ndarray:
    """Our lat-long map (Mitsuba convention) resampled into Blender's equirectangular convention
    (Z up, u = 0.5 - atan2(y, x) / 2 pi, v = 0.5 + elevation / pi; file row 0 = top)."""
    u = (np.arange(width) + 0.5) / width
    v = 1.0 - (np.arange(height) + 0.5) / height
    uu, vv = np.meshgrid(u, v)
    az, el = (0.5 - uu) * 2 * np.pi, (vv - 0.5) * np.pi
    world = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1)
    local = world @ to_world  # inverse rotation (orthonormal)
    mu = (np.arctan2(local[..., 0], -local[..., 2]) / (2 * np.pi)) % 1.0
    mv = np.arccos(np.clip(local[..., 1], -1, 1)) / np.pi
    h, w = env.shape[:2]
    return env[np.minimum((mv * h).astype(int), h - 1), np.minimum((mu * w).astype(int), w - 1)]


def export_scene(frames: int, folder: Path) -> dict:
    import cv2

    from scenes import load_scenario
    from simulator.physics.timeline import build_timeline
    from simulator.render.renderer import SequenceRenderer

    scenario = load_scenario(SCENE)
    timeline = build_timeline(scenario, 0, frames)
    renderer = SequenceRenderer(timeline)
    rot = np.array(renderer.sky.to_world.matrix, dtype=np.float64)[:3, :3]
    sky_rgb = _blender_equirect(renderer.sky.rgb, rot)
    sky_th = _blender_equirect(np.repeat(renderer.sky.thermal[..., None], 3, -1), rot)
    cv2.imwrite(str(folder / "sky_rgb.hdr"), sky_rgb[..., ::-1].astype(np.float32))
    cv2.imwrite(str(folder / "sky_thermal.hdr"), sky_th[..., ::-1].astype(np.float32))
    geo = renderer.geometry[0]
    meta = {"roles": geo.roles, "frames": frames, "spp": scenario.camera_rig.rgb.spp, "cameras": {},
            "sun_direction": renderer.sky.sun_direction.tolist(),
            "sun_irradiance": [float(v) for v in renderer.sky.sun_irradiance], "exposure": renderer.exposure}
    arrays = {}
    for role in geo.roles:
        arrays[f"faces_{role}"] = geo.faces(role).astype(np.int32)
    for which in ("rgb", "thermal"):
        cam = timeline.cameras[which]
        meta["cameras"][which] = {"width": cam.width_px, "height": cam.height_px, "hfov_deg": cam.hfov_deg}
        arrays[f"{which}_origin"] = cam.origin_m
        arrays[f"{which}_forward"] = cam.forward
        arrays[f"{which}_up"] = cam.up
    for i in range(frames):
        for role, verts in geo.world(i).items():
            arrays[f"v{i}_{role}"] = verts
            refl, _ = renderer.rgb_material(0, role, i, "rgb")
            arrays[f"albedo{i}_{role}"] = np.asarray(refl, np.float64)
            arrays[f"thermal{i}_{role}"] = np.array([renderer.thermal_radiance(0, role, i, "thermal")])
    np.savez(folder / "scene.npz", **arrays)
    (folder / "scene.json").write_text(json.dumps(meta))
    return meta


def time_ours(frames: int) -> tuple[float, int]:
    """Seconds per paired frame of our renderer (RGB + thermal + coverage + labels), after a
    warm-up sequence (kernel compilation), as `evids render` does it."""
    from scenes import load_scenario
    from simulator.physics.timeline import build_timeline
    from simulator.render.labels import coverage_labels
    from simulator.render.renderer import SequenceRenderer

    scenario = load_scenario(SCENE)
    n = max(frames, 32)
    scenario = scenario.model_copy(update={"duration_s": n / scenario.frame_rate_hz})
    list(SequenceRenderer(build_timeline(scenario, 1, n)).iter_frames())  # compile
    timeline = build_timeline(scenario, 0, n)
    renderer = SequenceRenderer(timeline)
    t0 = time.perf_counter()
    for i, fb in renderer.iter_frames():
        for which in ("rgb", "thermal"):
            cam = timeline.cameras[which]
            coverage_labels(timeline, i, which, fb.coverage[which], cam.width_px, cam.height_px,
                            0.05 if which == "thermal" else None)
    return (time.perf_counter() - t0) / n, n


# ------------------------------------------------------------------------------------------
# The Blender side (runs in an environment with bpy; imports nothing of ours)


def blender_side(folder: Path) -> None:
    import bpy

    meta = json.loads((folder / "scene.json").read_text())
    data = np.load(folder / "scene.npz")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = int(meta["spp"])
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.render.use_persistent_data = True
    scene.render.resolution_percentage = 100
    cam_data = bpy.data.cameras.new("cam")
    cam_data.sensor_fit = "HORIZONTAL"
    cam_data.clip_start, cam_data.clip_end = 0.1, 1e5
    cam = bpy.data.objects.new("cam", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    world = bpy.data.worlds.new("world")
    scene.world = world
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    nodes.clear()
    env = nodes.new("ShaderNodeTexEnvironment")
    bg = nodes.new("ShaderNodeBackground")
    out = nodes.new("ShaderNodeOutputWorld")
    links.new(env.outputs["Color"], bg.inputs["Color"])
    links.new(bg.outputs["Background"], out.inputs["Surface"])
    skies = {w: bpy.data.images.load(str(folder / f"sky_{w}.hdr")) for w in ("rgb", "thermal")}
    sun_data = bpy.data.lights.new("sun", "SUN")
    sun_data.energy = float(np.mean(meta["sun_irradiance"])) or 0.0
    sun_data.color = [c / max(max(meta["sun_irradiance"]), 1e-9) for c in meta["sun_irradiance"]]
    sun_data.angle = 0.0093
    sun = bpy.data.objects.new("sun", sun_data)
    scene.collection.objects.link(sun)
    d = -np.asarray(meta["sun_direction"])  # light travels along -sun_direction; Blender sun shines along its -Z
    z = -d / np.linalg.norm(d)
    x = np.cross([0.0, 0.0, 1.0], z) if abs(z[2]) < 0.99 else np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    sun.matrix_world = _matrix(x, y, z, np.zeros(3))
    parts = {}
    for role in meta["roles"]:
        faces = data[f"faces_{role}"]
        verts = data[f"v0_{role}"]
        mesh = bpy.data.meshes.new(role)
        mesh.from_pydata(verts.tolist(), [], faces.tolist())
        mesh.update()
        mat = bpy.data.materials.new(role)
        mat.use_nodes = True
        mnodes, mlinks = mat.node_tree.nodes, mat.node_tree.links
        mnodes.clear()
        diffuse = mnodes.new("ShaderNodeBsdfDiffuse")
        emission = mnodes.new("ShaderNodeEmission")
        mix = mnodes.new("ShaderNodeMixShader")
        mout = mnodes.new("ShaderNodeOutputMaterial")
        mlinks.new(diffuse.outputs["BSDF"], mix.inputs[1])
        mlinks.new(emission.outputs["Emission"], mix.inputs[2])
        mlinks.new(mix.outputs["Shader"], mout.inputs["Surface"])
        mesh.materials.append(mat)
        obj = bpy.data.objects.new(role, mesh)
        scene.collection.objects.link(obj)
        parts[role] = (mesh, diffuse, emission, mix)
    times = {"rgb": [], "thermal": []}
    for which in ("rgb", "thermal"):  # all frames of one pass, then the other (fewer state switches)
        for i in range(int(meta["frames"])):
            c = meta["cameras"][which]
            scene.render.resolution_x, scene.render.resolution_y = c["width"], c["height"]
            cam_data.angle = np.radians(c["hfov_deg"])
            origin = data[f"{which}_origin"][i]
            fwd, up = data[f"{which}_forward"][i], data[f"{which}_up"][i]
            right = np.cross(fwd, up)
            cam.matrix_world = _matrix(right, up, -fwd, origin)
            env.image = skies[which]
            sun_data.energy = (float(np.mean(meta["sun_irradiance"])) if which == "rgb" else 0.0)
            scene.cycles.max_bounces = 3 if which == "rgb" else 0
            for role, (mesh, diffuse, emission, mix) in parts.items():
                mesh.vertices.foreach_set("co", data[f"v{i}_{role}"].astype(np.float32).ravel())
                mesh.update()
                albedo = data[f"albedo{i}_{role}"]
                diffuse.inputs["Color"].default_value = (*albedo.tolist(), 1.0)
                emission.inputs["Strength"].default_value = float(data[f"thermal{i}_{role}"][0])
                mix.inputs["Fac"].default_value = 0.0 if which == "rgb" else 1.0
            t0 = time.perf_counter()
            bpy.ops.render.render(write_still=False)
            times[which].append(time.perf_counter() - t0)
    print(json.dumps({"blender": bpy.app.version_string, "times": times}))


def _matrix(x, y, z, t):
    from mathutils import Matrix

    return Matrix([[x[0], y[0], z[0], t[0]], [x[1], y[1], z[1], t[1]], [x[2], y[2], z[2], t[2]], [0, 0, 0, 1]])


# ------------------------------------------------------------------------------------------


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=6)
    parser.add_argument("--blender-python", default=sys.executable)
    parser.add_argument("--blender-side", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.blender_side:
        blender_side(args.blender_side)
        return
    probe = subprocess.run([args.blender_python, "-c", "import bpy"], capture_output=True, text=True)
    if probe.returncode:
        print(f"bpy is not importable by {args.blender_python}: Blender peer benchmark skipped "
              "(pip install bpy in a Python 3.11 environment and pass --blender-python)")
        return
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        meta = export_scene(args.frames + 1, folder)
        proc = subprocess.run([args.blender_python, __file__, "--blender-side", str(folder)],
                              capture_output=True, text=True)
        if proc.returncode:
            raise SystemExit(f"Blender side failed:\n{proc.stderr[-3000:]}")
        result = json.loads(proc.stdout.strip().splitlines()[-1])
    ours_s, ours_n = time_ours(args.frames)
    rgb = result["times"]["rgb"][1:]  # the first frame of each pass builds Cycles' kernels and BVH
    th = result["times"]["thermal"][1:]
    blender_paired = float(np.mean(rgb) + np.mean(th))
    print(f"scene {SCENE}: 640x512, {meta['spp']} spp, {args.frames} timed frames after one warm-up frame")
    print(f"blender {result['blender']} cycles CPU, RGB pass: " + " ".join(f"{t:.3f}" for t in rgb) + " s/frame")
    print("blender cycles CPU, thermal emission pass: " + " ".join(f"{t:.3f}" for t in th) + " s/frame")
    print(f"blender paired frame (RGB + thermal): {blender_paired:.3f} s")
    print(f"ours paired frame (RGB + thermal + coverage masks + labels, {ours_n} frames batched): {ours_s:.4f} s")
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    print(f"paired frame speedup vs blender cycles: {blender_paired / ours_s:.1f}")


if __name__ == "__main__":
    main()
