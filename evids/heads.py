"""Evidential (Dirichlet) classification heads and the quantities derived from alpha.

Conventions follow Sensoy et al. (2018) as used by the EviDS-UAV paper:
``e = softplus(W z)``, ``alpha = e + 1``, ``S = sum(alpha)``, ``p = alpha / S``, ``u = K / S``.
Every helper works on the last dimension of ``alpha`` (shape ``(..., K)``).
"""
from __future__ import annotations

from typing import Literal

import torch
import torch.nn.functional as F
from torch import Tensor, nn

Construction = Literal["canonical", "scaled"]

__all__ = [
    "BaselineHead",
    "Construction",
    "EvidentialHead",
    "belief_masses",
    "check_alpha",
    "dirichlet_strength",
    "evidence",
    "expected_probability",
    "opinion_to_alpha",
    "predictive_entropy",
    "vacuity",
]


def check_alpha(alpha: Tensor, name: str = "alpha", min_classes: int = 1) -> None:
    """Raise ValueError unless ``alpha`` is a floating tensor (..., K) of finite values >= 1.

    ``alpha >= 1`` is required because every alpha here is ``evidence + 1`` with evidence >= 0.
    """
    if not isinstance(alpha, Tensor):
        raise ValueError(f"{name} must be a torch.Tensor, got {type(alpha).__name__}")
    if not alpha.is_floating_point():
        raise ValueError(f"{name} must be a floating-point tensor, got dtype {alpha.dtype}")
    if alpha.dim() < 1 or alpha.shape[-1] < min_classes:
        raise ValueError(
            f"{name} must have shape (..., K) with K >= {min_classes}, got shape {tuple(alpha.shape)}"
        )
    if alpha.numel() == 0:
        return
    values = alpha.detach()
    lo, hi = torch.aminmax(values)
    if bool(lo >= 1.0) and bool(hi < float("inf")):
        return
    if not bool(torch.isfinite(values).all()):
        raise ValueError(f"{name} contains non-finite values (inf/NaN)")
    raise ValueError(f"{name} must be >= 1 everywhere (alpha = evidence + 1), got min {float(lo)!r}")


def _check_construction(construction: str) -> None:
    if construction not in ("canonical", "scaled"):
        raise ValueError(f"construction must be 'canonical' or 'scaled', got {construction!r}")


class EvidentialHead(nn.Module):
    """Linear layer + softplus giving non-negative evidence; ``forward`` returns ``alpha = e + 1``.

    ``num_classes = 1`` is rejected: with one class the EDL loss is identically zero and the DS
    conflict vanishes. Single-class detection needs K = 2 with a learned background output.
    """

    def __init__(self, in_features: int, num_classes: int, bias: bool = True) -> None:
        super().__init__()
        if not isinstance(in_features, int) or in_features < 1:
            raise ValueError(f"in_features must be a positive int, got {in_features!r}")
        if num_classes == 1:
            raise ValueError(
                "num_classes=1 is degenerate for an evidential head: the EDL loss is identically zero "
                "and the DS conflict is always 0. Use num_classes=2 with a learned background output "
                "(alpha = [alpha_target, alpha_background]), i.e. EvidentialHead(in_features, 2)."
            )
        if not isinstance(num_classes, int) or num_classes < 2:
            raise ValueError(f"num_classes must be an int >= 2, got {num_classes!r}")
        self.in_features = in_features
        self.num_classes = num_classes
        self.linear = nn.Linear(in_features, num_classes, bias=bias)

    def forward(self, z: Tensor) -> Tensor:
        if z.shape[-1] != self.in_features:
            raise ValueError(f"z must have last dimension {self.in_features}, got shape {tuple(z.shape)}")
        return F.softplus(self.linear(z)) + 1.0


class BaselineHead(nn.Module):
    """Linear head returning logits; ``probabilities`` applies softmax (K >= 2) or sigmoid (K = 1).

    This is the non-evidential comparator: a sigmoid head with one output per binary task, or a
    softmax head over K classes.
    """

    def __init__(
        self, in_features: int, num_classes: int, activation: Literal["softmax", "sigmoid"] = "softmax"
    ) -> None:
        super().__init__()
        if not isinstance(in_features, int) or in_features < 1:
            raise ValueError(f"in_features must be a positive int, got {in_features!r}")
        if not isinstance(num_classes, int) or num_classes < 1:
            raise ValueError(f"num_classes must be a positive int, got {num_classes!r}")
        if activation not in ("softmax", "sigmoid"):
            raise ValueError(f"activation must be 'softmax' or 'sigmoid', got {activation!r}")
        if activation == "softmax" and num_classes < 2:
            raise ValueError("activation='softmax' needs num_classes >= 2; use activation='sigmoid' for 1 output")
        self.in_features = in_features
        self.num_classes = num_classes
        self.activation = activation
        self.linear = nn.Linear(in_features, num_classes)

    def forward(self, z: Tensor) -> Tensor:
        if z.shape[-1] != self.in_features:
            raise ValueError(f"z must have last dimension {self.in_features}, got shape {tuple(z.shape)}")
        return self.linear(z)

    def probabilities(self, logits: Tensor) -> Tensor:
        """Class probabilities from logits (softmax over the last dim, or elementwise sigmoid)."""
        if self.activation == "softmax":
            return torch.softmax(logits, dim=-1)
        return torch.sigmoid(logits)


def evidence(alpha: Tensor) -> Tensor:
    """Evidence ``e = alpha - 1``."""
    check_alpha(alpha)
    return alpha - 1.0


def dirichlet_strength(alpha: Tensor) -> Tensor:
    """Dirichlet strength ``S = sum_k alpha_k`` (shape ``(...)``)."""
    check_alpha(alpha)
    return alpha.sum(dim=-1)


def expected_probability(alpha: Tensor) -> Tensor:
    """Expected class probabilities ``p = alpha / S`` (the Dirichlet mean)."""
    check_alpha(alpha)
    return alpha / alpha.sum(dim=-1, keepdim=True)


def vacuity(alpha: Tensor) -> Tensor:
    """Vacuity (uncertainty mass) ``u = K / S`` in (0, 1]."""
    check_alpha(alpha)
    return alpha.shape[-1] / alpha.sum(dim=-1)


def belief_masses(alpha: Tensor, construction: Construction = "canonical") -> tuple[Tensor, Tensor]:
    """Subjective-logic opinion ``(b, u)`` with ``sum(b) + u = 1``.

    ``"canonical"``: ``b = e / S`` (Sensoy et al.; equals ``p - u/K``).
    ``"scaled"``: ``b = p (1 - u)`` (the alternative valid construction).
    """
    check_alpha(alpha)
    _check_construction(construction)
    s = alpha.sum(dim=-1, keepdim=True)
    u = alpha.shape[-1] / s
    if construction == "canonical":
        b = (alpha - 1.0) / s
    else:
        b = (alpha / s) * (1.0 - u)
    return b, u.squeeze(-1)


def opinion_to_alpha(b: Tensor, u: Tensor, construction: Construction = "canonical") -> tuple[Tensor, Tensor]:
    """Invert :func:`belief_masses`: return ``(alpha, p)`` for an opinion ``(b, u)``.

    ``S = K / u``; canonical: ``alpha = b S + 1``; scaled: ``p = b / (1 - u)`` (uniform when the
    opinion is vacuous) and ``alpha = p S``. ``u`` is clamped to the smallest normal float so the
    strength stays finite.
    """
    _check_construction(construction)
    k = b.shape[-1]
    tiny = torch.finfo(b.dtype).tiny
    u_c = u.clamp(min=tiny, max=1.0).unsqueeze(-1)
    s = k / u_c
    if construction == "canonical":
        alpha = b * s + 1.0
        p = alpha / alpha.sum(dim=-1, keepdim=True)
    else:
        mass = b.sum(dim=-1, keepdim=True)
        safe = mass > tiny
        p = torch.where(safe, b / torch.where(safe, mass, torch.ones_like(mass)), torch.full_like(b, 1.0 / k))
        alpha = p * s
    return alpha, p


def predictive_entropy(probs: Tensor, normalise: bool = False) -> Tensor:
    """Shannon entropy (nats) of class probabilities over the last dim; ``0 log 0 = 0``.

    With ``normalise=True`` the entropy is divided by ``log K`` so it lies in [0, 1].
    Pass ``expected_probability(alpha)`` for evidential models (not softmax of the evidence).
    """
    if not isinstance(probs, Tensor) or not probs.is_floating_point() or probs.dim() < 1:
        raise ValueError("probs must be a floating tensor of shape (..., K)")
    k = probs.shape[-1]
    if k < 2:
        raise ValueError(f"probs must have K >= 2 classes on the last dim, got shape {tuple(probs.shape)}")
    plogp = torch.where(probs > 0, probs * torch.log(probs.clamp(min=torch.finfo(probs.dtype).tiny)), 0.0)
    h = -plogp.sum(dim=-1)
    if normalise:
        h = h / torch.log(torch.tensor(float(k), dtype=probs.dtype))
    return h
