"""Automatic gain as the cameras of the Svanström benchmark do it, computed over the whole frame.

- LWIR: **plateau histogram equalisation** of the radiometric counts, the AGC of FLIR's Tau 2 /
  Boson cores (FLIR application note 102-PS242-100-01 "FLIR Camera Adjustments", 2014: plateau
  value, maximum gain, tail rejection, a linear share, and an IIR filter on the transfer function
  over frames). The histogram is taken on fixed kelvin bins over the whole counts range, each bin
  clipped at the plateau (a fraction of the frame's pixels), so a large uniform area (the sky) gets
  grey levels in proportion to its temperature span rather than to its pixel count; a share
  ``linear_fraction`` of a linear map over the tail-rejected range is mixed in; a scene spanning
  less than ``min_span_k`` is compressed about mid-grey (the maximum gain); the transfer function
  is damped over time, T_n = d T_(n-1) + (1 - d) T_raw. Optionally first a base/detail split, the
  cores' local-contrast step (FLIR's digital detail enhancement acts on the equalised modes): the
  counts' Gaussian low-pass (``base_sigma_px``) is scaled by ``base_gain`` about its frame mean and
  the detail added back, so a slow sky gradient flattens to mid-grey while a hot ground leaves the
  dark halo above the horizon that the real clips show. The Gaussian base also rises around a hot target and
  leaves a dark ring round it (the halo of an unsharp mask); ``base_opening_px`` > 0 takes the base as
  the Gaussian of the counts' grey-scale opening over a disc that wide instead, so hot content narrower
  than the disc (the targets) stays wholly detail with no ring, while the ground and wider clouds still
  form the base: an edge-aware split in the spirit of FLIR's digital detail enhancement, which
  "attenuates high-amplitude signals" rather than cutting round them. Last, an optional gamma on the transfer
  (FLIR's "active contrast enhancement", ACE, same application note: gamma > 1 gives more grey
  levels to the hotter scene content and darkens the cold sky).
- Visible: **auto-exposure** metered over the whole frame (mean linear luminance driven to a key,
  damped in log exposure over frames) and a **camcorder tone curve**: the ITU-R BT.709 opto-
  electronic transfer function with a highlight knee (above ``knee_point`` of the output the slope
  is multiplied by ``knee_slope``; the white clip moves up accordingly), as consumer camcorders do.

Pure numpy; stateful objects keep the previous frame's transfer (frames arrive in order).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

COUNTS_LEVELS = 65536
LUMA_709 = (0.2126, 0.7152, 0.0722)


def plateau_transfer(hist: np.ndarray, plateau_fraction: float, linear_fraction: float, tail_fraction: float,
                     min_span_bins: float) -> np.ndarray:
    """Transfer function (float64 in [0, 1] per bin) of plateau equalisation for a histogram ``hist``
    (pixel count per fixed-width bin). Monotonic non-decreasing in the bin index."""
    n = float(hist.sum())
    cum = np.cumsum(hist)
    tail = tail_fraction * n
    lo = int(np.searchsorted(cum, tail, side="right"))                   # first bin past the cold tail
    hi = int(np.searchsorted(cum, n - tail, side="left"))                # last bin before the hot tail
    hi = max(hi, lo)
    bins = np.arange(hist.size, dtype=np.float64)
    kept = np.zeros(hist.size, dtype=np.float64)
    kept[lo:hi + 1] = np.minimum(hist[lo:hi + 1], max(plateau_fraction * n, 1.0))
    kept_cum = np.cumsum(kept)
    total = kept_cum[-1]
    equalised = (kept_cum - 0.5 * kept) / total if total > 0 else np.full(hist.size, 0.5)
    equalised[:lo] = 0.0
    equalised[hi + 1:] = 1.0
    span = float(hi - lo)
    if span > 0:
        linear = np.clip((bins - lo) / span, 0.0, 1.0)
    else:                                                                # one occupied bin: it sits at mid-grey
        linear = np.where(bins < lo, 0.0, np.where(bins > lo, 1.0, 0.5))
    transfer = linear_fraction * linear + (1.0 - linear_fraction) * equalised
    if span < min_span_bins:                                             # maximum gain: compress about mid-grey
        transfer = 0.5 + (transfer - 0.5) * (span / min_span_bins)
    return transfer


def pin_mean(shown: np.ndarray, hist: np.ndarray, mean_level: float, iterations: int = 40) -> np.ndarray:
    """``shown`` (transfer in [0, 1] per bin) raised to the exponent q in [1/8, 8] whose pixel mean over
    ``hist`` is ``mean_level`` (bisection in log q; the mean falls as q rises)."""
    occupied = hist > 0
    t = np.clip(shown[occupied], 0.0, 1.0)
    w = hist[occupied] / hist[occupied].sum()
    lo, hi = -np.log(8.0), np.log(8.0)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if float(w @ t ** np.exp(mid)) > mean_level:
            lo = mid
        else:
            hi = mid
    return np.clip(shown, 0.0, 1.0) ** np.exp(0.5 * (lo + hi))


@dataclass
class PlateauAgc:
    """Plateau histogram equalisation of uint16 counts -> uint8, with the transfer damped over frames."""

    kelvin_per_count: float
    bin_k: float
    plateau_fraction: float
    linear_fraction: float
    tail_fraction: float
    min_span_k: float
    damping: float
    base_sigma_px: float = 0.0
    base_gain: float = 1.0
    gamma: float = 1.0
    mean_level: float | None = None
    base_opening_px: int = 0
    _transfer: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        self.bin_counts = max(1, round(self.bin_k / self.kelvin_per_count))
        self.n_bins = (COUNTS_LEVELS - 1) // self.bin_counts + 1
        self.min_span_bins = self.min_span_k / (self.bin_counts * self.kelvin_per_count)
        self._disc = None
        if self.base_opening_px > 0:                                     # the opening's element, built once
            import cv2

            size = int(self.base_opening_px)
            self._disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))

    def transfer_of(self, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(bin index of every pixel, undamped transfer per bin) of one frame of counts."""
        binned = counts.ravel() // np.uint16(self.bin_counts)
        hist = np.bincount(binned, minlength=self.n_bins)
        return binned, plateau_transfer(hist, self.plateau_fraction, self.linear_fraction, self.tail_fraction,
                                        self.min_span_bins)

    def local_contrast(self, counts: np.ndarray) -> np.ndarray:
        """Counts with the base (the Gaussian, of the grey opening when ``base_opening_px`` > 0) scaled by
        base_gain about its mean (detail kept); uint16."""
        import cv2

        x = counts.astype(np.float32)
        smooth = x
        if self._disc is not None:                                       # hot content narrower than the disc out
            smooth = cv2.morphologyEx(x, cv2.MORPH_OPEN, self._disc, borderType=cv2.BORDER_REFLECT_101)
        base = cv2.GaussianBlur(smooth, (0, 0), self.base_sigma_px, borderType=cv2.BORDER_REFLECT_101)
        mean = np.float32(base.mean(dtype=np.float64))
        x -= base                                                        # detail
        base -= mean
        base *= np.float32(self.base_gain)
        x += base
        x += mean
        np.rint(x, out=x)
        return np.clip(x, 0, COUNTS_LEVELS - 1, out=x).astype(np.uint16)

    def __call__(self, counts: np.ndarray) -> np.ndarray:
        """The 8-bit view of one frame of counts (the next frame's transfer starts from this one's)."""
        if self.base_sigma_px > 0:
            counts = self.local_contrast(counts)
        binned, raw = self.transfer_of(counts)
        if self._transfer is None or self.damping <= 0:
            self._transfer = raw
        else:
            self._transfer = self.damping * self._transfer + (1.0 - self.damping) * raw
        shown = self._transfer if self.gamma == 1.0 else self._transfer ** self.gamma   # ACE: hot content gets more
        if self.mean_level is not None:
            shown = pin_mean(shown, np.bincount(binned, minlength=self.n_bins), self.mean_level)
        lut = np.rint(shown * 255.0).astype(np.uint8)
        return lut[binned].reshape(counts.shape)


def bt709_knee(value: np.ndarray, knee_point: float, knee_slope: float) -> np.ndarray:
    """Camcorder tone curve: BT.709 OETF V = 1.099 L^0.45 - 0.099 (4.5 L below L = 0.018) of linear
    L (1 = the nominal white), then above V = knee_point the slope times knee_slope; clipped to [0, 1]."""
    v = np.asarray(value, dtype=np.float64)
    v = np.where(v < 0.018, 4.5 * np.maximum(v, 0.0), 1.099 * np.power(np.maximum(v, 0.018), 0.45) - 0.099)
    v = np.where(v > knee_point, knee_point + (v - knee_point) * knee_slope, v)
    return np.clip(v, 0.0, 1.0)


@dataclass
class CamcorderExposure:
    """Whole-frame auto-exposure + BT.709/knee tone curve for linear ADC levels -> 8-bit.

    ``value_per_level``: the linear value (1 = nominal white) of one ADC level at the sensor's own
    exposure and gain; the metered mean linear luminance of each frame is driven to ``key`` by a
    digital exposure factor in [1/max_factor, max_factor], damped in log over frames."""

    value_per_level: float
    levels: int
    key: float
    damping: float
    knee_point: float
    knee_slope: float
    max_factor: float = 8.0
    colour_gain: float | None = None
    _log_factor: float | None = field(default=None, repr=False)
    _work: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)   # colour-gain buffers

    def factor(self, level: np.ndarray) -> float:
        """Update and return the exposure factor from one frame's ADC levels (H, W, 3)."""
        step = 4                                                      # meter on every 4th pixel per axis
        sample = level[::step, ::step].astype(np.float32)
        luma = float(np.tensordot(sample, np.asarray(LUMA_709, np.float32), axes=([2], [0])).mean())
        metered = max(luma * self.value_per_level, 1e-9)
        wanted = float(np.clip(np.log(self.key / metered), -np.log(self.max_factor), np.log(self.max_factor)))
        if self._log_factor is None or self.damping <= 0:
            self._log_factor = wanted
        else:
            self._log_factor = self.damping * self._log_factor + (1.0 - self.damping) * wanted
        return float(np.exp(self._log_factor))

    def __call__(self, level: np.ndarray) -> np.ndarray:
        """8-bit tone-mapped frame of uint16 ADC levels (H, W, 3); with ``colour_gain`` its chroma scaled
        (:func:`scale_chroma`) before the one rounding to 8 bits."""
        scale = self.factor(level) * self.value_per_level
        curve = bt709_knee(np.arange(self.levels + 1) * scale, self.knee_point, self.knee_slope) * 255.0
        if self.colour_gain is None:
            return np.rint(curve).astype(np.uint8).take(level.ravel()).reshape(level.shape)
        if self._work is None or self._work[0].shape != level.shape:   # reused: a fresh 4 MB per frame page-faults
            self._work = (np.empty(level.shape, np.float32), np.empty(level.shape, np.float32))
        tone, out = self._work
        curve.astype(np.float32).take(level, out=tone)
        out = scale_chroma(tone, self.colour_gain, out=out)
        return np.rint(out, out=out).astype(np.uint8)


def scale_chroma(rgb: np.ndarray, gain: float, out: np.ndarray | None = None) -> np.ndarray:
    """Gamma-encoded RGB (H, W, 3, float, 0-255) with its chroma (Cb, Cr: each channel's difference to the
    BT.709 luma Y' = 0.2126 R' + 0.7152 G' + 0.0722 B') multiplied by ``gain``, luma kept, clipped to [0, 255];
    a grey pixel is unchanged. What a camcorder's colour level does to its Y'CbCr before the encoder."""
    import cv2

    luma = np.asarray(LUMA_709, np.float64)
    matrix = gain * np.eye(3) + (1.0 - gain) * np.tile(luma, (3, 1))    # out = gain x rgb + (1 - gain) x Y'
    out = cv2.transform(np.ascontiguousarray(rgb, np.float32), matrix.astype(np.float32), dst=out)
    return np.clip(out, 0.0, 255.0, out=out)
