"""Render benchmark: paired RGB 640x512 + thermal 640x512 + masks + labels of a preset sequence.

Prints the time per pass and, last, `paired frames/s: X` sustained over the frames after warm-up.
Reference measured in the same run: the same frame rendered with Mitsuba's scalar variant is not
practical here, so the ratio printed is against the naive approach of re-building the Mitsuba
scene for every frame (what a simple loader-per-frame pipeline does).

    .venv/bin/python benchmarks/render.py [--scene clear_day_quad] [--frames 100] [--warmup 5]
"""
from __future__ import annotations

import argparse
import time

from scenes import load_scenario
from simulator.physics.timeline import build_timeline
from simulator.render.labels import frame_labels
from simulator.render.renderer import SequenceRenderer
from simulator.sensors.camera import CameraModel
from simulator.sensors.encode import agc_8bit, kelvin_to_counts, rgb_to_srgb8


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", default="clear_day_quad")
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--warmup", type=int, default=5)
    parser.add_argument("--naive-frames", type=int, default=5)
    args = parser.parse_args()
    scenario = load_scenario(args.scene)
    total = args.frames + args.warmup
    scenario = scenario.model_copy(update={"duration_s": total / scenario.frame_rate_hz})
    timeline = build_timeline(scenario, 0)
    t0 = time.perf_counter()
    renderer = SequenceRenderer(timeline)
    setup_s = time.perf_counter() - t0
    netd = scenario.camera_rig.thermal.netd_k
    kpc = scenario.camera_rig.thermal.kelvin_per_count
    passes = {"render (rgb + thermal + 2 masks)": 0.0, "encode (sRGB, counts, AGC)": 0.0, "labels": 0.0}
    # --- camera model (issue 13): on by default in render_sequence, so it counts in frames/s ---
    camera = CameraModel(timeline, renderer.exposure)
    passes["camera model (PSF, lag, noise, AGC)"] = 0.0
    # ---
    for i in range(args.warmup):
        renderer.render_frame(i)
    start = time.perf_counter()
    for i in range(args.warmup, total):
        a = time.perf_counter()
        fb = renderer.render_frame(i)
        b = time.perf_counter()
        rgb_to_srgb8(fb.rgb_linear)
        kelvin_to_counts(fb.thermal_kelvin, kpc)
        agc_8bit(fb.thermal_kelvin)
        c = time.perf_counter()
        frame_labels(timeline, i, "rgb", fb.mask_rgb)
        frame_labels(timeline, i, "thermal", fb.mask_thermal, fb.thermal_kelvin, netd)
        d = time.perf_counter()
        camera.record(i, fb.rgb_linear, fb.thermal_radiance, fb.thermal_kelvin)  # camera model block
        passes["camera model (PSF, lag, noise, AGC)"] += time.perf_counter() - d
        passes["render (rgb + thermal + 2 masks)"] += b - a
        passes["encode (sRGB, counts, AGC)"] += c - b
        passes["labels"] += d - c
    elapsed = time.perf_counter() - start
    fps = args.frames / elapsed
    naive_start = time.perf_counter()
    for i in range(args.naive_frames):
        SequenceRenderer(build_timeline(scenario, 0, n_frames=i + 1)).render_frame(i)
    naive_fps = args.naive_frames / (time.perf_counter() - naive_start)
    print(f"scene {args.scene}, {args.frames} frames after {args.warmup} warm-up, variant {renderer.mi.variant()}, "
          f"rgb spp {scenario.camera_rig.rgb.spp}, thermal spp {scenario.camera_rig.thermal.spp}")
    print(f"setup (sky maps + scene build): {setup_s:.3f} s")
    for name, seconds in passes.items():
        print(f"{name}: {1000 * seconds / args.frames:.1f} ms/frame")
    print(f"naive rebuild-per-frame: {naive_fps:.2f} paired frames/s; speedup {fps / naive_fps:.1f}x")
    print(f"paired frames/s: {fps:.2f}")


if __name__ == "__main__":
    main()
