"""Context.outputs encodes each modality once per (its own noise, seed, run) and shares it between
variants; whatever it caches, its outputs must equal a direct encode of the fully degraded inputs."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from evids.models.backbones import MODALITIES, build_model
from harness.experiments.config import DatasetConfig, ExperimentConfig, NoiseEntry, ProtocolConfig
from harness.experiments.data import Prepared
from harness.experiments.noise import degrade_clip
from harness.experiments.pipeline import Models, encode
from harness.experiments.runner import Context

from .fixtures import make_clips


def _context() -> Context:
    clips = make_clips(3, seed=4, splits=(1, 1, 1))
    split = {"train": [0, 1], "val": [2, 3], "test": [4, 5]}
    prep = Prepared(Path("."), clips, split, 60.0, None, True)
    cfg = ExperimentConfig(dataset=DatasetConfig(path="."), protocol=ProtocolConfig(noise_seeds=[5, 6]))
    unimodal = {(m, h): build_model(m, h, 10 * k + j, video_frames=2)
                for k, m in enumerate(MODALITIES) for j, h in enumerate(("sigmoid", "evidential"))}
    return Context(Path("."), cfg, prep, [Models(unimodal=unimodal, late=None, gmu=None)], progress=False)


def _direct(ctx: Context, seed: int, **kw):
    parts = [degrade_clip(ctx.prep.clips[i], i, seed, rf_range_db=60.0, **kw) for i in ctx.test]
    return encode(ctx.models[0], *(np.concatenate([getattr(p, f) for p in parts]) for f in ("mfcc", "video", "rf")))


def _assert_equal(a, b):
    np.testing.assert_array_equal(a.logit, b.logit)
    np.testing.assert_array_equal(a.alpha, b.alpha)
    np.testing.assert_array_equal(a.emb, b.emb)


def test_cached_variant_outputs_equal_a_direct_encode_of_the_degraded_inputs():
    ctx = _context()
    for variant in ("standard", "all_spec", "clean"):
        for seed in (5, 6):
            kw = {k: v for k, v in ctx.noise_kwargs(variant).items() if k in ("audio", "video", "rf_spec")}
            _assert_equal(ctx.outputs(variant, seed), _direct(ctx, seed, **kw))
    standard, all_spec, other_seed = ctx.outputs("standard", 5), ctx.outputs("all_spec", 5), ctx.outputs("standard", 6)
    video, rf = MODALITIES.index("video"), MODALITIES.index("rf")
    assert np.array_equal(standard.alpha[video], all_spec.alpha[video])      # shared video noise
    assert not np.array_equal(standard.alpha[rf], all_spec.alpha[rf])         # RF noise only in all_spec
    assert not np.array_equal(standard.alpha[video], other_seed.alpha[video])  # seeds are kept apart


def test_override_degrades_only_its_stream_and_keeps_the_others_clean():
    ctx = _context()
    entry = [NoiseEntry(name="video.gaussian_noise", params={"sigma": 0.3})]
    got = ctx.outputs("sweep", 5, video=entry)
    _assert_equal(got, _direct(ctx, 5, video=entry))
    clean = ctx.outputs("clean", 0)
    for m, modality in enumerate(MODALITIES):
        same = np.array_equal(got.alpha[m], clean.alpha[m])
        assert same == (modality != "video"), modality


def test_outputs_do_not_depend_on_what_the_store_already_holds():
    """A warm-up of the clean outputs (as before a fork) or clean outputs copied back from a worker
    change the work done, never a value."""
    from harness.experiments.store import ModalityKey, OutputsKey

    cold = _context()
    noisy_cold = cold.outputs("standard", 5)
    warm = _context()
    warm.outputs("clean", 0)
    _assert_equal(warm.outputs("standard", 5), noisy_cold)
    copied = _context()
    copied.store.put_clean(warm.outputs("clean", 0), "test", 0, [5, 6])
    _assert_equal(copied.outputs("standard", 5), noisy_cold)
    assert OutputsKey("clean", 6, "test", 0) in copied.store.outputs                  # every seed's key
    rf = ModalityKey("rf", 0, "test", 0, ())
    assert rf not in copied.store.modality           # reused from the copied clean outputs, not re-encoded
    assert rf in cold.store.modality                 # encoded per modality when nothing was held
    cold.drop_inputs()
    assert not cold.store.inputs and cold.store.outputs
