"""Sensor encodings: linear radiance -> sRGB 8-bit, kelvin -> 16-bit counts and an 8-bit AGC view."""
from __future__ import annotations

import numpy as np

AGC_MIN_SPAN_K = 2.0


def rgb_to_srgb8(rgb_linear: np.ndarray) -> np.ndarray:
    """Clip exposed linear sRGB to [0, 1], apply the sRGB transfer function, 8 bit.

    The IEC 61966-2-1 curve computed as colour-science's ``cctf_encoding(x, 'sRGB')`` does it (float64,
    the same operations), without its per-call overhead (~5 ms on a 112 px frame); equal to it (tested)."""
    linear = np.clip(rgb_linear, 0.0, 1.0).astype(np.float64)
    encoded = np.where(linear <= 0.0031308, linear * 12.92, 1.055 * np.power(linear, 1 / 2.4) - 0.055)
    return np.rint(encoded * 255.0).astype(np.uint8)


def kelvin_to_counts(kelvin: np.ndarray, kelvin_per_count: float) -> np.ndarray:
    """Radiometric 16-bit counts: counts = round(T / kelvin_per_count), clipped to uint16."""
    return np.clip(np.rint(kelvin / kelvin_per_count), 0, 65535).astype(np.uint16)


def counts_to_kelvin(counts: np.ndarray, kelvin_per_count: float) -> np.ndarray:
    return counts.astype(np.float32) * np.float32(kelvin_per_count)


def agc_8bit(kelvin: np.ndarray) -> tuple[np.ndarray, tuple[float, float]]:
    """Linear min/max AGC over the frame (span at least AGC_MIN_SPAN_K); returns image and range."""
    lo, hi = float(kelvin.min()), float(kelvin.max())
    if hi - lo < AGC_MIN_SPAN_K:
        mid = 0.5 * (hi + lo)
        lo, hi = mid - AGC_MIN_SPAN_K / 2, mid + AGC_MIN_SPAN_K / 2
    scaled = (kelvin - lo) / (hi - lo) * 255.0
    return np.clip(np.rint(scaled), 0, 255).astype(np.uint8), (lo, hi)
