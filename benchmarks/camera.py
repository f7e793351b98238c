"""Camera-model benchmark: cost per paired frame (RGB 640x512 + thermal 640x512) of
simulator.sensors.camera, and the optics stage against a direct spatial convolution.

Inputs are synthetic (a sky gradient with a moving 12-px target) so the figure isolates the camera
model; benchmarks/render.py reports it inside the full render loop too.

    .venv/bin/python benchmarks/camera.py [--frames 30]
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from scenes import load_scenario
from simulator.physics import thermal
from simulator.physics.timeline import build_timeline
from simulator.sensors.camera import CameraModel


def _inputs(h: int, w: int, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    yy, xx = np.mgrid[0:h, 0:w]
    kelvin = (250.0 + 20.0 * yy / h).astype(np.float32)
    cx = 100 + 3 * frame
    target = (np.abs(xx - cx) < 6) & (np.abs(yy - h // 2) < 4)
    kelvin[target] = 300.0
    rgb = np.repeat((0.3 + 0.2 * yy / h)[..., None], 3, axis=-1).astype(np.float32)
    rgb[target] = 0.05
    return rgb, thermal.band_radiance(kelvin).astype(np.float32), kelvin


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=30)
    args = parser.parse_args()
    scenario = load_scenario("clear_day_quad")
    scenario = scenario.model_copy(update={"duration_s": (args.frames + 2) / scenario.frame_rate_hz})
    timeline = build_timeline(scenario, 0)
    h, w = scenario.camera_rig.thermal.height_px, scenario.camera_rig.thermal.width_px
    t0 = time.perf_counter()
    model = CameraModel(timeline, render_exposure=30.0)
    setup_s = time.perf_counter() - t0
    frames = [_inputs(h, w, i) for i in range(args.frames + 1)]
    model.record(0, *frames[0])
    start, cpu_start = time.perf_counter(), time.process_time()
    for i in range(1, args.frames + 1):
        model.record(i, *frames[i])
    per_frame_s = (time.perf_counter() - start) / args.frames
    cpu_per_frame_s = (time.process_time() - cpu_start) / args.frames
    # reference in the same run: the optics stage as a direct spatial convolution (scipy.ndimage)
    from scipy.ndimage import convolve

    kernel = model.thermal.kernel
    radiance = frames[1][1].astype(np.float64)
    t0 = time.perf_counter()
    for _ in range(3):
        convolve(radiance, kernel, mode="reflect")
    direct_s = (time.perf_counter() - t0) / 3
    t0 = time.perf_counter()
    for _ in range(3):
        model.thermal.optics(radiance)
    fft_s = (time.perf_counter() - t0) / 3
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print(f"setup (PSF kernels, image motion, fixed pattern): {setup_s:.3f} s")
    print(f"thermal optics {kernel.shape[0]}x{kernel.shape[0]} kernel: KernelFilter (scipy FFT) {1000 * fft_s:.1f} ms "
          "vs direct "
          f"{1000 * direct_s:.1f} ms ({direct_s / fft_s:.1f}x)")
    print(f"camera model CPU time: {1000 * cpu_per_frame_s:.1f} ms per paired frame (single-threaded; ~ the idle wall "
          "time)")
    print(f"camera model: {1000 * per_frame_s:.1f} ms per paired frame ({1 / per_frame_s:.1f} paired frames/s alone)")


if __name__ == "__main__":
    main()
