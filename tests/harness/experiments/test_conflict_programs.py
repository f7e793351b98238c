"""Every twin-swap conflict program flips the compromised modality's vote on the targeted segments
of a small trained fixture, leaves the other modalities' inputs untouched, and the strength knob
interpolates between the clip and its twin."""
from __future__ import annotations

import numpy as np
import pytest

from degradations.crossmodal import blend_signature
from degradations.schedule import SWAP_PROGRAMS
from evids.models.backbones import build_model
from evids.models.train import TrainConfig, predict, train_model
from harness.experiments.noise import program_window, swap_clip, targeted_segments
from tests.harness.experiments.fixtures import make_clips

KEY = {"audio": "mfcc", "video": "video", "rf": "rf"}


@pytest.fixture(scope="module")
def trained():
    clips = make_clips(8, seed=11)
    train, test = clips[:12], clips[12:]
    y = np.concatenate([np.full(c.n_segments, c.label) for c in train])
    models = {}
    cfg = TrainConfig(epochs=5, patience=5, batch_size=8, kl_anneal_epochs=1.0)
    for m in ("audio", "video", "rf"):
        x = np.concatenate([getattr(c, KEY[m]) for c in train])
        model = build_model(m, "evidential", seed=5, video_frames=2)
        train_model(model, x, y, x, y, cfg, 3)
        models[m] = model
    return models, clips, test


def _votes(model, x):
    alpha, _ = predict(model, x)
    return alpha.argmax(1)


@pytest.mark.parametrize("program", sorted(SWAP_PROGRAMS))
def test_program_flips_the_compromised_votes(trained, program):
    models, clips, test = trained
    by_id = {c.clip_id: c for c in clips}
    _, kind, mods = SWAP_PROGRAMS[program]
    want = 0 if kind == "blind" else 1
    flipped, total = 0, 0
    for clip in (c for c in test if c.label == want):
        donor = by_id[clip.twin]
        w = program_window(clip.n_segments, 0.25, 0.5)
        t = targeted_segments(clip, donor, kind, mods, w)
        assert t.sum() == w.sum() == clip.n_segments // 2
        deg = swap_clip(clip, donor, mods, 1.0, w)
        for m in ("audio", "video", "rf"):
            before, after = getattr(clip, KEY[m]), getattr(deg, KEY[m])
            if m in mods:
                if m != "audio":          # strength 1: the twin's stream (RF through a dB round trip)
                    np.testing.assert_allclose(after[w].astype(float), getattr(donor, KEY[m])[w].astype(float),
                                               atol=1e-5)
                np.testing.assert_array_equal(after[~w], before[~w])
                v0, v1 = _votes(models[m], before), _votes(models[m], after)
                flipped += int((v0[t] != v1[t]).sum())
                total += int(t.sum())
            else:
                np.testing.assert_array_equal(after, before)
    assert total > 0 and flipped / total >= 0.5, (program, flipped, total)


def test_strength_interpolates_and_rejects_bad_values():
    x = np.full((2, 4, 4, 3), 200, np.uint8)
    d = np.full((2, 4, 4, 3), 100, np.uint8)
    assert (blend_signature(x, d, 1.0, "rgb") == 100).all() and (blend_signature(x, d, 0.5, "rgb") == 150).all()
    a, b = np.ones(8, np.float32), np.zeros(8, np.float32)
    np.testing.assert_allclose(blend_signature(a, b, 0.25, "audio"), 0.75)
    db = blend_signature(np.full((3, 3), 10.0), np.full((3, 3), 0.0), 0.5, "rf_spec")
    np.testing.assert_allclose(db, 10 * np.log10(0.5 * 10 + 0.5 * 1))       # power, not dB, is blended
    from degradations.errors import DegradationError

    with pytest.raises(DegradationError, match="strength"):
        blend_signature(a, b, 1.5, "audio")
    with pytest.raises(DegradationError, match="donor shape"):
        blend_signature(a, b[:4], 1.0, "audio")
