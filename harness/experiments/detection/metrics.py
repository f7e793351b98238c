"""Detection/tracking metrics through the field's own tools, on exported files.

- AP50: ``pycocotools`` COCOeval (bbox, category drone) on the COCO-video ground truth written by
  ``simulator.formats.coco.coco_video_json`` and a COCO results file of our detections.
- MOTA / IDF1 / HOTA: PyPI ``trackeval`` (``MotChallenge2DBox``, CLEAR + Identity + HOTA) on the
  MOTChallenge layout built from ``simulator.formats.mot.gt_rows`` / ``seqinfo_text`` in MM-UAV's
  class convention (drone = class 0, not_drone = 1; :class:`MMUAVBox`).
- Anti-UAV state accuracy, both variants (``evids.metrics.state_accuracy``: plain = mean IoU with
  1 for a correct empty prediction; penalised = EDTC's minus 0.2 * mean(penalty)^0.3) on the
  ``IR_label.json`` / ``visible.json`` written by ``simulator.formats.antiuav.export_antiuav``.
- Sequence-clustered comparisons: per-sequence paired differences, a percentile bootstrap over
  sequences, an exact-enumeration-or-Monte-Carlo sign-flip p value, and the minimum detectable
  difference ``2.8 s / sqrt(n)`` (two-sided alpha 0.05, 80 % power).
"""
from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from evids.metrics import box_iou, clustered_bootstrap, state_accuracy, uauc


# ------------------------------------------------------------------------------------------ COCO
def write_coco_gt(entries: list[dict[str, Any]], modality: str, path: Path) -> dict[str, int]:
    """COCO-video ground truth for ``entries`` (video names = sequence names); returns
    ``{f"{video}/{frame0}": image_id}``."""
    from simulator.formats.coco import coco_video_json
    from simulator.formats.native import write_json

    data = coco_video_json([(e["name"], Path(e["path"])) for e in entries], modality, distractors=True)
    write_json(path, data)
    videos = {v["id"]: v["file_name"] for v in data["videos"]}
    return {f"{videos[im['video_id']]}/{im['frame_id'] - 1}": im["id"] for im in data["images"]}


def coco_ap50(gt_path: Path, results_path: Path, detections: list[tuple[str, int, np.ndarray, np.ndarray]],
              image_ids: dict[str, int]) -> float:
    """Write the COCO results file and return COCOeval's AP at IoU 0.5 for category 1 (drone)."""
    results = []
    for video, frame0, boxes, scores in detections:
        iid = image_ids[f"{video}/{frame0}"]
        for b, s in zip(np.asarray(boxes).reshape(-1, 4), np.asarray(scores).reshape(-1)):
            results.append({"image_id": iid, "category_id": 1, "bbox": [round(float(v), 3) for v in b],
                            "score": round(float(s), 6)})
    Path(results_path).parent.mkdir(parents=True, exist_ok=True)
    Path(results_path).write_text(json.dumps(results))
    return coco_ap50_file(gt_path, results_path)


def coco_ap50_file(gt_path: Path, results_path: Path) -> float:
    """COCOeval AP50 (category drone) of a COCO results file against a COCO ground-truth file."""
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    if not json.loads(Path(results_path).read_text()):
        return 0.0
    with contextlib.redirect_stdout(io.StringIO()):
        gt = COCO(str(gt_path))
        dt = gt.loadRes(str(results_path))
        ev = COCOeval(gt, dt, "bbox")
        ev.params.catIds = [1]
        ev.evaluate()
        ev.accumulate()
        ev.summarize()
    return float(ev.stats[1])


# ------------------------------------------------------------------------------------- TrackEval
def _mmuav_dataset_class():
    from trackeval.datasets import MotChallenge2DBox

    class MMUAVBox(MotChallenge2DBox):
        """MotChallenge2DBox in MM-UAV's class convention: drone = 0 is evaluated, not_drone = 1."""

        def __init__(self, config: dict) -> None:
            super().__init__({**config, "CLASSES_TO_EVAL": ["pedestrian"]})
            self.valid_classes = ["drone"]
            self.class_list = ["drone"]
            unused = ["person_on_vehicle", "static_person", "distractor", "reflection", "non_mot_vehicle"]
            self.class_name_to_class_id = {"drone": 0, "not_drone": 1, **{n: -10 - i for i, n in enumerate(unused)}}
            self.valid_class_numbers = [0, 1]

    return MMUAVBox


def write_mot_gt(entries: list[dict[str, Any]], camera: str, gt_root: Path, bench_split: str) -> None:
    """MOTChallenge ground-truth layout (gt/gt.txt with MM-UAV rows, seqinfo.ini, seqmap)."""
    from simulator.formats.mot import gt_rows, seqinfo_text
    from simulator.formats.native import load_labels, load_meta

    root = Path(gt_root)
    for e in entries:
        seq = Path(e["path"])
        meta, labels = load_meta(seq), load_labels(seq)
        d = root / bench_split / e["name"]
        (d / "gt").mkdir(parents=True, exist_ok=True)
        rows = gt_rows(labels, camera)
        (d / "gt" / "gt.txt").write_text("".join(r + "\n" for r in rows))
        cam = meta["cameras"][camera]
        (d / "seqinfo.ini").write_text(seqinfo_text(e["name"], "img1", meta["frame_rate_hz"], meta["n_frames"],
                                                    cam["width_px"], cam["height_px"]))
    (root / "seqmaps").mkdir(parents=True, exist_ok=True)
    (root / "seqmaps" / f"{bench_split}.txt").write_text("name\n" + "".join(e["name"] + "\n" for e in entries))


def write_mot_tracker(path: Path, boxes: list[list[float] | None], scores: list[float], ids: list[int]) -> None:
    """MOTChallenge tracker rows ``frame,id,x,y,w,h,conf,-1,-1,-1`` (1-based frame)."""
    lines = []
    for t, (b, s, i) in enumerate(zip(boxes, scores, ids)):
        if b is not None:
            lines.append(f"{t + 1},{max(int(i), 1)},{b[0]:.2f},{b[1]:.2f},{b[2]:.2f},{b[3]:.2f},{s:.4f},-1,-1,-1\n")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(lines))


def trackeval_mot(gt_root: Path, trackers_root: Path, benchmark: str, split: str,
                  trackers: list[str]) -> dict[str, dict]:
    """MOTA, IDF1, HOTA (combined and per sequence) of each tracker via trackeval."""
    import trackeval

    dcfg = _mmuav_dataset_class().get_default_dataset_config()
    dcfg.update({"GT_FOLDER": str(gt_root), "TRACKERS_FOLDER": str(trackers_root), "BENCHMARK": benchmark,
                 "SPLIT_TO_EVAL": split, "TRACKERS_TO_EVAL": trackers, "SEQMAP_FOLDER": str(Path(gt_root) / "seqmaps"),
                 "PRINT_CONFIG": False, "DO_PREPROC": True, "SKIP_SPLIT_FOL": False})
    ecfg = trackeval.Evaluator.get_default_eval_config()
    ecfg.update({"USE_PARALLEL": False, "PRINT_RESULTS": False, "PRINT_CONFIG": False, "TIME_PROGRESS": False,
                 "OUTPUT_SUMMARY": False, "OUTPUT_DETAILED": False, "PLOT_CURVES": False, "DISPLAY_LESS_PROGRESS": True,
                 "OUTPUT_EMPTY_CLASSES": False, "LOG_ON_ERROR": None, "BREAK_ON_ERROR": True,
                 "PRINT_ONLY_COMBINED": True})
    dataset = _mmuav_dataset_class()(dcfg)
    quiet = {"PRINT_CONFIG": False}
    metrics = [trackeval.metrics.HOTA(quiet), trackeval.metrics.CLEAR(quiet), trackeval.metrics.Identity(quiet)]
    with contextlib.redirect_stdout(io.StringIO()):
        res, _ = trackeval.Evaluator(ecfg).evaluate([dataset], metrics)
    out = {}
    for tracker, by_seq in res[dataset.get_name()].items():
        rows = {}
        for seq, cls_res in by_seq.items():
            r = cls_res["drone"]
            rows[seq] = {"mota": float(r["CLEAR"]["MOTA"]), "idf1": float(r["Identity"]["IDF1"]),
                         "hota": float(np.mean(r["HOTA"]["HOTA"])), "ids": int(r["CLEAR"]["IDSW"])}
        out[tracker] = rows
    return out


# -------------------------------------------------------------------------------------- Anti-UAV
def antiuav_state_accuracy(label_file: Path, pred: list[list[float] | None]) -> dict[str, float]:
    from simulator.formats.antiuav import read_label_file

    exist, rects = read_label_file(label_file)
    return {v: state_accuracy(pred, [r if r is not None else [] for r in rects], exist, variant=v)
            for v in ("plain", "penalised")}


def per_frame_state_values(pred: list[list[float] | None], gt: list[list[float] | None]) -> np.ndarray:
    """The per-frame terms of the plain state accuracy (IoU if present, 1/0 for empty/non-empty if absent)."""
    vals = []
    for p, g in zip(pred, gt):
        if g is None:
            vals.append(1.0 if p is None else 0.0)
        else:
            vals.append(0.0 if p is None else float(box_iou(np.array([p]), np.array([g]))[0, 0]))
    return np.array(vals)


# ------------------------------------------------------------------------------------ statistics
def paired_comparison(a: ArrayLike, b: ArrayLike, seed: int, n_resamples: int) -> dict[str, float]:
    """Per-sequence values of systems A and B -> mean difference A - B, sequence-bootstrap 95 % CI,
    sign-flip permutation p value, MDE = 2.8 s / sqrt(n)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    ok = np.isfinite(a) & np.isfinite(b)
    d = a[ok] - b[ok]
    n = int(d.size)
    if n < 2:
        return {"diff": float(np.mean(d)) if n else float("nan"), "ci_low": float("nan"), "ci_high": float("nan"),
                "p": float("nan"), "mde": float("nan"), "n": n}
    boot = clustered_bootstrap(np.mean, d, clusters=np.arange(n), rng=np.random.default_rng(seed),
                               n_resamples=n_resamples)
    gen = np.random.default_rng(seed + 1)
    if n <= 16:
        signs = ((np.arange(2 ** n)[:, None] >> np.arange(n)) & 1) * 2 - 1
    else:
        signs = gen.choice([-1, 1], size=(n_resamples, n))
    null = np.abs((signs * d).mean(1))
    p = float(np.mean(null >= abs(d.mean()) - 1e-12))
    s = float(np.std(d, ddof=1))
    return {"diff": float(d.mean()), "ci_low": boot.ci_low, "ci_high": boot.ci_high, "p": p,
            "mde": 2.8 * s / np.sqrt(n), "n": n}


def clustered_uauc(unc: np.ndarray, is_error: np.ndarray, clusters: np.ndarray, seed: int,
                   n_resamples: int) -> dict[str, float]:
    """UAUC with a sequence-clustered bootstrap CI (NaN when one class is missing)."""
    unc, is_error, clusters = np.asarray(unc, float), np.asarray(is_error, bool), np.asarray(clusters)
    n_err, n = int(is_error.sum()), int(is_error.size)
    if n == 0 or n_err in (0, n):
        return {"uauc": float("nan"), "ci_low": float("nan"), "ci_high": float("nan"), "n": n, "n_error": n_err}

    def stat(u, e):
        return uauc(u, e) if 0 < e.sum() < e.size else np.nan

    boot = clustered_bootstrap(stat, unc, is_error, clusters=clusters, rng=np.random.default_rng(seed),
                               n_resamples=n_resamples)
    return {"uauc": boot.estimate, "ci_low": boot.ci_low, "ci_high": boot.ci_high, "n": n, "n_error": n_err,
            "n_clusters": boot.n_clusters}


def spearman_clustered(x: np.ndarray, y: np.ndarray, clusters: np.ndarray, seed: int,
                       n_resamples: int) -> dict[str, float]:
    from scipy.stats import spearmanr

    x, y = np.asarray(x, float), np.asarray(y, float)
    if x.size < 3:
        return {"rho": float("nan"), "ci_low": float("nan"), "ci_high": float("nan"), "n": int(x.size)}

    def stat(a, b):
        return float(spearmanr(a, b).statistic) if np.ptp(a) > 0 and np.ptp(b) > 0 else np.nan

    boot = clustered_bootstrap(stat, x, y, clusters=np.asarray(clusters), rng=np.random.default_rng(seed),
                               n_resamples=n_resamples)
    return {"rho": boot.estimate, "ci_low": boot.ci_low, "ci_high": boot.ci_high, "n": int(x.size),
            "n_clusters": boot.n_clusters}


AREA_STRATA = (("small <200", 0.0, 200.0), ("medium 200-1000", 200.0, 1000.0), ("large >1000", 1000.0, float("inf")))


def area_stratum(area: np.ndarray) -> np.ndarray:
    out = np.empty(np.asarray(area).shape, dtype=object)
    for name, lo, hi in AREA_STRATA:
        out[(area >= lo) & (area < hi)] = name
    return out


def detections_matched(boxes: np.ndarray, scores: np.ndarray, gt: list[float] | np.ndarray | None,
                       iou_threshold: float = 0.5) -> np.ndarray:
    """is_tp per detection against one frame's ground truth (a box, an (n, 4) array, or None)."""
    from evids.metrics import match_detections

    g = np.zeros((0, 4)) if gt is None else np.asarray(gt, float).reshape(-1, 4)
    if np.asarray(boxes).shape[0] == 0:
        return np.zeros(0, bool)
    return match_detections(np.asarray(boxes, float), np.asarray(scores, float), g, iou_threshold).is_tp
