"""Audio degradations on 1-D float waveforms (meta["sample_rate_hz"] where frequency matters).

SNR semantics: ``snr_db`` is relative to the RMS of the WHOLE item (silence included), or to
``meta["signal_rms"]`` when given (e.g. the clip RMS when degrading 0.25 s segments one by one).
The noise realisation is rescaled to exactly the target RMS, so the realised SNR (reported as
``realised_snr_db`` in the info dict, measured from ``y - x``) equals the target to float precision.
A silent item stays silent.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import signal

from degradations.base import Degradation, fast_normal
from degradations.errors import DegradationError
from degradations.registry import register

SNR_TABLE = (20.0, 15.0, 10.0, 5.0, 0.0)


def _sample_rate(meta: dict, name: str) -> float:
    sr = meta.get("sample_rate_hz")
    if sr is None or not (float(sr) > 0):
        raise DegradationError(f"{name}: meta['sample_rate_hz'] must be a positive number, got {sr!r}")
    return float(sr)


def coloured_noise(rng: np.random.Generator, n: int, beta: float) -> np.ndarray:
    """Unit-RMS noise with power spectrum ~ 1/f^beta (0 white, 1 pink, 2 brown), float32. The
    Gaussian draws come from ``fast_normal`` (the package's 16-bit inverse-CDF table: independent
    values, 65536 levels, tails at 4.33 sigma; ~20x cheaper here than a float64 draw and cast)."""
    w = fast_normal(rng, (n,))                                       # a fresh array (take copies)
    if beta != 0.0 and n > 2:
        spec = np.fft.rfft(w)
        f = np.arange(spec.size, dtype=np.float64)
        f[0] = f[1]
        spec *= f ** (-beta / 2.0)
        w = np.fft.irfft(spec, n).astype(np.float32)
        w -= w.mean()
    rms = _rms(w)
    if rms > 0:
        w /= np.float32(rms)
    return w


def _rms(x: np.ndarray) -> float:
    """RMS of a real array, accumulated in float64."""
    return float(np.sqrt(np.einsum("i,i->", x, x, dtype=np.float64) / x.size)) if x.size else 0.0


def signal_rms(x: np.ndarray, meta: dict) -> float:
    """RMS reference for SNR: meta['signal_rms'] if given, else the RMS of the whole item."""
    if meta.get("signal_rms") is not None:
        return float(meta["signal_rms"])
    return _rms(x.ravel())


def add_at_snr(x: np.ndarray, unit_noise: np.ndarray, snr_db: float, ref_rms: float) -> np.ndarray:
    """x + noise scaled so that ref_rms / rms(noise) = 10^(snr_db/20) exactly."""
    sigma = ref_rms / 10.0 ** (snr_db / 20.0)
    out = np.multiply(unit_noise, np.float32(sigma), dtype=np.float32)
    out += x
    return out


class _AudioNoise(Degradation):
    modality = "audio"
    table = {"snr_db": SNR_TABLE}
    identity = {"snr_db": math.inf}
    reports_snr = True
    beta = 0.0

    def _apply(self, x: np.ndarray, params: dict[str, Any], meta: dict) -> np.ndarray:
        noise = coloured_noise(self.noise_rng(params), x.size, self.beta)
        return add_at_snr(x, noise, float(params["snr_db"]), signal_rms(x, meta))


@register
class WhiteNoise(_AudioNoise):
    """Additive white Gaussian noise at ``snr_db``."""
    name = "audio.white_noise"


@register
class PinkNoise(_AudioNoise):
    """Additive pink (1/f, -3.01 dB/octave) noise at ``snr_db``."""
    name = "audio.pink_noise"
    beta = 1.0


@register
class BrownNoise(_AudioNoise):
    """Additive brown (1/f^2) noise at ``snr_db``."""
    name = "audio.brown_noise"
    beta = 2.0


@register
class PresetWhite10dB(_AudioNoise):
    """Published protocol: white noise at 10 dB SNR (whole-segment RMS). Severity only switches it on."""
    name = "audio.preset_white_10db"
    table = {"snr_db": (10.0, 10.0, 10.0, 10.0, 10.0)}


@register
class PresetLibraryDefault(_AudioNoise):
    """audiomentations ``AddGaussianSNR()`` defaults: SNR ~ U(5, 40) dB (uniform in dB), p = 0.5.

    The SNR and the apply/skip coin are drawn in ``sample_params`` (params ``snr_db``, ``applied``).
    """
    name = "audio.preset_library_default"
    table = {}
    identity = {}
    extra = {"min_snr_db": 5.0, "max_snr_db": 40.0, "p": 0.5}

    def _sample_extra(self, rng, meta, p):
        if not p["min_snr_db"] <= p["max_snr_db"]:
            raise DegradationError(f"{self.name}: min_snr_db {p['min_snr_db']} > max_snr_db {p['max_snr_db']}")
        p["snr_db"] = float(rng.uniform(p["min_snr_db"], p["max_snr_db"]))
        p["applied"] = bool(rng.random() < p["p"])

    def _apply(self, x, params, meta):
        if not params["applied"]:
            return x.copy()
        return super()._apply(x, params, meta)


@register
class Background(Degradation):
    """Mix a background recording (``meta['background']``: any 1-D array, tiled/cropped from a
    random offset) at ``snr_db`` relative to the item RMS."""
    name = "audio.background"
    modality = "audio"
    table = {"snr_db": SNR_TABLE}
    identity = {"snr_db": math.inf}
    reports_snr = True

    def _sample_extra(self, rng, meta, p):
        p["offset_frac"] = float(rng.random())

    def _apply(self, x, params, meta):
        bg = meta.get("background")
        if bg is None:
            raise DegradationError(f"{self.name}: meta['background'] (1-D array) is required")
        bg = np.asarray(bg, dtype=np.float32).ravel()
        rms = float(np.sqrt(np.mean(bg.astype(np.float64) ** 2))) if bg.size else 0.0
        if rms == 0.0:
            raise DegradationError(f"{self.name}: meta['background'] is empty or silent")
        off = int(params["offset_frac"] * bg.size)
        idx = (off + np.arange(x.size)) % bg.size
        seg = bg[idx]
        seg_rms = float(np.sqrt(np.mean(seg.astype(np.float64) ** 2))) or rms
        return add_at_snr(x, seg / np.float32(seg_rms), float(params["snr_db"]), signal_rms(x, meta))


@register
class Wind(Degradation):
    """Wind: low-passed brown noise with a slow gust envelope, at ``snr_db`` (needs sample_rate_hz)."""
    name = "audio.wind"
    modality = "audio"
    table = {"snr_db": (15.0, 10.0, 5.0, 0.0, -5.0)}
    identity = {"snr_db": math.inf}
    extra = {"gust_hz": 0.7, "cutoff_hz": 500.0}
    reports_snr = True

    def _apply(self, x, params, meta):
        sr = _sample_rate(meta, self.name)
        rng = self.noise_rng(params)
        n = coloured_noise(rng, x.size, 2.0)
        sos = signal.butter(2, min(params["cutoff_hz"], 0.45 * sr), btype="low", fs=sr, output="sos")
        n = signal.sosfilt(sos, n).astype(np.float32)
        t = np.arange(x.size, dtype=np.float32) / np.float32(sr)
        phase = rng.uniform(0, 2 * np.pi, 2)
        env = 1.0 + 0.6 * np.sin(2 * np.pi * params["gust_hz"] * t + phase[0]) \
            + 0.3 * np.sin(2 * np.pi * 2.3 * params["gust_hz"] * t + phase[1])
        n = n * np.clip(env, 0.05, None).astype(np.float32)
        rms = float(np.sqrt(np.mean(n.astype(np.float64) ** 2)))
        return add_at_snr(x, n / np.float32(rms if rms > 0 else 1.0), float(params["snr_db"]), signal_rms(x, meta))


@register
class GainClip(Degradation):
    """Pre-amp gain ``gain_db`` then hard clipping at +-``clip_level`` (full scale)."""
    name = "audio.gain_clip"
    modality = "audio"
    table = {"gain_db": (6.0, 12.0, 18.0, 24.0, 30.0)}
    identity = {"gain_db": 0.0}
    extra = {"clip_level": 1.0}
    random = False

    def _apply(self, x, params, meta):
        g = np.float32(10.0 ** (params["gain_db"] / 20.0))
        c = np.float32(params["clip_level"])
        if not c > 0:
            raise DegradationError(f"{self.name}: clip_level must be > 0, got {params['clip_level']}")
        return np.clip(x * g, -c, c)


@register
class BandLimit(Degradation):
    """Cheap microphone: Butterworth band-pass (order 4, zero-phase sosfiltfilt)."""
    name = "audio.bandlimit"
    modality = "audio"
    table = {"low_cut_hz": (100.0, 200.0, 300.0, 400.0, 600.0),
             "high_cut_hz": (8000.0, 5000.0, 3500.0, 2500.0, 1500.0)}
    identity = {"low_cut_hz": 0.0, "high_cut_hz": 20000.0}
    random = False

    def _apply(self, x, params, meta):
        sr = _sample_rate(meta, self.name)
        nyq = sr / 2.0
        lo, hi = float(params["low_cut_hz"]), float(params["high_cut_hz"])
        if lo >= hi:
            raise DegradationError(f"{self.name}: low_cut_hz {lo} must be below high_cut_hz {hi}")
        y = x.astype(np.float64)
        padlen = min(x.size - 1, 3 * 9)
        if hi < 0.99 * nyq:
            y = signal.sosfiltfilt(signal.butter(4, hi, btype="low", fs=sr, output="sos"), y, padlen=padlen)
        if lo > 1.0:
            y = signal.sosfiltfilt(signal.butter(4, lo, btype="high", fs=sr, output="sos"), y, padlen=padlen)
        return y.astype(np.float32)


@register
class Dropout(Degradation):
    """Dropouts: gaps of ``gap_ms`` zeroed at random positions until ``drop_fraction`` is covered."""
    name = "audio.dropout"
    modality = "audio"
    table = {"drop_fraction": (0.05, 0.1, 0.2, 0.3, 0.5)}
    identity = {"drop_fraction": 0.0}
    extra = {"gap_ms": 20.0}

    def _apply(self, x, params, meta):
        sr = _sample_rate(meta, self.name)
        gap = max(1, int(round(params["gap_ms"] * 1e-3 * sr)))
        n_blocks = max(1, x.size // gap)
        k = int(round(params["drop_fraction"] * n_blocks))
        order = self.noise_rng(params).permutation(n_blocks)  # same order at every severity: nested gaps
        keep = np.ones(n_blocks * gap, dtype=bool).reshape(n_blocks, gap)
        keep[order[:k]] = False
        mask = np.ones(x.size, dtype=bool)
        mask[: n_blocks * gap] = keep.ravel()
        return np.where(mask, x, np.float32(0.0)).astype(np.float32)
