"""Small synthetic clip sets (no renderer) for split, audit and conflict-program tests.

Each scene has a drone clip and its drone-absent twin: identical scene content (sky colour, audio
bed, RF interferers), plus in the drone clip a dark square in the video, a tone band in the MFCC
and a bright line in the RF spectrogram. ``confounded=True`` gives drone scenes a bluer sky and
background scenes a greyer one, with no twins: the class is readable from the scene.
"""
from __future__ import annotations

import numpy as np

from harness.experiments.data import ClipArrays
from simulator.formats.trident import mfcc_segments

S = 8            # segments per clip
FS = 8000.0      # only the waveform length matters here


def _scene_content(rng: np.random.Generator, confounded: bool, label: int):
    sky = rng.uniform(120, 200, 3)
    if confounded:
        sky = sky + (np.array([-25, -10, 30]) if label == 0 else np.array([15, 15, 15]))
    video = np.broadcast_to(sky.astype(np.uint8), (S, 7, 112, 112, 3)).copy()
    video += rng.integers(0, 6, video.shape, dtype=np.uint8)
    rf = np.clip(rng.normal(0.2, 0.02, (S, 112, 112)), 0, 1).astype(np.float32)
    audio = (rng.normal(0, 0.01, int(S * 0.25 * FS)) * rng.uniform(0.5, 2.0)).astype(np.float32)
    return video, rf, audio


def _add_drone(video, rf, audio, rng):
    video, rf = video.copy(), rf.copy()
    y, x = rng.integers(30, 70, 2)
    video[:, :, y:y + 8, x:x + 8] = 30
    rf[:, 40:44, :] = 0.9
    t = np.arange(audio.size) / FS
    tone = 0.05 * sum(np.sin(2 * np.pi * f * t) for f in (700.0, 1400.0, 2100.0))
    return video, rf, (audio + tone).astype(np.float32)


def make_clips(n_scenes: int, seed: int = 0, confounded: bool = False, twins: bool = True,
               splits: tuple[int, int, int] | None = None) -> list[ClipArrays]:
    """``n_scenes`` scenes; with twins each gives a Drone and a Background clip of the same scene.
    ``splits`` = (n_train, n_val, n_test) scenes records a dataset split per clip."""
    rng = np.random.default_rng(seed)
    clips = []
    for j in range(n_scenes):
        split = None
        if splits is not None:
            split = "train" if j < splits[0] else "val" if j < splits[0] + splits[1] else "test"
        labels = (0, 1) if twins else (j % 2,)
        base = _scene_content(rng, confounded, labels[0])
        for label in labels:
            video, rf, audio = base if label == 1 else _add_drone(*base, rng)
            mfcc = mfcc_segments(audio, FS, S)
            obs = {m: np.full(S, label == 0) for m in ("video", "audio", "rf")}
            cid = f"{['Drone', 'Background'][label]}/scene_{j:03d}/{2 * j + 1 + label}"
            twin = f"{['Background', 'Drone'][label]}/scene_{j:03d}/{2 * j + 2 - label}" if twins else None
            clips.append(ClipArrays(clip_id=cid, label=label, mfcc=mfcc, video=video, rf=rf, audio=audio,
                                    sample_rate_hz=FS, observability=obs, scene=f"scene_{j:03d}", split=split,
                                    twin=twin, drone_px=np.full(S, 8.0 if label == 0 else 0.0)))
    return clips
