"""Spectral shaping of the recording chain: peaking filters (resonances of a recorder housing or a
microphone mount) applied to a mix at the microphone."""
from __future__ import annotations

import numpy as np


def peaking_filter(x: np.ndarray, sample_rate_hz: float, centre_hz: float, gain_db: float, q: float) -> np.ndarray:
    """One resonance: ``x + (10^(gain_db/20) - 1) * bandpass(x)`` with the 2nd-order band-pass of
    ``scipy.signal.iirpeak`` (centre ``centre_hz``, quality factor ``q``: -3 dB bandwidth centre / q).

    iirpeak's band-pass is (1 - A(z)) / 2 with A an all-pass, so the sum is the Regalia-Mitra peaking
    equaliser: exactly ``gain_db`` at the centre (the band-pass there is 1 at zero phase), 0 dB at DC
    and Nyquist, never under 0 dB for a positive gain (no dips beside the peak). Causal (``lfilter``),
    not zero-phase: a resonance of a housing or a mount is causal and minimum-phase, and ``filtfilt``
    would square the band-pass (a narrower peak than ``q`` says) at twice the cost. Pure: float64 out,
    ``x`` untouched."""
    from scipy.signal import iirpeak, lfilter

    x = np.asarray(x, dtype=np.float64)
    if not 0.0 < centre_hz < 0.5 * sample_rate_hz:
        raise ValueError(f"centre_hz: must lie in (0, {0.5 * sample_rate_hz}) Hz, got {centre_hz}")
    if q <= 0:
        raise ValueError(f"q: must be > 0, got {q}")
    b, a = iirpeak(centre_hz, q, fs=sample_rate_hz)
    return x + (10.0 ** (gain_db / 20.0) - 1.0) * lfilter(b, a, x)


def resonances(x: np.ndarray, sample_rate_hz: float, peaks: list[tuple[float, float, float]]) -> np.ndarray:
    """``x`` through one :func:`peaking_filter` per ``(centre_hz, gain_db, q)`` in ``peaks``, then scaled
    back to the RMS of ``x`` (a recorder's gain is not a class cue: only the shape changes). No peaks:
    ``x`` as float64, byte for byte."""
    x = np.asarray(x, dtype=np.float64)
    y = x
    for centre_hz, gain_db, q in peaks:
        y = peaking_filter(y, sample_rate_hz, centre_hz, gain_db, q)
    if not peaks:
        return x
    rms_in, rms_out = np.sqrt(np.mean(x ** 2)), np.sqrt(np.mean(y ** 2))
    return y * (rms_in / rms_out) if rms_out > 0 else y
