import importlib.util
import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from evids.metrics import (
    accuracy,
    apply_temperature,
    average_precision,
    box_iou,
    brier,
    clustered_bootstrap,
    clustered_resample,
    detection_ece,
    detection_uauc,
    ece,
    fit_temperature,
    macro_f1,
    match_detections,
    mot_metrics,
    nll,
    paired_bootstrap,
    plot_reliability,
    reliability_diagram,
    state_accuracy,
    uauc,
)


def test_accuracy_f1_hand():
    y = [0, 0, 1, 1]
    p = [0, 1, 1, 1]
    assert accuracy(p, y) == 0.75
    # class 0: tp 1, fp 0, fn 1 -> F1 2/3; class 1: tp 2, fp 1, fn 0 -> F1 4/5
    assert macro_f1(p, y) == pytest.approx((2 / 3 + 4 / 5) / 2)
    probs = np.array([[0.9, 0.1], [0.4, 0.6], [0.2, 0.8], [0.3, 0.7]])
    assert accuracy(probs, y) == 0.75
    assert macro_f1(torch.tensor(p), torch.tensor(y), num_classes=3) == pytest.approx((2 / 3 + 4 / 5) / 3)


def test_nll_brier_hand():
    probs = np.array([[0.8, 0.2], [0.4, 0.6]])
    y = [0, 0]
    assert nll(probs, y) == pytest.approx(-(math.log(0.8) + math.log(0.4)) / 2)
    # (0.2^2 + 0.2^2 + 0.6^2 + 0.6^2) / 2 = 0.4
    assert brier(probs, y) == pytest.approx(0.4)
    with pytest.raises(ValueError, match="labels"):
        nll(probs, [0, 2])


def test_ece_confidence_one_goes_to_last_bin():
    # confidence 1.0 (wrong) and 0.95 (right) share the last bin [14/15, 1]:
    # |mean acc 0.5 - mean conf 0.975| = 0.475 (a separate bin for 1.0 would give 0.525)
    probs = np.array([[1.0, 0.0], [0.95, 0.05]])
    assert ece(probs, [1, 0], n_bins=15) == pytest.approx(0.475)
    data = reliability_diagram(probs, [1, 0], n_bins=15)
    assert data.count.tolist() == [0] * 14 + [2]


def test_ece_hand_two_bins():
    # n_bins=2: conf 0.6 (right), 0.7 (wrong) in bin 0.5-1.0; conf 0.5 ties -> argmax 0, right
    probs = np.array([[0.6, 0.4], [0.3, 0.7], [0.5, 0.5]])
    y = [0, 0, 0]
    # one bin holds all: mean conf 0.6, acc 2/3 -> |2/3 - 0.6| = 0.0667
    assert ece(probs, y, n_bins=2) == pytest.approx(2 / 3 - 0.6)


@pytest.mark.parametrize("k,seed", [(2, 0), (3, 1), (5, 2)])
def test_ece_equals_torchmetrics_multiclass(k, seed):
    from torchmetrics.functional.classification import multiclass_calibration_error

    gen = torch.Generator().manual_seed(seed)
    probs = torch.softmax(torch.randn(500, k, generator=gen, dtype=torch.float64) * 2, -1)
    y = torch.randint(0, k, (500,), generator=gen)
    ref = multiclass_calibration_error(probs, y, num_classes=k, n_bins=15, norm="l1").item()
    assert ece(probs, y, n_bins=15) == pytest.approx(ref, abs=1e-6)  # torchmetrics works in float32


@pytest.mark.parametrize("seed", [0, 1])
def test_detection_ece_equals_torchmetrics_binary(seed):
    from torchmetrics.functional.classification import binary_calibration_error

    gen = torch.Generator().manual_seed(seed)
    scores = torch.rand(400, generator=gen, dtype=torch.float64)
    tp = torch.rand(400, generator=gen, dtype=torch.float64) < scores
    ref = binary_calibration_error(scores, tp.long(), n_bins=15, norm="l1").item()
    assert detection_ece(scores, tp) == pytest.approx(ref, abs=1e-9)


def test_reliability_plot_writes_png(tmp_path):
    gen = np.random.default_rng(0)
    p = gen.dirichlet([1, 1, 1], size=200)
    y = gen.integers(0, 3, size=200)
    data = reliability_diagram(p, y)
    assert data.count.sum() == 200 and data.edges.shape == (16,)
    out = tmp_path / "rel.png"
    fig = plot_reliability(data, path=out)
    assert out.stat().st_size > 1000 and fig is not None


def test_uauc_perfect_reversed_ties():
    u = [0.1, 0.2, 0.8, 0.9]
    err = [False, False, True, True]
    assert uauc(u, err) == 1.0
    assert uauc([-x for x in u], err) == 0.0
    assert uauc([0.5] * 4, err) == 0.5
    # pairs (error, correct): 0.35 > 0.1, 0.35 < 0.4, 0.8 > both -> 3/4
    assert uauc([0.1, 0.4, 0.35, 0.8], [0, 0, 1, 1]) == 0.75
    assert math.isnan(uauc([0.1, 0.2], [True, True]))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 5), st.booleans()), min_size=2, max_size=30))
def test_uauc_equals_pairwise_count(rows):
    s = np.array([r[0] for r in rows], dtype=float)
    e = np.array([r[1] for r in rows])
    if e.all() or not e.any():
        return
    pos, neg = s[e], s[~e]
    brute = ((pos[:, None] > neg[None, :]).sum() + 0.5 * (pos[:, None] == neg[None, :]).sum()) / (pos.size * neg.size)
    assert uauc(s, e) == pytest.approx(brute)


def test_detection_uauc_fp_more_uncertain_is_one():
    assert detection_uauc([0.9, 0.8, 0.1, 0.2], [False, False, True, True]) == 1.0


def test_temperature_recovers_known_t_and_keeps_decisions():
    rng = np.random.default_rng(0)
    z = rng.normal(size=(20000, 3)) * 4
    p_true = apply_temperature(z, 2.5)
    y = (rng.random(20000)[:, None] > np.cumsum(p_true, 1)).sum(1)
    t = fit_temperature(z, y)
    assert t == pytest.approx(2.5, rel=0.05)
    assert np.array_equal(apply_temperature(z, t).argmax(1), z.argmax(1))
    nll_at = lambda tt: nll(apply_temperature(z, tt), y)  # noqa: E731
    assert nll_at(t) <= min(nll_at(t * 1.05), nll_at(t / 1.05))
    zb = rng.normal(size=5000) * 3
    yb = (rng.random(5000) < apply_temperature(zb, 0.5)).astype(int)
    assert fit_temperature(zb, yb) == pytest.approx(0.5, rel=0.1)


def test_resample_duplicates_rows_unlike_isin():
    clusters = np.array(["A", "A", "B", "C", "C", "C"])
    values = np.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    draw = np.array(["A", "A", "B"])
    idx = clustered_resample(clusters, draw)
    assert idx.tolist() == [0, 1, 0, 1, 2]
    # clip A twice: (1 + 1 + 1 + 1 + 0) / 5 = 0.8; isin masking keeps A once: (1 + 1 + 0) / 3
    assert values[idx].mean() == pytest.approx(0.8)
    assert values[np.isin(clusters, draw)].mean() == pytest.approx(2 / 3)


def test_bootstrap_matches_hand_computation():
    clusters = np.array([3, 3, 1, 2, 2, 2, 1])
    x = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0])
    res = clustered_bootstrap(np.mean, x, clusters=clusters, rng=np.random.default_rng(7), n_resamples=50)
    rows = {1: [2, 6], 2: [3, 4, 5], 3: [0, 1]}
    draws = np.random.default_rng(7).integers(0, 3, size=(50, 3))
    hand = [np.mean([x[i] for c in d for i in rows[[1, 2, 3][c]]]) for d in draws]
    assert np.allclose(res.samples, hand)
    assert res.estimate == pytest.approx(x.mean())
    assert res.ci_low <= res.ci_high and res.n_clusters == 3
    again = clustered_bootstrap(np.mean, x, clusters=clusters, rng=7, n_resamples=50)
    assert np.array_equal(again.samples, res.samples)
    with pytest.raises(TypeError):
        clustered_bootstrap(np.mean, x, clusters=clusters)  # rng is required


def test_paired_bootstrap():
    rng = np.random.default_rng(1)
    clusters = np.repeat(np.arange(20), 10)
    y = rng.integers(0, 2, 200)
    good = np.where(rng.random(200) < 0.9, y, 1 - y)
    bad = np.where(rng.random(200) < 0.6, y, 1 - y)
    res = paired_bootstrap(accuracy, y, good, bad, clusters, rng=np.random.default_rng(2), n_resamples=300)
    assert res.estimate == pytest.approx(accuracy(good, y) - accuracy(bad, y))
    assert res.ci_low > 0 and res.p_value < 0.01
    same = paired_bootstrap(accuracy, y, good, good, clusters, rng=3, n_resamples=50)
    assert same.p_value == 1.0 and same.ci_low == same.ci_high == 0.0


def test_box_iou_and_matching_hand():
    assert box_iou([[0, 0, 2, 2]], [[1, 1, 2, 2]])[0, 0] == pytest.approx(1 / 7)
    assert box_iou([[0, 0, 2, 2]], [[0, 0, 2, 2]], fmt="xyxy")[0, 0] == 1.0
    gt = [[0, 0, 10, 10], [20, 20, 10, 10]]
    pred = [[0, 0, 10, 10], [1, 1, 10, 10], [20, 20, 10, 10]]
    m = match_detections(pred, [0.9, 0.95, 0.8], gt)
    # 0.95 takes gt 0 (IoU 81/119 >= 0.5), 0.9 finds gt 0 taken -> FP, 0.8 takes gt 1
    assert m.is_tp.tolist() == [False, True, True]
    assert m.gt_index.tolist() == [-1, 0, 1]


def test_ap50_hand():
    gt = [[0, 0, 10, 10], [20, 20, 10, 10]]
    pred = [[0, 0, 10, 10], [50, 50, 5, 5], [20, 20, 10, 10]]
    scores = [0.9, 0.8, 0.7]
    # ranked: TP, FP, TP -> precision 1, 1/2, 2/3 at recall 1/2, 1/2, 1; envelope 1, 2/3, 2/3
    # all-point AP = 1/2 * 1 + 1/2 * 2/3 = 5/6
    assert average_precision([(pred, scores, gt)]) == pytest.approx(5 / 6)
    # 101-point: recall points 0..0.5 (51) at 1, 0.51..1 (50) at 2/3
    assert average_precision([(pred, scores, gt)], interpolation="coco101") == pytest.approx((51 + 50 * 2 / 3) / 101)
    assert math.isnan(average_precision([(pred, scores, [])]))


def test_state_accuracy_both_variants_hand():
    exist = [1, 1, 0, 0]
    gt = [[0, 0, 2, 2], [0, 0, 2, 2], [], [0]]
    pred = [[1, 1, 2, 2], [], None, [5, 5, 1, 1]]
    # per frame: IoU 1/7, 0 (missed), 1 (correctly empty), 0 (false alarm)
    plain = (1 / 7 + 0 + 1 + 0) / 4
    assert state_accuracy(pred, gt, exist) == pytest.approx(plain)
    # penalty on target frames: [0, 1] -> mean 0.5
    assert state_accuracy(pred, gt, exist, variant="penalised") == pytest.approx(plain - 0.2 * 0.5**0.3)
    with pytest.raises(ValueError, match="equal length"):
        state_accuracy(pred[:3], gt, exist)


@pytest.mark.skipif(importlib.util.find_spec("motmetrics") is None,
                    reason="optional dependency motmetrics not installed")
def test_mot_metrics_hand():
    box = [[0, 0, 10, 10]]
    # 4 frames, 1 GT track; hypothesis: frame 0-1 id 7, frame 2 missed, frame 3 id 8 (switch)
    gt = [([1], box)] * 4
    hyp = [([7], box), ([7], box), ([], np.zeros((0, 4))), ([8], box)]
    out = mot_metrics(gt, hyp)
    # MOTA = 1 - (FN 1 + FP 0 + IDSW 1) / 4 = 0.5; IDF1 = 2 IDTP / (GT 4 + pred 3) = 4/7
    assert out["mota"] == pytest.approx(0.5)
    assert out["num_switches"] == 1
    assert out["idf1"] == pytest.approx(4 / 7)
