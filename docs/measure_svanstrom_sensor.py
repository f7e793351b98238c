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
import io
import json
import os
import re
import subprocess
import tempfile
from pathlib import Path

import numpy as np

RING_PX = 4
CROP_PX = 32


def _blob(git_dir: str, path: str) -> bytes:
    return subprocess.run(["git", "--git-dir", git_dir, "cat-file", "blob", f"HEAD:{path}"], check=True,
                          capture_output=True).stdout


def calibration_clips(git_dir: str, band: str) -> dict[str, list[str]]:
    names = subprocess.run(["git", "--git-dir", git_dir, "ls-tree", "-r", "--name-only", "HEAD"], check=True,
                           capture_output=True, text=True).stdout.split()
    folder = "Video_IR" if band == "IR" else "Video_V"
    out: dict[str, list[str]] = {}
    for n in names:
        m = re.fullmatch(rf"Data/{folder}/{band}_([A-Z]+)_(\d+)\.mp4", n)
        if m and int(m.group(2)) % 2 == 1:                       # the calibration half only
            out.setdefault(m.group(1), []).append(n)
    return out


def frames_of(data: bytes) -> np.ndarray:
    import av

    with av.open(io.BytesIO(data)) as c:
        return np.stack([f.to_ndarray(format="gray") for f in c.decode(video=0)])


def labels_of(git_dir: str, mp4: str) -> list:
    from mcos_decoder import load_groundtruth

    with tempfile.NamedTemporaryFile(suffix=".mat") as f:
        f.write(_blob(git_dir, mp4.replace(".mp4", "_LABELS.mat")))
        f.flush()
        return load_groundtruth(f.name)


def target_stats(frame: np.ndarray, box) -> tuple[float, float | None, np.ndarray]:
    """(contrast, second-moment radius for small boxes, crop) of one labelled target."""
    h, w = frame.shape
    x, y, bw, bh = box
    x0, y0 = int(round(x - 1)), int(round(y - 1))               # MATLAB boxes are 1-based
    x1, y1 = x0 + max(1, int(round(bw))), y0 + max(1, int(round(bh)))
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
    n, h, w = frames.shape
    stack = frames[:10, : h // 5].astype(np.float64)
    keep = np.ones(w, bool)
    for b in boxes[:10]:
        if b is not None:
            keep[max(0, int(b[0]) - 8):int(b[0] + b[2]) + 8] = False
    return float(np.median(stack.std(axis=0)[:, keep])) if keep.any() else float("nan")


def measure(git_dir: str, band: str, per_class: int, step: int = 10) -> tuple[dict, dict]:
    summary, crops = {}, {}
    for cls, clips in sorted(calibration_clips(git_dir, band).items()):
        con, rad, bg, noise, cr = [], [], [], [], []
        used = 0
        for mp4 in clips:
            if used == per_class:
                break
            try:
                frames = frames_of(_blob(git_dir, mp4))
            except subprocess.CalledProcessError:           # a blob absent from this mirror
                continue
            used += 1
            if frames.ndim == 4:
                frames = frames[..., 0]
            boxes = labels_of(git_dir, mp4)
            bg.append(float(np.median(frames[::step])))
            noise.append(sky_noise(frames, boxes))
            for i in range(0, min(len(frames), len(boxes)), step):
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
    result = {}
    for band in ("IR", "V"):
        result[band], crops = measure(args.real, band, args.per_class)
        contact_sheet(crops, args.out / f"real_{band}_crops.png")
    (args.out / "real_stats.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
