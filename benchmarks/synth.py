"""Synthesis time of one 10 s TRIDENT-style tri-modal clip, rendering excluded.

Timed (best of --repeats, one process, one core): audio of every source + ambience at 44.1 kHz
(rotor harmonics, Doppler, spreading, ISO 9613-1 absorption), 40 MFCCs 1x40x40 (librosa), RF I/Q of
40 captures (40 x 50 400 complex64 at 20 MS/s: drone control + video links, Wi-Fi, Bluetooth,
noise) and the 40 spectrograms + uint8 images. Not timed: scenario loading and the timeline
(shared with the renderer). Reference in the same run: a naive per-harmonic np.sin oscillator bank
for the same rotor lines (what the Horner evaluation replaces).

Run: .venv/bin/python benchmarks/synth.py [--repeats N]   (last line: `clip synthesis s: X`)
"""
from __future__ import annotations

import argparse
import os
import sys
import time

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import numpy as np  # noqa: E402

from scenes.loader import load_scenario  # noqa: E402
from simulator.dataset import trident as tr  # noqa: E402
from simulator.physics.acoustics.ambience import Ambience  # noqa: E402
from simulator.physics.acoustics.levels import AUDIO_SAMPLE_RATE_HZ  # noqa: E402
from simulator.physics.acoustics.mix import synthesize_audio  # noqa: E402
from simulator.physics.rf import spectrogram_image, synthesize_rf  # noqa: E402
from simulator.physics.timeline import build_timeline  # noqa: E402


def _clip(timeline, seed: int, cfg: tr.TridentConfig, ambience: Ambience) -> dict[str, float]:
    t0 = time.perf_counter()
    audio = synthesize_audio(timeline, seed, ambience=ambience, duration_s=cfg.clip_duration_s)
    t1 = time.perf_counter()
    tr.mfcc_segments(audio.mix_pa / cfg.full_scale_pa, AUDIO_SAMPLE_RATE_HZ, cfg.n_segments)
    t2 = time.perf_counter()
    cap = synthesize_rf(timeline, seed, np.arange(cfg.n_segments) * tr.SEGMENT_S, config=cfg.rf,
                        clip_duration_s=cfg.clip_duration_s)
    spectrogram_image(cap.spectrogram_dbm, cfg.rf)
    t3 = time.perf_counter()
    return {"audio": t1 - t0, "mfcc": t2 - t1, "rf": t3 - t2, "total": t3 - t0}


def _naive_rotor_lines(timeline, n_samples: int) -> float:
    """Reference: the same 4 rotors x 13 lines as independent float64 np.sin oscillators."""
    track = timeline.targets[0]
    t = np.arange(n_samples) / AUDIO_SAMPLE_RATE_HZ
    t0 = time.perf_counter()
    out = np.zeros(n_samples)
    for r in range(track.rotor_rpm.shape[1]):
        shaft = np.interp(t, timeline.times_s, track.rotor_rpm[:, r]) / 60.0
        phase = 2 * np.pi * np.cumsum(shaft) / AUDIO_SAMPLE_RATE_HZ
        for power in [2 * k for k in range(1, 11)] + [1, 7, 14]:
            out += np.sin(power * phase) / power
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    cfg = tr.load_trident_config("trident_mini")
    scenario = tr.clip_scenario(load_scenario("clear_day_quad"), cfg)
    timeline = build_timeline(scenario, 1)
    ambience = Ambience(wind_db=42.0, traffic_db=40.0, rain_db=45.0, birdsong_db=38.0)
    _clip(timeline, 0, cfg, ambience)                       # warm-up: imports, FFT plans, librosa caches
    runs = [_clip(timeline, 1 + i, cfg, ambience) for i in range(args.repeats)]
    best = min(runs, key=lambda r: r["total"])
    naive = _naive_rotor_lines(timeline, int(cfg.clip_duration_s * AUDIO_SAMPLE_RATE_HZ))
    print(f"scenario clear_day_quad re-timed to {cfg.clip_duration_s:.0f} s at {cfg.video_fps} fps; "
          f"ambience wind+traffic+rain+birdsong; RF {cfg.rf.capture_samples} samples x {cfg.n_segments} captures "
          f"at {cfg.rf.sample_rate_hz / 1e6:.0f} MS/s")
    totals = ", ".join(f"{r['total']:.3f}" for r in runs)
    print(f"audio s: {best['audio']:.3f}  mfcc s: {best['mfcc']:.3f}  rf s: {best['rf']:.3f}  "
          f"(best of {args.repeats}; totals {totals})")
    print(f"naive np.sin oscillator bank for the rotor lines alone: {naive:.3f} s")
    print(f"clip synthesis s: {best['total']:.3f}")


if __name__ == "__main__":
    main()
