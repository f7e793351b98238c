"""Shortcut audit: can a classifier that never sees the target tell the classes apart?

Target-blind baselines are fitted on the train split and scored on the test split (balanced
accuracy, chance = 0.5, 95 % CI by resampling test scenes). Each uses features that describe the
scene, not the drone:

- ``video_median_colour``: per-channel median colour of the segment's frames (a 3-30 px drone moves
  a median of 12,544 pixels by at most a few of them);
- ``video_strip_colour``: mean and std colour of the top and bottom 16-row strips (target-free crops:
  the drone's path runs through the frame centre in generated data);
- ``audio_mean_mfcc``: mean MFCC over time, on segments where the drone is inaudible (truth) and on
  background segments;
- ``rf_mean_spectrum``: mean spectrogram over time, on segments where no drone link is observable
  (truth) and on background segments.

Without per-segment truth (public data), the audio/RF baselines use every segment, so they are
only target-blind when the target is absent from that modality. Two models per feature set:
logistic regression and 1-nearest-neighbour (scikit-learn). A baseline whose CI lies above 0.5
flags a shortcut: something other than the target differs between the classes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evids.experiments.data import ClipArrays
from scenes.errors import UserInputError

FEATURES = ("video_median_colour", "video_strip_colour", "audio_mean_mfcc", "rf_mean_spectrum")
STRIP_ROWS = 16


def _video_median(c: ClipArrays) -> np.ndarray:
    v = c.video.reshape(c.n_segments, -1, 3)
    return np.median(v, axis=1).astype(np.float64)


def _video_strips(c: ClipArrays) -> np.ndarray:
    top, bottom = c.video[:, :, :STRIP_ROWS], c.video[:, :, -STRIP_ROWS:]
    both = np.concatenate([top, bottom], axis=2).reshape(c.n_segments, -1, 3).astype(np.float64)
    return np.concatenate([both.mean(1), both.std(1)], axis=1)


def _audio_mfcc(c: ClipArrays) -> np.ndarray:
    return c.mfcc[:, 0].mean(axis=2).astype(np.float64)


def _rf_spectrum(c: ClipArrays) -> np.ndarray:
    return c.rf.mean(axis=2).astype(np.float64)


_FEATURE_FN = {"video_median_colour": (_video_median, None), "video_strip_colour": (_video_strips, None),
               "audio_mean_mfcc": (_audio_mfcc, "audio"), "rf_mean_spectrum": (_rf_spectrum, "rf")}


def blind_rows(c: ClipArrays, modality: str | None) -> np.ndarray:
    """Segments whose features carry no target evidence: all of a background clip; of a drone
    clip, those where the simulator says this modality does not observe the drone."""
    if modality is None or c.label == 1:
        return np.ones(c.n_segments, bool)
    obs = c.observability.get(modality)
    if obs is None:
        return np.ones(c.n_segments, bool)
    return ~np.asarray(obs, bool)


@dataclass
class _Rows:
    x: np.ndarray
    y: np.ndarray
    scene: np.ndarray


def _rows(clips: list[ClipArrays], idx: list[int], feature: str) -> _Rows:
    fn, modality = _FEATURE_FN[feature]
    xs, ys, ss = [], [], []
    for i in idx:
        c = clips[i]
        keep = blind_rows(c, modality)
        if keep.any():
            xs.append(fn(c)[keep])
            ys.append(np.full(int(keep.sum()), c.label))
            ss.append(np.full(int(keep.sum()), c.scene, dtype=object))
    if not xs:
        return _Rows(np.zeros((0, 1)), np.zeros(0, np.int64), np.zeros(0, object))
    return _Rows(np.concatenate(xs), np.concatenate(ys), np.concatenate(ss))


def balanced_accuracy(pred: np.ndarray, y: np.ndarray) -> float:
    return float(np.mean([np.mean(pred[y == k] == k) for k in (0, 1)]))


def _scene_ci(pred: np.ndarray, y: np.ndarray, scene: np.ndarray, rng: np.random.Generator, n: int,
              confidence: float) -> tuple[float, float]:
    keys = np.unique(scene.astype(str))
    rows = {k: np.flatnonzero(scene.astype(str) == k) for k in keys}
    vals = []
    for _ in range(n):
        pick = np.concatenate([rows[k] for k in keys[rng.integers(0, keys.size, keys.size)]])
        yy = y[pick]
        if (yy == 0).any() and (yy == 1).any():
            vals.append(balanced_accuracy(pred[pick], yy))
    a = (1 - confidence) / 2
    return float(np.quantile(vals, a)), float(np.quantile(vals, 1 - a))


def audit_clips(clips: list[ClipArrays], split: dict[str, list[int]], seed: int = 0, n_resamples: int = 1000,
                confidence: float = 0.95, min_segments: int = 20, tolerance: float = 0.05) -> dict:
    """Fit every target-blind baseline on ``split['train']``, score on ``split['test']``.

    Returns {"baselines": [...], "shortcut": bool, ...}; ``shortcut`` is True when any baseline's
    CI lies above chance. ``within_tolerance``: |score - 0.5| <= ``tolerance`` as well.
    """
    from sklearn.linear_model import LogisticRegression
    from sklearn.neighbors import KNeighborsClassifier
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    for name in ("train", "test"):
        if not split.get(name):
            raise UserInputError(f"split.{name}: the dataset has no {name} clips; the audit needs train and test splits")
    out = []
    for feature in FEATURES:
        tr, te = _rows(clips, split["train"], feature), _rows(clips, split["test"], feature)
        counts = {"train": [int((tr.y == k).sum()) for k in (0, 1)], "test": [int((te.y == k).sum()) for k in (0, 1)]}
        for model_name in ("logistic", "1nn"):
            row = {"feature": feature, "model": model_name, "n_train": counts["train"], "n_test": counts["test"],
                   "n_test_scenes": int(len(set(te.scene.tolist())))}
            if min(counts["train"] + counts["test"]) < min_segments:
                out.append({**row, "score": None, "ci_low": None, "ci_high": None, "beats_chance": False,
                            "status": f"not scored: fewer than {min_segments} target-blind segments of a class"})
                continue
            model = (make_pipeline(StandardScaler(), LogisticRegression(max_iter=2000, C=1.0))
                     if model_name == "logistic" else make_pipeline(StandardScaler(), KNeighborsClassifier(1)))
            model.fit(tr.x, tr.y)
            pred = model.predict(te.x)
            score = balanced_accuracy(pred, te.y)
            rng = np.random.default_rng(np.random.SeedSequence([seed, FEATURES.index(feature), len(model_name)]))
            lo, hi = _scene_ci(pred, te.y, te.scene, rng, n_resamples, confidence)
            beats = lo > 0.5
            out.append({**row, "score": score, "ci_low": lo, "ci_high": hi, "beats_chance": bool(beats),
                        "ci_includes_chance": bool(lo <= 0.5 <= hi),
                        "within_tolerance": bool(abs(score - 0.5) <= tolerance),
                        "status": "SHORTCUT: beats chance beyond its CI" if beats else "at chance"})
    scored = [r for r in out if r["score"] is not None]
    return {"baselines": out, "chance": 0.5, "metric": "balanced accuracy", "confidence": confidence,
            "tolerance": tolerance, "shortcut": any(r["beats_chance"] for r in out),
            "all_within_tolerance": all(r["within_tolerance"] for r in scored) if scored else None,
            "n_scored": len(scored)}


def dataset_split(clips: list[ClipArrays]) -> dict[str, list[int]]:
    """The dataset's own split (recorded per clip); UserInputError naming the field when absent."""
    if not clips or any(c.split is None for c in clips):
        missing = sum(c.split is None for c in clips)
        raise UserInputError(f"split: {missing} of {len(clips)} clips carry no train/val/test split "
                             "(labels/<label>/<scene>/<n>.json field 'split'); the audit needs a dataset with splits")
    split = {s: [i for i, c in enumerate(clips) if c.split == s] for s in ("train", "val", "test")}
    for name in ("train", "test"):
        if not split[name]:
            raise UserInputError(f"split: the dataset has no {name} clips; the audit needs train and test splits")
    return split
