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
only target-blind when the target is absent from that modality. Where every drone clip has a
drone-absent twin, each baseline is also run on the *twin counterfactual* (a drone clip's features
taken from its twin: same scene, no drone): only that variant decides, because "observed" features
of a near drone carry the drone itself (a rotor 20 dB under the 200-8000 Hz band level still shows
in the MFCC's low bands), which is target evidence, not a shortcut. Two models per feature set:
logistic regression and 1-nearest-neighbour (scikit-learn). A baseline whose CI lies above 0.5
flags a shortcut: something other than the target differs between the classes.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from evids.metrics.significance import A_BEATS_B, B_BEATS_A, NO_DIFFERENCE, UNDECIDED, comparison_verdict
from harness.experiments.config import AuditConfig
from harness.experiments.data import ClipArrays
from scenes.errors import UserInputError

FEATURES = ("video_median_colour", "video_strip_colour", "audio_mean_mfcc", "rf_mean_spectrum")
STRIP_ROWS = 16


def _video_median(c: ClipArrays) -> np.ndarray:
    """Per-channel median over frames 0, 3, 6 of the segment, every second pixel (a fixed subsample)."""
    v = c.video[:, ::3, ::2, ::2].reshape(c.n_segments, -1, 3)
    return np.median(v, axis=1).astype(np.float64)


def _video_strips(c: ClipArrays) -> np.ndarray:
    top, bottom = c.video[:, ::3, :STRIP_ROWS], c.video[:, ::3, -STRIP_ROWS:]
    both = np.concatenate([top, bottom], axis=2).reshape(c.n_segments, -1, 3).astype(np.float64)
    return np.concatenate([both.mean(1), both.std(1)], axis=1)


def _audio_mfcc(c: ClipArrays) -> np.ndarray:
    return c.mfcc[:, 0].mean(axis=2).astype(np.float64)


def _rf_spectrum(c: ClipArrays) -> np.ndarray:
    return c.rf.mean(axis=2).astype(np.float64)


_FEATURE_FN = {"video_median_colour": (_video_median, None), "video_strip_colour": (_video_strips, None),
               "audio_mean_mfcc": (_audio_mfcc, "audio"), "rf_mean_spectrum": (_rf_spectrum, "rf")}


#: drone-to-rest SNR (dB, simulator truth) below which a segment counts as target-blind; stricter
#: than the observability flag (0 dB): a tonal rotor 10 dB under the band level is still in the MFCC
BLIND_SNR_DB = {"audio": -20.0, "rf": -20.0}


def blind_rows(c: ClipArrays, modality: str | None) -> np.ndarray:
    """Segments whose features carry no target evidence: all of a background clip; of a drone
    clip, those where the simulator says this modality does not observe the drone AND the drone's
    SNR in it is below :data:`BLIND_SNR_DB` (no link at all counts as -inf)."""
    if modality is None or c.label == 1:
        return np.ones(c.n_segments, bool)
    obs = c.observability.get(modality)
    if obs is None:
        return np.ones(c.n_segments, bool)
    keep = ~np.asarray(obs, bool)
    snr = c.snr_db.get(modality)
    if snr is not None and len(snr) == len(keep):
        keep &= ~(np.nan_to_num(snr, nan=-np.inf) >= BLIND_SNR_DB[modality])
    return keep


@dataclass
class _Rows:
    x: np.ndarray
    y: np.ndarray
    scene: np.ndarray


def _rows(clips: list[ClipArrays], idx: list[int], feature: str, counterfactual: bool = False) -> _Rows:
    """Feature rows of the given clips. ``counterfactual``: a drone clip's features are computed
    on its drone-absent twin (same scene, same seeds, no drone), so only a difference between the
    classes OTHER than the drone can be learned; every segment is used."""
    fn, modality = _FEATURE_FN[feature]
    by_id = {c.clip_id: c for c in clips}
    xs, ys, ss = [], [], []
    for i in idx:
        c = clips[i]
        src = c
        if counterfactual:
            src = by_id.get(c.twin, c) if c.label == 0 and c.twin is not None else c
            keep = np.ones(c.n_segments, bool)
        else:
            keep = blind_rows(c, modality)
        if keep.any():
            xs.append(fn(src)[keep])
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


def audit_clips(clips: list[ClipArrays], split: dict[str, list[int]], settings: AuditConfig | None = None,
                confidence: float = 0.95) -> dict:
    """Fit every target-blind baseline on ``split['train']``, score on ``split['test']``.

    ``settings`` (seed, resamples, minimum segments, tolerance) default to AuditConfig's, so
    `evids audit` and a run's audit stage use the same seed. Each row's ``verdict`` follows the one
    rule (evids.metrics.significance.comparison_verdict) with the tolerance as the MDE; ``shortcut``
    is True when a decisive baseline beats chance by it. ``within_tolerance``: |score - 0.5| <= tolerance.
    """
    settings = settings or AuditConfig()
    seed, n_resamples = settings.seed, settings.n_resamples
    min_segments, tolerance = settings.min_segments, settings.tolerance
    from sklearn.linear_model import LogisticRegression
    from sklearn.neighbors import KNeighborsClassifier
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    for name in ("train", "test"):
        if not split.get(name):
            raise UserInputError(f"split.{name}: the dataset has no {name} clips; the audit needs train and test "
                                 "splits")
    by_id = {c.clip_id: c for c in clips}
    used = split["train"] + split["test"]
    has_twins = all(clips[i].twin in by_id for i in used if clips[i].label == 0)
    out: list[dict[str, Any]] = []
    variants = ("observed", "twin_counterfactual") if has_twins else ("observed",)
    for variant in variants:
        for feature in FEATURES:
            cf = variant == "twin_counterfactual"
            tr, te = _rows(clips, split["train"], feature, cf), _rows(clips, split["test"], feature, cf)
            counts = {"train": [int((tr.y == k).sum()) for k in (0, 1)],
                      "test": [int((te.y == k).sum()) for k in (0, 1)]}
            for model_name in ("logistic", "1nn"):
                row = {"variant": variant, "feature": feature, "model": model_name, "n_train": counts["train"],
                       "n_test": counts["test"], "n_test_scenes": len(set(te.scene.tolist()))}
                if min(counts["train"] + counts["test"]) < min_segments:
                    out.append({**row, "score": None, "ci_low": None, "ci_high": None, "beats_chance": False,
                                "status": f"not scored: fewer than {min_segments} target-blind segments of a class"})
                    continue
                model = (make_pipeline(StandardScaler(), LogisticRegression(max_iter=2000, C=1.0))
                         if model_name == "logistic" else make_pipeline(StandardScaler(), KNeighborsClassifier(1)))
                model.fit(tr.x, tr.y)
                pred = model.predict(te.x)
                score = balanced_accuracy(pred, te.y)
                rng = np.random.default_rng(np.random.SeedSequence([seed, FEATURES.index(feature), len(model_name),
                                                                    variants.index(variant)]))
                lo, hi = _scene_ci(pred, te.y, te.scene, rng, n_resamples, confidence)
                # the one verdict rule (evids.metrics.significance), the tolerance as the MDE
                verdict = comparison_verdict(score - 0.5, lo - 0.5, hi - 0.5, tolerance)
                beats = verdict == A_BEATS_B
                decisive = cf or not has_twins
                status = {NO_DIFFERENCE: "at chance", B_BEATS_A: "below chance",
                          UNDECIDED: "undecided (the CI neither clears chance by the tolerance nor lies within it)",
                          }.get(verdict, "SHORTCUT: beats chance beyond its CI" if decisive else
                                "drone signal in these features (the twin counterfactual decides)")
                out.append({**row, "score": score, "ci_low": lo, "ci_high": hi, "beats_chance": bool(beats),
                            "verdict": verdict,
                            "decisive": decisive, "ci_includes_chance": bool(lo <= 0.5 <= hi),
                            "within_tolerance": bool(abs(score - 0.5) <= tolerance), "status": status})
    decisive_rows = [r for r in out if r.get("decisive") and r["score"] is not None]
    return {"baselines": out, "chance": 0.5, "metric": "balanced accuracy", "confidence": confidence, "seed": seed,
            "tolerance": tolerance, "twins": has_twins,
            "decided_by": "twin_counterfactual" if has_twins else "observed",
            "shortcut": any(r["beats_chance"] for r in decisive_rows),
            "all_within_tolerance": all(r["within_tolerance"] for r in decisive_rows) if decisive_rows else None,
            "n_scored": len(decisive_rows)}


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
