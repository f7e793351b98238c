"""Sensor statistics of the Svanström benchmark's CALIBRATION half (odd clip numbers only), or of
any folder of mp4 + _LABELS.mat clips: per class median target contrast (box mean minus the median
of a 4-px ring around it, 8-bit grey levels), frame median (background level), temporal noise of
sky patches (per-pixel std over 10 consecutive frames in the top fifth, target excluded; median),
and the second-moment radius of small targets (box <= 8 px). Writes a JSON summary and PNG
contact sheets of target crops.

    python docs/measure_svanstrom_sensor.py --real <mirror.git or EVIDS_SVANSTROM> --out <folder> [--per-class 6]
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np

RING_PX = 4
CROP_PX = 32


def _grey(frame: np.ndarray) -> np.ndarray:
    """IR frames are luma already; visible RGB -> Rec. 601 luma (what an 8-bit grey decode gives)."""
    if frame.ndim == 2:
        return frame
    return np.rint(frame.astype(np.float32) @ np.array([0.299, 0.587, 0.114], np.float32)).astype(np.uint8)


def target_stats(frame: np.ndarray, box) -> tuple[float, float | None, np.ndarray]:
    """(contrast, second-moment radius for small boxes, crop) of one labelled target."""
    h, w = frame.shape
    x, y, bw, bh = box
    x0, y0 = round(x - 1), round(y - 1)                         # MATLAB boxes are 1-based
    x1, y1 = x0 + max(1, round(bw)), y0 + max(1, round(bh))
    x0, y0, x1, y1 = max(0, x0), max(0, y0), min(w, x1), min(h, y1)
    f = frame.astype(np.float64)
    inner = f[y0:y1, x0:x1]
    ry0, ry1, rx0, rx1 = max(0, y0 - RING_PX), min(h, y1 + RING_PX), max(0, x0 - RING_PX), min(w, x1 + RING_PX)
    outer = f[ry0:ry1, rx0:rx1].copy()
    outer[y0 - ry0:y1 - ry0, x0 - rx0:x1 - rx0] = np.nan
    ring = float(np.nanmedian(outer)) if np.isfinite(outer).any() else float(np.median(inner))
    contrast = float(inner.mean() - ring)
    radius = None
    if max(bw, bh) <= 8 and inner.size:
        excess = np.abs(f[ry0:ry1, rx0:rx1] - ring)
        total = excess.sum()
        if total > 0:
            yy, xx = np.mgrid[ry0:ry1, rx0:rx1]
            cy, cx = (excess * yy).sum() / total, (excess * xx).sum() / total
            radius = float(np.sqrt((excess * ((yy - cy) ** 2 + (xx - cx) ** 2)).sum() / total / 2))
    cx, cy = int((x0 + x1) / 2), int((y0 + y1) / 2)
    pad = np.pad(frame, CROP_PX, mode="edge")
    crop = pad[cy:cy + 2 * CROP_PX, cx:cx + 2 * CROP_PX]
    return contrast, radius, crop


def sky_noise(frames: np.ndarray, boxes) -> float:
    """Median per-pixel temporal std (10 frames) in the top fifth, the target's columns excluded."""
    _, h, w = frames.shape
    stack = frames[:10, : h // 5].astype(np.float64)
    keep = np.ones(w, bool)
    for b in boxes[:10]:
        if b is not None:
            keep[max(0, int(b[0]) - 8):int(b[0] + b[2]) + 8] = False
    return float(np.median(stack.std(axis=0)[:, keep])) if keep.any() else float("nan")


def measure(bench, sensor: str, per_class: int, step: int = 10) -> tuple[dict, dict]:
    """Statistics of the first ``per_class`` CALIBRATION clips of each class (reader: simulator.formats.svanstrom)."""
    from simulator.formats.validation import FormatError

    summary, crops = {}, {}
    clips = bench.clips(sensor, half="calibration")
    for cls in sorted({c.cls for c in clips}):
        con, rad, bg, noise, cr = [], [], [], [], []
        used = 0
        for clip in [c for c in clips if c.cls == cls]:
            if used == per_class:
                break
            assert clip.number % 2 == 1                             # the calibration half only
            try:
                frames = np.stack([_grey(f) for _, f in bench.frames(clip)])
                boxes = bench.aligned_labels(clip, len(frames))
            except FormatError:                                     # a clip the reader refuses: skipped
                continue
            used += 1
            bg.append(float(np.median(frames[::step])))
            noise.append(sky_noise(frames, boxes))
            for i in range(0, len(frames), step):
                if boxes[i] is None:
                    continue
                c, r, crop = target_stats(frames[i], boxes[i])
                con.append(c)
                if r is not None:
                    rad.append(r)
                if len(cr) < 24 and i % (3 * step) == 0:
                    cr.append(crop)
        summary[cls] = {"clips": used, "targets": len(con),
                        "contrast_median": round(float(np.median(con)), 2) if con else None,
                        "contrast_iqr": [round(float(v), 2) for v in np.percentile(con, [25, 75])] if con else None,
                        "abs_contrast_median": round(float(np.median(np.abs(con))), 2) if con else None,
                        "background_median": round(float(np.median(bg)), 1),
                        "sky_temporal_noise_median": round(float(np.nanmedian(noise)), 3),
                        "small_target_radius_px_median": round(float(np.median(rad)), 2) if rad else None,
                        "small_targets": len(rad)}
        crops[cls] = cr
    return summary, crops


def contact_sheet(crops: dict, path: Path) -> None:
    from PIL import Image

    rows = [np.concatenate(c[:12] + [np.zeros_like(c[0])] * (12 - len(c[:12])), axis=1) for c in crops.values() if c]
    if rows:
        Image.fromarray(np.concatenate(rows, axis=0).astype(np.uint8)).resize(
            (rows[0].shape[1] * 2, len(rows) * rows[0].shape[0] * 2), Image.NEAREST).save(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--real", default=os.environ.get("EVIDS_SVANSTROM"))
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--per-class", type=int, default=6)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    from simulator.formats.svanstrom import SvanstromBenchmark

    bench = SvanstromBenchmark(args.real)
    result = {}
    for band, sensor in (("IR", "ir"), ("V", "visible")):
        result[band], crops = measure(bench, sensor, args.per_class)
        contact_sheet(crops, args.out / f"real_{band}_crops.png")
    (args.out / "real_stats.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
