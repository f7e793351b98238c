"""Render benchmark: paired RGB 640x512 + thermal 640x512 + coverage masks + labels of a preset
sequence, and small-frame RGB video at 112x112 (the TRIDENT size `evids demo` renders).

Prints the time per stage and the lines `paired frames/s: X` (sustained after a warm-up batch;
render + labels + the camera model (which encodes), in frame order as in `evids render`, the next
batch rendering on a worker thread meanwhile; the per-stage times are printed too: the render's is
the time the loop waited for it), `evids render end to end paired
frames/s: X` (`render_sequence` of the same frames into a temporary folder: setup, PNG writing,
labels.json, hashes) and `video 112px frames/s: X` (`simulator.dataset.sequence.render_rgb_video`
of a whole clip, RGB only, setup included). Reference measured in the same run: the
previous renderer's approach, one Mitsuba launch per frame and pass (`mi.render` of a per-frame
scene with the same shapes, spp and integrators: RGB, thermal and two id-mask passes), so the
ratio shows what batching, ROI tiles and analytic coverage buy. The load average is printed
(the machine is shared; absolute figures vary with it).

    .venv/bin/python benchmarks/render.py [--scene clear_day_quad] [--frames 96] [--video-frames 224]
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from scenes import load_scenario
from simulator.dataset.sequence import render_rgb_video
from simulator.physics.timeline import build_timeline
from simulator.render.labels import coverage_labels
from simulator.render.plan import BATCH_FRAMES
from simulator.render.renderer import SequenceRenderer
from simulator.sensors.camera import CameraModel


def _per_launch_reference(scenario, n_frames: int) -> float:
    """Frames/s of one `mi.render` per frame and pass (RGB, thermal, 2 masks) at the same size/spp."""
    from simulator.render.mitsuba_setup import load_mitsuba

    mi = load_mitsuba()
    timeline = build_timeline(scenario, 0, n_frames + 1)
    renderer = SequenceRenderer(timeline, batch_frames=1, roi=False)
    views = renderer.views
    integrators = {"rgb": mi.load_dict({"type": "path", "max_depth": 3}),
                   "thermal": mi.load_dict({"type": "path", "max_depth": 1})}
    scenes = {}
    for which, view in views.items():
        cam = timeline.cameras[which]
        sensor = mi.load_dict({"type": "perspective", "fov": cam.hfov_deg, "fov_axis": "x",
                               "film": {"type": "hdrfilm", "width": cam.width_px, "height": cam.height_px,
                                        "rfilter": {"type": "box"}, "pixel_format": "rgb"},
                               "sampler": {"type": "independent", "sample_count": view.spp},
                               "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 0],
                                                                          target=cam.forward[0].tolist(),
                                                                         up=cam.up[0].tolist())})
        scenes[which] = (view.scene, sensor, mi.traverse(sensor))
    def one(frame: int) -> None:
        for which, view in views.items():
            cam = timeline.cameras[which]
            view.place([frame])
            scene, sensor, sp = scenes[which]
            sp["to_world"] = mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=cam.forward[frame].tolist(),
                                                            up=cam.up[frame].tolist())
            sp.update()
            np.array(mi.render(scene, sensor=sensor, integrator=integrators[which], seed=frame))
            np.array(mi.render(scene, sensor=sensor, integrator=integrators["thermal"], spp=1, seed=frame + 1))
    one(0)
    start = time.perf_counter()
    for i in range(1, n_frames + 1):
        one(i)
    return n_frames / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", default="clear_day_quad")
    parser.add_argument("--frames", type=int, default=96)
    parser.add_argument("--video-frames", type=int, default=224)
    parser.add_argument("--reference-frames", type=int, default=8)
    parser.add_argument("--video-pairs", type=int, default=3, help="alternating new-sky / reused-sky video clips")
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    scenario = load_scenario(args.scene)
    warm = BATCH_FRAMES
    total = args.frames + warm
    scenario = scenario.model_copy(update={"duration_s": total / scenario.frame_rate_hz})
    timeline = build_timeline(scenario, 0)
    t0 = time.perf_counter()
    renderer = SequenceRenderer(timeline)
    setup_s = time.perf_counter() - t0
    netd = scenario.camera_rig.thermal.netd_k
    rgb_cam, th_cam = timeline.cameras["rgb"], timeline.cameras["thermal"]
    stages = {"wait for the render (rgb + thermal + coverage, one batch ahead)": 0.0, "labels": 0.0,
              "camera model (PSF, lag, noise, encodings, AGC)": 0.0}
    # camera model (issue 13): on by default in render_sequence, so it counts in frames/s; it keeps
    # state (bolometer lag), so it runs in frame order here as it does there
    camera = CameraModel(timeline, renderer.exposure)
    frames = renderer.iter_frames(ahead=True)  # as render_sequence: the next batch renders beside the camera model
    for _ in range(warm):  # the first batch compiles the kernels
        i, fb = next(frames)
        camera.record_buffers(i, fb)
    start = time.perf_counter()
    a = start
    for i, fb in frames:
        b = time.perf_counter()
        coverage_labels(timeline, i, "rgb", fb.coverage["rgb"], rgb_cam.width_px, rgb_cam.height_px)
        coverage_labels(timeline, i, "thermal", fb.coverage["thermal"], th_cam.width_px, th_cam.height_px, netd)
        c = time.perf_counter()
        camera.record_buffers(i, fb)
        d = time.perf_counter()
        stages["wait for the render (rgb + thermal + coverage, one batch ahead)"] += b - a
        stages["labels"] += c - b
        stages["camera model (PSF, lag, noise, encodings, AGC)"] += d - c
        a = time.perf_counter()
    elapsed = time.perf_counter() - start
    fps = args.frames / elapsed
    reference_fps = _per_launch_reference(scenario, args.reference_frames)

    import tempfile
    from pathlib import Path

    from simulator.dataset.sequence import PassTimes, render_sequence

    with tempfile.TemporaryDirectory() as tmp:
        e2e_times = PassTimes()
        e0 = time.perf_counter()
        render_sequence(scenario, 0, Path(tmp), progress=False, times=e2e_times)
        e2e_s = time.perf_counter() - e0
    e2e_fps = timeline.n_frames / e2e_s

    video_scene = load_scenario(args.scene)
    video_scene = video_scene.model_copy(update={"duration_s": args.video_frames / video_scene.frame_rate_hz})
    render_rgb_video(video_scene, 1, 32, 112, 112)  # compile
    from simulator.render import renderer as renderer_module

    # alternately: the clip under a new sky (bake cleared: its setup includes the sky bake, as in
    # earlier figures) and the same clip with the bake reused (as a twin clip's is); medians
    fresh, cached = [], []
    for _ in range(args.video_pairs):
        renderer_module._SKY_BAKES.clear()
        v0 = time.perf_counter()
        video = render_rgb_video(video_scene, 0, args.video_frames, 112, 112)
        fresh.append(len(video) / (time.perf_counter() - v0))
        v0 = time.perf_counter()
        render_rgb_video(video_scene, 0, args.video_frames, 112, 112)
        cached.append(len(video) / (time.perf_counter() - v0))
    video_fps, video_cached_fps = float(np.median(fresh)), float(np.median(cached))
    pair_ratio = float(np.median(np.array(cached) / np.array(fresh)))

    print(f"scene {args.scene}, {args.frames} frames after a {warm}-frame warm-up batch, variant "
          f"{renderer.mi.variant()}, "
          f"rgb spp {scenario.camera_rig.rgb.spp}, thermal spp {scenario.camera_rig.thermal.spp}")
    print(f"layout: {renderer.record()}")
    print(f"setup (sky maps + scene build): {setup_s:.3f} s")
    for name, seconds in stages.items():
        print(f"{name}: {1000 * seconds / args.frames:.1f} ms/frame")
    print(f"reference, one launch per frame and pass (4 passes): {reference_fps:.2f} paired frames/s; "
          f"speedup {fps / reference_fps:.1f}x")
    print(f"video 112px: {len(video)} frames incl. sky maps and scene build per clip")
    print("render_sequence end to end (native layout, PNGs on writer threads, labels, hashes; "
          f"{timeline.n_frames} frames incl. setup): " + ", ".join(f"{k} {v:.2f} s"
                                                                   for k, v in e2e_times.seconds.items()))
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    print(f"paired frames/s: {fps:.2f}")
    print(f"evids render end to end paired frames/s: {e2e_fps:.2f}")
    print(f"video 112px frames/s: {video_fps:.1f}")
    print(f"video 112px frames/s, sky bake reused (twin clip / same sky): {video_cached_fps:.1f} "
          f"(median ratio to a new sky over {args.video_pairs} alternating pairs: {pair_ratio:.2f})")


if __name__ == "__main__":
    main()
