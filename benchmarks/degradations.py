"""Speed of every registered degradation, and ratios to peer libraries in the same run.

Inputs: one 640x512 RGB uint8 frame, one 640x512 thermal float32 frame (K), 0.25 s of audio at
44.1 kHz, one I/Q segment of 65536 complex64 samples, one 112x112 dB spectrogram. Each item is a
full ``degradations.apply`` call (rng derivation, params, dtype conversion included).
Peers (benchmark-only extras, imported lazily): albumentations GaussNoise, MotionBlur,
ImageCompression; audiomentations AddGaussianSNR, configured to the same strength.
Ratio = our items/s / peer items/s (>= 1.0 means we are at least as fast).

Run: .venv/bin/python benchmarks/degradations.py [--quick]
"""
from __future__ import annotations

import os
import sys
import time
from typing import Callable

import numpy as np

# This file is named like the package: drop its own folder from sys.path so `import degradations`
# finds the library (repo root) rather than this script.
_HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != _HERE]
sys.path.insert(0, os.path.dirname(_HERE))
import degradations  # noqa: E402
from degradations.spec import stream_is_a_parameter  # noqa: E402

H, W = 512, 640
SR = 44100


def inputs() -> dict[str, tuple[np.ndarray, dict]]:
    rng = np.random.default_rng(0)
    rgb = (rng.random((H, W, 3)) * 255).astype(np.uint8)
    th = (285 + rng.normal(0, 0.5, (H, W))).astype(np.float32)
    mask = np.zeros((H, W), bool)
    mask[250:262, 300:316] = True
    th[mask] += 2.0
    au = (0.1 * rng.normal(size=int(0.25 * SR))).astype(np.float32)
    iq = (rng.normal(size=65536) + 1j * rng.normal(size=65536)).astype(np.complex64) / np.float32(np.sqrt(2))
    sp = (-80 + 5 * rng.normal(size=(112, 112))).astype(np.float32)
    return {"rgb": (rgb, {"fps": 30.0}), "thermal": (th, {"thermal_mask": mask, "fps": 30.0}),
            "audio": (au, {"sample_rate_hz": SR, "background": rng.normal(size=SR).astype(np.float32)}),
            "rf_iq": (iq, {"sample_rate_hz": 1e6}), "rf_spec": (sp, {"frame_rate_hz": 4.0})}


def rate(fn: Callable[[], object], budget_s: float) -> float:
    """Items per second: best of repeated batches within a time budget (after one warm-up call)."""
    fn()
    n, best, spent = 1, 0.0, 0.0
    while spent < budget_s:
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        dt = time.perf_counter() - t0
        spent += dt
        best = max(best, n / dt)
        if dt < 0.05:
            n *= 2
    return best


def paired_rates(ours_fn, peer_fn, budget: float, rounds: int = 3) -> tuple[float, float]:
    """Best-of rates of ours and the peer, measured alternately so machine load hits both alike."""
    best_ours = best_peer = 0.0
    for _ in range(rounds):
        best_ours = max(best_ours, rate(ours_fn, budget))
        best_peer = max(best_peer, rate(peer_fn, budget))
    return best_ours, best_peer


def stream_of(name: str) -> str:
    from degradations.spec import default_stream
    return default_stream(name)


def main() -> None:
    quick = "--quick" in sys.argv
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    budget = 0.1 if quick else 0.4
    data = inputs()
    ours: dict[str, float] = {}
    print(f"{'degradation':34s} {'items/s':>10s}")
    for name in sorted(degradations.REGISTRY):
        stream = stream_of(name)
        kw = {"stream": stream} if stream_is_a_parameter(name) else {}
        x, meta = data[stream]
        if name in ("video.frame_drop", "video.frame_freeze", "crossmodal.frame_rate_mismatch",
                    "crossmodal.desync"):
            x = np.stack([x] * 8)  # retiming needs a clip: one item = 8 frames
        ours[name] = rate(lambda: degradations.apply(name, x, seed=1, severity=3, meta=meta, **kw), budget)
        print(f"{name:34s} {ours[name]:10.1f}")

    ratios: dict[str, float] = {}
    rgb, _ = data["rgb"]
    au, _ = data["audio"]
    try:
        import albumentations as A
        peers = {
            "video.gaussian_noise": A.GaussNoise(std_range=(0.18, 0.18), mean_range=(0, 0), p=1.0),
            "video.motion_blur": A.MotionBlur(blur_limit=(15, 15), p=1.0),
            "video.jpeg": A.ImageCompression(quality_range=(15, 15), p=1.0),
        }
        for name, tf in peers.items():
            mine, peer = paired_rates(lambda: degradations.apply(name, rgb, seed=1, severity=3),
                                      lambda: tf(image=rgb)["image"], budget)
            ratios[f"{name} vs albumentations.{type(tf).__name__}"] = mine / peer
            print(f"peer albumentations.{type(tf).__name__:26s} {peer:10.1f}")
    except ImportError:
        print("albumentations not installed: RGB peer ratios skipped (pip install .[bench])")
    try:
        import audiomentations as AM
        tf = AM.AddGaussianSNR(min_snr_db=10.0, max_snr_db=10.0, p=1.0)
        mine, peer = paired_rates(lambda: degradations.apply("audio.white_noise", au, seed=1, severity=3,
                                                             meta=data["audio"][1]),
                                  lambda: tf(samples=au, sample_rate=SR), budget)
        ratios["audio.white_noise vs audiomentations.AddGaussianSNR"] = mine / peer
        print(f"peer audiomentations.AddGaussianSNR     {peer:10.1f}")
    except ImportError:
        print("audiomentations not installed: audio peer ratio skipped (pip install .[bench])")
    for k, v in ratios.items():
        print(f"ratio {k}: {v:.2f}")
    worst = min(ratios.values()) if ratios else float("nan")
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    print(f"worst ratio vs peers: {worst:.2f}")


if __name__ == "__main__":
    main()
