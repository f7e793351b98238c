"""The project's own E1/E3 detector (``evids.models.detector.CentreDetector``, sigmoid head) trained
on synthetic frames, and the same detector trained on the real calibration half, both scored by
pycocotools AP50 on a COCO export of the real evaluation half's labels (every class is "target": the
detector is class-agnostic, as in E1/E3).

Both domains go through one input path: the recorded 8-bit frame (IR grey, visible RGB), shrunk by
an integer ``downscale`` (area averaging) when the sensor's targets are larger than the backbone's
~35 px receptive field was made for (the benchmark's visible targets are 27-118 px at 640x512; the
detections are scaled back, the ground truth stays at the recorded size), IR as ``thermal_input`` of
grey / ``GREY_PER_UNIT`` (frame median removed, +-8 units = +-64 grey levels) and visible as
``rgb_input`` of RGB / 255. Training is ``harness.experiments.detection.train.train_model``
(random crops, one-cycle AdamW), so the numbers answer "what would the E1/E3 detector learn from
this data", not a tuned detector's ceiling.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from harness.experiments.sim2real.samples import ClipSummary

GREY_PER_UNIT = 8.0
CATEGORY = {"id": 1, "name": "target"}


def shrink(summary: ClipSummary, factor: int) -> ClipSummary:
    """The clip's kept frames shrunk ``factor`` times by area averaging (sides floored) and its boxes
    scaled with them; ``factor`` 1 returns ``summary`` itself."""
    if factor == 1:
        return summary
    import cv2

    frames = []
    for k, frame, box in summary.frames:
        h, w = frame.shape[:2]
        small = cv2.resize(frame, (w // factor, h // factor), interpolation=cv2.INTER_AREA)
        scaled = None if box is None else (box[0] / factor, box[1] / factor, box[2] / factor, box[3] / factor)
        frames.append((k, small, scaled))
    return dataclasses.replace(summary, frames=frames, thumbnail=None)


def to_sequence(summary: ClipSummary, index: int):
    """A ``SequenceData`` of the clip's kept whole frames (zero-size stand-ins for the other stream)."""
    from harness.experiments.detection.data import SequenceData

    imgs = np.stack([f for _, f, _ in summary.frames])
    boxes = [np.array([b], np.float32) if b is not None else np.zeros((0, 4), np.float32) for _, _, b in summary.frames]
    gt = [list(b) if b is not None else None for _, _, b in summary.frames]
    t, h, w = imgs.shape[:3]
    if summary.sensor == "ir":
        thermal = imgs.astype(np.float32) / GREY_PER_UNIT
        rgb = np.broadcast_to(np.zeros((1, 1, 1, 3), np.float16), (t, h, w, 3))
    else:
        rgb = (imgs.astype(np.float32) / 255.0).astype(np.float16)
        thermal = np.broadcast_to(np.zeros((1, 1, 1), np.float32), (t, h, w))
    observed = np.array([b is not None for b in gt])
    return SequenceData(name=summary.clip, index=index, split=summary.half, set_name=summary.domain, tag=summary.cls,
                        rgb=rgb, thermal_k=thermal, boxes_rgb=boxes, boxes_thermal=boxes, gt_rgb=gt, gt_thermal=gt,
                        contrast_k=np.full(t, np.nan), netd_k=0.0, rgb_observed=observed, thermal_observed=observed,
                        registered=True)


def _frames_input(seq, sensor: str):
    import torch

    from harness.experiments.detection.data import pad_to_stride, rgb_input, thermal_input

    x = thermal_input(np.asarray(seq.thermal_k)) if sensor == "ir" else rgb_input(np.asarray(seq.rgb))
    return pad_to_stride(torch.from_numpy(x))


def detect(model, seqs: Sequence, sensor: str, max_peaks: int = 5, score_floor: float = 0.01,
           downscale: int = 1) -> list[list[dict]]:
    """Per sequence, per kept frame: decoded peaks (boxes [x, y, w, h] px, scores); boxes multiplied by
    ``downscale``, the factor the sequences' frames were shrunk by, so they are in recorded pixels."""
    import torch

    from evids.models.detector import decode_peaks

    out = []
    with torch.no_grad():
        for seq in seqs:
            o = model(_frames_input(seq, sensor))
            frames = decode_peaks(o.prob, o.box, score_floor, max_peaks)
            if downscale != 1:
                frames = [{**rec, "boxes": np.asarray(rec["boxes"]) * downscale} for rec in frames]
            out.append(frames)
    return out


def coco_ground_truth(clips: Sequence[ClipSummary]) -> tuple[dict[str, Any], dict[tuple[int, int], int]]:
    """COCO ground truth of the clips' kept frames at their recorded size: one image per frame, one
    "target" box per labelled frame; returns (dataset dict, {(clip index, frame position): image id})."""
    images: list[dict[str, Any]] = []
    annotations: list[dict[str, Any]] = []
    ids: dict[tuple[int, int], int] = {}
    for si, clip in enumerate(clips):
        for fi, (_, frame, box) in enumerate(clip.frames):
            h, w = frame.shape[:2]
            iid = len(images) + 1
            ids[(si, fi)] = iid
            images.append({"id": iid, "file_name": f"{clip.clip}/{fi}", "width": int(w), "height": int(h)})
            if box is not None:
                annotations.append({"id": len(annotations) + 1, "image_id": iid, "category_id": 1,
                                    "bbox": [round(float(v), 3) for v in box], "area": float(box[2] * box[3]),
                                    "iscrowd": 0})
    return {"images": images, "annotations": annotations, "categories": [CATEGORY]}, ids


def ap50(gt: dict[str, Any], ids: dict[tuple[int, int], int], detections: list[list[dict]], folder: Path,
         name: str) -> float:
    """pycocotools AP at IoU 0.5 of ``detections`` against ``gt`` (files kept in ``folder``)."""
    from harness.experiments.detection.metrics import coco_ap50_file
    from simulator.files import write_atomic

    results = []
    for si, frames in enumerate(detections):
        for fi, rec in enumerate(frames):
            for b, s in zip(rec["boxes"], rec["scores"]):
                results.append({"image_id": ids[(si, fi)], "category_id": 1, "bbox": [round(float(v), 3) for v in b],
                                "score": round(float(s), 6)})
    gt_path, res_path = folder / "gt.json", folder / f"{name}.json"
    if not gt_path.exists():
        write_atomic(gt_path, json.dumps(gt))
    write_atomic(res_path, json.dumps(results))
    return coco_ap50_file(gt_path, res_path)


def _train_and_detect(cond: str, seed: int) -> list[list[dict]]:
    """One forked job: train the detector on ``cond``'s clips with ``seed`` (one torch thread) and
    decode its peaks on the evaluation frames."""
    import torch

    from harness.experiments.detection.config import TrainConfig
    from harness.experiments.detection.train import train_model
    from simulator.jobs import job_context

    torch.set_num_threads(1)
    f = job_context()
    cfg = TrainConfig(seed=seed, steps=f["steps"], crop_px=f["crop"][cond], batch_size=8, threads=1)
    model, _ = train_model(f["name"], f["train"][cond], cfg)
    return detect(model, f["test"], f["sensor"], downscale=f["downscale"])


def run_detector(train_sets: dict[str, list[ClipSummary]], test: list[ClipSummary], sensor: str, *,
                 seeds: Sequence[int], steps: int, folder: Path, workers: int = 1, downscale: int = 1,
                 label: str | None = None) -> dict[str, Any]:
    """AP50 on ``test`` of the detector trained on each of ``train_sets`` (e.g. {"real": ..., "synthetic": ...})
    with every seed (the condition x seed runs are forked jobs on ``workers`` processes, one torch thread
    each); mean and per seed, and the ratio synthetic / real. Every frame is shrunk ``downscale`` times
    before the detector sees it; the scores are against the recorded-size labels."""
    from harness.experiments.pipeline import forked_map

    test_clips = [c for c in test if c.frames]
    if not test_clips:
        return {"note": "no evaluation frames"}
    test_seqs = [to_sequence(shrink(c, downscale), i) for i, c in enumerate(test_clips)]
    gt, ids = coco_ground_truth(test_clips)
    folder.mkdir(parents=True, exist_ok=True)
    result: dict[str, Any] = {"n_test_clips": len(test_seqs), "n_test_frames": len(ids),
                              "n_test_boxes": len(gt["annotations"]), "downscale": downscale, "conditions": {}}
    train: dict[str, list] = {}
    crop: dict[str, int] = {}
    for cond, clips in train_sets.items():
        seqs = [to_sequence(shrink(c, downscale), i) for i, c in enumerate(clips) if c.frames]
        if not seqs:
            continue
        side = min(min(np.asarray(s.thermal_k).shape[1:3]) for s in seqs + test_seqs)
        crop[cond] = int(min(96, side // 4 * 4))
        if crop[cond] < 32:
            result["conditions"][cond] = {"note": f"frames too small for the detector ({side} px)"}
            continue
        train[cond] = seqs
    jobs = [(cond, int(seed)) for cond in train for seed in seeds]
    context = dict(train=train, crop=crop, test=test_seqs, sensor=sensor, steps=steps, downscale=downscale,
                   name="thermal_sigmoid" if sensor == "ir" else "rgb_sigmoid")
    done = {jobs[i]: dets for i, dets in forked_map(_train_and_detect, jobs, workers, label, context=context)}
    for cond, seqs in train.items():
        scores = [ap50(gt, ids, done[(cond, int(seed))], folder, f"{cond}_seed{seed}") for seed in seeds]
        result["conditions"][cond] = {"ap50": float(np.mean(scores)), "per_seed": scores, "train_clips": len(seqs),
                                      "train_frames": int(sum(len(s.gt_thermal) for s in seqs))}
    c = result["conditions"]
    if c.get("real", {}).get("ap50") and "ap50" in c.get("synthetic", {}):
        result["ratio_synthetic_over_real"] = c["synthetic"]["ap50"] / c["real"]["ap50"]
    return result
