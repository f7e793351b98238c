"""Benchmark: the detection experiment's per-frame costs on the CPU.

- detector frames/s per stream (RGB 3-channel, thermal 1-channel, evidential head) at the chosen
  input size 320x256 (the rendered resolution of the detection presets; targets 3-30 px wide), at
  batch 1 and batched, with the same detector at 640x512 as the reference (ratio printed);
- fusion cost per frame: per-location Dempster-Shafer and averaging of two (h, w, 2) maps;
- tracking cost per frame: one SwitchingTracker step with 20 candidate detections;
- realised gated saving: a batch-1 loop that runs both detectors every frame vs one that runs
  only what the window-form hysteresis gate plans (a fixed vacuity pattern that closes the RGB
  gate on half the frames), both including fusion.
Weights are random (speed does not depend on them). Last line: ``detection frames/s: X`` =
paired RGB + thermal frames/s at batch 1 through both detectors, DS fusion and the tracker.
Run: ``.venv/bin/python benchmarks/detection.py [--frames 40] [--threads 1]``.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np
import torch

from evids.gating import GateParams, HysteresisGate
from evids.models.detector import CentreDetector, decode_peaks
from harness.experiments.detection.conditions import StreamMaps, fuse_maps
from harness.experiments.detection.tracking import FrameDetections, SwitchingTracker


def _best(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1, help="torch threads (1: stable timings on a shared machine)")
    ap.add_argument("--width", type=int, default=16, help="detector width (the experiment's default)")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    print(f"load average (1 min) at start: {os.getloadavg()[0]:.2f}; torch threads {args.threads}")
    torch.manual_seed(0)
    rgb_m = CentreDetector(3, "evidential", args.width).eval()
    th_m = CentreDetector(1, "evidential", args.width).eval()
    gen = torch.Generator().manual_seed(0)
    rgb = torch.rand(args.frames, 3, 256, 320, generator=gen) - 0.5
    th = torch.randn(args.frames, 1, 256, 320, generator=gen)

    fps = {}
    with torch.no_grad():
        for name, m, x in (("rgb", rgb_m, rgb), ("thermal", th_m, th)):
            m(x[:1])
            t1 = _best(lambda: [m(x[i:i + 1]) for i in range(args.frames)], args.repeats)
            tb = _best(lambda: [m(x[i:i + args.batch]) for i in range(0, args.frames, args.batch)], args.repeats)
            big = torch.nn.functional.interpolate(x[:8], scale_factor=2.0)
            t_ref = _best(lambda: [m(big[i:i + 1]) for i in range(8)], args.repeats) / 8
            fps[name] = args.frames / t1
            print(f"{name:8s} 320x256 batch 1: {args.frames / t1:7.1f} frames/s   batch {args.batch}: "
                  f"{args.frames / tb:7.1f} frames/s   "
                  f"640x512 batch 1: {1 / t_ref:6.1f} frames/s (320x256 is {t_ref / (t1 / args.frames):.1f}x faster)")

        a = StreamMaps.of(rgb_m(rgb[:1]))
        b = StreamMaps.of(th_m(th[:1]))
        t_ds = _best(lambda: [fuse_maps(a, b, "ds") for _ in range(20)], args.repeats) / 20
        t_avg = _best(lambda: [fuse_maps(a, b, "average") for _ in range(20)], args.repeats) / 20
        t_det = _best(lambda: [rgb_m(rgb[:1]) for _ in range(5)], args.repeats) / 5
        print(f"fusion per frame (80x64 locations): DS {t_ds * 1e3:.2f} ms, average {t_avg * 1e3:.2f} ms "
              f"({t_ds / t_det * 100:.1f} % of one detector forward)")

        rng = np.random.default_rng(0)
        dets = [FrameDetections(np.c_[rng.uniform(0, 300, (20, 2)), np.full((20, 2), 8.0)], rng.random(20),
                                rng.random(20) * 0.2)
                for _ in range(200)]
        dets = [FrameDetections(np.r_[[[100 + t * 0.5, 100, 8, 8]], d.boxes[1:]], np.r_[0.99, d.scores[1:]],
                                d.uncertainty)
                for t, d in enumerate(dets)]

        def track():
            trk = SwitchingTracker(0.5, 0.3, 24.0)
            for d in dets:
                trk.step(d)

        t_trk = _best(track, args.repeats) / len(dets)
        t_dec = _best(lambda: decode_peaks(a.prob, a.box, 0.01, 20, {"u": a.vacuity}), args.repeats)
        print(f"tracking per frame (20 candidates): {t_trk * 1e3:.3f} ms; peak decoding {t_dec * 1e3:.2f} ms")

        u_pattern = np.tile([0.9] * 5 + [0.05] * 5, args.frames // 10 + 1)[: args.frames]

        def full():
            for t in range(args.frames):
                ra, tb_ = StreamMaps.of(rgb_m(rgb[t:t + 1])), StreamMaps.of(th_m(th[t:t + 1]))
                fuse_maps(ra, tb_, "ds")

        def gated():
            g = HysteresisGate(2, GateParams(tau_high=0.5, tau_low=0.2, n=4, mode="window"))
            for t in range(args.frames):
                plan = g.plan()
                ra = StreamMaps.of(rgb_m(rgb[t:t + 1])) if plan[0] else None
                tb_ = StreamMaps.of(th_m(th[t:t + 1])) if plan[1] else None
                u = [float(u_pattern[t]) if ra is not None else 1.0, 0.05 if tb_ is not None else 1.0]
                fused = g.update(u)
                ref = ra if ra is not None else tb_
                vac = StreamMaps(ref.prob, ref.box, torch.ones_like(ref.alpha), None)
                fuse_maps(ra if ra is not None and fused[0] else vac, tb_ if tb_ is not None and fused[1] else vac,
                          "ds")
            return g.stats

        t_full = _best(full, args.repeats)
        t_gated = _best(gated, args.repeats)
        stats = gated()
        print(f"gating (batch 1, {args.frames} frames): ungated {t_full / args.frames * 1e3:.1f} ms/frame, gated "
              f"{t_gated / args.frames * 1e3:.1f} ms/frame, realised saving {(1 - t_gated / t_full) * 100:.1f} % "
              f"(RGB skipped on {stats.skip_rate_per_modality[0] * 100:.0f} % of frames)")
        paired = 1.0 / (1.0 / fps["rgb"] + 1.0 / fps["thermal"] + t_ds + t_trk + 2 * t_dec)
    print(f"load average (1 min) at end: {os.getloadavg()[0]:.2f}")
    print(f"detection frames/s: {paired:.1f}")


if __name__ == "__main__":
    main()
