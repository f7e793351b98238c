"""PNG encode cost of the native layout's frame files: the settings in
``simulator.formats.native.png_params`` (zlib level 1, run-length strategy, a fixed row filter per
image kind) against the reference in the same run on the same frames: level 1 with OpenCV's default
strategy and libpng's adaptive per-row filter choice (the native writer before issue 27).

The frames are rendered first (``render_sequence`` of each preset into a temporary folder, camera
model on, as ``evids render`` writes them), then every file kind (rgb, thermal counts, thermal AGC,
both masks) is encoded alternately by both settings, best of ``--repeats`` per frame; each encoding
is decoded and compared with the pixels (lossless, or the script fails).

    PYTHONPATH=. .venv/bin/python benchmarks/png_encode.py [--scenes clear_day_quad bird_confuser] [--frames 16]
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from scenes import load_scenario
from simulator.dataset.sequence import render_sequence
from simulator.formats.native import FRAME_FOLDERS, png_params


def reference_params(image: np.ndarray) -> list[int]:
    """The native writer before issue 27: level 1, OpenCV's default strategy, libpng's filter choice."""
    return [cv2.IMWRITE_PNG_COMPRESSION, 1]


def _encode_ms(image: np.ndarray, params: list[int], repeats: int) -> tuple[float, int]:
    best, size = float("inf"), 0
    for _ in range(repeats):
        t0 = time.perf_counter()
        ok, buf = cv2.imencode(".png", image, params)
        best = min(best, time.perf_counter() - t0)
        if not ok:
            raise RuntimeError("cv2.imencode failed")
        size = len(buf)
        decoded = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
        if decoded.dtype != image.dtype or not np.array_equal(decoded, image):
            raise RuntimeError("PNG round trip is not lossless")
    return 1e3 * best, size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenes", nargs="+", default=["clear_day_quad", "bird_confuser"])
    parser.add_argument("--frames", type=int, default=16, help="frames rendered per scene")
    parser.add_argument("--repeats", type=int, default=3, help="encodings per frame and setting (best counts)")
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; OpenCV {cv2.__version__}")
    totals = {"reference": [0.0, 0], "ours": [0.0, 0]}
    n_frames = 0
    for name in args.scenes:
        with tempfile.TemporaryDirectory() as tmp:
            folder = render_sequence(load_scenario(name), 0, Path(tmp), n_frames=args.frames, progress=False)["native"]
            print(f"\n{name}: {args.frames} frames   {'ref ms':>8s} {'ours ms':>8s} {'ratio':>6s} "
                  f"{'ref kB':>8s} {'ours kB':>8s}")
            for kind in FRAME_FOLDERS:
                images = [cv2.imread(str(p), cv2.IMREAD_UNCHANGED) for p in sorted((folder / kind).glob("*.png"))]
                row = {"reference": [0.0, 0], "ours": [0.0, 0]}
                for image in images:
                    for label, params in (("reference", reference_params(image)), ("ours", png_params(image))):
                        ms, size = _encode_ms(image, params, args.repeats)
                        row[label][0] += ms
                        row[label][1] += size
                for label in row:
                    totals[label][0] += row[label][0]
                    totals[label][1] += row[label][1]
                (ra, rs), (oa, os_) = row["reference"], row["ours"]
                k = len(images)
                print(f"  {kind:28s} {ra / k:8.2f} {oa / k:8.2f} {ra / oa:6.2f} "
                      f"{rs / k / 1e3:8.1f} {os_ / k / 1e3:8.1f}")
            n_frames += args.frames
    (ra, rs), (oa, os_) = totals["reference"], totals["ours"]
    print(f"\nall five files of a paired frame, mean over {n_frames} frames: reference {ra / n_frames:.1f} ms "
          f"{rs / n_frames / 1e3:.0f} kB, ours {oa / n_frames:.1f} ms {os_ / n_frames / 1e3:.0f} kB")
    print(f"PNG encode speed-up (reference/ours): {ra / oa:.2f}; size ratio (ours/reference): {os_ / rs:.3f}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
