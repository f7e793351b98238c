"""Classification metrics: accuracy, macro-F1, NLL, Brier, UAUC and temperature scaling."""
from __future__ import annotations

from typing import Any

import numpy as np
from scipy import optimize, special, stats

from evids.metrics._arrays import as_numpy, bool_1d, labels_1d, probs_2d

__all__ = ["accuracy", "apply_temperature", "brier", "fit_temperature", "macro_f1", "nll", "uauc"]


def _preds(preds_or_probs: Any, name: str = "preds") -> np.ndarray:
    a = as_numpy(preds_or_probs, name)
    if a.ndim == 2:
        return probs_2d(a, name).argmax(axis=1)
    if a.ndim == 1 and a.size and np.issubdtype(a.dtype, np.floating) and not np.all(np.mod(a, 1) == 0):
        raise ValueError(f"{name}: 1-D input must be integer class predictions; pass (N, K) probabilities instead")
    if a.ndim != 1:
        raise ValueError(f"{name} must be class predictions (N,) or probabilities (N, K), got shape {a.shape}")
    return a.astype(np.int64)


def accuracy(preds_or_probs: Any, labels: Any) -> float:
    """Fraction of correct predictions; probabilities (N, K) are reduced by argmax."""
    p = _preds(preds_or_probs)
    y = labels_1d(labels, p.shape[0])
    if p.size == 0:
        raise ValueError("accuracy needs at least one sample")
    return float((p == y).mean())


def macro_f1(preds_or_probs: Any, labels: Any, num_classes: int | None = None) -> float:
    """Unweighted mean of per-class F1 over ``num_classes`` classes (default: classes present in
    labels or predictions). A class with no true and no predicted samples has F1 = 0 only if it
    is listed explicitly via ``num_classes``, matching scikit-learn's ``zero_division=0``."""
    p = _preds(preds_or_probs)
    y = labels_1d(labels, p.shape[0])
    if p.size == 0:
        raise ValueError("macro_f1 needs at least one sample")
    classes = np.arange(num_classes) if num_classes is not None else np.union1d(y, p)
    f1s = []
    for c in classes:
        tp = np.sum((p == c) & (y == c))
        fp = np.sum((p == c) & (y != c))
        fn = np.sum((p != c) & (y == c))
        denom = 2 * tp + fp + fn
        f1s.append(2 * tp / denom if denom else 0.0)
    return float(np.mean(f1s))


def nll(probs: Any, labels: Any, eps: float = 1e-12) -> float:
    """Mean negative log-likelihood ``-log p[y]`` (probabilities clipped at ``eps``)."""
    p = probs_2d(probs)
    y = labels_1d(labels, p.shape[0], p.shape[1])
    if p.shape[0] == 0:
        raise ValueError("nll needs at least one sample")
    return float(-np.log(np.clip(p[np.arange(p.shape[0]), y], eps, 1.0)).mean())


def brier(probs: Any, labels: Any) -> float:
    """Multi-class Brier score ``mean_i sum_k (p_ik - y_ik)^2`` (0 best, 2 worst).

    A 1-D input (binary P(class 1)) is expanded to two columns, so the value is twice the
    one-column binary Brier score ``mean (p - y)^2``."""
    p = probs_2d(probs)
    y = labels_1d(labels, p.shape[0], p.shape[1])
    if p.shape[0] == 0:
        raise ValueError("brier needs at least one sample")
    onehot = np.eye(p.shape[1])[y]
    return float(((p - onehot) ** 2).sum(axis=1).mean())


def uauc(uncertainty: Any, is_error: Any) -> float:
    """AUROC of ``uncertainty`` as a score for ``is_error``: 1.0 = every error is more uncertain
    than every correct prediction, 0.5 = chance, 0.0 = perfectly inverted.

    Rank-based (Mann-Whitney U with average ranks for ties, so a tie counts 1/2). Returns NaN when
    ``is_error`` is all True or all False (AUROC undefined).
    """
    s = as_numpy(uncertainty, "uncertainty").astype(np.float64)
    if s.ndim != 1:
        raise ValueError(f"uncertainty must have shape (N,), got {s.shape}")
    if s.size and not np.isfinite(s).all():
        raise ValueError("uncertainty contains non-finite values")
    e = bool_1d(is_error, s.shape[0], "is_error")
    n_pos = int(e.sum())
    n_neg = int(e.size - n_pos)
    if n_pos == 0 or n_neg == 0:
        return float("nan")
    ranks = stats.rankdata(s)
    u_stat = ranks[e].sum() - n_pos * (n_pos + 1) / 2.0
    return float(u_stat / (n_pos * n_neg))


def apply_temperature(logits: Any, temperature: float) -> np.ndarray:
    """Probabilities from logits scaled by ``1/T``: softmax for (N, K), sigmoid P(class 1) for (N,)."""
    if not isinstance(temperature, (int, float)) or not temperature > 0:
        raise ValueError(f"temperature must be a positive number, got {temperature!r}")
    z = as_numpy(logits, "logits").astype(np.float64) / float(temperature)
    if z.ndim == 1:
        return special.expit(z)
    if z.ndim != 2:
        raise ValueError(f"logits must have shape (N,) or (N, K), got {z.shape}")
    return special.softmax(z, axis=1)


def _nll_at(z: np.ndarray, y: np.ndarray, t: float) -> float:
    if z.ndim == 1:
        s = z / t
        return float(np.mean(np.logaddexp(0.0, s) - y * s))
    s = z / t
    return float(np.mean(special.logsumexp(s, axis=1) - s[np.arange(s.shape[0]), y]))


def fit_temperature(logits: Any, labels: Any, t_min: float = 1e-2, t_max: float = 1e3) -> float:
    """Fit T > 0 minimising the validation NLL of ``softmax(logits / T)`` (or ``sigmoid`` for 1-D
    binary logits), searching ``log T`` in ``[log t_min, log t_max]`` (Guo et al. 2017).

    The NLL is convex in ``1/T``, so a bounded scalar search finds the global minimum; when it
    lies at a bound (e.g. NLL falls monotonically with T) the bound is returned, as the paper's
    E1 control caps T. T only rescales logits, so rankings and argmax decisions are unchanged.
    """
    z = as_numpy(logits, "logits").astype(np.float64)
    if z.ndim not in (1, 2) or z.shape[0] == 0:
        raise ValueError(f"logits must have shape (N,) or (N, K) with N >= 1, got {z.shape}")
    if not np.isfinite(z).all():
        raise ValueError("logits contain non-finite values")
    if not (0 < t_min < t_max):
        raise ValueError(f"need 0 < t_min < t_max, got t_min={t_min!r}, t_max={t_max!r}")
    k = 2 if z.ndim == 1 else z.shape[1]
    y = labels_1d(labels, z.shape[0], k)
    res = optimize.minimize_scalar(
        lambda lt: _nll_at(z, y, float(np.exp(lt))),
        bounds=(np.log(t_min), np.log(t_max)),
        method="bounded",
        options={"xatol": 1e-6},
    )
    return float(np.exp(res.x))


def fit_temperature_flagged(logits: Any, labels: Any, t_min: float = 0.05, t_max: float = 20.0,
                            rel_tol: float = 0.01) -> tuple[float, str | None]:
    """:func:`fit_temperature` plus which bound it hit (``"lower"``/``"upper"``) or None.

    A temperature at a bound is not a calibrated optimum (the NLL still falls beyond it), so
    reports must flag it rather than present the scaled model as calibrated.
    """
    t = fit_temperature(logits, labels, t_min=t_min, t_max=t_max)
    if t <= t_min * (1 + rel_tol):
        return t, "lower"
    if t >= t_max / (1 + rel_tol):
        return t, "upper"
    return t, None


def entropy_from_log_probs(log_probs: Any) -> np.ndarray:
    """Shannon entropy (nats) of (N, K) distributions given as log-probabilities.

    Computed as ``-sum p log p`` with ``p = exp(log p)`` taken from the log domain, so two nearly
    saturated predictions (p = 1 - 1e-20 vs 1 - 1e-30, both exactly 1.0 in float64) keep distinct
    entropies and rank metrics such as UAUC do not tie them.
    """
    lp = as_numpy(log_probs, "log_probs").astype(np.float64)
    if lp.ndim != 2:
        raise ValueError(f"log_probs must have shape (N, K), got {lp.shape}")
    with np.errstate(invalid="ignore"):
        terms = np.where(np.isneginf(lp), 0.0, np.exp(lp) * lp)
    return -terms.sum(axis=1)
