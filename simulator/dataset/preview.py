"""Contact sheet: RGB and thermal (AGC) side by side for a few frames, boxes drawn, with a zoomed
inset of each box so a 10-pixel drone can actually be seen."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from simulator.formats.native import (
    load_labels,
    load_meta,
    load_rgb,
    load_thermal_kelvin,
    write_png,
)
from simulator.sensors.encode import agc_8bit

CLASS_COLOURS = {"drone": (0, 255, 0), "bird": (255, 200, 0), "aircraft": (0, 200, 255)}
INSET_PX = 120


def _tile(image: np.ndarray, records: list[dict], caption: str, width: int) -> np.ndarray:
    rgb = image if image.ndim == 3 else np.repeat(image[..., None], 3, axis=-1)
    rgb = np.ascontiguousarray(rgb.copy())
    scale = width / rgb.shape[1]
    shown = cv2.resize(rgb, (width, int(round(rgb.shape[0] * scale))), interpolation=cv2.INTER_AREA)
    insets = []
    for rec in records:
        if not rec["exist"]:
            continue
        x, y, w, h = rec["box"]
        colour = CLASS_COLOURS.get(rec["class"], (255, 0, 255))
        pad = max(6, int(1.5 * max(w, h)))
        cx, cy = x + w / 2, y + h / 2
        x0, y0 = int(max(0, cx - pad)), int(max(0, cy - pad))
        x1, y1 = int(min(rgb.shape[1], cx + pad)), int(min(rgb.shape[0], cy + pad))
        crop = cv2.resize(rgb[y0:y1, x0:x1], (INSET_PX, INSET_PX), interpolation=cv2.INTER_NEAREST)
        cv2.rectangle(crop, (0, 0), (INSET_PX - 1, INSET_PX - 1), colour, 2)
        insets.append(crop)
        p0 = (int(x * scale) - 2, int(y * scale) - 2)
        p1 = (int((x + w) * scale) + 2, int((y + h) * scale) + 2)
        cv2.rectangle(shown, p0, p1, colour, 1)
    for k, crop in enumerate(insets[:3]):
        ys = shown.shape[0] - INSET_PX - 4
        xs = shown.shape[1] - (k + 1) * (INSET_PX + 4)
        if ys >= 0 and xs >= 0:
            shown[ys:ys + INSET_PX, xs:xs + INSET_PX] = crop
    strip = np.full((22, shown.shape[1], 3), 30, np.uint8)
    cv2.putText(strip, caption, (6, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (255, 255, 255), 1, cv2.LINE_AA)
    return np.vstack([strip, shown])


def contact_sheet(sequence_dir: Path, out_path: Path, n_rows: int = 4, tile_width: int = 480) -> Path:
    """Write a PNG with n_rows evenly spaced frames: RGB | thermal, boxes and insets, contrast in K."""
    sequence_dir = Path(sequence_dir)
    meta, labels = load_meta(sequence_dir), load_labels(sequence_dir)
    n = meta["n_frames"]
    picks = np.unique(np.linspace(0, n - 1, min(n_rows, n)).round().astype(int))
    rows = []
    for i in picks:
        frame = labels["frames"][i]
        t = frame["time_s"]
        rgb_tile = _tile(load_rgb(sequence_dir, i), frame["rgb"], f"RGB  t={t:.2f}s  frame {i + 1}", tile_width)
        kelvin = load_thermal_kelvin(sequence_dir, i)
        agc, (lo, hi) = agc_8bit(kelvin)
        contrasts = ", ".join(f"{r['name']} dT={r['contrast_k']:+.2f}K{' X' if r['crossover'] else ''}"
                              for r in frame["thermal"] if r["exist"] and r.get("contrast_k") is not None)
        th_tile = _tile(agc, frame["thermal"], f"LWIR {lo:.1f}-{hi:.1f}K  {contrasts}", tile_width)
        height = max(rgb_tile.shape[0], th_tile.shape[0])
        row = np.zeros((height, rgb_tile.shape[1] + th_tile.shape[1] + 4, 3), np.uint8)
        row[:rgb_tile.shape[0], :rgb_tile.shape[1]] = rgb_tile
        row[:th_tile.shape[0], rgb_tile.shape[1] + 4:] = th_tile
        rows.append(row)
    title = np.full((28, rows[0].shape[1], 3), 30, np.uint8)
    cv2.putText(title, f"{meta['scenario_name']}  seed {meta['seed']}  ({n} frames @ {meta['frame_rate_hz']} Hz)",
                (8, 19), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
    sheet = np.vstack([title] + [np.vstack([r, np.zeros((4, r.shape[1], 3), np.uint8)]) for r in rows])
    write_png(Path(out_path), sheet)
    return Path(out_path)
