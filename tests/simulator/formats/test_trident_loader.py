"""TRIDENT loader: round trip of a tiny generated clip, and the public layout's naming variants."""
from __future__ import annotations

import numpy as np
import pytest

from simulator.dataset import trident as tr
from simulator.formats.trident import LABELS, TridentDataset, discover_clips


def _frames(n: int, px: int = 112) -> np.ndarray:
    """Frame i is a flat grey of level 8 * i (survives JPEG), so segment alignment is checkable."""
    return np.broadcast_to((np.arange(n, dtype=np.uint8) * 8)[:, None, None, None], (n, px, px, 3)).copy()


@pytest.fixture
def tiny_trident(tmp_path):
    """A tiny TRIDENT-layout folder: one 1 s drone clip (4 segments) written by the generator, no rendering."""
    cfg = tr.load_trident_config({
        "name": "tiny", "clip_duration_s": 1.0, "rf": {"capture_samples": 112 * 40},
        "clips": [{"scenario": {"name": "hover", "duration_s": 1.0,
                                "targets": [{"name": "d", "kind": "quadcopter", "size_m": 0.45,
                                             "trajectory": {"kind": "hover", "center_m": [0, 60, 15]}}],
                                "camera_rig": {"position_m": [0, 0, 1.5], "look_at_m": [0, 60, 15]}}}]})
    scen = tr.clip_scenario(tr.resolve_scenario(cfg.clips[0]), cfg)
    clip = tr.synthesize_clip(scen, 9, cfg, frames=_frames(28))
    tr.write_clip(tmp_path, "hover", 1, clip, cfg, {"seed": 9})
    return tmp_path, clip


def test_round_trip_of_a_generated_clip(tiny_trident):
    root, clip = tiny_trident
    ds = TridentDataset(root)
    assert len(ds) == 4 and [c.clip_id for c in ds.clips] == ["Drone/hover/1"]
    segs = list(ds)
    assert [s.segment_index for s in segs] == [0, 1, 2, 3]
    for s, seg in enumerate(segs):
        assert seg.label == LABELS.index("Drone") == 0 and seg.clip_id == "Drone/hover/1"
        assert seg.audio_mfcc.shape == (1, 40, 40) and seg.video.shape == (7, 112, 112, 3) and seg.rf.shape == (112, 112)
        assert np.allclose(seg.audio_mfcc, clip.mfcc[s], atol=1e-4)           # same WAV values -> same MFCC
        assert np.array_equal(np.round(seg.rf * 255).astype(np.uint8), clip.rf_images[s])   # PNG is lossless
        levels = seg.video.reshape(7, -1).mean(axis=1)
        assert np.allclose(levels, 8 * np.arange(7 * s, 7 * s + 7), atol=2)   # frames 7s..7s+6, in order
        assert seg.observability == {"video": bool(clip.truth.video_visible[s]),
                                     "audio": bool(clip.truth.audio_audible[s]),
                                     "rf": bool(clip.truth.rf_observable[s])}
    again = ds[2]
    assert np.array_equal(again.audio_mfcc, segs[2].audio_mfcc)


def test_public_layout_variants(tmp_path):
    """Real-TRIDENT style: 16-bit WAV, 1-based frames at another size, colour RF JPEGs, no labels/."""
    import cv2
    import soundfile

    for label, n in (("Drone", "7"), ("Background", "3")):
        for sub in ("audio", "video", "rf"):
            (tmp_path / sub / label / "site_a").mkdir(parents=True)
        t = np.arange(44100) / 44100
        soundfile.write(str(tmp_path / "audio" / label / "site_a" / f"{n}.wav"), 0.3 * np.sin(2 * np.pi * 300 * t),
                        44100, subtype="PCM_16")
        for i in range(1, 30):                                   # 29 frames -> 4 full segments
            img = np.full((224, 224, 3), 8 * (i - 1), np.uint8)
            cv2.imwrite(str(tmp_path / "video" / label / "site_a" / f"{n}_frame_{i}.jpg"), img)
        for s in range(5):                                       # one more RF image than needed
            cv2.imwrite(str(tmp_path / "rf" / label / "site_a" / f"{n}_spec_{s}.jpg"), np.full((112, 112, 3), 40 * s, np.uint8))
    # a clip present in audio only is skipped
    soundfile.write(str(tmp_path / "audio" / "Drone" / "site_a" / "99.wav"), np.zeros(44100), 44100)
    ds = TridentDataset(tmp_path)
    assert [c.clip_id for c in ds.clips] == ["Drone/site_a/7", "Background/site_a/3"]
    assert len(ds) == 8                                          # min(4 audio, 29 // 7 = 4 video, 5 rf) per clip
    seg = ds[5]
    assert seg.label == 1 and seg.clip_id == "Background/site_a/3" and seg.segment_index == 1
    assert seg.video.shape == (7, 112, 112, 3) and seg.rf.shape == (112, 112, 3)
    assert np.allclose(seg.video.reshape(7, -1).mean(axis=1), 8 * np.arange(7, 14), atol=2)
    assert np.allclose(seg.rf, 40 / 255, atol=2 / 255)
    assert seg.observability is None


def test_missing_modality_root_is_reported(tmp_path):
    (tmp_path / "audio").mkdir()
    with pytest.raises(ValueError, match="video"):
        discover_clips(tmp_path)
