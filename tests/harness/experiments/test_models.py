"""Backbones, heads and the seeded training loop."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from evids.models import TrainConfig, build_model, predict, train_model
from evids.models.backbones import UnimodalModel


@pytest.mark.parametrize("modality,shape,dtype", [("audio", (5, 1, 40, 40), np.float32),
                                                  ("video", (5, 7, 112, 112, 3), np.uint8),
                                                  ("rf", (5, 112, 112), np.float32)])
@pytest.mark.parametrize("head", ["sigmoid", "evidential"])
def test_backbone_shapes_and_heads(modality, shape, dtype, head):
    model = build_model(modality, head, seed=1)
    x = np.random.default_rng(0).integers(0, 255, shape).astype(dtype)
    out, emb = predict(model, x)
    assert emb.shape == (5, 32)
    if head == "sigmoid":
        assert out.shape == (5,)
    else:
        assert out.shape == (5, 2) and (out >= 1.0).all()      # alpha = evidence + 1
    p = UnimodalModel.probabilities(torch.from_numpy(np.atleast_1d(out)), head)
    np.testing.assert_allclose(p.sum(-1).numpy(), 1.0, rtol=1e-9)


def test_init_is_seeded_and_leaves_global_rng_alone():
    torch.manual_seed(1234)
    before = torch.get_rng_state().clone()
    a = build_model("rf", "evidential", seed=7)
    b = build_model("rf", "evidential", seed=7)
    c = build_model("rf", "evidential", seed=8)
    assert torch.equal(torch.get_rng_state(), before)
    wa, wb, wc = (next(m.parameters()).detach() for m in (a, b, c))
    assert torch.equal(wa, wb) and not torch.equal(wa, wc)


def _toy(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    y = rng.integers(0, 2, n)
    x = rng.normal(0.0, 0.3, (n, 1, 40, 40)).astype(np.float32)
    x[y == 1, :, :20, :] += 1.5                      # class 1: energy in the low coefficients
    return x, y


@pytest.mark.parametrize("head", ["sigmoid", "evidential"])
def test_training_learns_is_deterministic_and_keeps_best_checkpoint(head):
    rng = np.random.default_rng(0)
    xt, yt = _toy(96, rng)
    xv, yv = _toy(48, rng)
    cfg = TrainConfig(epochs=4, batch_size=16, lr=5e-3, patience=3, kl_anneal_epochs=3)
    runs = []
    for _ in range(2):
        model = build_model("audio", head, seed=3)
        res = train_model(model, xt, yt, xv, yv, cfg, seed=11)
        out, _ = predict(model, xv)
        runs.append((res, out))
    (r1, o1), (r2, o2) = runs
    np.testing.assert_array_equal(o1, o2)                       # same seeds -> identical model
    assert r1.val_loss == r2.val_loss
    assert r1.best_val_loss == min(r1.val_loss) and r1.val_loss[r1.best_epoch] == r1.best_val_loss
    pred = (o1 > 0).astype(int) if head == "sigmoid" else o1.argmax(1)
    assert (pred == yv).mean() > 0.9


def test_early_stopping_stops_after_patience():
    rng = np.random.default_rng(1)
    xt, yt = rng.normal(size=(32, 1, 40, 40)).astype(np.float32), rng.integers(0, 2, 32)
    xv, yv = rng.normal(size=(16, 1, 40, 40)).astype(np.float32), rng.integers(0, 2, 16)   # pure noise
    model = build_model("audio", "sigmoid", seed=0)
    res = train_model(model, xt, yt, xv, yv, TrainConfig(epochs=40, lr=0.05, patience=2), seed=0)
    assert res.stopped_early and len(res.val_loss) == res.best_epoch + 3


def test_training_rejects_empty_or_mismatched_sets():
    model = build_model("audio", "sigmoid", seed=0)
    x = np.zeros((4, 1, 40, 40), np.float32)
    with pytest.raises(ValueError, match="same number of rows"):
        train_model(model, x, np.zeros(3), x, np.zeros(4), TrainConfig(), seed=0)
    with pytest.raises(ValueError, match="must not be empty"):
        train_model(model, x[:0], np.zeros(0), x, np.zeros(4), TrainConfig(), seed=0)


def test_saved_models_bytes_do_not_depend_on_which_process_built_them(tmp_path):
    """models.pt of fusion heads fitted in a worker (their dict keys arrive as fresh strings after
    unpickling) is byte-identical to the same models built in-process."""
    import pickle

    from evids.fusion import GMU, LateFusion
    from evids.models.backbones import MODALITIES
    from harness.experiments.pipeline import Models, save_models

    unimodal = {(m, h): build_model(m, h, 1, video_frames=2) for m in MODALITIES for h in ("sigmoid", "evidential")}
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(0)
        heads = (LateFusion(3), GMU([32] * 3, 16, 1), LateFusion(3), GMU([32] * 3, 16, 1))
    local = Models(unimodal, *heads, temperatures={"audio": 1.5, "late": 0.4}, temperature_flags={"late": None})
    shipped = pickle.loads(pickle.dumps(local))          # what a forked job returns
    assert all(a is not b for a, b in zip(local.temperatures, shipped.temperatures))   # fresh key strings
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    save_models([local], tmp_path / "a" / "models.pt")
    save_models([Models(unimodal, *heads, temperatures=shipped.temperatures,
                        temperature_flags=shipped.temperature_flags)], tmp_path / "b" / "models.pt")
    assert (tmp_path / "a" / "models.pt").read_bytes() == (tmp_path / "b" / "models.pt").read_bytes()
