"""Fitting on the validation split of the detection experiment: the tracking thresholds, the gate's
tau_high and the feature-fusion temperature (nothing here sees the test split)."""
from __future__ import annotations

from typing import Any

import numpy as np

from harness.experiments.detection.config import DetectionConfig
from harness.experiments.detection.data import SequenceData
from harness.experiments.detection.detect import gated_dets, gt_of
from harness.experiments.detection.tracking import FrameDetections, run_tracker


def _seq_state(frames: list[FrameDetections], gt: list, det_thr: float, theta: float, cfg,
               tau_det=None) -> tuple[float, list]:
    from harness.experiments.detection.metrics import per_frame_state_values

    steps = run_tracker(frames, det_thr, theta, cfg.tracker.search_px, tau_det)
    return float(np.mean(per_frame_state_values([s.box for s in steps], gt))), steps


def fit_tracking(val: list[tuple[SequenceData, dict]], key: str, cfg: DetectionConfig,
                 tau_det_grid: bool = False) -> dict[str, Any]:
    """Grid search on val for the detection threshold and the tracker's switching threshold theta
    (and tau_det for condition (c)), maximising mean per-sequence state accuracy."""
    det_grid = [0.01, 0.02, 0.03, 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 0.9]
    unc_all = np.concatenate([np.concatenate([f.uncertainty for f in out["dets"][key][0]] or [np.zeros(0)])
                              for _, out in val]) if val else np.zeros(0)
    qs = np.unique(np.quantile(unc_all, [0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 1.0])) if unc_all.size else np.array([1.0])
    theta_grid = [float(q) + 1e-9 for q in qs] if cfg.tracker.theta is None else [cfg.tracker.theta]
    tau_grid = [None] + ([float(q) + 1e-9 for q in qs] if tau_det_grid else [])
    best: dict[str, Any] = {"score": -1.0}
    for d in det_grid:
        for th in theta_grid:
            for tau in tau_grid:
                if tau_det_grid and tau is None:
                    continue
                vals = [_seq_state(out["dets"][key][0], gt_of(seq, key), d, th, cfg, tau)[0] for seq, out in val]
                score = float(np.mean(vals)) if vals else 0.0
                if score > best["score"] + 1e-12:
                    best = {"score": score, "det_threshold": d, "theta": th, "tau_det": tau}
    best["fitted_on"] = "val"
    return best


def fit_gate(val: list[tuple[SequenceData, dict]], val_maps: list[dict], cfg: DetectionConfig,
             track_fit: dict) -> dict[str, Any]:
    """tau_high from the val distribution of per-frame stream vacuity: the quantile (grid) that
    maximises val state accuracy of (f), with (e)'s fitted tracking thresholds."""
    if cfg.gate.tau_high is not None:
        return {"tau_high": cfg.gate.tau_high, "tau_low": cfg.gate.tau_high * cfg.gate.tau_low_fraction,
                "fitted_on": "config"}
    u = np.concatenate([np.concatenate([o["extra"]["frame_u"]["rgb"], o["extra"]["frame_u"]["thermal"]])
                        for _, o in val])
    best: dict[str, Any] = {"score": -1.0}
    for q in (0.5, 0.7, 0.8, 0.9, 0.95, 0.99):
        tau_high = float(min(np.quantile(u, q), 1.0))
        gate = {"tau_high": tau_high, "tau_low": tau_high * cfg.gate.tau_low_fraction}
        vals = []
        for (s, _), maps in zip(val, val_maps):
            (frames, _), _, _ = gated_dets(s, maps, cfg, gate)
            vals.append(_seq_state(frames, s.gt_rgb, track_fit["det_threshold"], track_fit["theta"], cfg)[0])
        score = float(np.mean(vals)) if vals else 0.0
        if score > best["score"] + 1e-12:
            best = {"score": score, "quantile": q, **gate}
    best["fitted_on"] = "val"
    return best


def fit_temperature_on_val(val: list[tuple[SequenceData, dict]]) -> float:
    from evids.metrics import fit_temperature
    from harness.experiments.detection.metrics import detections_matched

    logits, labels = [], []
    for seq, out in val:
        frames, decoded = out["dets"]["g_feature_fusion/fused"]
        for t, (f, d) in enumerate(zip(frames, decoded)):
            tp = detections_matched(f.boxes, f.scores, seq.gt_rgb[t])
            logits.append(d["logit"])
            labels.append(tp.astype(np.float64))
    z, y = np.concatenate(logits), np.concatenate(labels)
    return float(fit_temperature(z, y, t_min=0.05, t_max=200.0)) if z.size else 1.0
