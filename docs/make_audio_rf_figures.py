"""Figures for docs/AUDIO_RF.md: audio spectrograms (drone flyby / mix) and RF spectrogram images.

Run: .venv/bin/python docs/make_audio_rf_figures.py   (writes docs/images/audio_spectrogram.png and
docs/images/rf_spectrograms.png; no rendering)
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.signal import spectrogram  # noqa: E402

from scenes.loader import load_scenario, scenario_from_dict  # noqa: E402
from simulator.dataset import trident as tr  # noqa: E402
from simulator.physics.acoustics import (  # noqa: E402
    AUDIO_SAMPLE_RATE_HZ,
    Ambience,
    pa_to_db_spl,
    synthesize_audio,
)
from simulator.physics.rf import spectrogram_image, synthesize_rf  # noqa: E402
from simulator.physics.timeline import build_timeline  # noqa: E402

OUT = Path(__file__).resolve().parent / "images"


def main() -> None:
    OUT.mkdir(exist_ok=True)
    cfg = tr.load_trident_config("trident_mini")
    flyby = tr.clip_scenario(scenario_from_dict({
        "name": "flyby_doc", "duration_s": 10.0,
        "targets": [{"name": "drone", "kind": "quadcopter", "size_m": 0.45,
                     "trajectory": {"kind": "flyby", "start_m": [-150, 40, 20], "velocity_mps": [30, 0, 0]}}],
        "camera_rig": {"position_m": [0, 0, 1.5], "track_target": "drone"}}), cfg)
    timeline = build_timeline(flyby, 1)
    audio = synthesize_audio(timeline, 1, ambience=Ambience(wind_db=42.0, birdsong_db=40.0), duration_s=10.0)
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.2), sharey=True)
    for ax, (title, x) in zip(axes, [("drone only (quadcopter flyby, 30 m/s, closest 40 m at t = 5 s)",
                                      audio.targets_pa["drone"]), ("mix: drone + wind 42 dB + birdsong 40 dB", audio.mix_pa)]):
        f, t, s = spectrogram(x, fs=AUDIO_SAMPLE_RATE_HZ, nperseg=4096, noverlap=3072)
        im = ax.pcolormesh(t, f, pa_to_db_spl(np.sqrt(s)), vmin=-20, vmax=50, shading="auto", cmap="magma")
        ax.set_ylim(0, 3000)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("time (s)")
    axes[0].set_ylabel("frequency (Hz)")
    fig.colorbar(im, ax=axes, label="dB re 20 uPa per Hz^0.5 (PSD)")
    fig.savefig(OUT / "audio_spectrogram.png", dpi=90)
    plt.close(fig)

    quad = tr.clip_scenario(load_scenario("clear_day_quad"), cfg)
    tl_quad = build_timeline(quad, 2)
    starts = np.arange(40) * tr.SEGMENT_S
    drone = synthesize_rf(tl_quad, 2, starts, config=cfg.rf, clip_duration_s=10.0)
    silent = synthesize_rf(tl_quad, 2, starts, config=cfg.rf, rf_silent=True, clip_duration_s=10.0)
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.4))
    half = cfg.rf.sample_rate_hz / 2e6
    extent = [0, cfg.rf.capture_samples / cfg.rf.sample_rate_hz * 1e3, -half, half]
    panels = [("Drone clip, segment 0", drone, 0), ("Drone clip, segment 20", drone, 20),
              ("same clip, radios off (background emitters only)", silent, 0)]
    for ax, (title, cap, s) in zip(axes, panels):
        ax.imshow(spectrogram_image(cap.spectrogram_dbm[s], cfg.rf), cmap="gray", vmin=0, vmax=255, aspect="auto", extent=extent)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("time in capture (ms)")
    axes[0].set_ylabel("offset from 2.44 GHz (MHz)")
    fig.suptitle("RF spectrogram images as written (112x112 uint8; black = noise/bin - 10 dB, white = +70 dB)", fontsize=10)
    fig.savefig(OUT / "rf_spectrograms.png", dpi=90)
    plt.close(fig)
    print(f"wrote {OUT / 'audio_spectrogram.png'} and {OUT / 'rf_spectrograms.png'}")


if __name__ == "__main__":
    main()
