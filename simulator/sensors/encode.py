"""Sensor encodings: linear radiance -> sRGB 8-bit, kelvin -> 16-bit counts and an 8-bit AGC view."""
from __future__ import annotations

from functools import lru_cache

import numpy as np

AGC_MIN_SPAN_K = 2.0


def rgb_to_srgb8(rgb_linear: np.ndarray) -> np.ndarray:
    """Clip exposed linear sRGB to [0, 1], apply the sRGB transfer function, 8 bit.

    The IEC 61966-2-1 curve computed as colour-science's ``cctf_encoding(x, 'sRGB')`` does it (float64,
    the same operations), without its per-call overhead (~5 ms on a 112 px frame); equal to it (tested).
    float32 input (the renderer's) is encoded by a table of that same curve (``_srgb8_tables``), the
    same bytes at about a tenth of the cost; other dtypes by the curve itself."""
    x = np.asarray(rgb_linear)
    if x.dtype != np.float32:
        return _srgb8_curve(x)
    base, last_of_base = _srgb8_tables()
    bits = np.clip(x, 0.0, 1.0).view(np.uint32)          # a new array (NaN stays NaN, as in the curve)
    bucket = np.right_shift(bits, np.uint32(_SRGB8_BUCKET_SHIFT))
    out = base.take(bucket)
    out += bits > last_of_base.take(bucket)
    return out


def _srgb8_curve(rgb_linear: np.ndarray) -> np.ndarray:
    """The sRGB 8-bit encoding computed in float64 (the definition ``rgb_to_srgb8`` equals)."""
    linear = np.clip(rgb_linear, 0.0, 1.0).astype(np.float64)
    encoded = np.where(linear <= 0.0031308, linear * 12.92, 1.055 * np.power(linear, 1 / 2.4) - 0.055)
    return np.rint(encoded * 255.0).astype(np.uint8)


_SRGB8_BUCKET_SHIFT = 16   # buckets of float32 bit patterns sharing their top 16 bits (7 mantissa bits)


@lru_cache(maxsize=1)
def _srgb8_tables() -> tuple[np.ndarray, np.ndarray]:
    """Per bucket of float32 bit patterns: the 8-bit code of its lowest pattern and the last pattern
    with that code (the bucket's last when the code does not step in it), found by bisection on
    ``_srgb8_curve`` itself.

    For non-negative floats the bit pattern orders like the value and the curve is non-decreasing, so a
    bucket's codes are its base up to the step; a bucket spans 1/128 of an octave, less than any two
    codes apart (checked here: a bucket whose codes differ by more than one raises), so it holds at
    most one step. Negative and NaN patterns have one code per bucket (clipped to 0, or the curve's NaN
    cast). Equal to ``_srgb8_curve`` on every float32 in [0, 1] (all 1,065,353,217 compared once, see
    docs/BENCHMARKS.md) and on bucket edges, specials and random values (tested)."""
    n = 1 << (32 - _SRGB8_BUCKET_SHIFT)
    first = np.arange(n, dtype=np.uint32) << np.uint32(_SRGB8_BUCKET_SHIFT)
    last = first | np.uint32((1 << _SRGB8_BUCKET_SHIFT) - 1)

    def code(bits: np.ndarray) -> np.ndarray:
        with np.errstate(invalid="ignore"):               # the NaN patterns' cast to uint8
            return _srgb8_curve(bits.view(np.float32)).astype(np.int32)

    base, top = code(first), code(last)
    nan = (first & np.uint32(0x7F800000)) == np.uint32(0x7F800000)      # exponent all ones: after the clip, NaN only
    base[nan] = top[nan]
    steps = np.flatnonzero(~nan & (top != base))
    if np.any(top[steps] - base[steps] != 1):
        raise RuntimeError("sRGB table: a bucket holds more than one code step")
    lo, hi = first[steps], last[steps]                  # code(lo) = base, code(hi) = base + 1
    for _ in range(_SRGB8_BUCKET_SHIFT):
        mid = lo + (hi - lo) // np.uint32(2)
        up = code(mid) > base[steps]
        hi = np.where(up, mid, hi)
        lo = np.where(up, lo, mid)
    last_of_base = last.copy()
    last_of_base[steps] = lo
    return base.astype(np.uint8), last_of_base


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
