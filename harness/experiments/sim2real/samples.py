"""Per-frame samples of real clips and of generated sequences, made by the same functions: a target
crop, a background patch and the image statistics of docs/SIM2REAL.md.

A frame is an 8-bit grey (IR) or RGB (visible) image as the camera recorded it, with the target's
box ``(x, y, w, h)`` in pixels (or None when the target is absent). For generated sequences the IR
frame is the thermal camera's recorded 8-bit view (``thermal_agc/``: the camera model's gain stage
and, when switched on, its H.264 recording chain) and the visible frame the RGB camera's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

Box = tuple[float, float, float, float]

STAT_NAMES = ("box_w_px", "box_h_px", "contrast", "peak", "background", "row_gradient", "spatial_noise",
              "temporal_noise")
CLIP_STAT_NAMES = ("absent_fraction",)


@dataclass
class FrameSample:
    """One sampled frame of one clip: crop and background patch (uint8, crop_px square; grey 2-D or RGB),
    the per-frame statistics, and where it came from."""

    domain: str                # "real" | "synthetic"
    sensor: str                # "ir" | "visible"
    cls: str                   # benchmark class: DRONE, BIRD, AIRPLANE, HELICOPTER
    clip: str                  # clip or sequence id (the unit of splitting and bootstrapping)
    half: str                  # "calibration" | "evaluation" (real) | "synthetic"
    frame: int
    crop: np.ndarray
    background: np.ndarray | None
    stats: dict[str, float] = field(default_factory=dict)


@dataclass
class ClipSummary:
    domain: str
    sensor: str
    cls: str
    clip: str
    half: str
    n_frames: int
    absent_fraction: float
    thumbnail: np.ndarray | None = None     # one whole frame, for the contact sheets
    frames: list[tuple[int, np.ndarray, Box | None]] = field(default_factory=list)  # kept whole frames (detector)


def grey(image: np.ndarray) -> np.ndarray:
    """float32 grey levels 0-255 (ITU-R BT.601 luma for RGB, as the H.264 Y plane)."""
    if image.ndim == 2:
        return image.astype(np.float32)
    return image.astype(np.float32) @ np.array([0.299, 0.587, 0.114], np.float32)


def _clip_box(box: Box, w: int, h: int) -> tuple[int, int, int, int] | None:
    x0, y0 = max(0, int(math.floor(box[0]))), max(0, int(math.floor(box[1])))
    x1, y1 = min(w, int(math.ceil(box[0] + box[2]))), min(h, int(math.ceil(box[1] + box[3])))
    return (x0, y0, x1, y1) if x1 > x0 and y1 > y0 else None


def ring_mask(shape: tuple[int, int], box: Box, width_px: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(box mask, ring mask): the ring is the box grown by ``width_px`` (default: half its larger side,
    at least 3 px) on every side, minus the box."""
    h, w = shape
    inner = _clip_box(box, w, h)
    box_m, ring_m = np.zeros(shape, bool), np.zeros(shape, bool)
    if inner is None:
        return box_m, ring_m
    g = width_px if width_px is not None else max(3.0, 0.5 * max(box[2], box[3]))
    outer = _clip_box((box[0] - g, box[1] - g, box[2] + 2 * g, box[3] + 2 * g), w, h)
    x0, y0, x1, y1 = outer  # type: ignore[misc]
    ring_m[y0:y1, x0:x1] = True
    bx0, by0, bx1, by1 = inner
    box_m[by0:by1, bx0:bx1] = True
    ring_m &= ~box_m
    return box_m, ring_m


def frame_statistics(image: np.ndarray, box: Box | None, previous: np.ndarray | None = None) -> dict[str, float]:
    """Image statistics of one frame in 8-bit grey levels (see docs/SIM2REAL.md for each definition).

    contrast: |mean(box) - mean(ring)|; peak: max |box - median(ring)|; background: median of the frame;
    row_gradient: median of the bottom quarter of rows minus median of the top quarter; spatial_noise:
    robust std (1.4826 MAD) of the frame minus its 3x3 median, outside the ring; temporal_noise: robust
    std of the difference to the previous frame outside the ring, / sqrt(2)."""
    g = grey(image)
    h, w = g.shape
    out: dict[str, float] = {"background": float(np.median(g))}
    q = max(1, h // 4)
    out["row_gradient"] = float(np.median(g[-q:]) - np.median(g[:q]))
    if box is not None:
        box_m, ring_m = ring_mask((h, w), box)
        away = ~(box_m | ring_m)
        if box_m.any() and ring_m.any():
            ring_vals = g[ring_m]
            out["box_w_px"], out["box_h_px"] = float(box[2]), float(box[3])
            out["contrast"] = float(abs(g[box_m].mean() - ring_vals.mean()))
            out["peak"] = float(np.abs(g[box_m] - np.median(ring_vals)).max())
    else:
        away = np.ones((h, w), bool)
    residual = g - cv2.medianBlur(np.ascontiguousarray(grey(image).round().clip(0, 255).astype(np.uint8)), 3)
    out["spatial_noise"] = _robust_std(residual[away])
    if previous is not None and previous.shape == image.shape:
        out["temporal_noise"] = _robust_std((g - grey(previous))[away]) / math.sqrt(2.0)
    return out


def _robust_std(values: np.ndarray) -> float:
    if values.size == 0:
        return float("nan")
    med = np.median(values)
    return float(1.4826 * np.median(np.abs(values - med)))


def crop_around(image: np.ndarray, centre_xy: tuple[float, float], side_px: float, out_px: int) -> np.ndarray:
    """Square crop of ``side_px`` centred on ``centre_xy`` (edges replicated), resized to ``out_px``."""
    side = max(2, int(round(side_px)))
    x0 = int(round(centre_xy[0] - side / 2))
    y0 = int(round(centre_xy[1] - side / 2))
    h, w = image.shape[:2]
    pad = max(0, -x0, -y0, x0 + side - w, y0 + side - h)
    if pad:
        image = cv2.copyMakeBorder(image, pad, pad, pad, pad, cv2.BORDER_REPLICATE)
        x0, y0 = x0 + pad, y0 + pad
    crop = image[y0:y0 + side, x0:x0 + side]
    interp = cv2.INTER_AREA if side > out_px else cv2.INTER_LINEAR
    return cv2.resize(np.ascontiguousarray(crop), (out_px, out_px), interpolation=interp)


def target_crop(image: np.ndarray, box: Box, out_px: int, context: float, min_side_px: int) -> np.ndarray:
    side = max(min_side_px, context * max(box[2], box[3]))
    return crop_around(image, (box[0] + box[2] / 2, box[1] + box[3] / 2), side, out_px)


def background_patch(image: np.ndarray, box: Box | None, side_px: int, out_px: int, rng: np.random.Generator,
                     tries: int = 20) -> np.ndarray | None:
    """A random square of ``side_px`` not overlapping the box grown by its own size."""
    h, w = image.shape[:2]
    side = min(side_px, w, h)
    for _ in range(tries):
        x0, y0 = int(rng.integers(0, w - side + 1)), int(rng.integers(0, h - side + 1))
        if box is not None:
            gx, gy = box[2], box[3]
            if (x0 < box[0] + box[2] + gx and x0 + side > box[0] - gx and y0 < box[1] + box[3] + gy
                    and y0 + side > box[1] - gy):
                continue
        patch = image[y0:y0 + side, x0:x0 + side]
        return cv2.resize(np.ascontiguousarray(patch), (out_px, out_px), interpolation=cv2.INTER_AREA)
    return None


def pick_frames(n_frames: int, k: int) -> list[int]:
    """``k`` frame indices spread evenly over the clip (each with its predecessor for temporal noise)."""
    if n_frames <= 1:
        return [0]
    k = min(k, n_frames - 1)
    return sorted({int(round(v)) for v in np.linspace(1, n_frames - 1, k)})


def samples_from_frames(frames: Iterator[tuple[int, np.ndarray]], boxes: list[Box | None], wanted: list[int], *,
                        domain: str, sensor: str, cls: str, clip: str, half: str, crop_px: int, context: float,
                        min_crop_px: int, rng: np.random.Generator,
                        keep: int = 0) -> tuple[list[FrameSample], ClipSummary]:
    """Samples of the wanted frames (targets present only; background patches always) and the clip
    summary, which keeps ``keep`` of the wanted frames whole (spread evenly; for the detector).
    ``frames`` must yield every wanted index and its predecessor, in order."""
    kept_idx = {wanted[int(round(j))]
                for j in np.linspace(0, len(wanted) - 1, min(keep, len(wanted)))} if keep else set()
    kept: list[tuple[int, np.ndarray, Box | None]] = []
    samples: list[FrameSample] = []
    wanted_set = set(wanted)
    previous: tuple[int, np.ndarray] | None = None
    thumb = None
    bg_side = max(min_crop_px, crop_px)
    for i, image in frames:
        if i in wanted_set:
            box = boxes[i] if i < len(boxes) else None
            prev = previous[1] if previous is not None and previous[0] == i - 1 else None
            stats = frame_statistics(image, box, prev)
            if box is not None and box[2] > 0 and box[3] > 0:
                crop = target_crop(image, box, crop_px, context, min_crop_px)
            else:
                crop = None
            bg = background_patch(image, box, bg_side, crop_px, rng)
            if crop is not None or bg is not None:
                samples.append(FrameSample(domain, sensor, cls, clip, half, i,
                                           crop if crop is not None else np.empty((0,), np.uint8), bg, stats))
            if thumb is None and box is not None:
                thumb = image
            if i in kept_idx:
                kept.append((i, image, box))
        previous = (i, image)
    n = len(boxes)
    absent = sum(b is None for b in boxes) / n if n else float("nan")
    return samples, ClipSummary(domain, sensor, cls, clip, half, n, absent, thumb, kept)


def needed_indices(wanted: list[int]) -> set[int]:
    return set(wanted) | {i - 1 for i in wanted if i > 0}


# ------------------------------------------------------------------------------------------------
# Real clips


def real_clip_samples(bench, clip, *, frames_per_clip: int, crop_px: int, context: float, min_crop_px: int,
                      seed: int, keep: int = 0) -> tuple[list[FrameSample], ClipSummary]:
    """Samples of one real clip (the benchmark's aligned labels; frames decoded once)."""
    from simulator.seeding import rng_for

    n = bench.video_frame_count(clip)
    boxes = bench.aligned_labels(clip, n)
    present = [i for i in range(1, n) if boxes[i] is not None]
    wanted = pick_frames(n, frames_per_clip) if not present else \
        [present[int(round(j))] for j in np.linspace(0, len(present) - 1, min(frames_per_clip, len(present)))]
    rng = rng_for(seed, "sim2real", *_sample_key("real", clip.sensor, clip.cls, clip.number))
    frames = bench.frames(clip, indices=needed_indices(wanted))
    return samples_from_frames(frames, boxes, sorted(set(wanted)), domain="real", sensor=clip.sensor, cls=clip.cls,
                               clip=clip.name, half=clip.half, crop_px=crop_px, context=context,
                               min_crop_px=min_crop_px, rng=rng, keep=keep)


def _sample_key(domain: str, sensor: str, cls: str, number: int) -> tuple[int, int, int, int]:
    """Sub-stream of the "sim2real" stream for one clip's background-patch draws."""
    classes = ("AIRPLANE", "BIRD", "DRONE", "HELICOPTER")
    return (("real", "synthetic").index(domain), ("ir", "visible").index(sensor),
            classes.index(cls) if cls in classes else len(classes), number)


# ------------------------------------------------------------------------------------------------
# Generated native sequences


def synthetic_frames(sequence_dir: Path, sensor: str, indices: set[int]) -> Iterator[tuple[int, np.ndarray]]:
    """8-bit frames of a native sequence as its camera recorded them: the thermal camera's 8-bit view
    (``thermal_agc/``: its gain stage and recording chain) and the RGB camera's frame."""
    from simulator.formats.native import frame_name, load_rgb, read_image

    for i in sorted(indices):
        if sensor == "ir":
            yield i, read_image(sequence_dir / "thermal_agc" / frame_name(i, "png"))
        else:
            yield i, load_rgb(sequence_dir, i)


def synthetic_boxes(sequence_dir: Path, sensor: str) -> list[Box | None]:
    """Per-frame box of the sequence's primary target (its first object) on the sensor's camera."""
    from simulator.formats.native import load_labels

    labels = load_labels(sequence_dir)
    camera = "thermal" if sensor == "ir" else "rgb"
    target_id = labels["objects"][0]["id"]
    out: list[Box | None] = []
    for frame in labels["frames"]:
        rec = next((r for r in frame[camera] if r["id"] == target_id), None)
        if rec and rec["exist"]:
            x0, y0, x1, y1 = (float(v) for v in rec["box"])
            out.append((x0, y0, x1, y1))
        else:
            out.append(None)
    return out


def synthetic_sequence_samples(sequence_dir: Path, *, sensor: str, cls: str, frames_per_clip: int, crop_px: int,
                               context: float, min_crop_px: int, seed: int, index: int, keep: int = 0
                               ) -> tuple[list[FrameSample], ClipSummary]:
    from simulator.seeding import rng_for

    boxes = synthetic_boxes(sequence_dir, sensor)
    wanted = pick_frames(len(boxes), frames_per_clip)
    rng = rng_for(seed, "sim2real", *_sample_key("synthetic", sensor, cls, index))
    frames = synthetic_frames(sequence_dir, sensor, needed_indices(wanted))
    return samples_from_frames(frames, boxes, wanted, domain="synthetic", sensor=sensor, cls=cls,
                               clip=f"{cls}/{sequence_dir.name}", half="synthetic", crop_px=crop_px,
                               context=context, min_crop_px=min_crop_px, rng=rng, keep=keep)
