"""Conditions (a)-(h): from per-stream detector maps to per-frame detections (boxes, scores and the
uncertainty the tracker switches on).

Fusion of the two streams:
- registered cameras (same intrinsics, no thermal offset): per location, on the (h, w) maps:
  (d) ``evids.fusion.average`` of the two Dirichlets (p = mean of alpha/S), (e) ``dempster_shafer``;
  box geometry from the RGB head (RGB coordinates, as the paper's E3);
- a camera offset: each stream is decoded to peaks first, then RGB and thermal peaks are matched
  one-to-one by the Hungarian algorithm on centre distance, gated at ``match_px``; a matched pair
  is fused as above, an unmatched peak keeps its own opinion (the other stream missing, which is
  the identity of both rules), with its own box.
The uncertainty handed to the tracker is the vacuity ``u = K / S`` for evidential outputs and
``1 - p`` for sigmoid outputs.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from scipy.optimize import linear_sum_assignment

from evids.fusion import FusionResult, average, dempster_shafer
from evids.models.detector import DetectorOutput, decode_peaks
from harness.experiments.detection.tracking import FrameDetections


def _conflict(res: FusionResult) -> torch.Tensor:
    """Dempster's conflict per fold step (dempster_shafer always returns it)."""
    if res.conflict is None:
        raise ValueError("dempster_shafer returned no conflict term")
    return res.conflict


@dataclass
class StreamMaps:
    """Detector output over a whole sequence, (T, h, w[, 2]) tensors."""

    prob: torch.Tensor
    box: torch.Tensor
    alpha: torch.Tensor | None
    logit: torch.Tensor | None

    @staticmethod
    def of(out: DetectorOutput) -> "StreamMaps":
        return StreamMaps(out.prob, out.box, out.alpha, out.logit)

    @property
    def vacuity(self) -> torch.Tensor:
        if self.alpha is None:
            raise ValueError("vacuity needs an evidential detector's alpha maps (these are a sigmoid detector's)")
        return 2.0 / self.alpha.sum(-1)


@torch.no_grad()
def run_model(model: torch.nn.Module, x: torch.Tensor | tuple[torch.Tensor, torch.Tensor],
              batch: int = 8) -> StreamMaps:
    """Evaluate a frozen detector over a sequence in batches of ``batch`` frames."""
    outs = []
    n = (x[0] if isinstance(x, tuple) else x).shape[0]
    for i in range(0, n, batch):
        if isinstance(x, tuple):
            outs.append(model(x[0][i:i + batch], x[1][i:i + batch]))
        else:
            outs.append(model(x[i:i + batch]))
    cat = lambda name: None if getattr(outs[0], name) is None else torch.cat([getattr(o, name) for o in outs])  # noqa: E731
    return StreamMaps(cat("prob"), cat("box"), cat("alpha"), cat("logit"))


def _frames(prob: torch.Tensor, box: torch.Tensor, unc: torch.Tensor, floor: float, k: int,
            extra: dict[str, torch.Tensor] | None = None) -> tuple[list[FrameDetections], list[dict]]:
    decoded = decode_peaks(prob, box, floor, k, {"unc": unc, **(extra or {})})
    return [FrameDetections(d["boxes"], d["scores"], d["unc"]) for d in decoded], decoded


def single_stream(maps: StreamMaps, floor: float, k: int) -> tuple[list[FrameDetections], list[dict]]:
    """(a)/(b)/(c): one stream's peaks; uncertainty = vacuity (evidential) or 1 - p (sigmoid)."""
    if maps.alpha is not None:
        extra = {"alpha_t": maps.alpha[..., 0], "alpha_b": maps.alpha[..., 1]}
        return _frames(maps.prob, maps.box, maps.vacuity, floor, k, extra)
    return _frames(maps.prob, maps.box, 1.0 - maps.prob, floor, k, {"logit": maps.logit})


def fuse_maps(rgb: StreamMaps, thermal: StreamMaps, rule: str, available: np.ndarray | None = None
              ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Per-location fusion of two evidential maps; ``available`` (T, 2) bool gates whole frames.

    Returns fused target probability, fused vacuity and DS conflict (zeros for the average), (T, h, w).
    """
    a = torch.stack([rgb.alpha, thermal.alpha]).to(torch.float64)   # (2, T, h, w, 2)
    mask = None
    if available is not None:
        m = torch.as_tensor(np.asarray(available, bool).T)          # (2, T)
        mask = m[:, :, None, None].expand(a.shape[:-1])
    if rule == "average":
        res = average(a, available=mask)
        conflict = torch.zeros_like(res.u)
    elif rule == "ds":
        res = dempster_shafer(a, available=mask)
        conflict = _conflict(res).amax(0)
    else:
        raise ValueError(f"rule must be 'average' or 'ds', got {rule!r}")
    return res.p[..., 0].to(torch.float32), res.u.to(torch.float32), conflict.to(torch.float32)


def fused_registered(rgb: StreamMaps, thermal: StreamMaps, rule: str, floor: float, k: int,
                     available: np.ndarray | None = None) -> tuple[list[FrameDetections], list[dict]]:
    p, u, c = fuse_maps(rgb, thermal, rule, available)
    box = rgb.box
    if available is not None:
        # an RGB stream gated off gives no geometry: take the thermal head's box there
        off = torch.as_tensor(~np.asarray(available, bool)[:, 0])[:, None, None, None]
        box = torch.where(off, thermal.box, rgb.box)
    return _frames(p, box, u, floor, k, {"conflict": c})


def match_peaks(rgb_boxes: np.ndarray, th_boxes: np.ndarray, match_px: float) -> list[tuple[int, int]]:
    """Hungarian matching of RGB and thermal peaks on centre distance, pairs within ``match_px``."""
    if rgb_boxes.shape[0] == 0 or th_boxes.shape[0] == 0:
        return []
    ca = rgb_boxes[:, :2] + rgb_boxes[:, 2:] / 2
    cb = th_boxes[:, :2] + th_boxes[:, 2:] / 2
    d = np.linalg.norm(ca[:, None] - cb[None], axis=2)
    cost = np.where(d <= match_px, d, 1e6)
    rows, cols = linear_sum_assignment(cost)
    return [(int(i), int(j)) for i, j in zip(rows, cols) if cost[i, j] < 1e6]


def fused_matched(rgb: StreamMaps, thermal: StreamMaps, rule: str, floor: float, k: int, match_px: float,
                  available: np.ndarray | None = None) -> tuple[list[FrameDetections], list[dict]]:
    """Box-level fusion for cameras with an offset (see module doc)."""
    _, dr = single_stream(rgb, floor, k)
    _, dt = single_stream(thermal, floor, k)
    frames, decoded = [], []
    for t, (a, b) in enumerate(zip(dr, dt)):
        on = np.ones(2, bool) if available is None else np.asarray(available[t], bool)
        pairs = match_peaks(a["boxes"], b["boxes"], match_px) if on.all() else []
        ia = {i for i, _ in pairs}
        ib = {j for _, j in pairs}
        alphas_r, alphas_t, avail, boxes = [], [], [], []
        for i, j in pairs:
            alphas_r.append([a["alpha_t"][i], a["alpha_b"][i]])
            alphas_t.append([b["alpha_t"][j], b["alpha_b"][j]])
            avail.append([True, True])
            boxes.append(a["boxes"][i])
        if on[0]:
            for i in range(a["boxes"].shape[0]):
                if i not in ia:
                    alphas_r.append([a["alpha_t"][i], a["alpha_b"][i]])
                    alphas_t.append([1.0, 1.0])
                    avail.append([True, False])
                    boxes.append(a["boxes"][i])
        if on[1]:
            for j in range(b["boxes"].shape[0]):
                if j not in ib:
                    alphas_r.append([1.0, 1.0])
                    alphas_t.append([b["alpha_t"][j], b["alpha_b"][j]])
                    avail.append([False, True])
                    boxes.append(b["boxes"][j])
        if not boxes:
            frames.append(FrameDetections.empty())
            decoded.append({"boxes": np.zeros((0, 4)), "scores": np.zeros(0), "unc": np.zeros(0),
                            "conflict": np.zeros(0)})
            continue
        al = torch.tensor([alphas_r, alphas_t], dtype=torch.float64)
        m = torch.tensor(avail).T
        res = average(al, available=m) if rule == "average" else dempster_shafer(al, available=m)
        conflict = np.zeros(len(boxes)) if rule == "average" else _conflict(res).amax(0).numpy()
        p, u = res.p[:, 0].numpy(), res.u.numpy()
        order = np.argsort(-p, kind="stable")[:k]
        keep = order[p[order] >= floor]
        fb = np.asarray(boxes, np.float64)[keep]
        frames.append(FrameDetections(fb, p[keep], u[keep]))
        decoded.append({"boxes": fb, "scores": p[keep], "unc": u[keep], "conflict": conflict[keep]})
    return frames, decoded


def frame_vacuity(maps: StreamMaps) -> np.ndarray:
    """Per-frame stream uncertainty for the gate: vacuity at the stream's most probable location, (T,)."""
    t = maps.prob.shape[0]
    flat = maps.prob.reshape(t, -1).argmax(1)
    return maps.vacuity.reshape(t, -1)[torch.arange(t), flat].numpy().astype(np.float64)


def gate_mask(u_rgb: np.ndarray, u_th: np.ndarray, tau_high: float, tau_low: float,
              n: int) -> tuple[np.ndarray, np.ndarray]:
    """Offline window-form hysteresis gate (evids.gating) over one sequence; returns (fused mask
    (T, 2), evaluated mask (T, 2)). At least one stream is fused at every frame."""
    from evids.gating import GateParams, HysteresisGate

    gate = HysteresisGate(2, GateParams(tau_high=tau_high, tau_low=tau_low, n=n, mode="window"))
    fused, evaluated = [], []
    for ur, ut in zip(u_rgb, u_th):
        ev = gate.plan()
        fu = gate.update([float(ur), float(ut)])
        fused.append(fu)
        evaluated.append(ev)
    return np.array(fused, bool), np.array(evaluated, bool)
