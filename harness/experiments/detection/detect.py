"""Detection inference of the detection experiment: the stream maps of a sequence, and every
condition's detections from them ((a)-(h) of harness.experiments.detection.config), plus the
per-target uncertainty read-outs the analyses use."""
from __future__ import annotations

from typing import Any

import numpy as np
import torch

from harness.experiments.detection.conditions import (
    StreamMaps,
    frame_vacuity,
    fused_matched,
    fused_registered,
    gate_mask,
    run_model,
    single_stream,
)
from harness.experiments.detection.config import DetectionConfig, split_key
from harness.experiments.detection.data import SequenceData, inputs

MATCH_PX = 24.0


def compute_maps(seq: SequenceData, models: dict[str, torch.nn.Module]) -> dict[str, StreamMaps]:
    x = inputs(seq)
    maps: dict[str, StreamMaps] = {}
    for name, m in models.items():
        if name == "fusion_sigmoid":
            maps[name] = run_model(m, (x["rgb"], x["thermal"]))
        else:
            maps[name] = run_model(m, x[name.split("_")[0]])
    return maps


def gated_dets(seq: SequenceData, maps: dict[str, StreamMaps], cfg: DetectionConfig, gate: dict[str, float]):
    """Condition (f): DS with the window-form hysteresis gate on per-frame stream vacuity."""
    floor, k = cfg.tracker.score_floor, cfg.tracker.max_peaks
    r, t = maps["rgb_evidential"], maps["thermal_evidential"]
    avail, evaluated = gate_mask(frame_vacuity(r), frame_vacuity(t), gate["tau_high"], gate["tau_low"], cfg.gate.n)
    if seq.registered:
        return fused_registered(r, t, "ds", floor, k, avail), avail, evaluated
    return fused_matched(r, t, "ds", floor, k, MATCH_PX, avail), avail, evaluated


def condition_dets(seq: SequenceData, maps: dict[str, StreamMaps], cfg: DetectionConfig,
                   gate: dict[str, float] | None, temperature: float | None) -> dict[str, Any]:
    """All condition-stream detections of one sequence (f needs ``gate``, h needs ``temperature``)."""
    floor, k = cfg.tracker.score_floor, cfg.tracker.max_peaks
    dets: dict[str, Any] = {}
    gate_info = None
    for c in cfg.conditions:
        if c == "a_sigmoid":
            for s in ("rgb", "thermal"):
                dets[f"{c}/{s}"] = single_stream(maps[f"{s}_sigmoid"], floor, k)
        elif c in ("b_evidential", "c_evidential_tau"):
            for s in ("rgb", "thermal"):
                dets[f"{c}/{s}"] = dets.get(f"b_evidential/{s}") or single_stream(maps[f"{s}_evidential"], floor, k)
        elif c in ("d_average", "e_ds"):
            rule = "average" if c == "d_average" else "ds"
            r, t = maps["rgb_evidential"], maps["thermal_evidential"]
            if seq.registered:
                dets[f"{c}/fused"] = fused_registered(r, t, rule, floor, k)
            else:
                dets[f"{c}/fused"] = fused_matched(r, t, rule, floor, k, MATCH_PX)
        elif c == "f_ds_gated" and gate is not None:
            dets[f"{c}/fused"], avail, evaluated = gated_dets(seq, maps, cfg, gate)
            gate_info = {"fused": avail, "evaluated": evaluated}
        elif c == "g_feature_fusion":
            dets[f"{c}/fused"] = single_stream(maps["fusion_sigmoid"], floor, k)
        elif c == "h_feature_fusion_ts" and temperature is not None:
            fm = maps["fusion_sigmoid"]
            if fm.logit is None:
                raise ValueError("condition h_feature_fusion_ts needs the feature-fusion detector's logits")
            z = fm.logit / temperature
            dets[f"{c}/fused"] = single_stream(StreamMaps(torch.sigmoid(z), fm.box, None, z), floor, k)
    extra: dict[str, Any] = {"gate": gate_info}
    if "thermal_evidential" in maps:
        extra["thermal_u_at_target"], extra["thermal_p_at_target"] = _at_target(maps["thermal_evidential"],
                                                                                seq.gt_thermal)
        extra["rgb_u_at_target"], extra["rgb_p_at_target"] = _at_target(maps["rgb_evidential"], seq.gt_rgb)
        extra["frame_u"] = {"rgb": frame_vacuity(maps["rgb_evidential"]),
                            "thermal": frame_vacuity(maps["thermal_evidential"])}
        if seq.registered:
            extra["ds_conflict_at_target"] = fuse_maps_at_target(maps, seq)[2]
    return {"dets": dets, "extra": extra}


def _at_target(maps: StreamMaps, gt: list) -> tuple[np.ndarray, np.ndarray]:
    from evids.models.detector import STRIDE

    h, w = maps.prob.shape[1:]
    u, p = np.full(len(gt), np.nan), np.full(len(gt), np.nan)
    for t, g in enumerate(gt):
        if g is None:
            continue
        i = min(int((g[1] + g[3] / 2) // STRIDE), h - 1)
        j = min(int((g[0] + g[2] / 2) // STRIDE), w - 1)
        u[t] = float(maps.vacuity[t, i, j])
        p[t] = float(maps.prob[t, i, j])
    return u, p


def fuse_maps_at_target(maps: dict[str, StreamMaps], seq: SequenceData):
    from evids.models.detector import STRIDE
    from harness.experiments.detection.conditions import fuse_maps

    p, u, c = fuse_maps(maps["rgb_evidential"], maps["thermal_evidential"], "ds")
    h, w = p.shape[1:]
    out = np.full(seq.n_frames, np.nan)
    for t, g in enumerate(seq.gt_rgb):
        if g is not None:
            out[t] = float(c[t, min(int((g[1] + g[3] / 2) // STRIDE), h - 1), min(int((g[0] + g[2] / 2) // STRIDE),
                                                                                  w - 1)])
    return p, u, out


def gt_of(seq: SequenceData, key: str) -> list:
    return seq.gt_thermal if split_key(key)[1] == "thermal" else seq.gt_rgb
