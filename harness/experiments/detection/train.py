"""Seeded training of the detectors: per stream (RGB, thermal) x head (sigmoid, evidential), and
the feature-fusion baseline. AdamW + one-cycle schedule, a fixed number of steps on random crops
drawn from a numpy Generator; weights initialised inside ``seeded_init`` (caller's RNG untouched)."""
from __future__ import annotations

import time
from typing import Any

import numpy as np
import torch

from evids.models.backbones import HeadKind, seeded_init
from evids.models.detector import CentreDetector, FeatureFusionDetector, detection_loss, encode_targets
from harness.experiments.detection.data import SequenceData, rng, sample_crops

MODEL_IDS = {"rgb_sigmoid": 1, "thermal_sigmoid": 2, "rgb_evidential": 3, "thermal_evidential": 4, "fusion_sigmoid": 5}
#: the single-stream detectors: name -> (input channels, head)
STREAM_MODELS: dict[str, tuple[int, HeadKind]] = {"rgb_sigmoid": (3, "sigmoid"), "thermal_sigmoid": (1, "sigmoid"),
                                                  "rgb_evidential": (3, "evidential"),
                                                  "thermal_evidential": (1, "evidential")}


def build_model(name: str, width: int) -> torch.nn.Module:
    if name == "fusion_sigmoid":
        return FeatureFusionDetector(width)
    if name not in STREAM_MODELS:
        raise ValueError(f"unknown model {name!r}; valid: {sorted(MODEL_IDS)}")
    channels, head = STREAM_MODELS[name]
    return CentreDetector(channels, head, width)


def train_model(name: str, seqs: list[SequenceData], cfg, log=None) -> tuple[torch.nn.Module, dict[str, Any]]:
    """Train model ``name`` (a key of MODEL_IDS) on the training sequences; returns (model, record)."""
    if name not in MODEL_IDS:
        raise ValueError(f"unknown model {name!r}; valid: {sorted(MODEL_IDS)}")
    with seeded_init(int(np.random.SeedSequence([cfg.seed, MODEL_IDS[name]]).generate_state(1)[0])):
        model = build_model(name, cfg.width)  # weight init: the one global-RNG use, isolated by fork_rng
    gen = rng(cfg.seed, 10, MODEL_IDS[name])
    streams = ("rgb", "thermal") if name == "fusion_sigmoid" else (name.split("_")[0],)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=cfg.lr, total_steps=cfg.steps, pct_start=0.15)
    anneal = max(1.0, cfg.anneal_fraction * cfg.steps)
    model.train()
    t0 = time.perf_counter()
    history = []
    for step in range(cfg.steps):
        batch, boxes = sample_crops(seqs, streams, cfg.crop_px, cfg.batch_size, cfg.target_crop_fraction, gen)
        label, reg, _ = encode_targets(boxes, cfg.crop_px, cfg.crop_px)
        out = model(batch["rgb"], batch["thermal"]) if name == "fusion_sigmoid" else model(batch[streams[0]])
        loss, parts = detection_loss(out, label, reg, epoch=float(step), anneal_epochs=anneal)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 10.0)
        opt.step()
        sched.step()
        if step % max(1, cfg.steps // 10) == 0 or step == cfg.steps - 1:
            history.append({"step": step, "loss": float(loss.detach()), **parts})
            if log is not None:
                log(f"  {name} step {step + 1}/{cfg.steps} loss {float(loss.detach()):.3f}")
    model.eval()
    return model, {"name": name, "steps": cfg.steps, "seconds": round(time.perf_counter() - t0, 2), "history": history,
                   "parameters": int(sum(p.numel() for p in model.parameters()))}
