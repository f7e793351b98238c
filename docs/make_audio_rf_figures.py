"""Figures for docs/AUDIO_RF.md: audio spectrograms, A-weighted level vs distance (ground effect),
RF spectrogram images of the link presets, path loss (Friis vs two-ray) and hop statistics.

Run: .venv/bin/python docs/make_audio_rf_figures.py   (writes docs/images/audio_spectrogram.png,
audio_level_vs_range.png, rf_spectrograms.png, rf_propagation.png; no rendering)
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
from simulator.physics import acoustics as ac  # noqa: E402
from simulator.physics import propagation as prop  # noqa: E402
from simulator.physics import rf_links  # noqa: E402
from simulator.physics.rf import RFConfig, spectrogram_image, synthesize_rf  # noqa: E402
from simulator.physics.timeline import TargetTrack, build_timeline, rotor_hover_rpm  # noqa: E402
from simulator.seeding import rng_for  # noqa: E402

OUT = Path(__file__).resolve().parent / "images"
FS = ac.AUDIO_SAMPLE_RATE_HZ


def _audio_spectrogram(cfg) -> None:
    flyby = tr.clip_scenario(scenario_from_dict({
        "name": "flyby_doc", "duration_s": 10.0,
        "targets": [{"name": "drone", "kind": "quadcopter", "size_m": 0.45,
                     "trajectory": {"kind": "flyby", "start_m": [-150, 40, 20], "velocity_mps": [30, 0, 0]}}],
        "camera_rig": {"position_m": [0, 0, 1.5], "track_target": "drone"}}), cfg)
    timeline = build_timeline(flyby, 1)
    audio = ac.synthesize_audio(timeline, 1, ambience=ac.Ambience(wind_db=42.0, birdsong_db=40.0), duration_s=10.0)
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.2), sharey=True)
    for ax, (title, x) in zip(axes, [("drone only (quadcopter flyby, 30 m/s, closest 40 m at t = 5 s)",
                                      audio.targets_pa["drone"]),
                                      ("mix: drone + wind 42 dB + birdsong 40 dB", audio.mix_pa)]):
        f, t, s = spectrogram(x, fs=FS, nperseg=4096, noverlap=3072)
        im = ax.pcolormesh(t, f, ac.pa_to_db_spl(np.sqrt(s)), vmin=-20, vmax=50, shading="auto", cmap="magma")
        ax.set_ylim(0, 3000)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("time (s)")
    axes[0].set_ylabel("frequency (Hz)")
    fig.colorbar(im, ax=axes, label="dB re 20 uPa per Hz^0.5 (PSD)")
    fig.savefig(OUT / "audio_spectrogram.png", dpi=90)
    plt.close(fig)


def _a_level_db(x: np.ndarray) -> float:
    spec = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(x.size, 1.0 / FS)
    w = 10 ** (ac.a_weighting_db(np.maximum(f, 1.0)) / 10)
    return float(10 * np.log10(2 * np.sum(spec * w) / x.size ** 2 / ac.P_REF_PA ** 2))


def _audio_level_vs_range() -> None:
    distances = np.geomspace(20, 3000, 14)
    t = np.arange(0.0, 0.6, 1.0 / 28)
    mic = np.array([0.0, 0.0, 1.5])
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    for g, style in ((None, "k-"), (0.0, "b--"), (0.5, "g-."), (1.0, "r:")):
        levels = []
        for k, d in enumerate(distances):
            pos = np.tile([0.0, d, 30.0], (t.size, 1))
            track = TargetTrack(1, "q", "quadcopter", 0.45, pos, np.zeros_like(pos), np.tile(np.eye(3), (t.size, 1, 1)),
                                np.full((t.size, 4), rotor_hover_rpm("quadcopter", 0.45)), np.zeros(t.size),
                                np.zeros(t.size), n_blades=2)
            x, _ = ac.synthesize_target(track, t, mic, FS // 2, FS, 288.15, 0.7, rng_for(k, "acoustics", 0),
                                        ground_factor=g)
            levels.append(_a_level_db(x[FS // 20:]))
        ax.semilogx(distances, levels, style, label="free field" if g is None else f"ISO 9613-2 ground G = {g}")
    ax.axhline(35.0, color="0.5", lw=0.8)
    ax.text(25, 36, "broadband level of a quiet rural ambience ~35 dBA (rotor lines stay detectable below it)",
            fontsize=7, color="0.4")
    ax.set_xlabel("horizontal distance (m), drone 30 m up, microphone 1.5 m")
    ax.set_ylabel("drone level dB(A)")
    ax.set_title(f"0.45 m quad at hover: L_WA {ac.sound_power_dba('quadcopter', 0.45):.1f} dB, 15 C / 70 % RH",
                 fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "audio_level_vs_range.png", dpi=90)
    plt.close(fig)


def _rf_spectrograms(cfg) -> None:
    quad = tr.clip_scenario(load_scenario("clear_day_quad"), cfg)
    tl_quad = build_timeline(quad, 2)
    starts = np.arange(40) * tr.SEGMENT_S
    rf = RFConfig(links=("elrs_like_250hz", "ocusync_like_10mhz"))
    # seed 1 puts the OcuSync-like link on 2436.5 MHz (inside the window): pick captures that show each case
    drone = synthesize_rf(tl_quad, 1, starts, config=rf, clip_duration_s=10.0)
    silent = synthesize_rf(tl_quad, 1, starts, config=rf, rf_silent=True, clip_duration_s=10.0)
    ctrl = drone.bursts_per_capture["drone/elrs_like_250hz"]
    video = drone.bursts_per_capture["drone/ocusync_like_10mhz"]
    pick = {"control burst(s) + video": int(np.argmax((ctrl > 0) & (video > 0))),
            "video only (no hop landed)": int(np.argmax((ctrl == 0) & (video > 0)))}
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.4))
    half = cfg.rf.sample_rate_hz / 2e6
    extent = [0, cfg.rf.capture_samples / cfg.rf.sample_rate_hz * 1e3, -half, half]
    panels = [(f"drone, segment {s}: {name}", drone, s) for name, s in pick.items()]
    panels.append(("same clip, radios off (Wi-Fi + Bluetooth only)", silent, 0))
    for ax, (title, cap, s) in zip(axes, panels):
        ax.imshow(spectrogram_image(cap.spectrogram_dbm[s], rf), cmap="gray", vmin=0, vmax=255, aspect="auto",
                  extent=extent)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("time in capture (ms)")
    axes[0].set_ylabel("offset from 2.44 GHz (MHz)")
    fig.suptitle("RF spectrogram images as written (112x112 uint8; black = noise/bin - 10 dB, white = +70 dB); "
                 "ExpressLRS-like 250 Hz LoRa hops + OcuSync-like 10 MHz OFDM", fontsize=9)
    fig.savefig(OUT / "rf_spectrograms.png", dpi=90)
    plt.close(fig)


def _rf_propagation() -> None:
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.3))
    d = np.geomspace(50, 20e3, 400)
    ax = axes[0]
    ax.semilogx(d, prop.free_space_path_loss_db(d, 2.44e9), "k-", label="Friis (free space)")
    ax.semilogx(d, prop.two_ray_path_loss_db(d, 30.0, 1.5, 2.44e9, -1.0), "b-",
                label="two-ray, Gamma = -1 (30 m / 1.5 m)")
    ax.semilogx(d, prop.two_ray_path_loss_db(d, 30.0, 1.5, 2.44e9, "vertical"), "g--",
                label="two-ray, average ground, vertical pol.")
    ax.semilogx(d, prop.two_ray_path_loss_db(d, 10.0, 1.5, 2.44e9, -1.0), "r:",
                label="two-ray, Gamma = -1 (10 m / 1.5 m)")
    ax.plot([10e3], [126.9], "ko", ms=4)
    ax.annotate("126.9 dB vs 120.2 dB at 10 km", (10e3, 126.9), (1.2e3, 132), fontsize=8,
                arrowprops={"arrowstyle": "->"})
    ax.set_xlabel("horizontal distance (m)")
    ax.set_ylabel("path loss at 2.44 GHz (dB)")
    ax.set_ylim(70, 150)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax = axes[1]
    cfg = RFConfig()
    lo, hi = cfg.passband_hz
    for name, color in (("elrs_like_250hz", "C0"), ("elrs_like_500hz", "C1"), ("frsky_like", "C2")):
        preset = rf_links.LINK_PRESETS[name]
        counts = []
        for k in range(20):
            starts = np.sort(rng_for(k, "rf", 9000).uniform(0, 60, 200))
            sched = rf_links.fhss_schedule(preset, rng_for(k, "rf", 9001), 61.0)
            vis = (sched.centre_hz >= lo) & (sched.centre_hz <= hi)
            counts += [int(np.sum(vis[i])) for i in rf_links.bursts_in_windows(sched, starts, cfg.capture_s)]
        hist = np.bincount(counts, minlength=4)[:4] / len(counts)
        expected = rf_links.expected_fhss_counts(preset, cfg.capture_s, cfg.fhss_visible_fraction(preset))["mean"]
        ax.bar(np.arange(4) + {"C0": -0.27, "C1": 0.0, "C2": 0.27}[color], hist, width=0.25, color=color,
               label=f"{name}: mean {np.mean(counts):.2f} (analytic {expected:.2f})")
    ax.set_xticks(range(4), ["0", "1", "2", "3"])
    ax.set_xlabel("control bursts in one 2.52 ms capture (+-9 MHz window)")
    ax.set_ylabel("fraction of captures")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(OUT / "rf_propagation.png", dpi=90)
    plt.close(fig)


def main() -> None:
    OUT.mkdir(exist_ok=True)
    cfg = tr.load_trident_config("trident_mini")
    _audio_spectrogram(cfg)
    _audio_level_vs_range()
    _rf_spectrograms(cfg)
    _rf_propagation()
    print(f"wrote {', '.join(p.name for p in sorted(OUT.glob('*.png')) if p.stem.startswith(('audio', 'rf')))} in "
          f"{OUT}")


if __name__ == "__main__":
    main()
