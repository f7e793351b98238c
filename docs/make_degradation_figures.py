"""Before/after grids, one PNG per modality: docs/images/degradations_<modality>.png.

Run: .venv/bin/python docs/make_degradation_figures.py   (synthetic inputs, seed 0, severity 3)
"""
from __future__ import annotations

import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy import signal  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import degradations  # noqa: E402
from degradations.spec import stream_is_a_parameter  # noqa: E402

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "images")
H, W = 128, 160


def scene_rgb() -> np.ndarray:
    """Sky gradient, ground, and a dark quadcopter-like blob; uint8 (H, W, 3)."""
    y = np.linspace(0, 1, H)[:, None]
    sky = np.stack([0.45 + 0.3 * y, 0.6 + 0.25 * y, 0.9 - 0.1 * y], -1) * np.ones((1, W, 1))
    img = sky.copy()
    img[int(H * 0.75):] = [0.3, 0.42, 0.25]
    rng = np.random.default_rng(1)
    img[int(H * 0.75):] += 0.05 * rng.normal(size=(H - int(H * 0.75), W, 1))
    img[50:56, 70:90] = [0.1, 0.1, 0.12]
    img[47:50, 68:74] = img[47:50, 86:92] = [0.15, 0.15, 0.15]
    return (np.clip(img, 0, 1) * 255).astype(np.uint8)


def scene_thermal() -> tuple[np.ndarray, np.ndarray]:
    y = np.linspace(0, 1, H)[:, None]
    x = (230 + 40 * y) * np.ones((1, W))
    x[int(H * 0.75):] = 283
    x += np.random.default_rng(2).normal(0, 0.1, x.shape)
    m = np.zeros((H, W), bool)
    m[50:56, 70:90] = True
    x[m] += 25.0
    return x.astype(np.float32), m


def grid(names, x, show, meta, fname, ncols=5, **kw):
    n = len(names) + 1
    rows = int(np.ceil(n / ncols))
    fig, axes = plt.subplots(rows, ncols, figsize=(2.6 * ncols, 2.3 * rows))
    axes = axes.ravel()
    show(axes[0], x)
    axes[0].set_title("original", fontsize=8)
    for ax, name in zip(axes[1:], names):
        extra = {"stream": kw["stream"]} if stream_is_a_parameter(name) and "stream" in kw else {}
        y = degradations.apply(name, x, seed=0, severity=3, meta=meta, **extra)
        show(ax, y)
        ax.set_title(name, fontsize=8)
    for ax in axes:
        ax.set_xticks([])
        ax.set_yticks([])
    for ax in axes[n:]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(os.path.join(OUT, fname), dpi=80)
    plt.close(fig)


def main() -> None:
    os.makedirs(OUT, exist_ok=True)
    names = sorted(degradations.REGISTRY)
    rgb = scene_rgb()
    still = [n for n in names if n.startswith("video.") and n not in ("video.frame_drop", "video.frame_freeze")]
    grid(still + ["crossmodal.misalignment"], rgb, lambda ax, im: ax.imshow(im), {"range_m": 400.0},
         "degradations_rgb.png", stream="rgb")
    th, m = scene_thermal()
    tnames = [n for n in names if n.startswith("thermal.")] + ["crossmodal.misalignment"]
    grid(tnames, th, lambda ax, im: ax.imshow(im, cmap="inferno", vmin=225, vmax=300), {"thermal_mask": m},
         "degradations_thermal.png", ncols=5, stream="thermal")
    sr = 16000
    t = np.arange(int(0.25 * sr)) / sr
    au = (0.3 * np.sin(2 * np.pi * 180 * t * (1 + 0.02 * np.sin(2 * np.pi * 8 * t)))
          + 0.15 * np.sin(2 * np.pi * 360 * t) + 0.08 * np.sin(2 * np.pi * 1440 * t)).astype(np.float32)

    def spec_show(ax, a):
        f, tt, s = signal.spectrogram(a, fs=sr, nperseg=256, noverlap=192)
        ax.pcolormesh(tt, f, 10 * np.log10(s + 1e-12), shading="auto", vmin=-90, vmax=-20)
        ax.set_ylim(0, 4000)
    anames = [n for n in names if n.startswith("audio.")]
    grid(anames, au, spec_show, {"sample_rate_hz": sr, "background": np.random.default_rng(3).normal(size=sr)},
         "degradations_audio.png", ncols=4)
    # RF: I/Q shown as its spectrogram; spectrogram-domain ones on a synthetic spectrogram image
    n = 16384
    k = np.arange(n)
    rng = np.random.default_rng(4)
    hop = np.repeat(rng.integers(-3, 4, n // 1024), 1024) * 0.06
    iq = (np.exp(2j * np.pi * (0.05 + hop) * k) * (np.repeat(rng.random(n // 512) < 0.7, 512))).astype(np.complex64)
    iq += (0.01 * (rng.normal(size=n) + 1j * rng.normal(size=n))).astype(np.complex64)

    def iq_show(ax, a):
        f, tt, s = signal.spectrogram(a, fs=1.0, nperseg=256, noverlap=128, return_onesided=False)
        ax.pcolormesh(tt, np.fft.fftshift(f), np.fft.fftshift(10 * np.log10(s + 1e-12), axes=0), shading="auto",
                      vmin=-60, vmax=10)
    inames = [x for x in names if x.startswith("rf.") and not x.startswith("rf.spec_")]
    grid(inames, iq, iq_show, {"sample_rate_hz": 1e6}, "degradations_rf_iq.png", ncols=4)
    f, tt, s = signal.spectrogram(iq, fs=1.0, nperseg=128, noverlap=0, return_onesided=False)
    spec = np.fft.fftshift(10 * np.log10(s + 1e-12), axes=0).astype(np.float32)
    snames = [x for x in names if x.startswith("rf.spec_")]
    grid(snames, spec, lambda ax, im: ax.imshow(im, aspect="auto", origin="lower", vmin=-60, vmax=10), {},
         "degradations_rf_spec.png", ncols=3)
    print("wrote", sorted(x for x in os.listdir(OUT) if x.startswith("degradations_")))


if __name__ == "__main__":
    main()
