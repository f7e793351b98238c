"""Experiment config validation, test-time noise and conflict programs on a synthetic clip."""
from __future__ import annotations

import numpy as np
import pytest

from harness.experiments.config import (
    DEMO_CONFIG,
    QUICK_CONFIG,
    NoiseEntry,
    SplitConfig,
    load_experiment_config,
)
from harness.experiments.data import ClipArrays, split_clips
from harness.experiments.noise import (
    conflict_clip,
    db_to_image,
    degrade_clip,
    image_to_db,
    item_seed,
)
from scenes.errors import UserInputError


def test_example_config_validates_and_bad_generation_config_is_named():
    assert load_experiment_config("examples/experiment.yaml").protocol.noise_seeds == [42, 123, 456]
    bad = {**QUICK_CONFIG,
           "dataset": {"generate": {"name": "x", "clips": [{"scenario": "clear_day_quad", "count": 0}]}}}
    with pytest.raises(UserInputError, match=r"dataset.generate: .*clips.0.count"):
        load_experiment_config(bad)


def test_demo_configs_validate():
    assert load_experiment_config(DEMO_CONFIG).protocol.noise_seeds == [42, 123, 456]
    q = load_experiment_config(QUICK_CONFIG)
    assert q.dataset.generate == "trident_scenes_quick" and len(q.models.seeds) >= 2
    assert len(load_experiment_config(DEMO_CONFIG).models.seeds) >= 3


@pytest.mark.parametrize("patch,needle", [
    ({"dataset": {"path": "x", "generate": "trident_mini"}}, "exactly one of dataset.generate"),
    ({"split": {"val_fraction": 0.6, "test_fraction": 0.5}}, "val_fraction + test_fraction"),
    ({"models": {"train": {"epochs": 0}}}, "models.train.epochs"),
    ({"protocol": {"audio": [{"name": "audio.nope"}]}}, "unknown degradation 'audio.nope'"),
    ({"conflict": {"programs": ["ir_blind"]}}, "conflict.programs.0"),
    ({"bogus": 1}, "bogus"),
])
def test_bad_configs_name_the_field(patch, needle):
    data = {**QUICK_CONFIG, **patch}
    with pytest.raises(UserInputError, match="experiment config|exactly one") as info:
        load_experiment_config(data)
    assert needle in str(info.value)


def _clip(label: int = 0, s: int = 4, seed: int = 0) -> ClipArrays:
    rng = np.random.default_rng(seed)
    fs = 8000.0
    t = np.arange(int(s * 0.25 * fs)) / fs
    audio = (0.3 * np.sin(2 * np.pi * 440 * t) + 0.01 * rng.standard_normal(t.size)).astype(np.float32)
    from simulator.formats.trident import mfcc_segments

    return ClipArrays(clip_id=f"c{seed}", label=label, mfcc=mfcc_segments(audio, fs, s),
                      video=rng.integers(60, 200, (s, 7, 112, 112, 3)).astype(np.uint8),
                      rf=rng.random((s, 112, 112)).astype(np.float32), audio=audio, sample_rate_hz=fs)


def test_image_db_round_trip_and_row_order():
    img = np.random.default_rng(0).random((2, 112, 112)).astype(np.float32)
    db = image_to_db(img, 60.0)
    np.testing.assert_allclose(db[:, 0], img[:, -1] * 60.0, rtol=1e-6)       # row 0 = lowest frequency
    np.testing.assert_allclose(db_to_image(db, 60.0), img, atol=1e-6)


def test_degrade_clip_streams_are_independent_and_seeded():
    clip = _clip()
    clean = degrade_clip(clip, 0, 42)
    assert clean.mfcc is clip.mfcc and clean.video is clip.video and clean.rf is clip.rf
    v = [NoiseEntry(name="video.gaussian_noise", params={"sigma": 0.2})]
    a = degrade_clip(clip, 0, 42, video=v)
    b = degrade_clip(clip, 0, 42, video=v)
    c = degrade_clip(clip, 0, 123, video=v)
    np.testing.assert_array_equal(a.video, b.video)
    assert not np.array_equal(a.video, c.video)
    assert a.mfcc is clip.mfcc and a.rf is clip.rf                              # other streams untouched
    au = degrade_clip(clip, 0, 42, audio=[NoiseEntry(name="audio.white_noise", params={"snr_db": 0.0})])
    assert not np.allclose(au.mfcc, clip.mfcc)
    assert item_seed(42, 0, "audio") != item_seed(42, 1, "audio") != item_seed(42, 0, "video")
    with pytest.raises(ValueError, match="no I/Q capture"):
        degrade_clip(clip, 0, 42, rf_iq=[NoiseEntry(name="rf.awgn", params={"snr_db": 10.0})])


@pytest.mark.parametrize("program,stream", [("audio_masked", "audio"), ("rf_silent", "rf"), ("rgb_blind", "video"),
                                            ("decoy", "video")])
def test_conflict_program_flags_only_its_modality_inside_the_window(program, stream):
    clip = _clip(s=8)
    deg, flags = conflict_clip(clip, 0, 42, program, onset_s=0.5, duration_s=1.0, severity=5.0)
    expect = np.array([0, 0, 1, 1, 1, 1, 0, 0], bool)
    np.testing.assert_array_equal(flags["compromised"][stream], expect)
    for other in {"audio", "video", "rf"} - {stream}:
        assert not flags["compromised"][other].any()
    np.testing.assert_array_equal(flags["conflict"], expect)
    changed = {"audio": not np.allclose(deg.mfcc[2:6], clip.mfcc[2:6]),
               "video": not np.array_equal(deg.video[2:6], clip.video[2:6]),
               "rf": not np.allclose(deg.rf[2:6], clip.rf[2:6], atol=1e-4)}
    assert changed[stream]
    if stream != "audio":       # frames/columns outside the window are untouched
        arr, ref = {"video": (deg.video, clip.video), "rf": (deg.rf, clip.rf)}[stream]
        np.testing.assert_allclose(arr[:2].astype(float), ref[:2].astype(float), atol=1e-4)


def test_split_is_stratified_seeded_and_disjoint():
    clips = [_clip(label=i % 2, s=1, seed=i) for i in range(10)]      # no scene recorded: each clip its own
    s1 = split_clips(clips, SplitConfig(seed=42, val_fraction=0.2, test_fraction=0.3))
    s2 = split_clips(clips, SplitConfig(seed=42, val_fraction=0.2, test_fraction=0.3))
    assert s1 == s2
    allidx = s1["train"] + s1["val"] + s1["test"]
    assert sorted(allidx) == list(range(10))
    for part in s1.values():
        assert {clips[i].label for i in part} == {0, 1}
    with pytest.raises(UserInputError, match="split.unit"):
        split_clips(clips[:2], SplitConfig())
