"""Unimodal backbones sized for a 2-core CPU, and :class:`UnimodalModel` = backbone + head.

Inputs (as produced by :mod:`harness.experiments.data`):

- audio: MFCC ``(B, 1, 40, 40)`` float32 (LeNet-like 2-D CNN);
- video: ``(B, 7, 112, 112, 3)`` uint8 RGB; a (2+1)-D CNN whose first op is a 7x7 convolution at
  full resolution (stride 4), so a 3 px target is seen before any downsampling (max-pools after);
- rf: spectrogram ``(B, 112, 112)`` float32 in [0, 1] (pooled 2x, small 2-D CNN).

Heads: ``"sigmoid"`` gives one logit (P(class 1) = sigmoid; class 0 = Drone as in TRIDENT),
``"evidential"`` gives Dirichlet ``alpha`` over K = 2 classes (Drone, Background).
"""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Literal

import torch
from torch import Tensor, nn

from evids.heads import BaselineHead, EvidentialHead
from evids.modalities import MODALITIES as MODALITIES  # re-exported: the table lives in evids.modalities
from evids.modalities import Modality as Modality

HeadKind = Literal["sigmoid", "evidential"]


class AudioLeNet(nn.Module):
    """LeNet-like CNN on a 1x40x40 MFCC; per-sample standardised input."""

    def __init__(self, width: int = 8, out_features: int = 32) -> None:
        super().__init__()
        self.out_features = out_features
        self.net = nn.Sequential(
            nn.Conv2d(1, width, 5, padding=2), nn.ReLU(), nn.MaxPool2d(2),          # 20x20
            nn.Conv2d(width, 2 * width, 5, padding=2), nn.ReLU(), nn.MaxPool2d(2),  # 10x10
            nn.AdaptiveAvgPool2d(4), nn.Flatten(), nn.Linear(2 * width * 16, out_features), nn.ReLU())

    def forward(self, x: Tensor) -> Tensor:
        x = x.float()
        mu = x.mean(dim=(1, 2, 3), keepdim=True)
        sd = x.std(dim=(1, 2, 3), keepdim=True).clamp(min=1e-3)
        return self.net((x - mu) / sd)


class VideoNet(nn.Module):
    """Compact (2+1)-D CNN on a 7-frame RGB segment that keeps a 3-30 px target.

    The first operation is a (pool + 3) x (pool + 3) convolution at the full 112 px resolution with
    stride ``pool`` (7x7 stride 4 by default: neighbouring windows overlap by 3 px, so every 3 px
    patch lies wholly inside one window), so a 3 px drone reaches a learned filter before anything
    is downsampled; later stages max-pool
    (a small dark or bright spot survives a max, not an average) and the embedding is the max over
    space. ``frames`` evenly spaced frames of the 7 are used (temporal cost knob). Each segment's
    mean colour is removed first, so the sky's colour is not a feature.
    """

    def __init__(self, width: int = 8, out_features: int = 32, pool: int = 4, frames: int = 7) -> None:
        super().__init__()
        self.out_features = out_features
        self.pool = pool
        self.frames = frames
        k = pool + 3 if pool > 1 else 3
        self.spatial1 = nn.Conv3d(3, width, (1, k, k), stride=(1, pool, pool), padding=(0, k // 2, k // 2))
        self.temporal1 = nn.Conv3d(width, width, (3, 1, 1), padding=(1, 0, 0))
        self.spatial2 = nn.Conv3d(width, 2 * width, (1, 3, 3), padding=(0, 1, 1))
        self.temporal2 = nn.Conv3d(2 * width, 2 * width, (3, 1, 1), padding=(1, 0, 0))
        self.fc = nn.Linear(2 * width * 2, out_features)

    def forward(self, x: Tensor) -> Tensor:
        # (B, T, H, W, 3) uint8 -> (B, 3, T, H, W) float in [0, 1] at full resolution
        t = x.shape[1]
        if self.frames < t:
            idx = torch.linspace(0, t - 1, self.frames).round().long()
            x = x[:, idx]
        x = x.permute(0, 4, 1, 2, 3).float() / 255.0
        x = x - x.mean(dim=(2, 3, 4), keepdim=True)          # remove the sky's mean colour
        x = torch.relu(self.temporal1(torch.relu(self.spatial1(x))))
        x = nn.functional.max_pool3d(x, (1, 2, 2))
        x = torch.relu(self.temporal2(torch.relu(self.spatial2(x))))
        # max over space keeps a small target; mean and max over time
        x = x.amax(dim=(3, 4))
        x = torch.cat([x.mean(dim=2), x.amax(dim=2)], dim=1)
        return torch.relu(self.fc(x))


class RFNet(nn.Module):
    """Small 2-D CNN on a 112x112 spectrogram (grayscale, or RGB averaged)."""

    def __init__(self, width: int = 8, out_features: int = 32) -> None:
        super().__init__()
        self.out_features = out_features
        self.net = nn.Sequential(
            nn.AvgPool2d(2),                                                          # 56
            nn.Conv2d(1, width, 5, padding=2), nn.ReLU(), nn.MaxPool2d(2),           # 28
            nn.Conv2d(width, 2 * width, 3, padding=1), nn.ReLU(), nn.MaxPool2d(2),   # 14
            nn.AdaptiveMaxPool2d(4), nn.Flatten(), nn.Linear(2 * width * 16, out_features), nn.ReLU())

    def forward(self, x: Tensor) -> Tensor:
        x = x.float()
        if x.dim() == 4 and x.shape[-1] == 3:
            x = x.mean(dim=-1)
        return self.net(x.unsqueeze(1))


def build_backbone(modality: Modality, width: int = 8, out_features: int = 32, video_pool: int = 4,
                   video_frames: int = 7) -> nn.Module:
    """The backbone of one modality."""
    if modality == "audio":
        return AudioLeNet(width, out_features)
    if modality == "video":
        return VideoNet(width, out_features, video_pool, video_frames)
    if modality == "rf":
        return RFNet(width, out_features)
    raise ValueError(f"modality must be one of {MODALITIES}, got {modality!r}")


class UnimodalModel(nn.Module):
    """Backbone + interchangeable head. ``forward`` returns (head output, embedding)."""

    def __init__(self, modality: Modality, head: HeadKind, backbone: nn.Module) -> None:
        super().__init__()
        if head not in ("sigmoid", "evidential"):
            raise ValueError(f"head must be 'sigmoid' or 'evidential', got {head!r}")
        self.modality = modality
        self.head_kind = head
        self.backbone = backbone
        d = int(backbone.out_features)
        self.head = BaselineHead(d, 1, "sigmoid") if head == "sigmoid" else EvidentialHead(d, 2)

    def forward(self, x: Tensor) -> tuple[Tensor, Tensor]:
        z = self.backbone(x)
        out = self.head(z)
        return (out.squeeze(-1) if self.head_kind == "sigmoid" else out), z

    @staticmethod
    def probabilities(out: Tensor, head: HeadKind) -> Tensor:
        """(N, 2) class probabilities from a head output (sigmoid logit -> [1 - s, s]; alpha -> alpha/S)."""
        if head == "sigmoid":
            s = torch.sigmoid(out)
            return torch.stack([1.0 - s, s], dim=-1)
        return out / out.sum(dim=-1, keepdim=True)


@contextmanager
def seeded_init(seed: int) -> Iterator[None]:
    """Run module construction with torch's global RNG seeded, then restore the caller's RNG state.

    ``nn.Module`` constructors draw their initial weights from torch's global generator and accept
    no ``generator=``; this is the one unavoidable global call, isolated with ``fork_rng`` so the
    caller's global state is untouched afterwards.
    """
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(int(seed))
        yield


def build_model(modality: Modality, head: HeadKind, seed: int, width: int = 8, out_features: int = 32,
                video_pool: int = 4, video_frames: int = 7) -> UnimodalModel:
    """A freshly initialised model; the same seed gives the same weights."""
    with seeded_init(seed):
        return UnimodalModel(modality, head, build_backbone(modality, width, out_features, video_pool, video_frames))
