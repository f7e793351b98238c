"""A plain, seeded torch training loop for one unimodal model.

Deterministic data order (``torch.randperm`` with an explicit ``torch.Generator``), no dropout (so
no hidden global draws during training), validation-loss checkpointing (the best state dict is
kept in memory and restored), early stopping after ``patience`` epochs without improvement, and
KL annealing ``lambda_t = min(1, t / kl_anneal_epochs)`` for evidential heads. The validation loss
of an evidential model uses the full KL weight (lambda = 1) so epochs are comparable.
"""
from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field

import numpy as np
import torch
from pydantic import BaseModel, ConfigDict, Field

from evids.losses import bce_loss, edl_loss
from evids.models.backbones import UnimodalModel


class TrainConfig(BaseModel):
    """Hyper-parameters of the unimodal training loop (all recorded in the run folder)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    epochs: int = Field(default=12, ge=1, le=500)
    batch_size: int = Field(default=32, ge=1, le=4096)
    lr: float = Field(default=3e-3, gt=0.0, le=1.0)
    weight_decay: float = Field(default=1e-4, ge=0.0, le=1.0)
    patience: int = Field(default=4, ge=1, le=500)
    kl_anneal_epochs: float = Field(default=5.0, gt=0.0)


@dataclass
class TrainResult:
    """What training did: per-epoch losses, the chosen epoch and the wall time."""

    train_loss: list[float] = field(default_factory=list)
    val_loss: list[float] = field(default_factory=list)
    best_epoch: int = -1
    best_val_loss: float = float("inf")
    stopped_early: bool = False
    seconds: float = 0.0

    def to_json(self) -> dict:
        return {"train_loss": [round(v, 6) for v in self.train_loss], "val_loss": [round(v, 6) for v in self.val_loss],
                "best_epoch": self.best_epoch, "best_val_loss": round(self.best_val_loss, 6),
                "stopped_early": self.stopped_early, "seconds": round(self.seconds, 3)}


def _loss(model: UnimodalModel, out: torch.Tensor, y: torch.Tensor, epoch: float, anneal: float) -> torch.Tensor:
    if model.head_kind == "sigmoid":
        return bce_loss(out, y.float())
    return edl_loss(out, y, epoch=epoch, anneal_epochs=anneal)


def _batches(x: np.ndarray, idx: torch.Tensor, batch_size: int):
    for i in range(0, len(idx), batch_size):
        sel = idx[i:i + batch_size].numpy()
        yield sel, torch.from_numpy(np.ascontiguousarray(x[sel]))


@torch.no_grad()
def predict(model: UnimodalModel, x: np.ndarray, batch_size: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """(head outputs, embeddings) for every row of ``x`` in order; sigmoid -> (N,), evidential -> (N, 2)."""
    model.eval()
    outs, embs = [], []
    for _, xb in _batches(x, torch.arange(len(x)), batch_size):
        out, z = model(xb)
        outs.append(out.double().numpy())
        embs.append(z.float().numpy())
    if not outs:
        k = () if model.head_kind == "sigmoid" else (2,)
        return np.zeros((0, *k)), np.zeros((0, int(model.backbone.out_features)), np.float32)
    return np.concatenate(outs), np.concatenate(embs)


@torch.no_grad()
def _val_loss(model: UnimodalModel, x: np.ndarray, y: np.ndarray, cfg: TrainConfig) -> float:
    model.eval()
    total, n = 0.0, 0
    yt = torch.from_numpy(y.astype(np.int64))
    for sel, xb in _batches(x, torch.arange(len(x)), 128):
        out, _ = model(xb)
        loss = _loss(model, out, yt[sel], epoch=cfg.kl_anneal_epochs, anneal=cfg.kl_anneal_epochs)
        total += float(loss) * len(sel)
        n += len(sel)
    return total / max(n, 1)


def train_model(model: UnimodalModel, x_train: np.ndarray, y_train: np.ndarray, x_val: np.ndarray,
                y_val: np.ndarray, cfg: TrainConfig, seed: int, progress: bool = False) -> TrainResult:
    """Train in place and restore the best-validation-loss weights; returns the training record."""
    if len(x_train) != len(y_train) or len(x_val) != len(y_val):
        raise ValueError("x and y must have the same number of rows (train and val)")
    if len(x_train) == 0 or len(x_val) == 0:
        raise ValueError("training and validation sets must not be empty")
    t0 = time.perf_counter()
    gen = torch.Generator().manual_seed(int(seed))
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    yt = torch.from_numpy(y_train.astype(np.int64))
    res = TrainResult()
    best_state = copy.deepcopy(model.state_dict())
    since_best = 0
    for epoch in range(cfg.epochs):
        model.train()
        order = torch.randperm(len(x_train), generator=gen)
        total = 0.0
        for sel, xb in _batches(x_train, order, cfg.batch_size):
            out, _ = model(xb)
            loss = _loss(model, out, yt[sel], epoch=epoch + 1, anneal=cfg.kl_anneal_epochs)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            total += float(loss.detach()) * len(sel)
        res.train_loss.append(total / len(x_train))
        vl = _val_loss(model, x_val, y_val, cfg)
        res.val_loss.append(vl)
        if vl < res.best_val_loss:
            res.best_val_loss, res.best_epoch, since_best = vl, epoch, 0
            best_state = copy.deepcopy(model.state_dict())
        else:
            since_best += 1
            if since_best >= cfg.patience:
                res.stopped_early = True
                break
    model.load_state_dict(best_state)
    model.eval()
    res.seconds = time.perf_counter() - t0
    return res
