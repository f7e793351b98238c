"""Small synthetic inputs shared by the degradation tests (64x80 frames, 0.25 s audio)."""
from __future__ import annotations

import cv2
import numpy as np

H, W, T = 64, 80, 4
SR = 16000


def rgb_clip(seed: int = 0) -> np.ndarray:
    """Textured uint8 clip (T, H, W, 3): smoothed noise, different per frame."""
    rng = np.random.default_rng([seed, 1])
    x = rng.random((T, H, W, 3)).astype(np.float32)
    x = np.stack([cv2.GaussianBlur(f, (0, 0), 1.2) for f in x])
    x = (x - x.min()) / (x.max() - x.min())
    return (x * 200 + 28).astype(np.uint8)


def moving_clip(n: int = 20, px_per_frame: int = 2) -> np.ndarray:
    """uint8 clip whose content pans right: showing frame t-k instead of t errs in proportion to k."""
    cols = np.arange(W)[None, :, None]
    f = [np.broadcast_to((cols + px_per_frame * t) * 2 % 256, (H, W, 3)) for t in range(n)]
    return np.stack(f).astype(np.uint8)


def target_mask() -> np.ndarray:
    m = np.zeros((H, W), bool)
    m[28:36, 36:46] = True
    return m


def thermal_clip(seed: int = 0) -> np.ndarray:
    """Kelvin clip (T, H, W): 280 K sky with 0.3 K texture and a +2 K target in target_mask()."""
    rng = np.random.default_rng([seed, 2])
    x = (280.0 + rng.normal(0, 0.3, (T, H, W))).astype(np.float32)
    x[:, target_mask()] += 2.0
    return x


def audio(seed: int = 0) -> np.ndarray:
    """0.25 s broadband signal (two tones + noise), float32."""
    rng = np.random.default_rng([seed, 3])
    t = np.arange(int(0.25 * SR)) / SR
    x = 0.2 * np.sin(2 * np.pi * 440 * t) + 0.1 * np.sin(2 * np.pi * 2500 * t) + 0.15 * rng.normal(size=t.size)
    return x.astype(np.float32)


def iq(seed: int = 0) -> np.ndarray:
    """QPSK-like complex64 I/Q segment (4096 samples, unit power)."""
    rng = np.random.default_rng([seed, 4])
    sym = (rng.choice([-1, 1], 1024) + 1j * rng.choice([-1, 1], 1024)) / np.sqrt(2)
    x = np.convolve(np.repeat(sym, 4), np.hanning(8), mode="same")  # pulse-shaped: varying envelope
    return (x / np.sqrt(np.mean(np.abs(x) ** 2))).astype(np.complex64)


def spec_db(seed: int = 0) -> np.ndarray:
    """Spectrogram (F=64, T=80) in dB: noise floor -90 dB with a few signal lines."""
    rng = np.random.default_rng([seed, 5])
    p = rng.standard_exponential((64, 80)) * 1e-9
    p[20:23] += 1e-6
    p[:, 30:40] += 3e-8
    return (10 * np.log10(p)).astype(np.float32)
