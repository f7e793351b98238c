"""Clip-clustered bootstrap: resample clips (clusters) with replacement and keep every row of every
drawn clip, so a clip drawn twice contributes its rows twice. (Masking rows with ``isin`` on the
drawn clip ids silently turns this into a subsample without replacement.)"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from evids.metrics._arrays import as_numpy

__all__ = ["BootstrapResult", "clustered_bootstrap", "clustered_resample", "paired_bootstrap"]


@dataclass(frozen=True)
class BootstrapResult:
    """``estimate`` on the full data, percentile ``ci_low``/``ci_high`` at ``confidence``, the
    bootstrap ``samples``, and a two-sided ``p_value`` for H0: statistic = 0 (meaningful for a
    paired difference): ``min(1, 2 min(P*(stat <= 0), P*(stat >= 0)))``."""

    estimate: float
    ci_low: float
    ci_high: float
    p_value: float
    samples: np.ndarray
    confidence: float
    n_clusters: int


def _rng(rng: np.random.Generator | int) -> np.random.Generator:
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        return np.random.default_rng(int(rng))
    raise ValueError(f"rng must be a numpy Generator or an int seed, got {type(rng).__name__}")


def _cluster_rows(clusters: Any) -> tuple[np.ndarray, list[np.ndarray]]:
    c = as_numpy(clusters, "clusters")
    if c.ndim != 1 or c.size == 0:
        raise ValueError(f"clusters must be a non-empty 1-D array of clip ids, got shape {c.shape}")
    labels, inverse = np.unique(c, return_inverse=True)
    order = np.argsort(inverse, kind="stable")
    bounds = np.cumsum(np.bincount(inverse, minlength=labels.size))[:-1]
    return labels, np.split(order, bounds)


def clustered_resample(clusters: Any, draw: Any) -> np.ndarray:
    """Row indices for a draw of clip ids (with repeats): the rows of each drawn clip, in draw
    order, repeated as often as the clip was drawn."""
    labels, rows = _cluster_rows(clusters)
    d = as_numpy(draw, "draw")
    pos = np.searchsorted(labels, d)
    if d.ndim != 1 or np.any(pos >= labels.size) or np.any(labels[np.minimum(pos, labels.size - 1)] != d):
        raise ValueError("draw must be a 1-D array of clip ids that occur in clusters")
    return np.concatenate([rows[i] for i in pos]) if pos.size else np.zeros(0, dtype=np.int64)


def clustered_bootstrap(
    statistic: Callable[..., float],
    *arrays: Any,
    clusters: Any,
    rng: np.random.Generator | int,
    n_resamples: int = 2000,
    confidence: float = 0.95,
) -> BootstrapResult:
    """Bootstrap ``statistic(*arrays)`` over clips.

    Each resample draws ``n_clusters`` clip positions with
    ``rng.integers(0, n_clusters, size=(n_resamples, n_clusters))`` (clips sorted by id) and
    evaluates the statistic on the concatenated rows of the drawn clips. ``rng`` is required: a
    ``numpy.random.Generator`` or an int seed.
    """
    gen = _rng(rng)
    if not isinstance(n_resamples, (int, np.integer)) or n_resamples < 1:
        raise ValueError(f"n_resamples must be a positive int, got {n_resamples!r}")
    if not isinstance(confidence, float) or not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be a float in (0, 1), got {confidence!r}")
    if not arrays:
        raise ValueError("clustered_bootstrap needs at least one data array")
    data = [as_numpy(a, f"arrays[{i}]") for i, a in enumerate(arrays)]
    labels, rows = _cluster_rows(clusters)
    n = sum(r.size for r in rows)
    for i, a in enumerate(data):
        if a.shape[:1] != (n,):
            raise ValueError(f"arrays[{i}] must have {n} rows (one per clusters entry), got shape {a.shape}")
    estimate = float(statistic(*data))
    draws = gen.integers(0, labels.size, size=(int(n_resamples), labels.size))
    samples = np.empty(int(n_resamples), dtype=np.float64)
    for b in range(int(n_resamples)):
        idx = np.concatenate([rows[i] for i in draws[b]])
        samples[b] = float(statistic(*[a[idx] for a in data]))
    finite = samples[np.isfinite(samples)]
    alpha = (1.0 - confidence) / 2.0
    if finite.size:
        lo, hi = np.quantile(finite, [alpha, 1.0 - alpha])
        p = min(1.0, 2.0 * float(min(np.mean(finite <= 0.0), np.mean(finite >= 0.0))))
    else:
        lo = hi = p = float("nan")
    return BootstrapResult(estimate, float(lo), float(hi), float(p), samples, confidence, int(labels.size))


def paired_bootstrap(
    metric: Callable[..., float],
    labels: Any,
    outputs_a: Any,
    outputs_b: Any,
    clusters: Any,
    rng: np.random.Generator | int,
    n_resamples: int = 2000,
    confidence: float = 0.95,
) -> BootstrapResult:
    """Paired clip-level comparison: bootstrap ``metric(outputs_a, labels) - metric(outputs_b,
    labels)`` with both systems evaluated on the same resampled rows. The CI and ``p_value`` refer
    to the difference (positive = A better for a higher-is-better metric)."""
    return clustered_bootstrap(
        lambda y, a, b: metric(a, y) - metric(b, y),
        labels,
        outputs_a,
        outputs_b,
        clusters=clusters,
        rng=rng,
        n_resamples=n_resamples,
        confidence=confidence,
    )
