"""Levels and the standards behind them: dB SPL conversions, IEC 61672-1 A-weighting, the EU 2019/945
sound-power limits and a drone's default sound power, the rotor directivity, ISO 9613-1 atmospheric
absorption and ISO 9613-2 ground attenuation, and band levels of a signal. No synthesis here."""
from __future__ import annotations

import numpy as np
import scipy.fft as sfft

AUDIO_SAMPLE_RATE_HZ = 44_100
AUDIO_BAND_HZ = 16_000.0          # highest frequency any model synthesises; fs must be >= 2x this
P_REF_PA = 20e-6                  # reference pressure of dB SPL
FULL_SCALE_PA = 1.0               # WAV sample 1.0 == 1 Pa (94 dB SPL)

SPHERE_DB = 10.0 * np.log10(4.0 * np.pi)  # L_p(1 m) = L_W - 10.99 dB in free field (sphere of 1 m^2 x 4 pi)
# mass from overall span (kg): multirotor 0.75 kg at 0.45 m (a C1-class folding quad), fixed wing 1.2 kg at 1.5 m
_MASS_REFERENCE = {"quadcopter": (0.45, 0.75), "hexacopter": (0.45, 0.75), "fixed_wing": (1.5, 1.2)}
# EU 2019/945 Part 15: max L_WA (dB) for C1 and C2 below 900 g, by time since entry into force (0, 2, 4 years);
# C2 from 900 g to 4 kg: limit + 18.5 lg(m / 900 g). None above 4 kg (not in the open-category classes).
EU_LWA_LIMIT_DB = (85.0, 83.0, 81.0)
EU_C2_SLOPE_DB = 18.5
SOUND_POWER_PHASE = 1                     # default level: the 2-year curve 83 + 18.5 lg(m / 0.9 kg)
# directivity about the body's up axis, phi = angle below the rotor plane; power shapes (normalised to a
# unit sphere average): tonal 0.35 + sin^2(2 phi) (lobes ~45 deg off the rotor plane), broadband 1 + 0.5 sin^2 phi
TONAL_DIRECTIVITY = (0.35, 1.0)
BROADBAND_DIRECTIVITY = (1.0, 0.5)
DEFAULT_GROUND_FACTOR = 0.5               # ISO 9613-2 G of a mixed site (grass and hard surfaces)
OCTAVE_BANDS_HZ = (63.0, 125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0, 8000.0)


def check_nonnegative(name: str, values: np.ndarray) -> None:
    values = np.asarray(values)
    if values.size and (not np.all(np.isfinite(values)) or np.min(values) < 0):
        raise ValueError(f"{name} must be finite and >= 0, got min {np.nanmin(values):.6g}")


def check_sample_rate(sample_rate_hz: float, highest_band_hz: float = AUDIO_BAND_HZ) -> None:
    """Reject a sample rate that cannot carry the highest synthesised band (Nyquist)."""
    if not sample_rate_hz >= 2.0 * highest_band_hz:
        raise ValueError(f"sample_rate_hz must be >= 2 x highest band ({2 * highest_band_hz:.0f} Hz), got "
                         f"{sample_rate_hz}")


def db_spl_to_pa(level_db: float) -> float:
    return P_REF_PA * 10.0 ** (level_db / 20.0)


def pa_to_db_spl(rms_pa: np.ndarray | float) -> np.ndarray:
    return 20.0 * np.log10(np.maximum(np.asarray(rms_pa, dtype=np.float64), 1e-12) / P_REF_PA)


# --------------------------------------------------------------------------------------------
# Atmosphere
# --------------------------------------------------------------------------------------------

def speed_of_sound_mps(air_temperature_k: float) -> float:
    """Ideal-gas speed of sound in dry air, 331.3 m/s at 273.15 K."""
    if not air_temperature_k > 0:
        raise ValueError(f"air_temperature_k must be > 0, got {air_temperature_k}")
    return 331.3 * float(np.sqrt(air_temperature_k / 273.15))


def iso9613_absorption_db_per_m(frequency_hz: np.ndarray | float, air_temperature_k: float,
                                relative_humidity: float, pressure_pa: float = 101_325.0) -> np.ndarray:
    """Pure-tone atmospheric absorption coefficient (dB/m), ISO 9613-1:1993 equations (1)-(5).

    ``relative_humidity`` is a fraction (0-1) as in the scenario schema.
    """
    f = np.asarray(frequency_hz, dtype=np.float64)
    check_nonnegative("frequency_hz", f)
    if not 0.0 <= relative_humidity <= 1.0:
        raise ValueError(f"relative_humidity must be a fraction in [0, 1], got {relative_humidity}")
    if not pressure_pa > 0:
        raise ValueError(f"pressure_pa must be > 0, got {pressure_pa}")
    t = float(air_temperature_k)
    if not t > 0:
        raise ValueError(f"air_temperature_k must be > 0, got {t}")
    pr_kpa, t0, t01 = 101.325, 293.15, 273.16
    pa_rel = (pressure_pa / 1000.0) / pr_kpa
    c_exp = -6.8346 * (t01 / t) ** 1.261 + 4.6151
    h = 100.0 * relative_humidity * 10.0 ** c_exp / pa_rel          # molar concentration of water vapour, %
    fr_o = pa_rel * (24.0 + 4.04e4 * h * (0.02 + h) / (0.391 + h))
    fr_n = pa_rel * (t / t0) ** -0.5 * (9.0 + 280.0 * h * np.exp(-4.170 * ((t / t0) ** (-1.0 / 3.0) - 1.0)))
    return 8.686 * f ** 2 * (
        1.84e-11 / pa_rel * (t / t0) ** 0.5
        + (t / t0) ** -2.5 * (0.01275 * np.exp(-2239.1 / t) / (fr_o + f ** 2 / fr_o)
                              + 0.1068 * np.exp(-3352.0 / t) / (fr_n + f ** 2 / fr_n)))


def a_weighting_db(frequency_hz: np.ndarray | float) -> np.ndarray:
    """IEC 61672-1 A-weighting (dB): 20 lg R_A(f) + 2.00, R_A = 12194^2 f^4 / ((f^2 + 20.6^2)
    sqrt((f^2 + 107.7^2)(f^2 + 737.9^2)) (f^2 + 12194^2))."""
    f2 = np.asarray(frequency_hz, dtype=np.float64) ** 2
    ra = 12194.0 ** 2 * f2 ** 2 / ((f2 + 20.6 ** 2) * np.sqrt((f2 + 107.7 ** 2) * (f2 + 737.9 ** 2))
                                   * (f2 + 12194.0 ** 2))
    return 20.0 * np.log10(np.maximum(ra, 1e-30)) + 2.00


def drone_mass_kg(kind: str, size_m: float) -> float:
    """Take-off mass from overall span, m ~ span^3 (0.75 kg at 0.45 m for multirotors, 1.2 kg at 1.5 m wings)."""
    if kind not in _MASS_REFERENCE:
        raise ValueError(f"kind: no mass model for {kind!r}")
    span, mass = _MASS_REFERENCE[kind]
    return mass * (size_m / span) ** 3


def eu_class(mass_kg: float) -> str:
    """EU 2019/945 open-category class by mass alone: C0 < 250 g, C1 < 900 g, C2 < 4 kg, else 'none'."""
    return "C0" if mass_kg < 0.25 else "C1" if mass_kg < 0.9 else "C2" if mass_kg < 4.0 else "none"


def eu_sound_power_limit_db(mass_kg: float, phase: int = 0) -> float | None:
    """Maximum L_WA of EU 2019/945 Part 15 (C1/C2), ``phase`` 0/1/2 = at entry, +2 years, +4 years.

    85/83/81 dB below 900 g (C1 and C2), + 18.5 lg(m / 900 g) from 900 g to 4 kg; None for C0 (no
    limit) and above 4 kg.
    """
    if phase not in (0, 1, 2):
        raise ValueError(f"phase must be 0, 1 or 2, got {phase}")
    cls = eu_class(mass_kg)
    if cls in ("C0", "none"):
        return None
    base = EU_LWA_LIMIT_DB[phase]
    return base if mass_kg < 0.9 else base + EU_C2_SLOPE_DB * np.log10(mass_kg / 0.9)


def sound_power_dba(kind: str, size_m: float) -> float:
    """Default A-weighted sound power L_WA at hover: 83 + 18.5 lg(m / 0.9 kg) (the EU 2-year limit
    curve extended to all masses), never above the class limit at entry into force."""
    mass = drone_mass_kg(kind, size_m)
    level = EU_LWA_LIMIT_DB[SOUND_POWER_PHASE] + EU_C2_SLOPE_DB * np.log10(mass / 0.9)
    cap = eu_sound_power_limit_db(mass, 0)
    return float(level if cap is None else min(level, cap))


def _directivity_power(sin_below: np.ndarray, shape: tuple[float, float], kind: str) -> np.ndarray:
    """Power directivity (unit sphere average) from sin(angle below the rotor plane)."""
    base, depth = shape
    u2 = np.clip(np.asarray(sin_below, dtype=np.float64) ** 2, 0.0, 1.0)
    if kind == "tonal":                        # base + depth sin^2(2 phi); sphere mean of sin^2(2 phi) = 8/15
        return (base + depth * 4.0 * u2 * (1.0 - u2)) / (base + depth * 8.0 / 15.0)
    return (base + depth * u2) / (base + depth / 3.0)   # sphere mean of sin^2 phi = 1/3


def rotor_directivity(emission_dir: np.ndarray, body_up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Amplitude factors (tonal, broadband) for unit emission directions (N, 3) and body up axes (N, 3)."""
    d = np.asarray(emission_dir, dtype=np.float64)
    d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
    sin_below = -np.sum(d * np.asarray(body_up, dtype=np.float64), axis=-1)
    return (np.sqrt(_directivity_power(sin_below, TONAL_DIRECTIVITY, "tonal")),
            np.sqrt(_directivity_power(sin_below, BROADBAND_DIRECTIVITY, "broadband")))


def iso9613_ground_attenuation_db(source_height_m: np.ndarray | float, receiver_height_m: float,
                                  horizontal_range_m: np.ndarray | float, ground_factor: float) -> np.ndarray:
    """ISO 9613-2:1996 ground attenuation A_gr = A_s + A_r + A_m (dB) per octave band 63 Hz-8 kHz.

    Table 3: source/receiver regions -1.5 (63 Hz), -1.5 + G a'(h) / b'(h) / c'(h) / d'(h) (125 Hz
    -1 kHz), -1.5 (1 - G) (2-8 kHz); middle region -3q (63 Hz), -3q (1 - G) otherwise, q = 0 for
    d_p <= 30 (h_s + h_r) else 1 - 30 (h_s + h_r) / d_p. One G for all three regions. Negative =
    gain (a hard ground adds the reflection: -3 dB). Returns (..., 8).
    """
    if not 0.0 <= ground_factor <= 1.0:
        raise ValueError(f"ground_factor must be in [0, 1], got {ground_factor}")
    hs = np.maximum(np.asarray(source_height_m, dtype=np.float64), 0.0)
    dp = np.maximum(np.asarray(horizontal_range_m, dtype=np.float64), 0.0)
    hs, dp = np.broadcast_arrays(hs, dp)
    hr = max(float(receiver_height_m), 0.0)
    g = float(ground_factor)
    near = 1.0 - np.exp(-dp / 50.0)

    def region(h):
        a = (1.5 + 3.0 * np.exp(-0.12 * (h - 5.0) ** 2) * near + 5.7 * np.exp(-0.09 * h ** 2)
             * (1 - np.exp(-2.8e-6 * dp ** 2)))
        b = 1.5 + 8.6 * np.exp(-0.09 * h ** 2) * near
        c = 1.5 + 14.0 * np.exp(-0.46 * h ** 2) * near
        d = 1.5 + 5.0 * np.exp(-0.9 * h ** 2) * near
        hi = np.full_like(h, -1.5 * (1 - g))
        return np.stack([np.full_like(h, -1.5), -1.5 + g * a, -1.5 + g * b, -1.5 + g * c, -1.5 + g * d, hi, hi, hi], -1)

    q = np.where(dp <= 30.0 * (hs + hr), 0.0, 1.0 - 30.0 * (hs + hr) / np.maximum(dp, 1e-9))
    middle = np.stack([-3.0 * q] + [-3.0 * q * (1 - g)] * 7, -1)
    return region(hs) + region(np.full_like(hs, hr)) + middle


def band_level_db(x_pa: np.ndarray, sample_rate_hz: float, low_hz: float, high_hz: float,
                  segment_samples: int) -> np.ndarray:
    """Per-segment band-limited RMS level (dB SPL) from an FFT of each segment (last partial dropped)."""
    x = np.asarray(x_pa, dtype=np.float64)
    n_seg = x.size // segment_samples
    segs = x[: n_seg * segment_samples].reshape(n_seg, segment_samples)
    spec = np.abs(sfft.rfft(segs, axis=-1)) ** 2
    f = np.fft.rfftfreq(segment_samples, 1.0 / sample_rate_hz)
    band = (f >= low_hz) & (f <= high_hz)
    power = 2.0 * np.sum(spec[:, band], axis=-1) / segment_samples ** 2
    return 10.0 * np.log10(np.maximum(power, 1e-30) / P_REF_PA ** 2)
