"""Per-frame, per-camera, per-object labels.

``coverage_labels`` (what the renderer writes) takes each target's exact coverage from the
renderer's coverage rays (a regular 8 x 8 grid per pixel against the true geometry, occlusion
included): the box is the tight box of every pixel the silhouette touches, ``visible_px`` the
covered area in pixels (sub-pixel targets keep their fraction), and the thermal contrast comes
from the target's own at-sensor radiance against the sky behind it, not from partially covered
pixels. ``frame_labels``/``tight_box``/``local_contrast_k`` work on id masks (files on disk,
degraded data).
"""
from __future__ import annotations

import numpy as np

from simulator.physics import thermal
from simulator.physics.timeline import Timeline

CLASS_OF_KIND = {"quadcopter": "drone", "hexacopter": "drone", "fixed_wing": "drone", "bird": "bird",
                 "airliner": "aircraft",
                 "helicopter": "helicopter"}
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


def _record(track, cam, frame: int, box: list[int] | None, visible_px: float, width: int, height: int) -> dict:
    """The camera-independent fields of one target's label record (both label builders share them)."""
    range_m = float(np.linalg.norm(track.position_m[frame] - cam.origin_m[frame]))
    return {
        "id": track.target_id,
        "name": track.name,
        "class": CLASS_OF_KIND[track.kind],
        "exist": int(box is not None),
        "box": box if box is not None else [],
        "visible_px": visible_px,
        "range_m": round(range_m, 4),
        "truncated": bool(box is not None and (box[0] == 0 or box[1] == 0 or box[0] + box[2] == width
                                                or box[1] + box[3] == height)),
    }


def frame_labels(timeline: Timeline, frame: int, camera: str, id_mask: np.ndarray,
                 kelvin: np.ndarray | None = None, netd_k: float | None = None) -> list[dict]:
    """One record per target for this camera and frame."""
    cam = timeline.cameras[camera]
    records = []
    height, width = id_mask.shape
    for track in timeline.targets:
        mask = id_mask == track.target_id
        box = tight_box(mask)
        record = _record(track, cam, frame, box, int(mask.sum()), width, height)
        if kelvin is not None:
            contrast = local_contrast_k(kelvin, id_mask, track.target_id, box) if box is not None else None
            record["contrast_k"] = None if contrast is None or np.isnan(contrast) else round(contrast, 5)
            record["crossover"] = bool(record["contrast_k"] is not None and abs(record["contrast_k"]) < netd_k)
        records.append(record)
    return records


def pad_labels(records: list[dict], margin_px: tuple[int, int], width: int, height: int) -> list[dict]:
    """Records with every box grown by ``margin_px`` = [x, y] pixels on each side and clipped to the
    frame, the way human annotators draw boxes around small targets. The exact box is kept in
    ``box_tight``; ``truncated`` still says whether the target itself touches the frame edge.
    (0, 0) returns the records as they are."""
    mx, my = int(margin_px[0]), int(margin_px[1])
    if mx == 0 and my == 0:
        return records
    out = []
    for rec in records:
        rec = dict(rec)
        box = rec["box"]
        rec["box_tight"] = list(box)
        if box:
            x0, y0 = max(0, box[0] - mx), max(0, box[1] - my)
            x1, y1 = min(width, box[0] + box[2] + mx), min(height, box[1] + box[3] + my)
            rec["box"] = [x0, y0, x1 - x0, y1 - y0]
        out.append(rec)
    return out


def _box_of_coverage(cov) -> list[int] | None:
    """[x, y, w, h] of the pixels with any coverage (full-frame coordinates), None if none."""
    box = tight_box(cov.coverage > 0)
    if box is None:
        return None
    return [box[0] + cov.region[0], box[1] + cov.region[1], box[2], box[3]]


def target_contrast_k(cov) -> float:
    """Brightness temperature of the target's visible surface (its parts' at-sensor radiances
    weighted by their visible area) minus that of the sky behind it (coverage-weighted)."""
    area = sum(cov.role_px.values())
    radiance = sum(cov.role_px[r] * cov.role_radiance[r] for r in cov.role_px) / area
    return float(thermal.brightness_temperature(radiance) - thermal.brightness_temperature(cov.sky_radiance))


def coverage_labels(timeline: Timeline, frame: int, camera: str, coverage: list, width: int, height: int,
                    netd_k: float | None = None) -> list[dict]:
    """One record per target for this camera and frame, from the renderer's coverage.

    ``exist`` = 1 when any coverage ray of the frame hits the target (unchanged meaning: some part
    of it is visible in the image); ``box`` = tight box of the touched pixels (``[]`` when absent);
    ``visible_px`` = covered area in pixels (float, 1/64 px resolution); thermal records add
    ``contrast_k`` (target radiance vs sky behind it) and ``crossover`` (|contrast_k| < NETD).
    """
    cam = timeline.cameras[camera]
    by_id = {c.target_id: c for c in coverage}
    records = []
    for track in timeline.targets:
        cov = by_id.get(track.target_id)
        box = _box_of_coverage(cov) if cov is not None else None
        visible_px = round(cov.visible_px, 4) if cov is not None and box is not None else 0.0
        record = _record(track, cam, frame, box, visible_px, width, height)
        if netd_k is not None:
            contrast = round(target_contrast_k(cov), 5) if box is not None else None
            record["contrast_k"] = contrast
            record["crossover"] = bool(contrast is not None and abs(contrast) < netd_k)
        records.append(record)
    return records
