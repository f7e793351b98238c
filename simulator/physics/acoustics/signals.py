"""Signal helpers shared by the sources and the ambient beds: band-shaped Gaussian noise, slow random
modulations and Poisson-timed chirps. They take an rng and return unit-scaled arrays; no levels, no physics."""
from __future__ import annotations

import numpy as np
import scipy.fft as sfft


def shaped_gain(f_hz: np.ndarray, low_hz: float, high_hz: float, slope_db_per_octave: float = 0.0) -> np.ndarray:
    """Amplitude response of :func:`shaped_noise`: 2nd-order high-pass, 4th-order low-pass, tilt."""
    f_safe = np.maximum(np.asarray(f_hz, dtype=np.float64), 1e-3)
    hp = (f_safe / low_hz) ** 2 / (1.0 + (f_safe / low_hz) ** 2) if low_hz > 0 else np.ones_like(f_safe)
    lp = 1.0 / (1.0 + (f_safe / high_hz) ** 4)
    tilt = (f_safe / max(low_hz, 1.0)) ** (slope_db_per_octave / 6.0206)
    return hp * lp * np.minimum(tilt, 1e3)


def shaped_noise(rng: np.random.Generator, n: int, sample_rate_hz: float, low_hz: float, high_hz: float,
                  slope_db_per_octave: float = 0.0) -> np.ndarray:
    """Unit-RMS Gaussian noise band-passed (smooth 2nd-order edges) with an optional spectral tilt."""
    n_fft = sfft.next_fast_len(n, real=True)
    white = rng.standard_normal(n_fft)
    f = np.fft.rfftfreq(n_fft, 1.0 / sample_rate_hz)
    shaped = sfft.irfft(sfft.rfft(white) * shaped_gain(f, low_hz, high_hz, slope_db_per_octave), n=n_fft)[:n]
    rms = np.sqrt(np.mean(shaped ** 2))
    return shaped / max(rms, 1e-30)


def smooth_random(rng: np.random.Generator, n: int, sample_rate_hz: float, corner_hz: float) -> np.ndarray:
    """Zero-mean, unit-RMS noise low-passed at corner_hz (slow modulations: gusts, traffic)."""
    step = max(1, int(sample_rate_hz / (20.0 * corner_hz)))
    coarse = shaped_noise(rng, n // step + 4, sample_rate_hz / step, 0.0, corner_hz)
    return np.interp(np.arange(n) / step, np.arange(coarse.size), coarse)


def chirp_events(rng: np.random.Generator, n: int, sample_rate_hz: float, rate_per_s: float,
                  f_range_hz: tuple[float, float], dur_range_s: tuple[float, float]) -> np.ndarray:
    """Poisson-timed frequency-swept calls with a 2nd harmonic and a Hann envelope (unit peak)."""
    out = np.zeros(n)
    count = rng.poisson(rate_per_s * n / sample_rate_hz)
    starts = rng.integers(0, max(n, 1), size=count)
    durations = rng.uniform(*dur_range_s, size=count)
    f_start = rng.uniform(*f_range_hz, size=count)
    f_end = f_start * rng.uniform(0.7, 1.4, size=count)
    trill_hz = rng.uniform(10.0, 40.0, size=count)
    for s0, dur, fa, fb, tr in zip(starts, durations, f_start, f_end, trill_hz):
        m = int(dur * sample_rate_hz)
        stop = min(n, s0 + m)
        t = np.arange(stop - s0) / sample_rate_hz
        inst = fa + (fb - fa) * t / dur + 0.08 * fa * np.sin(2 * np.pi * tr * t)
        ph = 2 * np.pi * np.cumsum(inst) / sample_rate_hz
        env = np.sin(np.pi * np.arange(stop - s0) / max(m, 1)) ** 2
        out[s0:stop] += env * (np.sin(ph) + 0.3 * np.sin(2 * ph))
    return out
