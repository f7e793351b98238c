"""Cost per 640x512 frame of the sensor stages added for sim-to-real realism, each printed next to
a reference computed in the same run on the same frames:

- plateau equalisation (agc: plateau) vs the plain histogram equalisation (agc: histogram);
- the local-contrast step's halo-free base (agc_base_opening_px 21, the sim2real drone camera's) vs its
  Gaussian base (sigma 15 px), both at that camera's 320x256 (every other pixel of the same frames);
- the camcorder tone (tone: camcorder) vs the fixed sRGB look-up (tone: srgb), and with its colour level
  (colour_gain 1.5) vs without;
- the H.264 recording stage (camera_rig.recording) for an RGB and a grey frame vs writing the same
  frame as PNG (simulator.formats.native.write_png, which every native render already does);
- the thermal camera's record step (radiance -> kelvin, counts, 8-bit) with the per-pixel gain residual
  (fpn_pixel_gain) vs the column terms only, at the sim2real camera's 320x256.

Inputs are synthetic (a noisy sky gradient over a warm ground band with a moving target).

    .venv/bin/python benchmarks/sensor_stages.py [--frames 30] [--preset veryfast]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from scenes.schema import Recording
from simulator.formats.native import write_png
from simulator.physics.thermal import band_radiance
from simulator.sensors.agc import CamcorderExposure, PlateauAgc
from simulator.sensors.camera import ThermalSensor, equalise_counts
from simulator.sensors.recording import H264Stream

H, W = 512, 640


def _frames(n: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    rng = np.random.default_rng(0)
    yy = np.arange(H)[:, None] * np.ones((1, W))
    counts, levels = [], []
    for i in range(n):
        kelvin = 270.0 + 4.0 * yy / H
        kelvin[2 * H // 3:] = 285.0 + 3.0 * rng.random((H - 2 * H // 3, W))
        kelvin[200:206, 100 + 3 * i:110 + 3 * i] += 5.0
        kelvin += rng.normal(0, 0.05, kelvin.shape)
        counts.append(np.rint(kelvin / 0.01).astype(np.uint16))
        lin = np.repeat((1500 + 800 * yy / H)[..., None], 3, axis=-1) + rng.normal(0, 20, (H, W, 3))
        levels.append(np.clip(lin, 0, 4095).astype(np.uint16))
    return counts, levels


def _thermal_sensors() -> tuple[ThermalSensor, ThermalSensor]:
    """The sim2real drone camera's settings at 320x256, without and with the per-pixel gain residual."""
    from scenes import load_scenario
    from simulator.physics.timeline import build_timeline

    scenario = load_scenario(Path(__file__).resolve().parents[1] / "examples" / "sim2real" / "realism_drone.yaml")
    timeline = build_timeline(scenario, 0)
    with_pixel = scenario.camera_rig.thermal
    columns_only = with_pixel.model_copy(update={"fpn_pixel_gain": None})
    return (ThermalSensor(columns_only, timeline, 1 / 30, 285.0), ThermalSensor(with_pixel, timeline, 1 / 30, 285.0))


def _per_frame_ms(fn, items) -> float:
    t0 = time.perf_counter()
    for x in items:
        fn(x)
    return (time.perf_counter() - t0) / len(items) * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--preset", default="veryfast")
    args = parser.parse_args()
    counts, levels = _frames(args.frames)
    plateau = PlateauAgc(0.01, 0.05, 0.01, 0.2, 0.005, 4.0, 0.9)
    local = PlateauAgc(0.01, 0.05, 0.005, 0.5, 0.005, 16.0, 0.9, base_sigma_px=30.0, base_gain=0.0)   # 15 px at 320
    gaussian_320 = PlateauAgc(0.01, 0.05, 0.005, 0.1, 0.0, 16.0, 0.9, base_sigma_px=15.0, base_gain=0.02)
    opened_320 = PlateauAgc(0.01, 0.05, 0.005, 0.1, 0.0, 16.0, 0.9, base_sigma_px=15.0, base_gain=0.02,
                            base_opening_px=21)
    counts_320 = [np.ascontiguousarray(c[::2, ::2]) for c in counts]
    camcorder = CamcorderExposure(1 / 4095, 4095, 0.25, 0.9, 0.85, 0.25)
    vivid = CamcorderExposure(1 / 4095, 4095, 0.25, 0.9, 0.85, 0.25, colour_gain=1.5)
    srgb_lut = np.arange(4096, dtype=np.uint16).astype(np.uint8)
    rgb8 = [camcorder(x) for x in levels]
    grey8 = [plateau(c) for c in counts]
    rec = Recording(crf=28.0, preset=args.preset)
    rgb_stream = H264Stream(W, H, 30.0, rec, colour=True)
    grey_stream = H264Stream(W, H, 30.0, rec, colour=False)
    columns_only, with_pixel = _thermal_sensors()
    radiance_320 = [band_radiance(c[::2, ::2].astype(np.float32) * 0.01).astype(np.float32) for c in counts]
    with tempfile.TemporaryDirectory() as tmp:
        rows = [
            ("plateau AGC (thermal)", _per_frame_ms(plateau, counts), "histogram AGC",
             _per_frame_ms(equalise_counts, counts)),
            ("plateau + local contrast", _per_frame_ms(local, counts), "histogram AGC",
             _per_frame_ms(equalise_counts, counts)),
            ("320x256: opening base", _per_frame_ms(opened_320, counts_320), "Gaussian base",
             _per_frame_ms(gaussian_320, counts_320)),
            ("camcorder AE + tone (RGB)", _per_frame_ms(camcorder, levels), "sRGB LUT",
             _per_frame_ms(lambda x: srgb_lut.take(x.ravel()).reshape(x.shape), levels)),
            ("camcorder + colour gain", _per_frame_ms(vivid, levels), "camcorder",
             _per_frame_ms(camcorder, levels)),
            ("H.264 encode+decode RGB", _per_frame_ms(rgb_stream, rgb8), "PNG write RGB",
             _per_frame_ms(lambda x: write_png(Path(tmp) / "a.png", x), rgb8)),
            ("H.264 encode+decode grey", _per_frame_ms(grey_stream, grey8), "PNG write grey",
             _per_frame_ms(lambda x: write_png(Path(tmp) / "b.png", x), grey8)),
            ("320x256: record, pixel FPN", _per_frame_ms(lambda r: with_pixel.record(0, r), radiance_320),
             "column FPN only", _per_frame_ms(lambda r: columns_only.record(0, r), radiance_320)),
        ]
    print(f"per {W}x{H} frame, {args.frames} frames, preset {args.preset} (single thread)")
    for name, ms, ref, ref_ms in rows:
        print(f"{name:28s} {ms:7.2f} ms   {ref:16s} {ref_ms:7.2f} ms   ratio {ms / ref_ms:5.2f}")


if __name__ == "__main__":
    main()
