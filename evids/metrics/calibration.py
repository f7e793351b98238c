"""Expected calibration error, reliability-diagram data and plot.

Bins are ``n_bins`` equal-width intervals ``[i/n, (i+1)/n)`` over the confidence; a confidence of
exactly 1.0 falls in the last bin. (torchmetrics puts exactly-1.0 confidences in an extra bin of
their own; the two agree whenever no confidence equals 1.0.)
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evids.metrics._arrays import as_numpy, bool_1d, labels_1d, probs_2d

__all__ = ["ReliabilityData", "detection_ece", "ece", "plot_reliability", "reliability_diagram"]


@dataclass(frozen=True)
class ReliabilityData:
    """Per-bin statistics: ``edges`` (n_bins + 1), ``confidence``/``accuracy`` (NaN for empty bins),
    ``count`` per bin, and the ``ece`` they imply."""

    edges: np.ndarray
    confidence: np.ndarray
    accuracy: np.ndarray
    count: np.ndarray
    ece: float


def _check_bins(n_bins: int) -> None:
    if not isinstance(n_bins, (int, np.integer)) or isinstance(n_bins, bool) or n_bins < 1:
        raise ValueError(f"n_bins must be an int >= 1, got {n_bins!r}")


def _binned(conf: np.ndarray, correct: np.ndarray, n_bins: int) -> ReliabilityData:
    _check_bins(n_bins)
    if conf.size == 0:
        raise ValueError("calibration error needs at least one sample")
    edges = np.linspace(0.0, 1.0, n_bins + 1)
    idx = np.clip(np.searchsorted(edges, conf, side="right") - 1, 0, n_bins - 1)
    count = np.bincount(idx, minlength=n_bins).astype(np.float64)
    conf_sum = np.bincount(idx, weights=conf, minlength=n_bins)
    acc_sum = np.bincount(idx, weights=correct.astype(np.float64), minlength=n_bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        conf_bin = np.where(count > 0, conf_sum / count, np.nan)
        acc_bin = np.where(count > 0, acc_sum / count, np.nan)
    gap = np.where(count > 0, np.abs(acc_bin - conf_bin), 0.0)
    value = float((gap * count).sum() / count.sum())
    return ReliabilityData(edges, conf_bin, acc_bin, count.astype(np.int64), value)


def reliability_diagram(probs: Any, labels: Any, n_bins: int = 15) -> ReliabilityData:
    """Top-label reliability data: confidence = max_k p_k, correct = argmax == label.

    ``probs`` is (N, K) or a 1-D P(class 1) (expanded to [1 - p, p]). For evidential models pass
    ``p = alpha / S``, not a softmax of the evidence.
    """
    p = probs_2d(probs)
    y = labels_1d(labels, p.shape[0], p.shape[1])
    return _binned(p.max(axis=1), p.argmax(axis=1) == y, n_bins)


def ece(probs: Any, labels: Any, n_bins: int = 15) -> float:
    """Top-label expected calibration error, ``sum_b (n_b / N) |acc_b - conf_b|`` (L1, equal width)."""
    return reliability_diagram(probs, labels, n_bins).ece


def detection_ece(scores: Any, is_tp: Any, n_bins: int = 15) -> float:
    """Detection-level ECE: confidence = detection score, "correct" = matched to a ground truth
    (see :func:`evids.metrics.match_detections`). Same binning as :func:`ece`."""
    s = as_numpy(scores, "scores").astype(np.float64)
    if s.ndim != 1:
        raise ValueError(f"scores must have shape (N,), got {s.shape}")
    if s.size and (not np.isfinite(s).all() or s.min() < 0.0 or s.max() > 1.0):
        raise ValueError("scores must be finite values in [0, 1]")
    tp = bool_1d(is_tp, s.shape[0], "is_tp")
    return _binned(s, tp, n_bins).ece


def plot_reliability(
    data: ReliabilityData,
    path: str | Path | None = None,
    title: str | None = None,
    ax: Any = None,
) -> Any:
    """Draw a reliability diagram (bars of per-bin accuracy, the diagonal, and a count histogram).

    Uses an Agg-canvas ``Figure`` directly (no pyplot, no global backend change). Draws into ``ax``
    when given, else creates a figure; saves to ``path`` when given. Returns the figure.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if not isinstance(data, ReliabilityData):
        raise ValueError(f"data must be a ReliabilityData from reliability_diagram(), got {type(data).__name__}")
    if ax is None:
        fig = Figure(figsize=(4.0, 4.0))
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(1, 1, 1)
    else:
        fig = ax.figure
    left = data.edges[:-1]
    width = np.diff(data.edges)
    filled = data.count > 0
    ax.bar(left[filled], data.accuracy[filled], width=width[filled], align="edge",
           edgecolor="black", linewidth=0.5, label="accuracy")
    ax.bar(left[filled], (data.confidence - data.accuracy)[filled], bottom=data.accuracy[filled],
           width=width[filled], align="edge", color="tab:red", alpha=0.3, label="gap")
    ax.plot([0, 1], [0, 1], "k--", linewidth=1)
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_xlabel("confidence")
    ax.set_ylabel("accuracy")
    ax.set_title(title if title is not None else f"ECE = {data.ece:.4f} ({len(width)} bins)")
    ax.legend(loc="upper left")
    if path is not None:
        fig.savefig(str(path), dpi=120, bbox_inches="tight")
    return fig
