"""EDL training objective (Sensoy et al. 2018) with the annealed KL regulariser, plus BCE/CE baselines.

``L = risk(alpha, y) + lambda_t * KL(Dir(alpha~) || Dir(1))`` with ``alpha~ = y + (1 - y) alpha`` and
``lambda_t = min(1, epoch / anneal_epochs)``. Risks:

- ``"digamma"``: ``sum_k y_k (psi(S) - psi(alpha_k))`` (expected cross-entropy under the Dirichlet),
- ``"log"``: ``sum_k y_k (log S - log alpha_k)`` (type-II maximum likelihood),
- ``"mse"``: ``sum_k (y_k - p_k)^2 + p_k (1 - p_k) / (S + 1)`` (expected squared error).

Reduced-precision inputs are evaluated in float64 and cast back: ``lgamma(S) - sum lgamma(alpha)``
cancels catastrophically in float32 once alpha reaches ~1e4.
"""
from __future__ import annotations

from typing import Literal

import torch
import torch.nn.functional as F
from torch import Tensor

from evids.heads import check_alpha

Kind = Literal["digamma", "log", "mse"]
Reduction = Literal["mean", "sum", "none"]

__all__ = ["annealing_coefficient", "bce_loss", "ce_loss", "dirichlet_kl_uniform", "edl_loss", "one_hot_target"]


def annealing_coefficient(epoch: float, anneal_epochs: float) -> float:
    """``lambda_t = min(1, epoch / anneal_epochs)``."""
    if not isinstance(anneal_epochs, (int, float)) or not anneal_epochs > 0:
        raise ValueError(f"anneal_epochs must be a positive number, got {anneal_epochs!r}")
    if not isinstance(epoch, (int, float)) or not epoch >= 0:
        raise ValueError(f"epoch must be a non-negative number, got {epoch!r}")
    return min(1.0, float(epoch) / float(anneal_epochs))


def one_hot_target(target: Tensor, num_classes: int, dtype: torch.dtype) -> Tensor:
    """Accept class indices ``(...)`` or a one-hot ``(..., K)`` tensor and return one-hot floats."""
    if not isinstance(target, Tensor):
        raise ValueError(f"target must be a torch.Tensor, got {type(target).__name__}")
    if not target.is_floating_point() and target.dtype != torch.bool:
        if target.numel() and (int(target.min()) < 0 or int(target.max()) >= num_classes):
            raise ValueError(
                f"target class indices must lie in [0, {num_classes - 1}], "
                f"got range [{int(target.min())}, {int(target.max())}]"
            )
        return F.one_hot(target.long(), num_classes).to(dtype)
    y = target.to(dtype)
    if y.shape[-1] != num_classes:
        raise ValueError(f"one-hot target must have last dimension {num_classes}, got shape {tuple(y.shape)}")
    if y.numel() and not bool(((y == 0) | (y == 1)).all() and torch.all(y.sum(-1) == 1)):
        raise ValueError("one-hot target must contain only 0/1 with exactly one 1 per row")
    return y


def dirichlet_kl_uniform(alpha: Tensor) -> Tensor:
    """``KL(Dir(alpha) || Dir(1))`` per row; exactly 0 where ``alpha == 1``.

    ``= lgamma(S) - lgamma(K) - sum lgamma(alpha_k) + sum (alpha_k - 1)(psi(alpha_k) - psi(S))``.
    """
    k = alpha.shape[-1]
    s = alpha.sum(dim=-1)
    log_norm = torch.lgamma(s) - torch.lgamma(torch.full_like(s, float(k))) - torch.lgamma(alpha).sum(dim=-1)
    digamma_term = ((alpha - 1.0) * (torch.digamma(alpha) - torch.digamma(s).unsqueeze(-1))).sum(dim=-1)
    return log_norm + digamma_term


def _reduce(x: Tensor, reduction: str) -> Tensor:
    if reduction == "mean":
        return x.mean()
    if reduction == "sum":
        return x.sum()
    return x


def edl_loss(
    alpha: Tensor,
    target: Tensor,
    epoch: float,
    anneal_epochs: float,
    kind: Kind = "digamma",
    reduction: Reduction = "mean",
) -> Tensor:
    """EDL loss of Dirichlet parameters ``alpha`` (..., K) against class indices or one-hot targets.

    ``epoch`` / ``anneal_epochs`` set the KL weight ``min(1, epoch / anneal_epochs)``. K must be >= 2
    (with K = 1 the objective is identically zero: use a learned background class).
    """
    if not isinstance(alpha, Tensor) or alpha.dim() < 1:
        raise ValueError("alpha must be a tensor of shape (..., K)")
    if alpha.shape[-1] < 2:
        raise ValueError(
            f"alpha must have K >= 2 classes, got K={alpha.shape[-1]}: with K=1 the EDL loss is identically 0; "
            "append a learned background output (K=2)"
        )
    check_alpha(alpha)
    if kind not in ("digamma", "log", "mse"):
        raise ValueError(f"kind must be 'digamma', 'log' or 'mse', got {kind!r}")
    if reduction not in ("mean", "sum", "none"):
        raise ValueError(f"reduction must be 'mean', 'sum' or 'none', got {reduction!r}")
    lam = annealing_coefficient(epoch, anneal_epochs)

    out_dtype = alpha.dtype
    work = alpha if alpha.dtype == torch.float64 else alpha.to(torch.float64)
    y = one_hot_target(target, work.shape[-1], work.dtype)
    if y.shape != work.shape:
        raise ValueError(f"target shape {tuple(target.shape)} does not match alpha shape {tuple(alpha.shape)}")

    s = work.sum(dim=-1, keepdim=True)
    if kind == "digamma":
        risk = (y * (torch.digamma(s) - torch.digamma(work))).sum(dim=-1)
    elif kind == "log":
        risk = (y * (torch.log(s) - torch.log(work))).sum(dim=-1)
    else:
        p = work / s
        risk = ((y - p) ** 2 + p * (1.0 - p) / (s + 1.0)).sum(dim=-1)

    if lam > 0.0:
        alpha_tilde = y + (1.0 - y) * work
        loss = risk + lam * dirichlet_kl_uniform(alpha_tilde)
    else:
        loss = risk
    return _reduce(loss, reduction).to(out_dtype)


def bce_loss(logits: Tensor, target: Tensor, reduction: Reduction = "mean") -> Tensor:
    """Binary cross-entropy on sigmoid logits (baseline for the sigmoid heads)."""
    if not isinstance(logits, Tensor) or not logits.is_floating_point():
        raise ValueError("logits must be a floating tensor")
    if target.shape != logits.shape:
        raise ValueError(f"target shape {tuple(target.shape)} must equal logits shape {tuple(logits.shape)}")
    t = target.to(logits.dtype)
    if t.numel() and not bool(((t >= 0) & (t <= 1)).all()):
        raise ValueError("target for bce_loss must lie in [0, 1]")
    if reduction not in ("mean", "sum", "none"):
        raise ValueError(f"reduction must be 'mean', 'sum' or 'none', got {reduction!r}")
    return F.binary_cross_entropy_with_logits(logits, t, reduction=reduction)


def ce_loss(logits: Tensor, target: Tensor, reduction: Reduction = "mean") -> Tensor:
    """Softmax cross-entropy on logits (N, K) against class indices (N,) (baseline)."""
    if not isinstance(logits, Tensor) or not logits.is_floating_point() or logits.dim() != 2:
        raise ValueError("logits must be a floating tensor of shape (N, K)")
    if target.dim() != 1 or target.shape[0] != logits.shape[0] or target.is_floating_point():
        raise ValueError(f"target must be integer class indices of shape ({logits.shape[0]},), got "
                         f"{tuple(target.shape)}")
    if reduction not in ("mean", "sum", "none"):
        raise ValueError(f"reduction must be 'mean', 'sum' or 'none', got {reduction!r}")
    if target.numel() and (int(target.min()) < 0 or int(target.max()) >= logits.shape[1]):
        raise ValueError(f"target class indices must lie in [0, {logits.shape[1] - 1}]")
    return F.cross_entropy(logits, target.long(), reduction=reduction)
