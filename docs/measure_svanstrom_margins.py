"""How generously the Svanström benchmark's annotators drew their boxes, on the CALIBRATION half only
(odd clip numbers): per band and class, the label box against the extent of the target inside it
(pixels deviating from the median of a 4-px ring by more than max(4 x the ring's robust noise + 1,
a quarter of the box's peak deviation)), and the box's brightest grey level. The margin per side,
(box - extent) / 2, sets ``label_margin_px`` of examples/sim2real/realism_*.yaml.

    python docs/measure_svanstrom_margins.py --real <mirror.git or folder> --out margins.json [--per-class 10]
"""
from __future__ import annotations

import argparse
import json

import numpy as np

RING_PX = 4


def box_vs_extent(grey: np.ndarray, box: tuple[float, float, float, float]) -> list[float] | None:
    """[box w, box h, extent w, extent h, peak deviation, box max] of one labelled target, or None."""
    h, w = grey.shape
    x, y, bw, bh = box
    x0, y0, x1, y1 = max(0, round(x)), max(0, round(y)), min(w, round(x + bw)), min(h, round(y + bh))
    if x1 - x0 < 2 or y1 - y0 < 2:
        return None
    ox0, oy0, ox1, oy1 = max(0, x0 - RING_PX), max(0, y0 - RING_PX), min(w, x1 + RING_PX), min(h, y1 + RING_PX)
    window = grey[oy0:oy1, ox0:ox1]
    inner = np.zeros(window.shape, bool)
    inner[y0 - oy0:y1 - oy0, x0 - ox0:x1 - ox0] = True
    ring = window[~inner]
    med = float(np.median(ring))
    noise = 1.4826 * float(np.median(np.abs(ring - med))) + 1.0
    dev = np.abs(grey[y0:y1, x0:x1] - med)
    peak = float(dev.max())
    mask = dev > max(4 * noise, 0.25 * peak)
    if not mask.any():
        return None
    rows, cols = np.flatnonzero(mask.any(1)), np.flatnonzero(mask.any(0))
    return [x1 - x0, y1 - y0, cols[-1] - cols[0] + 1, rows[-1] - rows[0] + 1, peak, float(grey[y0:y1, x0:x1].max())]


def measure(bench, per_class: int, step: int = 25, per_clip: int = 12) -> dict:
    out = {}
    for sensor in ("ir", "visible"):
        clips = bench.clips(sensor, half="calibration")
        for cls in sorted({c.cls for c in clips}):
            rows, used = [], 0
            for clip in [c for c in clips if c.cls == cls]:
                if used >= per_class:
                    break
                try:
                    n = bench.video_frame_count(clip)
                    boxes = bench.aligned_labels(clip, n)
                except Exception:   # a clip the reader refuses is skipped, as evids sim2real does
                    continue
                wanted = [i for i in range(0, n, step) if boxes[i] is not None][:per_clip]
                if not wanted:
                    continue
                used += 1
                for i, frame in bench.frames(clip, wanted):
                    g = frame.astype(np.float64)
                    if g.ndim == 3:
                        g = g @ np.array([0.299, 0.587, 0.114])
                    row = box_vs_extent(g, boxes[i])
                    if row is not None:
                        rows.append(row)
            if not rows:
                continue
            a = np.asarray(rows, np.float64)

            def q(v: np.ndarray) -> list[float]:
                return [round(float(t), 2) for t in np.percentile(v, [25, 50, 75])]

            out[f"{sensor}/{cls}"] = {"targets": len(a), "clips": used, "box_w": q(a[:, 0]), "box_h": q(a[:, 1]),
                                      "extent_w": q(a[:, 2]), "extent_h": q(a[:, 3]),
                                      "margin_x_px": q((a[:, 0] - a[:, 2]) / 2),
                                      "margin_y_px": q((a[:, 1] - a[:, 3]) / 2),
                                      "peak": q(a[:, 4]), "box_max": q(a[:, 5])}
            print(sensor, cls, json.dumps(out[f"{sensor}/{cls}"]), flush=True)
    return out


def main() -> None:
    from simulator.formats.svanstrom import open_benchmark

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--real", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--per-class", type=int, default=10)
    args = ap.parse_args()
    result = measure(open_benchmark(args.real), args.per_class)
    with open(args.out, "w") as fh:
        json.dump(result, fh, indent=1)


if __name__ == "__main__":
    main()
