"""RF degradations: complex I/Q segments (N,) and spectrograms (F, T) in dB.

I/Q SNR semantics: ``snr_db`` / ``sir_db`` are relative to the mean signal power mean(|x|^2) over
the whole segment (or meta['signal_power'] when given); noise realisations are rescaled to exactly
the target power, and the realised SNR (from y - x) is reported in the info dict.
Spectrogram semantics: values are power in dB; noise is added in LINEAR power (10^(dB/10)), the
SNR is mean signal power / mean added power over the whole image, and frequency index 0 is the
lowest frequency row (pink noise power ~ 1/(k + 1) over rows).
"""
from __future__ import annotations

import math

import numpy as np

from degradations.base import Degradation
from degradations.errors import DegradationError
from degradations.registry import register

SNR_TABLE = (20.0, 10.0, 5.0, 0.0, -5.0)


def signal_power(x: np.ndarray, meta: dict) -> float:
    """Reference power: meta['signal_power'] if given, else mean(|x|^2) of the whole item."""
    if meta.get("signal_power") is not None:
        return float(meta["signal_power"])
    return float(np.mean(np.abs(x.astype(np.complex128)) ** 2))


def complex_noise(rng: np.random.Generator, n: int) -> np.ndarray:
    """Circular complex Gaussian noise rescaled to exactly unit mean power (complex64)."""
    z = rng.standard_normal((2, n), dtype=np.float32)
    w = (z[0] + 1j * z[1]).astype(np.complex64)
    p = float(np.mean(np.abs(w.astype(np.complex128)) ** 2))
    return w / np.float32(np.sqrt(p)) if p > 0 else w


class _IQ(Degradation):
    modality = "rf_iq"


@register
class AWGN(_IQ):
    """Additive white complex Gaussian noise at ``snr_db`` relative to mean(|x|^2)."""
    name = "rf.awgn"
    table = {"snr_db": SNR_TABLE}
    identity = {"snr_db": math.inf}
    reports_snr = True

    def _apply(self, x, params, meta):
        pn = signal_power(x, meta) / 10.0 ** (params["snr_db"] / 10.0)
        return x + complex_noise(self.noise_rng(params), x.size) * np.float32(np.sqrt(pn))


@register
class WifiBurst(_IQ):
    """Wi-Fi-like co-channel bursts: OFDM-like band-limited noise (``bandwidth_frac`` of the
    sample rate, random centre) switched on for ``duty`` of the segment, at ``sir_db`` during bursts."""
    name = "rf.wifi_burst"
    table = {"duty": (0.05, 0.1, 0.2, 0.3, 0.5), "sir_db": (10.0, 5.0, 0.0, -5.0, -10.0)}
    identity = {"duty": 0.0, "sir_db": 30.0}
    extra = {"bandwidth_frac": 0.25, "burst_frac": 0.02}
    reports_snr = True

    def _sample_extra(self, rng, meta, p):
        p["centre_frac"] = float(rng.uniform(-0.35, 0.35))

    def _apply(self, x, params, meta):
        n = x.size
        rng = self.noise_rng(params)
        f = np.fft.fftfreq(n)
        band = np.abs(f - params["centre_frac"]) <= params["bandwidth_frac"] / 2
        sym = (rng.choice([-1.0, 1.0], n) + 1j * rng.choice([-1.0, 1.0], n)) * band
        w = np.fft.ifft(sym).astype(np.complex64)
        blen = max(16, int(params["burst_frac"] * n))
        nb = max(1, n // blen)
        order = rng.permutation(nb)
        gate = np.zeros(nb, bool)
        gate[order[: int(round(params["duty"] * nb))]] = True
        g = np.zeros(n, bool)
        g[: nb * blen] = np.repeat(gate, blen)
        if not g.any():
            return x.copy()
        pw = float(np.mean(np.abs(w[g]) ** 2))
        target = signal_power(x, meta) / 10.0 ** (params["sir_db"] / 10.0)
        return x + np.where(g, w * np.float32(np.sqrt(target / pw)), 0).astype(np.complex64)


@register
class FreqOffset(_IQ):
    """Carrier frequency offset ``offset_norm`` (cycles/sample) plus linear drift ``drift_norm``
    (change over the segment); the sign is drawn. offset_hz = offset_norm * sample_rate_hz."""
    name = "rf.freq_offset"
    table = {"offset_norm": (0.001, 0.002, 0.005, 0.01, 0.02),
             "drift_norm": (0.0005, 0.001, 0.002, 0.004, 0.008)}
    identity = {"offset_norm": 0.0, "drift_norm": 0.0}

    def _sample_extra(self, rng, meta, p):
        p["sign"] = 1 if rng.random() < 0.5 else -1
        if meta.get("sample_rate_hz"):
            p["offset_hz"] = p["sign"] * p["offset_norm"] * float(meta["sample_rate_hz"])

    def _apply(self, x, params, meta):
        n = np.arange(x.size, dtype=np.float64)
        ph = 2 * np.pi * params["sign"] * (params["offset_norm"] * n + 0.5 * params["drift_norm"] / max(x.size, 1)
                                           * n**2)
        return (x * np.exp(1j * ph)).astype(np.complex64)


@register
class Fading(_IQ):
    """Block multipath fading: ``n_taps`` taps with exponential power-delay profile (``delay_spread``
    samples); tap 0 is Rician with K-factor ``k_factor`` (0 = Rayleigh). E|h|^2 = 1."""
    name = "rf.fading"
    table = {"k_factor": (10.0, 5.0, 2.0, 0.5, 0.0), "delay_spread": (0.5, 1.0, 1.5, 2.0, 3.0)}
    identity = {"k_factor": 1e9, "delay_spread": 0.0}
    extra = {"n_taps": 6}

    def _sample_extra(self, rng, meta, p):
        p["los_phase"] = float(rng.uniform(0, 2 * np.pi))

    def taps(self, params) -> np.ndarray:
        """Channel taps (complex128) regenerated from noise_seed."""
        nt = int(params["n_taps"])
        if nt < 1:
            raise DegradationError(f"{self.name}: n_taps must be >= 1, got {nt}")
        z = self.noise_rng(params).standard_normal((2, nt))
        g = (z[0] + 1j * z[1]) / np.sqrt(2)
        ds = max(float(params["delay_spread"]), 1e-3)
        pdp = np.exp(-np.arange(nt) / ds)
        pdp /= pdp.sum()
        k = float(params["k_factor"])
        h = g * np.sqrt(pdp) * np.sqrt(1.0 / (k + 1.0))
        h[0] += np.sqrt(k / (k + 1.0)) * np.exp(1j * params["los_phase"])
        return h

    def _apply(self, x, params, meta):
        return np.convolve(x, self.taps(params).astype(np.complex64))[: x.size].astype(np.complex64)


@register
class IQImbalance(_IQ):
    """IQ imbalance: y = K1 x + K2 conj(x), K1 = (1 + g e^{-j phi})/2, K2 = (1 - g e^{j phi})/2,
    g = 10^(amp_db/20), phi = phase_deg."""
    name = "rf.iq_imbalance"
    table = {"amp_db": (0.2, 0.5, 1.0, 2.0, 3.0), "phase_deg": (1.0, 2.0, 5.0, 10.0, 15.0)}
    identity = {"amp_db": 0.0, "phase_deg": 0.0}
    random = False
    reports_snr = True

    def _apply(self, x, params, meta):
        g = 10.0 ** (params["amp_db"] / 20.0)
        phi = np.deg2rad(params["phase_deg"])
        k1 = (1 + g * np.exp(-1j * phi)) / 2
        k2 = (1 - g * np.exp(1j * phi)) / 2
        return (k1 * x + k2 * np.conj(x)).astype(np.complex64)


@register
class ADC(_IQ):
    """ADC: clip I and Q at full scale ``clip_rms`` x per-component RMS, quantise to ``bits`` bits
    (mid-rise, uniform)."""
    name = "rf.adc"
    table = {"bits": (10.0, 8.0, 6.0, 4.0, 3.0), "clip_rms": (4.0, 3.0, 2.5, 2.0, 1.5)}
    identity = {"bits": 24.0, "clip_rms": 100.0}
    integer_params = ("bits",)
    random = False
    reports_snr = True

    def _apply(self, x, params, meta):
        b = int(params["bits"])
        if not 1 <= b <= 24:
            raise DegradationError(f"{self.name}: bits must be in 1..24, got {b}")
        fs = params["clip_rms"] * np.sqrt(max(signal_power(x, meta), 1e-30) / 2)
        step = 2 * fs / 2**b

        def q(v):
            v = np.clip(v, -fs, fs - 1e-12 * fs)
            return (np.floor(v / step) + 0.5) * step
        return (q(x.real) + 1j * q(x.imag)).astype(np.complex64)


@register
class LinkSilence(_IQ):
    """The drone's link falls silent (autonomous flight): the segment is attenuated by
    ``attenuation_db`` and a receiver noise floor ``noise_floor_db`` below the original power is added."""
    name = "rf.link_silence"
    table = {"attenuation_db": (6.0, 12.0, 20.0, 30.0, 60.0)}
    identity = {"attenuation_db": 0.0}
    extra = {"noise_floor_db": 30.0}

    def _apply(self, x, params, meta):
        p = signal_power(x, meta)
        n = complex_noise(self.noise_rng(params), x.size) * np.float32(np.sqrt(p
                                                                               / 10 ** (params["noise_floor_db"] / 10)))
        return (x * np.float32(10 ** (-params["attenuation_db"] / 20)) + n).astype(np.complex64)


# ----------------------------------------------------------------------------- spectrogram domain
class _Spec(Degradation):
    modality = "rf_spec"

    def measure(self, x, y, params, meta=None):
        px = 10.0 ** (np.asarray(x, np.float64) / 10.0)
        py = 10.0 ** (np.asarray(y, np.float64) / 10.0)
        ps, pn = float(px.mean()), float(np.abs(py - px).mean())
        snr = math.inf if pn == 0 else 10 * math.log10(ps / pn)
        return {"realised_snr_db": snr, "signal_power": ps, "noise_power": pn}


@register
class SpecPinkNoise(_Spec):
    """Additive pink noise in linear power: per-row mean power ~ 1/(k+1), exponential (|complex
    Gaussian|^2) fluctuations, total mean rescaled to mean(P)/10^(snr_db/10) exactly."""
    name = "rf.spec_pink_noise"
    table = {"snr_db": SNR_TABLE}
    identity = {"snr_db": math.inf}

    def _apply(self, x, params, meta):
        P = np.power(np.float32(10.0), x / np.float32(10.0), dtype=np.float32)
        F, T = x.shape
        prof = (1.0 / np.arange(1, F + 1, dtype=np.float32))[:, None]
        n = self.noise_rng(params).standard_exponential((F, T), dtype=np.float32) * prof
        n *= np.float32(float(P.mean(dtype=np.float64)) / 10 ** (params["snr_db"] / 10)
                        / float(n.mean(dtype=np.float64)))
        return (np.float32(10.0) * np.log10(P + n)).astype(np.float32)


class _SpecMask(_Spec):
    table = {"mask_fraction": (0.05, 0.1, 0.15, 0.2, 0.3)}
    identity = {"mask_fraction": 0.0}
    extra = {"n_masks": 2}
    axis = 1

    def _apply(self, x, params, meta):
        L = x.shape[self.axis]
        k = int(params["n_masks"])
        if k < 1:
            raise DegradationError(f"{self.name}: n_masks must be >= 1, got {k}")
        width = int(round(params["mask_fraction"] * L / k))
        starts = self.noise_rng(params).random(k)
        keep = np.ones(L, bool)
        for s in starts:
            a = int(s * max(L - width, 0))
            keep[a:a + width] = False
        fill = np.float32(x.min())
        shape = (1, L) if self.axis == 1 else (L, 1)
        return np.where(keep.reshape(shape), x, fill).astype(np.float32)


@register
class SpecTimeMask(_SpecMask):
    """SpecAugment time masking: ``n_masks`` bands covering ``mask_fraction`` of columns, filled with the image
    minimum."""
    name = "rf.spec_time_mask"
    axis = 1


@register
class SpecFreqMask(_SpecMask):
    """SpecAugment frequency masking: bands covering ``mask_fraction`` of rows, filled with the image minimum."""
    name = "rf.spec_freq_mask"
    axis = 0


@register
class SpecInterference(_Spec):
    """Interference stripes: ``n_carriers`` narrowband carriers (rows) and wideband bursts (columns,
    ``burst_fraction`` of time), total added mean power at ``sir_db`` below the signal mean power."""
    name = "rf.spec_interference"
    table = {"sir_db": (10.0, 5.0, 0.0, -5.0, -10.0)}
    identity = {"sir_db": math.inf}
    extra = {"n_carriers": 3, "burst_fraction": 0.1}

    def _apply(self, x, params, meta):
        F, T = x.shape
        rng = self.noise_rng(params)
        P = np.power(np.float32(10.0), x / np.float32(10.0), dtype=np.float32)
        interf = np.zeros((F, T), np.float32)
        rows = rng.integers(0, F, int(params["n_carriers"]))
        interf[rows] += 1.0
        cols = rng.random(T) < params["burst_fraction"]
        interf[:, cols] += 0.3
        interf *= rng.standard_exponential((F, T), dtype=np.float32)
        m = float(interf.mean(dtype=np.float64))
        if m == 0:
            return x.copy()
        interf *= np.float32(float(P.mean(dtype=np.float64)) / 10 ** (params["sir_db"] / 10) / m)
        return (np.float32(10.0) * np.log10(P + interf)).astype(np.float32)


@register
class SpecLinkSilence(_Spec):
    """Spectrogram of a silent link: power above the noise floor (10th percentile) is attenuated by
    ``attenuation_db``."""
    name = "rf.spec_link_silence"
    table = {"attenuation_db": (6.0, 12.0, 20.0, 30.0, 60.0)}
    identity = {"attenuation_db": 0.0}
    random = False

    def _apply(self, x, params, meta):
        P = np.power(np.float32(10.0), x / np.float32(10.0), dtype=np.float32)
        floor = np.float32(np.percentile(P, 10))
        Q = (floor + np.maximum(P - floor, 0) * np.float32(10 ** (-params["attenuation_db"] / 10))
             + np.minimum(P - floor, 0))
        return (np.float32(10.0) * np.log10(np.maximum(Q, 1e-30))).astype(np.float32)
