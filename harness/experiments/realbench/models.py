"""Per-sensor classifiers with the softmax baseline or the evidential (Dirichlet) head.

The crop model is the sim-to-real crop CNN (``sim2real.classify._net``) with its last linear layer
either kept (softmax baseline, class-balanced cross-entropy) or replaced by ``evids.heads.EvidentialHead``
(EDL loss of ``evids.losses``, KL annealed over the first half of training). The audio model is a
small log-mel CNN with the same two heads (drone vs not-drone, K = 2). Training runs a fixed number of
optimiser steps (no early stopping: nothing is chosen on held-out data), deterministic per seed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

HEADS = ("softmax", "evidential")


@dataclass
class Scores:
    """Model outputs on a test set: class probabilities (n, K) and, for the evidential head, the
    vacuity K / S (n,)."""

    probs: np.ndarray
    vacuity: np.ndarray | None


def _with_head(body_and_linear, head: str, n_classes: int):
    """Keep the final nn.Linear (softmax) or swap it for an EvidentialHead of the same input size."""
    from torch import nn

    from evids.heads import EvidentialHead

    layers = list(body_and_linear)
    last = layers[-1]
    if not isinstance(last, nn.Linear):
        raise TypeError("the network must end with nn.Linear")
    if head == "softmax":
        return body_and_linear
    if head != "evidential":
        raise ValueError(f"head must be one of {HEADS}, got {head!r}")
    return nn.Sequential(*layers[:-1], EvidentialHead(last.in_features, n_classes))


def crop_net(in_channels: int, n_classes: int, head: str):
    """The sim-to-real crop CNN with the chosen head."""
    from harness.experiments.sim2real.classify import _net

    return _with_head(_net(in_channels, n_classes), head, n_classes)


def audio_net(head: str):
    """Log-mel window CNN (1 x mels x frames in), two outputs (not-drone, drone)."""
    from torch import nn

    return _with_head(nn.Sequential(
        nn.Conv2d(1, 16, 3, padding=1), nn.BatchNorm2d(16), nn.ReLU(), nn.MaxPool2d(2),
        nn.Conv2d(16, 32, 3, padding=1), nn.BatchNorm2d(32), nn.ReLU(), nn.MaxPool2d(2),
        nn.Conv2d(32, 32, 3, padding=1), nn.BatchNorm2d(32), nn.ReLU(), nn.AdaptiveAvgPool2d(1),
        nn.Flatten(), nn.Dropout(0.3), nn.Linear(32, 2)), head, 2)


def class_balanced_weights(y: np.ndarray, n_classes: int) -> np.ndarray:
    """Per-sample weights, each present class's total equal; mean 1."""
    counts = np.bincount(y, minlength=n_classes).astype(np.float64)
    per_class = np.where(counts > 0, counts.sum() / np.maximum(counts, 1) / max(1, (counts > 0).sum()), 0.0)
    return per_class[y]


def train(net, x: np.ndarray, y: np.ndarray, weights: np.ndarray, *, head: str, n_classes: int, seed: int,
          steps: int, batch_size: int, learning_rate: float, flips: bool):
    """Adam + one-cycle schedule for ``steps`` steps on weighted mini-batches (drawn with a seeded
    generator); random horizontal flips when ``flips``. EDL: KL weight ramps 0 -> 1 over steps/2."""
    import torch
    import torch.nn.functional as F

    from evids.losses import edl_loss

    torch.manual_seed(seed)
    gen = torch.Generator().manual_seed(seed)
    xt, yt = torch.from_numpy(np.ascontiguousarray(x, np.float32)), torch.from_numpy(y.astype(np.int64))
    wt = torch.from_numpy(weights.astype(np.float32))
    opt = torch.optim.Adam(net.parameters(), lr=learning_rate, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=learning_rate, total_steps=max(1, steps))
    n = len(yt)
    net.train()
    for step in range(steps):
        idx = torch.randint(0, n, (min(batch_size, n),), generator=gen)
        xb = xt[idx]
        if flips:
            flip = torch.rand(len(idx), generator=gen) < 0.5
            xb = torch.where(flip.view(-1, *([1] * (xb.dim() - 1))), xb.flip(-1), xb)
        out = net(xb)
        if head == "evidential":
            loss_rows = edl_loss(out, yt[idx], epoch=float(step), anneal_epochs=max(1.0, steps / 2), reduction="none")
        else:
            loss_rows = F.cross_entropy(out, yt[idx], reduction="none")
        loss = (loss_rows * wt[idx]).sum() / wt[idx].sum().clamp(min=1e-9)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
    net.eval()
    return net


def predict(net, x: np.ndarray, head: str, batch_size: int = 1024) -> Scores:
    """Probabilities (softmax, or the Dirichlet mean alpha / S) and vacuity (evidential only)."""
    import torch

    from evids.heads import expected_probability, vacuity

    probs, vac = [], []
    with torch.no_grad():
        for s in range(0, len(x), batch_size):
            out = net(torch.from_numpy(np.ascontiguousarray(x[s:s + batch_size], np.float32)))
            if head == "evidential":
                probs.append(expected_probability(out).double().numpy())
                vac.append(vacuity(out).double().numpy())
            else:
                probs.append(torch.softmax(out.double(), dim=1).numpy())
    p = np.concatenate(probs) if probs else np.zeros((0, 0))
    return Scores(p, np.concatenate(vac) if vac else None)
