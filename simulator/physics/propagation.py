"""Radio propagation between a drone and a ground receiver: free space, two-ray ground reflection,
antenna gain patterns and small-scale (Rician / Rayleigh) fading.

Geometry is in the world frame with the ground plane at z = 0 (metres). The two-ray model adds the
direct ray and the ray reflected at the ground (image of the transmitter below the plane), each
weighted by the antenna gains in its own direction and the Fresnel reflection coefficient of the
ground; it reduces to 40 log10 d - 20 log10(h_t h_r) far beyond the break distance (Rappaport,
*Wireless Communications*, 2nd ed., sec. 4.6). Fading gains have unit mean power so they change the
received power only statistically. See docs/AUDIO_RF.md.
"""
from __future__ import annotations

import numpy as np

SPEED_OF_LIGHT_MPS = 299_792_458.0
DIPOLE_PEAK_GAIN = 1.640922      # half-wave dipole directivity (2.15 dBi)
PATCH_EXPONENT = 2.0             # cos^q main lobe; directivity 2 (q + 1) = 6 (7.8 dBi)
PATCH_BACK_LOBE_DB = -20.0       # front-to-back ratio of the patch
MIN_HEIGHT_M = 0.1               # antennas closer to the ground plane are clamped (two-ray needs h > 0)
ANTENNAS = ("isotropic", "dipole", "patch")


def _check_positive(name: str, value: float) -> None:
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be finite and > 0, got {value}")


def free_space_path_loss_db(range_m: np.ndarray | float, frequency_hz: float) -> np.ndarray:
    """Friis free-space loss 20 log10(4 pi d f / c), isotropic antennas; range clamped to >= 1 m."""
    r = np.asarray(range_m, dtype=np.float64)
    if r.size and (not np.all(np.isfinite(r)) or np.min(r) < 0):
        raise ValueError(f"range_m must be finite and >= 0, got min {np.nanmin(r):.6g}")
    _check_positive("frequency_hz", frequency_hz)
    return 20 * np.log10(4 * np.pi * np.maximum(r, 1.0) * frequency_hz / SPEED_OF_LIGHT_MPS)


def ground_reflection_coefficient(grazing_rad: np.ndarray, frequency_hz: float, *, polarization: str = "vertical",
                                  relative_permittivity: float = 15.0,
                                  conductivity_s_per_m: float = 0.005) -> np.ndarray:
    """Fresnel reflection coefficient of a flat lossy ground at grazing angle psi (complex).

    eps_c = eps_r - j 60 sigma lambda; vertical: (eps_c sin psi - sqrt(eps_c - cos^2 psi)) /
    (eps_c sin psi + sqrt(...)), horizontal: (sin psi - sqrt(...)) / (sin psi + sqrt(...)). Both tend
    to -1 at grazing incidence. Defaults: average ground (ITU-R P.527: eps_r 15, sigma 5 mS/m).
    """
    _check_positive("relative_permittivity", relative_permittivity)
    if conductivity_s_per_m < 0:
        raise ValueError(f"conductivity_s_per_m must be >= 0, got {conductivity_s_per_m}")
    wavelength = SPEED_OF_LIGHT_MPS / frequency_hz
    eps = relative_permittivity - 1j * 60.0 * conductivity_s_per_m * wavelength
    s, c = np.sin(grazing_rad), np.cos(grazing_rad)
    root = np.sqrt(eps - c ** 2)
    if polarization == "vertical":
        return (eps * s - root) / (eps * s + root)
    if polarization == "horizontal":
        return (s - root) / (s + root)
    raise ValueError(f"polarization must be 'vertical' or 'horizontal', got {polarization!r}")


def antenna_gain(kind: str, direction: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Linear power gain of an antenna in ``direction`` (..., 3), given its ``axis`` (..., 3).

    isotropic: 1. dipole (half-wave, ``axis`` along the element): 1.641 [cos(pi/2 cos t)/sin t]^2 with
    t the angle from the element. patch (``axis`` = boresight): 2(q+1) cos^q(t) in front (q = 2,
    7.8 dBi), floored at the -20 dB back lobe.
    """
    d = np.asarray(direction, dtype=np.float64)
    a = np.asarray(axis, dtype=np.float64)
    cos_t = np.sum(d * a, axis=-1) / np.maximum(np.linalg.norm(d, axis=-1) * np.linalg.norm(a, axis=-1), 1e-12)
    cos_t = np.clip(cos_t, -1.0, 1.0)
    if kind == "isotropic":
        return np.ones_like(cos_t)
    if kind == "dipole":
        sin_t = np.sqrt(np.maximum(1.0 - cos_t ** 2, 1e-12))
        return DIPOLE_PEAK_GAIN * (np.cos(0.5 * np.pi * cos_t) / sin_t) ** 2
    if kind == "patch":
        peak = 2.0 * (PATCH_EXPONENT + 1.0)
        front = peak * np.maximum(cos_t, 0.0) ** PATCH_EXPONENT
        return np.maximum(front, peak * 10 ** (PATCH_BACK_LOBE_DB / 10))
    raise ValueError(f"antenna must be one of {ANTENNAS}, got {kind!r}")


def two_ray_path_gain(tx_m: np.ndarray, rx_m: np.ndarray, frequency_hz: np.ndarray | float, *,
                      tx_antenna: str = "isotropic", tx_axis: np.ndarray | None = None,
                      rx_antenna: str = "isotropic", rx_axis: np.ndarray | None = None,
                      reflection: str | complex = "vertical", relative_permittivity: float = 15.0,
                      conductivity_s_per_m: float = 0.005) -> np.ndarray:
    """Linear power gain P_rx / P_tx of the direct plus ground-reflected ray (antenna gains included).

    ``tx_m``/``rx_m`` (..., 3) with z the height above the ground (clamped to >= 0.1 m);
    ``reflection`` is 'vertical'/'horizontal' (Fresnel, lossy ground), 'none' (free space with
    antenna gains), or a fixed complex coefficient (e.g. -1 for the textbook plane-earth model).
    Gain = (lambda / 4 pi)^2 |sqrt(Gt1 Gr1) e^{-jk r1} / r1 + Gamma sqrt(Gt2 Gr2) e^{-jk r2} / r2|^2.
    """
    tx = np.array(tx_m, dtype=np.float64)
    rx = np.array(rx_m, dtype=np.float64)
    if not (np.all(np.isfinite(tx)) and np.all(np.isfinite(rx))):
        raise ValueError("tx_m and rx_m must be finite positions")
    f = np.asarray(frequency_hz, dtype=np.float64)
    if f.size and not np.all(f > 0):
        raise ValueError(f"frequency_hz must be > 0, got min {np.min(f)}")
    tx[..., 2] = np.maximum(tx[..., 2], MIN_HEIGHT_M)
    rx[..., 2] = np.maximum(rx[..., 2], MIN_HEIGHT_M)
    up = np.array([0.0, 0.0, 1.0])
    tx_axis = up if tx_axis is None else np.asarray(tx_axis, dtype=np.float64)
    rx_axis = up if rx_axis is None else np.asarray(rx_axis, dtype=np.float64)
    k = 2 * np.pi * f / SPEED_OF_LIGHT_MPS
    d1 = rx - tx                                           # direct ray, tx -> rx
    r1 = np.maximum(np.linalg.norm(d1, axis=-1), 1.0)
    g1 = antenna_gain(tx_antenna, d1, tx_axis) * antenna_gain(rx_antenna, -d1, rx_axis)
    field = np.sqrt(g1) * np.exp(-1j * k * r1) / r1
    if not (isinstance(reflection, str) and reflection == "none"):
        image = tx * np.array([1.0, 1.0, -1.0])            # transmitter mirrored in the ground
        d2 = rx - image                                    # reflected ray as seen from the image
        r2 = np.maximum(np.linalg.norm(d2, axis=-1), 1.0)
        leave = d2 * np.array([1.0, 1.0, -1.0])            # direction leaving the real tx (downwards)
        g2 = antenna_gain(tx_antenna, leave, tx_axis) * antenna_gain(rx_antenna, -d2, rx_axis)
        gamma: complex | np.ndarray
        if isinstance(reflection, str):
            grazing = np.arcsin(np.clip((tx[..., 2] + rx[..., 2]) / r2, 0.0, 1.0))
            gamma = ground_reflection_coefficient(grazing, float(np.mean(f)), polarization=reflection,
                                                  relative_permittivity=relative_permittivity,
                                                  conductivity_s_per_m=conductivity_s_per_m)
        else:
            gamma = complex(reflection)
        field = field + gamma * np.sqrt(g2) * np.exp(-1j * k * r2) / r2
    return (1.0 / (2 * k)) ** 2 * np.abs(field) ** 2       # (lambda / 4 pi)^2 = (1 / 2k)^2


def two_ray_path_loss_db(horizontal_range_m: np.ndarray | float, tx_height_m: float, rx_height_m: float,
                         frequency_hz: float, reflection: str | complex = -1.0) -> np.ndarray:
    """Two-ray loss (dB, isotropic antennas) over flat ground at horizontal distance d."""
    d = np.atleast_1d(np.asarray(horizontal_range_m, dtype=np.float64))
    tx = np.stack([np.zeros_like(d), np.zeros_like(d), np.full_like(d, tx_height_m)], -1)
    rx = np.stack([np.zeros_like(d), d, np.full_like(d, rx_height_m)], -1)
    return -10 * np.log10(two_ray_path_gain(tx, rx, frequency_hz, reflection=reflection))


def rician_gains(rng: np.random.Generator, shape: int | tuple[int, ...], k_factor_db: float | None) -> np.ndarray:
    """Complex small-scale fading gains with E|h|^2 = 1: Rician with K (dB), Rayleigh when K is None.

    h = sqrt(K/(K+1)) e^{j phi} + sqrt(1/(K+1)) CN(0, 1), phi uniform (the LOS phase).
    """
    k = 0.0 if k_factor_db is None else 10 ** (k_factor_db / 10)
    diffuse = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2)
    los = np.exp(1j * rng.uniform(0, 2 * np.pi, size=shape))
    return np.sqrt(k / (k + 1)) * los + np.sqrt(1 / (k + 1)) * diffuse


def rician_k_from_samples(h: np.ndarray) -> float:
    """Moment estimate of K from |h|^2 samples: gamma = Var/Mean^2, K = sqrt(1-gamma)/(1-sqrt(1-gamma))."""
    p = np.abs(np.asarray(h)) ** 2
    gamma = float(np.var(p) / np.mean(p) ** 2)
    root = np.sqrt(max(1.0 - gamma, 0.0))
    return float(root / max(1.0 - root, 1e-12))
