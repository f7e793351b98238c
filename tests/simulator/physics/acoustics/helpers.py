"""Shared by the acoustics tests: sample rate, microphone, hand-built tracks, peak and A-level measures."""
from __future__ import annotations

import numpy as np

from simulator.physics import acoustics as ac
from simulator.physics.timeline import TargetTrack

FS = ac.AUDIO_SAMPLE_RATE_HZ
MIC = np.array([0.0, 0.0, 1.5])


def _track(position_m, velocity_mps, rpm=6000.0, duration_s=3.0, kind="quadcopter", n_rotors=4, fps=28.0):
    t = np.arange(0.0, duration_s + 1.0 / fps, 1.0 / fps)
    pos = np.asarray(position_m, float) + np.outer(t, np.asarray(velocity_mps, float))
    vel = np.tile(np.asarray(velocity_mps, float), (t.size, 1))
    zeros = np.zeros(t.size)
    track = TargetTrack(target_id=1, name="d", kind=kind, size_m=0.45, position_m=pos, velocity_mps=vel,
                        rotation=np.tile(np.eye(3), (t.size, 1, 1)), rotor_rpm=np.full((t.size, n_rotors), rpm),
                        rotor_angle_rad=zeros, flap_phase_rad=zeros, n_blades=2)
    return track, t


def _peak_hz(x: np.ndarray, lo: float, hi: float, pad: int = 8) -> tuple[float, float]:
    """Frequency of the largest spectral line in [lo, hi] (zero-padded FFT) and the unpadded bin width."""
    n = x.size
    spec = np.abs(np.fft.rfft(x * np.hanning(n), n * pad))
    f = np.fft.rfftfreq(n * pad, 1.0 / FS)
    band = (f >= lo) & (f <= hi)
    return float(f[band][np.argmax(spec[band])]), FS / n


def _a_level_db(x: np.ndarray) -> float:
    spec = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(x.size, 1.0 / FS)
    weights = 10 ** (ac.a_weighting_db(np.maximum(f, 1.0)) / 10)
    return float(10 * np.log10(2 * np.sum(spec * weights) / x.size ** 2 / ac.P_REF_PA ** 2))


def _fibonacci_sphere(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5 ** 0.5) * i
    return np.stack([np.sqrt(1 - z ** 2) * np.cos(phi), np.sqrt(1 - z ** 2) * np.sin(phi), z], -1)


def _hover_track(kind: str, size_m: float, position_m, rpm_factor: float = 1.0, duration_s: float = 0.6):
    from simulator.physics.timeline import rotor_hover_rpm

    t = np.arange(0.0, duration_s, 1.0 / 28)
    pos = np.tile(np.asarray(position_m, float), (t.size, 1))
    n_rotors = 6 if kind == "hexacopter" else 4
    rpm = np.full((t.size, n_rotors), rpm_factor * rotor_hover_rpm(kind, size_m))
    zeros = np.zeros(t.size)
    return TargetTrack(1, "d", kind, size_m, pos, np.zeros_like(pos), np.tile(np.eye(3), (t.size, 1, 1)), rpm,
                       zeros, zeros, n_blades=2), t
