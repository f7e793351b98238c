"""TRIDENT clips: MFCC framing, segment alignment across modalities, observability truth, writer."""
from __future__ import annotations

import json

import numpy as np
import pytest

from scenes.errors import UserInputError
from simulator.dataset import trident as tr

# a continuous video link inside the receiver window, so every short capture holds drone RF
# (the realistic presets hop: most 2.5 ms captures hold 0-1 control bursts, see tests/simulator/physics/test_rf.py)
ALWAYS_ON_LINK = {"kind": "ofdm", "name": "video", "role": "video", "tx_power_dbm": 23.0, "bandwidth_hz": 9e6,
                  "subcarrier_spacing_hz": 15e3, "channel_centres_hz": [2440e6], "duty": 1.0,
                  "burst_range_s": [1e-3, 2e-3]}
RIG_FIXED = {"position_m": [0, 0, 1.5], "look_at_m": [0, 80, 20], "rgb": {"hfov_deg": 30}}


def _scenario(targets, rig=RIG_FIXED, name="s"):
    return {"name": name, "duration_s": 1.0, "targets": targets, "camera_rig": rig}


def _hover(name, center, kind="quadcopter"):
    return {"name": name, "kind": kind, "size_m": 0.45,
            "trajectory": {"kind": "hover", "center_m": center, "drift_m": 0.1}}


def _config(clips, **kw):
    base = {"name": "tiny", "clip_duration_s": 1.0, "save_iq": True, "clips": clips,
            "rf": {"capture_samples": 112 * 40, "wifi_rx_dbm": -70.0, "links": [ALWAYS_ON_LINK]}}
    base.update(kw)
    return tr.load_trident_config(base)


def _frames(scenario, seed, n, w, h, layout=None):
    return np.broadcast_to((np.arange(n, dtype=np.uint8) * 9)[:, None, None, None], (n, h, w, 3)).copy()


def test_mfcc_is_1x40x40_per_quarter_second():
    assert tr.mfcc_hop_length(11025) == 282 and 1 + 11025 // 282 == 40
    t = np.arange(44100 * 2) / 44100
    m = tr.mfcc_segments((0.1 * np.sin(2 * np.pi * 440 * t)).astype(np.float32), 44100)
    assert m.shape == (8, 1, 40, 40) and m.dtype == np.float32
    assert np.allclose(m[2], m[5], atol=1e-3)          # stationary tone: segments alike
    with pytest.raises(ValueError, match="sample_rate_hz"):
        tr.mfcc_segments(np.zeros(100, np.float32), 0.0)


def _clip(targets, rig=RIG_FIXED, seed=3, **kw):
    cfg = _config([{"scenario": _scenario(targets, rig)}])
    scen = tr.clip_scenario(tr.resolve_scenario(cfg.clips[0]), cfg)
    frames = _frames(scen, seed, 28, 112, 112)
    return tr.synthesize_clip(scen, seed, cfg, frames=frames, **kw), cfg


def test_segments_align_across_modalities_and_truth():
    clip, cfg = _clip([_hover("d", [0, 40, 10])])  # 41 m: audible over 45 dB wind with the calibrated 70.5 dBA at 1 m
    n = cfg.n_segments
    assert n == 4
    assert clip.audio.shape == (44100,) and clip.mfcc.shape == (n, 1, 40, 40)
    assert clip.rf.iq.shape == (n, 112 * 40) and clip.rf_images.shape == (n, 112, 112)
    assert clip.frames.shape == (n * 7, 112, 112, 3)
    for arr in (clip.truth.drone_present, clip.truth.video_visible, clip.truth.audio_audible, clip.truth.rf_observable):
        assert arr.shape == (n,)
    assert clip.truth.label == "Drone" and clip.truth.drone_present.all()
    assert clip.truth.video_visible.all() and clip.truth.audio_audible.all() and clip.truth.rf_observable.all()


def test_observability_out_of_view_silent_and_far():
    behind = {"position_m": [0, 0, 1.5], "look_at_m": [0, -80, 20], "rgb": {"hfov_deg": 30}}
    clip, _ = _clip([_hover("d", [0, 40, 10])], rig=behind, rf_silent=True)
    assert not clip.truth.video_visible.any()        # out of the camera view ...
    assert clip.truth.audio_audible.all()            # ... but audible
    assert not clip.truth.rf_observable.any()        # radios off (autonomous flight)
    far, _ = _clip([_hover("d", [0, 3000, 60])], rig={"position_m": [0, 0, 1.5], "look_at_m": [0, 3000, 60]})
    assert not far.truth.audio_audible.any()         # too far to hear over the wind
    assert far.truth.rf_observable.all()             # the radio link still reaches
    bird, _ = _clip([_hover("b", [0, 80, 20], kind="bird")])
    assert bird.truth.label == "Background"
    assert not (bird.truth.drone_present | bird.truth.video_visible | bird.truth.audio_audible
                | bird.truth.rf_observable).any()


def test_generate_is_deterministic_atomic_and_in_trident_layout(tmp_path):
    cfg = _config([{"scenario": _scenario([_hover("d", [0, 80, 20])], name="quad"), "count": 1},
                   {"scenario": _scenario([_hover("b", [0, 70, 20], kind="bird")], name="bird"), "group": "birds"}])
    a = tr.generate_trident(cfg, tmp_path / "a", 5, progress=False, render_frames=_frames)
    b = tr.generate_trident(cfg, tmp_path / "b", 5, progress=False, render_frames=_frames)
    c = tr.generate_trident(cfg, tmp_path / "c", 6, progress=False, render_frames=_frames)
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    assert [f for f in files if (a / f).read_bytes() != (b / f).read_bytes()] == []
    assert (a / "audio/Drone/quad/1.wav").read_bytes() != (c / "audio/Drone/quad/1.wav").read_bytes()
    names = {str(f) for f in files}
    assert {"audio/Drone/quad/1.wav", "audio/Background/birds/2.wav", "video/Drone/quad/1_frame_27.jpg",
            "rf/Background/birds/2_rf_3.png", "rf_iq/Drone/quad/1.npy", "labels/Drone/quad/1.json",
            "manifest.json"} <= names
    assert sum(n.startswith("video/Drone/quad/") for n in names) == 28
    from simulator.formats.trident import clip_files

    listed = clip_files("Drone", "quad", 1, n_frames=28, n_segments=4, save_iq=True)
    listed += clip_files("Background", "birds", 2, n_frames=28, n_segments=4, save_iq=True)
    assert names == set(listed) | {"manifest.json"}          # the layout's one file list is what write_clip writes
    assert sum(n.startswith("rf/Drone/quad/") for n in names) == 4
    manifest = json.loads((a / "manifest.json").read_text())
    assert manifest["seed"] == 5 and len(manifest["clips"]) == 2 and len(manifest["content_sha256"]) == 64
    assert np.load(a / "rf_iq/Drone/quad/1.npy").dtype == np.complex64
    assert manifest["complete"] is True and [c["name"] for c in manifest["clips"]] == ["clip000001", "clip000002"]
    assert all(len(c["content_sha256"]) == 64 for c in manifest["clips"])
    before = {f: (a / f).read_bytes() for f in files}
    assert tr.generate_trident(cfg, a, 5, progress=False, render_frames=_frames) == a    # the same dataset: kept
    assert {f: (a / f).read_bytes() for f in files} == before
    with pytest.raises(UserInputError, match="different dataset"):
        tr.generate_trident(cfg, a, 6, progress=False, render_frames=_frames)
    (tmp_path / "e").mkdir()
    (tmp_path / "e" / "notes.txt").write_text("mine")
    with pytest.raises(UserInputError, match="not empty"):
        tr.generate_trident(cfg, tmp_path / "e", 5, progress=False, render_frames=_frames)
    assert (tmp_path / "e" / "notes.txt").read_text() == "mine"


_FAIL_ON = set()


def _flaky_frames(scenario, seed, n, w, h, layout=None):
    if scenario.name in _FAIL_ON:
        raise RuntimeError("renderer exploded")
    return _frames(scenario, seed, n, w, h, layout)


def test_a_failed_clip_is_named_the_others_are_kept_and_a_rerun_finishes_byte_identical(tmp_path):
    from simulator.dataset.driver import GenerationFailed
    from simulator.dataset.generate import verify_dataset
    from simulator.formats.trident import discover_clips

    cfg = _config([{"scenario": _scenario([_hover("d", [0, 80, 20])], name="quad"), "count": 1},
                   {"scenario": _scenario([_hover("b", [0, 70, 20], kind="bird")], name="bird"), "group": "birds"}])
    ref = tr.generate_trident(cfg, tmp_path / "ref", 5, progress=False, render_frames=_flaky_frames)
    _FAIL_ON.add("bird")
    try:
        with pytest.raises(GenerationFailed, match="clip000002: RuntimeError: renderer exploded"):
            tr.generate_trident(cfg, tmp_path / "d", 5, progress=False, render_frames=_flaky_frames)
    finally:
        _FAIL_ON.clear()
    d = tmp_path / "d"
    partial = json.loads((d / "manifest.json").read_text())
    assert partial["complete"] is False and partial["content_sha256"] is None
    assert [c["content_sha256"] is not None for c in partial["clips"]] == [True, False]   # clip 1 recorded
    assert verify_dataset(d).incomplete and not verify_dataset(d).ok
    with pytest.raises(ValueError, match="unfinished"):
        discover_clips(d)
    kept = (d / "audio/Drone/quad/1.wav").stat().st_mtime_ns
    tr.generate_trident(cfg, d, 5, progress=False, render_frames=_flaky_frames)
    assert (d / "audio/Drone/quad/1.wav").stat().st_mtime_ns == kept    # the recorded clip was not rewritten
    files = sorted(p.relative_to(ref) for p in ref.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(d) for p in d.rglob("*") if p.is_file())
    assert [f for f in files if (ref / f).read_bytes() != (d / f).read_bytes()] == []   # manifest included
    report = verify_dataset(d)
    assert report.ok and report.checked == 2 and report.noun == "clip"


def test_verify_names_a_changed_or_missing_clip_and_a_rerun_repairs_it(tmp_path):
    from simulator.dataset.generate import verify_dataset

    cfg = _config([{"scenario": _scenario([_hover("d", [0, 80, 20])], name="quad"), "count": 2}])
    d = tr.generate_trident(cfg, tmp_path / "d", 3, progress=False, render_frames=_frames)
    good = (d / "rf/Drone/quad/2_rf_1.png").read_bytes()
    (d / "rf/Drone/quad/2_rf_1.png").write_bytes(good[:-7])
    assert verify_dataset(d).corrupt == {"clip000002": ["content differs from manifest.json"]}
    (d / "labels/Drone/quad/1.json").unlink()
    assert verify_dataset(d).corrupt["clip000001"] == ["labels/Drone/quad/1.json (absent)"]
    (d / "video/Drone/quad/stray.jpg").write_bytes(b"x")
    tr.generate_trident(cfg, d, 3, progress=False, render_frames=_frames)
    assert verify_dataset(d).ok and (d / "rf/Drone/quad/2_rf_1.png").read_bytes() == good
    assert not (d / "video/Drone/quad/stray.jpg").exists()
    (d / "extra.txt").write_text("x")
    assert verify_dataset(d).corrupt == {"(dataset)": ["a file no clip lists was added, or a clip's file changed"]}


def test_config_errors_name_the_field_and_preset_validates():
    with pytest.raises(UserInputError, match=r"clips\.0\.count"):
        _config([{"scenario": "clear_day_quad", "count": 0}])
    with pytest.raises(UserInputError, match="clip_duration_s"):
        _config([{"scenario": "clear_day_quad"}], clip_duration_s=1.1)
    cfg = tr.load_trident_config("trident_mini")
    labels = [tr.clip_label(tr.resolve_scenario(c)) for c in cfg.clips for _ in range(c.count)]
    assert labels.count("Drone") >= 2 and labels.count("Background") >= 2
    assert any(c.rf_silent for c in cfg.clips)


def test_audio_goes_through_the_recording_chain():
    from simulator.physics.acoustics import synthesize_audio
    from simulator.physics.timeline import build_timeline
    from simulator.sensors.microphone import record

    targets = [_hover("d", [0, 40, 10])]
    recorded, cfg = _clip(targets)
    steps = recorded.audio.astype(np.float64) * 32767
    assert np.allclose(steps, np.round(steps), atol=1e-3)                  # the recorder's 16-bit samples
    scen = tr.clip_scenario(tr.resolve_scenario(cfg.clips[0]), cfg)
    mix = synthesize_audio(build_timeline(scen, 3), 3, ambience=cfg.clips[0].ambience, duration_s=1.0).mix_pa
    assert recorded.audio.tobytes() == record(mix, 44100, seed=3, index=0, full_scale_pa=0.1,
                                              config=cfg.recorder).tobytes()
    off = _config([{"scenario": _scenario(targets)}], recorder={"enabled": False})
    raw = tr.synthesize_clip(scen, 3, off, frames=_frames(scen, 3, 28, 112, 112))
    assert np.allclose(raw.audio, mix / 0.1, atol=1e-6)                     # switched off: pressure / full scale
    assert np.array_equal(raw.truth.audio_snr_db, recorded.truth.audio_snr_db)   # truth comes from pressure
