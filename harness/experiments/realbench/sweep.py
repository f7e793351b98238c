"""The degradation specs of the real-benchmark sweep and how they are applied to classifier inputs.

Every degradation is a registered ``degradations`` entry (``sample_params(rng, meta)`` + pure
``apply``) called through ``degradations.apply`` at a severity in [0, 5]; the same seed at two
severities gives the same noise field scaled (paired severities), and real and synthetic inputs go
through the same call. Visual degradations act on the 32-px target crop the classifiers see (one
one-frame clip per crop); audio degradations on the whole 10 s clip before its log-mel windows.

IR crops are 8-bit AGC views, while the thermal degradations work in kelvin: a crop is mapped to
kelvin with the nominal gain :data:`IR_KELVIN_PER_GREY` around 293.15 K (grey 128), degraded, and
mapped back (rounded, clipped to 0-255). The gain is an assumption, the same for both domains, so it
scales how hard a thermal spec bites but not whether real and synthetic agree.
"""
from __future__ import annotations

import numpy as np

#: Specs per sensor: (short label, registered degradation). Compression on IR is the visible camera's
#: block coder applied to the grey crop (replicated to three channels, luma taken back).
SPECS: dict[str, tuple[tuple[str, str], ...]] = {
    "ir": (("noise", "thermal.netd_noise"), ("blur", "thermal.blur_halo"), ("contrast loss", "thermal.crossover"),
           ("dead/stuck pixels", "thermal.dead_pixels"), ("non-uniformity", "thermal.fixed_pattern"),
           ("compression", "video.block_compression")),
    "visible": (("noise", "video.gaussian_noise"), ("blur", "video.defocus_blur"),
                ("motion blur", "video.motion_blur"), ("low light", "video.low_light"), ("glare", "video.sun_glare"),
                ("haze", "video.fog"), ("occlusion", "video.smoke")),
    "audio": (("noise", "audio.white_noise"), ("wind", "audio.wind"), ("clipping", "audio.gain_clip"),
              ("dropouts", "audio.dropout")),
}
IR_KELVIN_PER_GREY = 0.1       # nominal: the 8-bit range spans 25.5 K
IR_REFERENCE_K = 293.15


def centre_mask(px: int, context: float) -> np.ndarray:
    """Target mask of a crop: the centre square of side px / context (the crop is ``context`` x the box)."""
    side = max(1, int(round(px / context)))
    m = np.zeros((px, px), bool)
    a = (px - side) // 2
    m[a:a + side, a:a + side] = True
    return m


def degrade_crops(crops: np.ndarray, sensor: str, name: str, severity: float, seed: int,
                  context: float = 2.0) -> np.ndarray:
    """Degrade a stack of uint8 crops ((n, px, px) IR grey or (n, px, px, 3) visible RGB) with
    registered ``name`` at ``severity``; returns uint8 of the same shape. Item i draws from
    ``SeedSequence([seed, crc32(name), i])`` (``degradations.apply`` on a batch)."""
    import degradations

    if severity <= 0 or len(crops) == 0:
        return crops.copy()
    if name.startswith("thermal."):
        k = IR_REFERENCE_K + (crops.astype(np.float32) - 128.0) * np.float32(IR_KELVIN_PER_GREY)
        meta = {"thermal_mask": centre_mask(crops.shape[1], context)}
        y = degradations.apply(name, k[:, None], seed=seed, severity=severity, meta=meta)[:, 0]
        return np.clip(np.round((y - IR_REFERENCE_K) / IR_KELVIN_PER_GREY + 128.0), 0, 255).astype(np.uint8)
    if not name.startswith("video."):
        raise ValueError(f"{name}: not a visual degradation")
    rgb = crops if crops.ndim == 4 else np.repeat(crops[..., None], 3, axis=3)
    x = rgb.astype(np.float32) / 255.0
    y = degradations.apply(name, x[:, None], seed=seed, severity=severity)[:, 0]
    y = np.clip(np.round(y * 255.0), 0, 255)
    if crops.ndim == 3:
        y = y @ np.array([0.299, 0.587, 0.114], np.float32)
        y = np.clip(np.round(y), 0, 255)
    return y.astype(np.uint8)


def degrade_audio(samples: np.ndarray, sample_rate_hz: int, name: str, severity: float, seed: int) -> np.ndarray:
    """Degrade one mono clip (float32) with registered audio ``name`` at ``severity``."""
    import degradations

    if severity <= 0:
        return samples.copy()
    y = degradations.apply(name, samples.astype(np.float32), seed=seed, severity=severity,
                           meta={"sample_rate_hz": float(sample_rate_hz)})
    return np.asarray(y, np.float32)
