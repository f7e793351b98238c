"""Thermal (LWIR) degradations on kelvin frames (H, W) or clips (T, H, W), float32.

Sensor facts used (docs/REFERENCES section 2): uncooled microbolometer NETD 40-50 mK; fixed-pattern
noise as per-column offset/gain; 8-bit output after AGC (linear min/max); a hot object entering the
frame compresses the AGC range. Transforms that emulate the 8-bit view return kelvin again
(dequantised), so every stage keeps the kelvin-in/kelvin-out contract.
"""
from __future__ import annotations

import cv2
import numpy as np

from degradations.base import Degradation, fast_normal
from degradations.errors import DegradationError
from degradations.registry import register
from degradations.video import _Decoy

#: NETD of a typical uncooled microbolometer (K); the crossover criterion uses it.
NETD_K = 0.05


def target_mask(meta: dict, shape: tuple[int, int, int], name: str) -> np.ndarray:
    """Boolean target mask (T, H, W) from meta['mask'] or meta['thermal_mask'] ((H, W) or (T, H, W))."""
    m = meta.get("mask", meta.get("thermal_mask"))
    if m is None:
        raise DegradationError(f"{name}: meta['thermal_mask'] (or meta['mask']) is required")
    m = np.asarray(m).astype(bool)
    T, H, W = shape
    if m.shape == (H, W):
        m = np.broadcast_to(m, (T, H, W))
    if m.shape != (T, H, W):
        raise DegradationError(f"{name}: mask shape {m.shape} does not match frames {(T, H, W)}")
    return m


def ring_masks(mask: np.ndarray, ring_px: int) -> np.ndarray:
    """Local background ring around each frame's target: dilate(mask, ring_px) minus the mask."""
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * ring_px + 1, 2 * ring_px + 1))
    return np.stack([cv2.dilate(f.astype(np.uint8), k).astype(bool) & ~f for f in mask])


def contrast_k(x: np.ndarray, mask: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """Per-frame mean target minus mean ring temperature (NaN where no target)."""
    out = np.full(x.shape[0], np.nan)
    for t in range(x.shape[0]):
        if mask[t].any() and ring[t].any():
            out[t] = float(x[t][mask[t]].mean() - x[t][ring[t]].mean())
    return out


@register
class Crossover(Degradation):
    """Thermal crossover: target pixels move toward the mean of their local background ring by
    ``strength`` (0..1), so the mean contrast becomes (1 - strength) * contrast; at strength 1
    every target pixel equals the ring mean (|contrast| = 0 < NETD)."""
    name = "thermal.crossover"
    modality = "thermal"
    table = {"strength": (0.2, 0.4, 0.6, 0.8, 1.0)}
    identity = {"strength": 0.0}
    extra = {"ring_px": 5}
    random = False

    def check_param(self, key, value):
        super().check_param(key, value)
        if key == "strength" and not 0.0 <= float(value) <= 1.0:
            raise DegradationError(f"{self.name}: strength must be in [0, 1], got {value!r}")

    def _apply(self, x, params, meta):
        mask = target_mask(meta, x.shape, self.name)
        ring = ring_masks(mask, int(params["ring_px"]))
        s = np.float32(params["strength"])
        y = x.copy()
        for t in range(x.shape[0]):
            if mask[t].any() and ring[t].any():
                bg = np.float32(x[t][ring[t]].mean())
                y[t][mask[t]] = x[t][mask[t]] + s * (bg - x[t][mask[t]])
        return y

    def measure(self, x, y, params, meta=None):
        xs = np.asarray(x, np.float64)
        ys = np.asarray(y, np.float64)
        if xs.ndim == 2:
            xs, ys = xs[None], ys[None]
        mask = target_mask(meta or {}, xs.shape, self.name)
        ring = ring_masks(mask, int(params["ring_px"]))
        return {"contrast_k_before": contrast_k(xs, mask, ring).tolist(),
                "contrast_k_after": contrast_k(ys, mask, ring).tolist()}


@register
class NETDNoise(Degradation):
    """Temporal sensor noise: Gaussian with sigma ``netd_k`` kelvin, fresh per frame by default."""
    name = "thermal.netd_noise"
    modality = "thermal"
    table = {"netd_k": (0.05, 0.1, 0.2, 0.35, 0.5)}
    identity = {"netd_k": 0.0}

    def _apply(self, x, params, meta):
        n = fast_normal(self.noise_rng(params), self.field_shape(x.shape, params))
        n *= np.float32(params["netd_k"])
        return x + n


@register
class FixedPattern(Degradation):
    """Fixed-pattern noise, static per camera: y = ref + (x - ref)(1 + g_col + g_row) + o_col + o_row.

    Column gain/offset stds are ``gain_std`` and ``offset_std_k``; rows get half of each. ``ref_k``
    is the non-uniformity-correction reference temperature (gain errors vanish there).
    """
    name = "thermal.fixed_pattern"
    modality = "thermal"
    table = {"gain_std": (0.01, 0.02, 0.04, 0.06, 0.08), "offset_std_k": (0.05, 0.1, 0.2, 0.4, 0.8)}
    identity = {"gain_std": 0.0, "offset_std_k": 0.0}
    extra = {"ref_k": 293.15}
    default_temporal = "static"

    def _apply(self, x, params, meta):
        T, H, W = x.shape
        n = 1 if params["temporal"] == "static" else T
        rng = self.noise_rng(params)
        z = rng.standard_normal((n, 4, max(H, W))).astype(np.float32)
        g = params["gain_std"] * (z[:, 0, None, :W] + 0.5 * z[:, 1, :H, None])
        o = params["offset_std_k"] * (z[:, 2, None, :W] + 0.5 * z[:, 3, :H, None])
        ref = np.float32(params["ref_k"])
        return (ref + (x - ref) * (1.0 + g) + o).astype(np.float32)


@register
class DeadPixels(Degradation):
    """Dead (read the frame minimum) and stuck-hot (frame maximum) pixels, ``fraction`` of the
    array, half each; static positions by default."""
    name = "thermal.dead_pixels"
    modality = "thermal"
    table = {"fraction": (0.0005, 0.001, 0.002, 0.005, 0.01)}
    identity = {"fraction": 0.0}
    default_temporal = "static"

    def _apply(self, x, params, meta):
        u = self.noise_rng(params).random(self.field_shape(x.shape, params), dtype=np.float32)
        f = np.float32(params["fraction"])
        lo = x.min(axis=(1, 2), keepdims=True)
        hi = x.max(axis=(1, 2), keepdims=True)
        y = np.where(u < f / 2, lo, x)
        return np.where((u >= f / 2) & (u < f), hi, y).astype(np.float32)


def agc_view(x: np.ndarray, bits: int, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Linear AGC to 2^bits levels between lo and hi (per frame), returned dequantised in kelvin."""
    levels = np.float32(2**bits - 1)
    span = np.maximum(hi - lo, np.float32(1e-6))
    q = np.round(np.clip((x - lo) / span, 0, 1) * levels)
    return (lo + q / levels * span).astype(np.float32)


@register
class AGCSaturation(Degradation):
    """A hot object (``hot_k``, ~3% of the frame, drawn position) enters; linear min/max AGC to 8
    bits then maps the scene into few levels (range compression), returned as kelvin."""
    name = "thermal.agc_saturation"
    modality = "thermal"
    table = {"hot_k": (340.0, 380.0, 450.0, 550.0, 700.0)}
    identity = {"hot_k": 0.0}
    extra = {"bits": 8, "size_frac": 0.08}
    default_temporal = "static"

    def _sample_extra(self, rng, meta, p):
        p["cx_frac"], p["cy_frac"] = (float(v) for v in rng.random(2))

    def _apply(self, x, params, meta):
        T, H, W = x.shape
        r = max(1, int(params["size_frac"] * min(H, W)))
        spot = np.zeros((H, W), np.uint8)
        cv2.circle(spot, (int(params["cx_frac"] * W), int(params["cy_frac"] * H)), r, 1, -1)
        y = np.where(spot.astype(bool)[None], np.maximum(x, np.float32(params["hot_k"])), x)
        lo = y.min(axis=(1, 2), keepdims=True)
        hi = y.max(axis=(1, 2), keepdims=True)
        return agc_view(y, int(params["bits"]), lo, hi)


@register
class BlurHalo(Degradation):
    """Optics blur (Gaussian ``sigma_px``) plus the dark/bright halo of sharpening in the camera
    pipeline: y = b + halo (b - G_{4 sigma}(x))."""
    name = "thermal.blur_halo"
    modality = "thermal"
    table = {"sigma_px": (0.5, 1.0, 1.5, 2.0, 3.0), "halo": (0.1, 0.2, 0.3, 0.4, 0.5)}
    identity = {"sigma_px": 0.0, "halo": 0.0}
    random = False

    def _apply(self, x, params, meta):
        s = max(float(params["sigma_px"]), 1e-3)
        out = np.empty_like(x)
        for t in range(x.shape[0]):
            b = cv2.GaussianBlur(x[t], (0, 0), s, borderType=cv2.BORDER_REFLECT)
            wide = cv2.GaussianBlur(x[t], (0, 0), 4 * s, borderType=cv2.BORDER_REFLECT)
            out[t] = b + np.float32(params["halo"]) * (b - wide)
        return out


@register
class Quantize8Bit(Degradation):
    """Per-frame linear min/max AGC to ``bits`` bits (8 at level 1 down to 4), returned in kelvin."""
    name = "thermal.quantize_8bit"
    modality = "thermal"
    table = {"bits": (8.0, 7.0, 6.0, 5.0, 4.0)}
    identity = {"bits": 16.0}
    integer_params = ("bits",)
    random = False

    def _apply(self, x, params, meta):
        b = int(params["bits"])
        if not 1 <= b <= 16:
            raise DegradationError(f"{self.name}: bits must be in 1..16, got {b}")
        return agc_view(x, b, x.min(axis=(1, 2), keepdims=True), x.max(axis=(1, 2), keepdims=True))


@register
class ThermalDecoy(_Decoy):
    """Decoy bird in thermal: a warm flapping blob ``contrast_k`` above the local scene."""
    name = "thermal.decoy_bird"
    modality = "thermal"
    extra = {"contrast_k": 3.0}

    def _apply(self, x, params, meta):
        T, H, W = x.shape
        m = self.mask(T, H, W, params, meta)
        return x + np.float32(params["contrast_k"]) * m
