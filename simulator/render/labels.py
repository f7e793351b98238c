"""Per-frame, per-camera, per-object labels computed from the id masks (never from projections)."""
from __future__ import annotations

import numpy as np

from simulator.physics.timeline import Timeline

CLASS_OF_KIND = {"quadcopter": "drone", "hexacopter": "drone", "fixed_wing": "drone", "bird": "bird", "airliner": "aircraft"}
BACKGROUND_RING_PX = 4


def tight_box(mask: np.ndarray) -> list[int] | None:
    """[x, y, w, h] of the tight box of a boolean mask (pixels, top-left + size), None if empty."""
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(mask.any(axis=0))
    return [int(cols[0]), int(rows[0]), int(cols[-1] - cols[0] + 1), int(rows[-1] - rows[0] + 1)]


def local_contrast_k(kelvin: np.ndarray, id_mask: np.ndarray, target_id: int, box: list[int]) -> float:
    """Mean apparent temperature over the target's pixels minus the mean over a ring of
    background pixels (no object) around its box."""
    x, y, w, h = box
    pad = max(BACKGROUND_RING_PX, int(0.5 * max(w, h)))
    y0, y1 = max(0, y - pad), min(kelvin.shape[0], y + h + pad)
    x0, x1 = max(0, x - pad), min(kelvin.shape[1], x + w + pad)
    window_ids = id_mask[y0:y1, x0:x1]
    window_k = kelvin[y0:y1, x0:x1]
    inside = np.zeros_like(window_ids, dtype=bool)
    inside[y - y0:y - y0 + h, x - x0:x - x0 + w] = True
    background = (window_ids == 0) & ~inside
    target = window_ids == target_id
    if not background.any():
        background = window_ids == 0
    if not background.any():
        return float("nan")
    return float(window_k[target].mean() - window_k[background].mean())


def frame_labels(timeline: Timeline, frame: int, camera: str, id_mask: np.ndarray,
                 kelvin: np.ndarray | None = None, netd_k: float | None = None) -> list[dict]:
    """One record per target for this camera and frame."""
    cam = timeline.cameras[camera]
    records = []
    height, width = id_mask.shape
    for track in timeline.targets:
        mask = id_mask == track.target_id
        box = tight_box(mask)
        range_m = float(np.linalg.norm(track.position_m[frame] - cam.origin_m[frame]))
        record = {
            "id": track.target_id,
            "name": track.name,
            "class": CLASS_OF_KIND[track.kind],
            "exist": int(box is not None),
            "box": box if box is not None else [],
            "visible_px": int(mask.sum()),
            "range_m": round(range_m, 4),
            "truncated": bool(box is not None and (box[0] == 0 or box[1] == 0 or box[0] + box[2] == width
                                                    or box[1] + box[3] == height)),
        }
        if kelvin is not None:
            contrast = local_contrast_k(kelvin, id_mask, track.target_id, box) if box is not None else None
            record["contrast_k"] = None if contrast is None or np.isnan(contrast) else round(contrast, 5)
            record["crossover"] = bool(record["contrast_k"] is not None and abs(record["contrast_k"]) < netd_k)
        records.append(record)
    return records
