"""The registry (plain dict name -> class) and the one-line entry point ``apply``."""
from __future__ import annotations

from typing import Any

import numpy as np

from degradations.base import Degradation, make_rng
from degradations.errors import DegradationError

REGISTRY: dict[str, type[Degradation]] = {}


def register(cls: type[Degradation]) -> type[Degradation]:
    """Class decorator: add to REGISTRY under ``cls.name`` (names are unique)."""
    if not cls.name or cls.name in REGISTRY:
        raise DegradationError(f"bad or duplicate degradation name {cls.name!r}")
    REGISTRY[cls.name] = cls
    return cls


def get(name: str) -> type[Degradation]:
    """Class for a registered name; the error lists close names."""
    try:
        return REGISTRY[name]
    except KeyError:
        prefix = name.split(".")[0]
        near = sorted(k for k in REGISTRY if k.startswith(prefix + "."))
        raise DegradationError(
            f"unknown degradation {name!r}; known{' ' + prefix if near else ''}: {near or sorted(REGISTRY)}"
        ) from None


def _to_numpy(x: Any):
    """Return (numpy array, restore) so torch tensors come back as tensors on their device."""
    mod = type(x).__module__
    if mod.startswith("torch"):
        import torch  # lazy: numpy users never pay for it

        if not isinstance(x, torch.Tensor):
            raise DegradationError(f"unsupported input type {type(x).__name__}")
        dev, dt = x.device, x.dtype
        arr = x.detach().cpu().numpy()

        def restore(y: np.ndarray):
            return torch.from_numpy(np.ascontiguousarray(y)).to(device=dev, dtype=dt)
        return arr, restore
    if isinstance(x, np.ndarray):
        return x, lambda y: y
    raise DegradationError(f"input must be a numpy array or torch tensor, got {type(x).__name__}")


def run_one(deg: Degradation, x: np.ndarray, rng: np.random.Generator, meta: dict | None, measure: bool = True):
    """Sample params, apply, update meta and (with ``measure``) measure for one item (numpy). The
    measurement (e.g. the realised SNR) only goes into the info, so callers that drop it skip it."""
    meta = dict(meta or {})
    params = deg.sample_params(rng, meta)
    y = deg.apply(x, params, meta)
    info: dict[str, Any] = {"name": deg.name, "params": params, "meta": deg.update_meta(params, meta, tuple(x.shape))}
    if measure:
        info.update(deg.measure(x, y, params, meta))
    return y, info


def apply(name: str, x: Any, *, seed: int, severity: float | None = None, meta: dict | list | None = None,
          temporal: str | None = None, return_info: bool = False, **params: Any):
    """Degrade ``x`` (numpy or torch; one item or a batch) with registered ``name``.

    ``severity`` is a continuous level in [0, 5] (None = level 3 unless params are given);
    explicit ``params`` override the severity table. A batch (one extra leading axis) gets an
    independent generator per item from ``SeedSequence([seed, crc32(name), item_index])``; a single
    item uses item_index 0, so ``apply(x[None])[0] == apply(x)``. Returns ``x``'s type, dtype and
    device; with ``return_info=True`` returns ``(y, info)`` (info has params, updated meta and
    measured values such as ``realised_snr_db``; for a batch, ``info["items"]`` is a list).
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise DegradationError(f"seed must be a non-negative int, got {seed!r}")
    deg = get(name)(severity, temporal=temporal, **params)
    arr, restore = _to_numpy(x)
    ndims = deg.item_ndims()
    if arr.ndim in ndims:
        y, info = run_one(deg, arr, make_rng(seed, name, 0), meta if isinstance(meta, dict) or meta is None else None,
                          measure=return_info)
        if isinstance(meta, list):
            raise DegradationError("meta: a list of per-item dicts needs a batched input")
        out = restore(y)
        return (out, info) if return_info else out
    if arr.ndim == max(ndims) + 1:
        n = arr.shape[0]
        if isinstance(meta, list) and len(meta) != n:
            raise DegradationError(f"meta: got {len(meta)} per-item dicts for a batch of {n}")
        ys, infos = [], []
        for i in range(n):
            m = meta[i] if isinstance(meta, list) else meta
            y, info = run_one(deg, arr[i], make_rng(seed, name, i), m, measure=return_info)
            ys.append(y)
            infos.append(info)
        out = restore(np.stack(ys))
        return (out, {"name": name, "items": infos}) if return_info else out
    raise DegradationError(
        f"{name}: input has ndim {arr.ndim} (shape {tuple(arr.shape)}); expected one item with ndim "
        f"in {ndims} or a batch with ndim {max(ndims) + 1} for modality {deg.modality!r}")
