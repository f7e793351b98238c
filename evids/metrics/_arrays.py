"""Input coercion shared by the metric functions (torch or numpy in, float64/int numpy out)."""
from __future__ import annotations

from typing import Any

import numpy as np


def as_numpy(x: Any, name: str) -> np.ndarray:
    """Convert a tensor / array / sequence to a numpy array, raising ValueError naming ``name``."""
    if hasattr(x, "detach"):
        x = x.detach().cpu().numpy()
    try:
        return np.asarray(x)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} cannot be converted to an array: {exc}") from exc


def probs_2d(probs: Any, name: str = "probs") -> np.ndarray:
    """Probabilities as float64 (N, K); a 1-D input is P(class 1) and becomes [1 - p, p]."""
    p = as_numpy(probs, name).astype(np.float64)
    if p.ndim == 1:
        p = np.stack([1.0 - p, p], axis=1)
    if p.ndim != 2 or p.shape[1] < 2:
        raise ValueError(f"{name} must have shape (N, K) with K >= 2 or (N,), got {p.shape}")
    if p.size and (not np.isfinite(p).all() or p.min() < 0.0 or p.max() > 1.0):
        raise ValueError(f"{name} must be finite probabilities in [0, 1]")
    return p


def labels_1d(labels: Any, n: int, num_classes: int | None = None, name: str = "labels") -> np.ndarray:
    """Integer class labels (N,), checked against the expected length and class count."""
    y = as_numpy(labels, name)
    if y.ndim != 1 or y.shape[0] != n:
        raise ValueError(f"{name} must have shape ({n},), got {y.shape}")
    if y.dtype == bool:
        y = y.astype(np.int64)
    if y.size and not np.issubdtype(y.dtype, np.integer):
        if not np.all(np.equal(np.mod(y, 1), 0)):
            raise ValueError(f"{name} must be integer class indices")
        y = y.astype(np.int64)
    y = y.astype(np.int64)
    if y.size and (y.min() < 0 or (num_classes is not None and y.max() >= num_classes)):
        hi = "" if num_classes is None else f", {num_classes - 1}"
        raise ValueError(f"{name} must lie in [0{hi}], got range [{y.min()}, {y.max()}]")
    return y


def bool_1d(x: Any, n: int | None, name: str) -> np.ndarray:
    """A boolean / 0-1 vector."""
    a = as_numpy(x, name)
    if a.ndim != 1 or (n is not None and a.shape[0] != n):
        want = "(N,)" if n is None else f"({n},)"
        raise ValueError(f"{name} must have shape {want}, got {a.shape}")
    if a.dtype != bool:
        if a.size and not np.isin(a, (0, 1)).all():
            raise ValueError(f"{name} must be boolean or 0/1")
        a = a.astype(bool)
    return a
