"""Data for the detection experiment: native datasets (``evids generate``) read through
``simulator.formats.native``, load-time sensor degradations, per-frame ground truth of which stream
observes the target, network inputs and training crops.

Observability ground truth per frame (target = the first drone-class object):
- thermal: the target exists in the thermal frame and ``|contrast_k| >= netd_k`` (not a crossover);
- RGB: the target exists and its mean luma differs from a 4-px ring of sky around its box by more
  than ``max(2/255, 2 * ring std)`` in the (degraded) frame the detector sees.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch

from scenes.errors import UserInputError
from simulator.seeding import STREAMS

DETECTION_STREAM = STREAMS["detection"]  # SeedSequence stream id of this experiment
THERMAL_SCALE_K = 1.0    # thermal input = (T - frame median) / 1 K, clipped to +-8


def seed_for(seed: int, *keys: int) -> int:
    """A 31-bit seed from SeedSequence([seed, DETECTION_STREAM, *keys])."""
    return int(np.random.SeedSequence([int(seed), DETECTION_STREAM, *map(int, keys)]).generate_state(1)[0] & 0x7FFFFFFF)


def rng(seed: int, *keys: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([int(seed), DETECTION_STREAM, *map(int, keys)]))


def scene_tag(source: str) -> str:
    """``det_crossover_b`` -> ``crossover``; any other mixture source stays as it is."""
    s = Path(str(source)).stem
    if s.startswith("det_") and s[-2:] in ("_a", "_b"):
        return s[4:-2]
    return s


@dataclass
class SequenceData:
    name: str
    index: int
    split: str
    set_name: str
    tag: str
    rgb: np.ndarray                 # (T, H, W, 3) float16 in [0, 1], after load-time degradations (halves memory)
    thermal_k: np.ndarray           # (T, H, W) float32 kelvin, after NETD noise
    boxes_rgb: list[np.ndarray]     # per frame (n, 4) drone boxes [x, y, w, h]
    boxes_thermal: list[np.ndarray]
    gt_rgb: list[list[float] | None]      # primary drone per frame (None: absent)
    gt_thermal: list[list[float] | None]
    contrast_k: np.ndarray          # (T,) thermal contrast of the primary drone (NaN when absent)
    netd_k: float
    rgb_observed: np.ndarray        # (T,) bool
    thermal_observed: np.ndarray    # (T,) bool
    registered: bool
    degradations: list[dict[str, Any]] = field(default_factory=list)

    @property
    def n_frames(self) -> int:
        return int(self.rgb.shape[0])

    @property
    def exist(self) -> np.ndarray:
        return np.array([b is not None for b in self.gt_rgb])


def dataset_entries(path: Path, need_splits: tuple[str, ...], field_name: str) -> list[dict[str, Any]]:
    """Manifest entries of a complete native dataset, checked for thermal frames and the splits."""
    from simulator.dataset.generate import dataset_sequences

    path = Path(path)
    if not (path / "manifest.json").is_file():
        raise UserInputError(f"{field_name}: {str(path)!r} is not an evids native dataset (no manifest.json)")
    entries = dataset_sequences(path)
    if not entries:
        raise UserInputError(f"{field_name}: dataset {str(path)!r} holds no sequences")
    for split in need_splits:
        if not any(e["split"] == split for e in entries):
            raise UserInputError(f"{field_name}: dataset {str(path)!r} has no {split!r} split (needed: "
                                 f"{', '.join(need_splits)})")
    first = Path(entries[0]["path"])
    meta = json.loads((first / "meta.json").read_text()) if (first / "meta.json").is_file() else {}
    if "thermal" not in meta.get("cameras", {}) or not (first / "thermal").is_dir():
        raise UserInputError(f"{field_name}: dataset {str(path)!r} has no thermal stream (need paired RGB + thermal)")
    return entries


def _drone_records(frame: dict, camera: str) -> list[dict]:
    return sorted((r for r in frame[camera] if r["class"] == "drone"), key=lambda r: r["id"])


def _registered(scenario: dict) -> bool:
    rig = scenario.get("camera_rig", {})
    off = rig.get("thermal_offset", {}) or {}
    zero = all(abs(float(v)) < 1e-12 for v in off.get("translation_m", (0, 0, 0))) and all(
        abs(float(off.get(k, 0.0))) < 1e-12 for k in ("yaw_deg", "pitch_deg", "roll_deg"))
    same = all(rig.get("rgb", {}).get(k) == rig.get("thermal", {}).get(k)
               for k in ("width_px", "height_px", "hfov_deg"))
    return bool(zero and same)


def rgb_observed(rgb: np.ndarray, box: list[float] | None) -> bool:
    """Luma contrast of the box centre region against a 4-px ring around the box (see module doc)."""
    if box is None:
        return False
    h, w = rgb.shape[:2]
    x, y, bw, bh = box
    luma = rgb[..., 0] * 0.299 + rgb[..., 1] * 0.587 + rgb[..., 2] * 0.114
    x0, y0, x1, y1 = int(np.floor(x)), int(np.floor(y)), int(np.ceil(x + bw)), int(np.ceil(y + bh))
    inner = luma[max(y0, 0):max(y1, 1), max(x0, 0):max(x1, 1)]
    r = 4
    outer = np.zeros((h, w), bool)
    outer[max(y0 - r, 0):min(y1 + r, h), max(x0 - r, 0):min(x1 + r, w)] = True
    outer[max(y0, 0):min(y1, h), max(x0, 0):min(x1, w)] = False
    ring = luma[outer]
    if inner.size == 0 or ring.size < 4:
        return False
    # the target is darker or brighter than the sky in its most contrasting pixels
    dev = np.abs(inner - np.median(ring))
    signal = float(np.quantile(dev, 0.75))
    return signal > max(2.0 / 255.0, 2.0 * float(np.std(ring)))


def _apply_degradations(clip: np.ndarray, items: list, seed: int, meta: dict, log: list, stream: str) -> np.ndarray:
    from degradations.registry import apply

    for k, item in enumerate(items):
        s = seed_for(seed, k, 1 if stream == "rgb" else 2)
        clip, info = apply(item.name, clip, seed=s, severity=item.severity, meta=meta, return_info=True)
        log.append({"stream": stream, "name": item.name, "severity": item.severity, "seed": s,
                    "params": info.get("params", {})})
    return clip


def load_sequence(entry: dict[str, Any], set_name: str, config, exp_seed: int, dataset_index: int) -> SequenceData:
    """Read one native sequence, apply the load-time degradations of its scene tag, label observability."""
    from simulator.formats import native

    seq = Path(entry["path"])
    meta = native.load_meta(seq)
    labels = native.load_labels(seq)
    import yaml

    scenario = yaml.safe_load((seq / "scenario.yaml").read_text())
    n = int(meta["n_frames"])
    rgb = np.stack([native.load_rgb(seq, i) for i in range(n)]).astype(np.float32) / np.float32(255.0)
    thermal = np.stack([native.load_thermal_kelvin(seq, i) for i in range(n)]).astype(np.float32)
    netd = float(meta["cameras"]["thermal"].get("netd_k", 0.05))
    tag = scene_tag(entry.get("source", ""))
    log: list[dict[str, Any]] = []
    base_seed = seed_for(exp_seed, dataset_index, int(entry["index"]))
    ranges = []
    boxes_rgb, boxes_th, gt_rgb, gt_th, contrast = [], [], [], [], []
    for frame in labels["frames"]:
        r, t = _drone_records(frame, "rgb"), _drone_records(frame, "thermal")
        boxes_rgb.append(np.array([x["box"] for x in r if x["exist"]], np.float64).reshape(-1, 4))
        boxes_th.append(np.array([x["box"] for x in t if x["exist"]], np.float64).reshape(-1, 4))
        gt_rgb.append(list(map(float, r[0]["box"])) if r and r[0]["exist"] else None)
        gt_th.append(list(map(float, t[0]["box"])) if t and t[0]["exist"] else None)
        contrast.append(float(t[0]["contrast_k"]) if t and t[0]["exist"] and t[0].get("contrast_k") is not None
                        else np.nan)
        ranges.append(float(r[0]["range_m"]) if r and r[0].get("range_m") is not None else 300.0)
    degs = config.data.degradations.get(tag)
    if degs is not None and degs.rgb:
        rgb = np.clip(_apply_degradations(rgb, degs.rgb, base_seed, {"range_m": np.array(ranges)}, log, "rgb"), 0,
                      1).astype(np.float32)
    # datasets rendered with the camera model (meta "sensor": {"sensor": "camera", ...}) already carry
    # NETD noise; only ideal or older renders get it here
    camera_noise = isinstance(meta.get("sensor"), dict) and meta["sensor"].get("sensor") == "camera"
    if config.data.thermal_netd_noise and not camera_noise:
        from degradations.registry import apply

        s = seed_for(base_seed, 99)
        thermal = apply("thermal.netd_noise", thermal, seed=s, netd_k=netd).astype(np.float32)
        log.append({"stream": "thermal", "name": "thermal.netd_noise", "netd_k": netd, "seed": s})
    if degs is not None and degs.thermal:
        thermal = _apply_degradations(thermal, degs.thermal, base_seed, {}, log, "thermal").astype(np.float32)
    contrast_arr = np.array(contrast)
    th_obs = np.array([g is not None and np.isfinite(c) and abs(c) >= netd for g, c in zip(gt_th, contrast_arr)])
    rgb_obs = np.array([rgb_observed(rgb[i], gt_rgb[i]) for i in range(n)])
    return SequenceData(name=entry["name"], index=int(entry["index"]), split=entry["split"], set_name=set_name, tag=tag,
                        rgb=rgb.astype(np.float16), thermal_k=thermal, boxes_rgb=boxes_rgb, boxes_thermal=boxes_th,
                        gt_rgb=gt_rgb,
                        gt_thermal=gt_th, contrast_k=contrast_arr, netd_k=netd, rgb_observed=rgb_obs,
                        thermal_observed=th_obs, registered=_registered(scenario), degradations=log)


def thermal_input(thermal_k: np.ndarray) -> np.ndarray:
    """(T, H, W) kelvin -> (T, 1, H, W) float32: minus the frame median, over 1 K, clipped to +-8."""
    med = np.median(thermal_k.reshape(thermal_k.shape[0], -1), axis=1)[:, None, None]
    return np.clip((thermal_k - med) / THERMAL_SCALE_K, -8.0, 8.0).astype(np.float32)[:, None]


def rgb_input(rgb: np.ndarray) -> np.ndarray:
    """(T, H, W, 3) in [0, 1] -> (T, 3, H, W) float32 centred at 0."""
    return (np.transpose(rgb.astype(np.float32), (0, 3, 1, 2)) - np.float32(0.5)).astype(np.float32)


def inputs(seq: SequenceData) -> dict[str, torch.Tensor]:
    return {"rgb": torch.from_numpy(rgb_input(seq.rgb)), "thermal": torch.from_numpy(thermal_input(seq.thermal_k))}


def pad_to_stride(x: torch.Tensor, stride: int = 4) -> torch.Tensor:
    h, w = x.shape[-2:]
    ph, pw = (-h) % stride, (-w) % stride
    return torch.nn.functional.pad(x, (0, pw, 0, ph)) if ph or pw else x


def sample_crops(seqs: list[SequenceData], streams: tuple[str, ...], crop: int, batch: int, target_fraction: float,
                 gen: np.random.Generator) -> tuple[dict[str, torch.Tensor], list[np.ndarray]]:
    """A training batch of ``crop`` x ``crop`` windows (same window in every stream: registered
    training uses each stream's own boxes) with the boxes shifted into the window; random h-flip."""
    out: dict[str, list[np.ndarray]] = {s: [] for s in streams}
    boxes_out: list[np.ndarray] = []
    ref = "thermal" if streams == ("thermal",) else "rgb"
    for _ in range(batch):
        seq = seqs[int(gen.integers(0, len(seqs)))]
        t = int(gen.integers(0, seq.n_frames))
        h, w = seq.rgb.shape[1:3]
        boxes = (seq.boxes_thermal if ref == "thermal" else seq.boxes_rgb)[t]
        if boxes.shape[0] and gen.random() < target_fraction:
            x, y, bw, bh = boxes[int(gen.integers(0, boxes.shape[0]))]
            cx, cy = x + bw / 2, y + bh / 2
            x0 = int(np.clip(cx - gen.uniform(0.15, 0.85) * crop, 0, w - crop))
            y0 = int(np.clip(cy - gen.uniform(0.15, 0.85) * crop, 0, h - crop))
        else:
            x0, y0 = int(gen.integers(0, w - crop + 1)), int(gen.integers(0, h - crop + 1))
        flip = bool(gen.random() < 0.5)
        for s in streams:
            img = seq.rgb[t] if s == "rgb" else seq.thermal_k[t]
            if s == "rgb":
                a = rgb_input(img[None, y0:y0 + crop, x0:x0 + crop])[0]
            else:
                full = thermal_input(seq.thermal_k[t:t + 1])[0]
                a = full[:, y0:y0 + crop, x0:x0 + crop]
            out[s].append(a[:, :, ::-1].copy() if flip else a)
        b = boxes.copy()
        if b.shape[0]:
            b[:, 0] -= x0
            b[:, 1] -= y0
            if flip:
                b[:, 0] = crop - b[:, 0] - b[:, 2]
            x1 = np.clip(b[:, 0] + b[:, 2], 0, crop)
            y1 = np.clip(b[:, 1] + b[:, 3], 0, crop)
            b[:, 0] = np.clip(b[:, 0], 0, crop)
            b[:, 1] = np.clip(b[:, 1], 0, crop)
            b[:, 2], b[:, 3] = x1 - b[:, 0], y1 - b[:, 1]
            b = b[(b[:, 2] >= 1) & (b[:, 3] >= 1)]
        boxes_out.append(b)
    return {s: torch.from_numpy(np.stack(v)) for s, v in out.items()}, boxes_out


def crop_resize(img: np.ndarray, box: np.ndarray, context: float, size: int) -> np.ndarray:
    """A square crop around ``box`` with ``context`` x its larger side, aspect-preserving, zero-padded
    outside the image, resized to ``size`` x ``size``. ``img`` is (C, H, W)."""
    c, h, w = img.shape
    x, y, bw, bh = box
    side = max(float(max(bw, bh)) * context, 8.0)
    cx, cy = x + bw / 2, y + bh / 2
    x0, y0 = int(round(cx - side / 2)), int(round(cy - side / 2))
    s = int(round(side))
    canvas = np.zeros((c, s, s), np.float32)
    sx0, sy0, sx1, sy1 = max(x0, 0), max(y0, 0), min(x0 + s, w), min(y0 + s, h)
    if sx1 > sx0 and sy1 > sy0:
        canvas[:, sy0 - y0:sy1 - y0, sx0 - x0:sx1 - x0] = img[:, sy0:sy1, sx0:sx1]
    resized = cv2.resize(np.transpose(canvas, (1, 2, 0)), (size, size), interpolation=cv2.INTER_LINEAR)
    return np.transpose(resized.reshape(size, size, c), (2, 0, 1))
