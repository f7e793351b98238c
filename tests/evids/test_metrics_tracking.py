"""HOTA / MOTA / IDF1 via trackeval (installed by the test extras, so these run in CI)."""
import importlib.util
import math
import sys

import numpy as np
import pytest

from evids.metrics import hota, track_scores

needs_trackeval = pytest.mark.skipif(
    importlib.util.find_spec("trackeval") is None, reason="optional dependency trackeval not installed"
)
BOX = [[0, 0, 10, 10]]
NONE = ([], np.zeros((0, 4)))


@needs_trackeval
def test_hota_perfect():
    # two objects moving over 3 frames, hypothesis identical up to id labels
    gt = [([1, 2], [[t, 0, 10, 10], [50, t, 8, 12]]) for t in range(3)]
    hyp = [(["a", "b"], [[t, 0, 10, 10], [50, t, 8, 12]]) for t in range(3)]
    out = hota(gt, hyp)
    assert out == {"hota": pytest.approx(1.0), "deta": pytest.approx(1.0), "assa": pytest.approx(1.0)}


@needs_trackeval
def test_hota_id_switch_halfway():
    # 1 GT track (id 1) over 4 frames; hypothesis boxes are exact (IoU 1, so every alpha matches)
    # but the id switches 7 -> 8 after frame 1.
    # DetA = TP / (TP + FN + FP) = 4 / 4 = 1 at every alpha.
    # AssA = (1/TP) sum_c A(c); for both matched pairs A = TPA / (TPA + FNA + FPA):
    #   (1, 7): TPA 2, FNA 4 - 2 = 2, FPA 2 - 2 = 0 -> 2/4; (1, 8) likewise 2/4.
    #   AssA = (2 * 0.5 + 2 * 0.5) / 4 = 0.5.  HOTA = sqrt(DetA * AssA) = sqrt(0.5).
    gt = [([1], BOX)] * 4
    hyp = [([7], BOX), ([7], BOX), ([8], BOX), ([8], BOX)]
    out = hota(gt, hyp)
    assert out["deta"] == pytest.approx(1.0)
    assert out["assa"] == pytest.approx(0.5)
    assert out["hota"] == pytest.approx(math.sqrt(0.5))


@needs_trackeval
def test_hota_alpha_average():
    # one frame, IoU = (10 * 5.2) / 100 = 0.52: a match for alpha in {0.05, ..., 0.50} (10 of the 19
    # thresholds, HOTA = DetA = AssA = 1 there) and none for alpha >= 0.55 (all 0), so each mean is 10/19.
    out = hota([([1], BOX)], [([1], [[0, 0, 10, 5.2]])])
    for k in ("hota", "deta", "assa"):
        assert out[k] == pytest.approx(10 / 19)


@needs_trackeval
def test_hota_empty_hypothesis_and_xyxy():
    gt = [([1], BOX)] * 3
    assert hota(gt, [NONE] * 3) == {"hota": 0.0, "deta": 0.0, "assa": 0.0}
    # frame 1 missed: DetA = TP 2 / (2 + FN 1) = 2/3; pair (1, 5) has TPA 2, FNA 1 (the missed GT
    # det still belongs to GT track 1), FPA 0 -> AssA = 2/3; HOTA = sqrt(2/3 * 2/3) = 2/3.
    out = hota(gt, [([5], [[0, 0, 10, 10]]), NONE, ([5], [[0, 0, 10, 10]])], fmt="xyxy")
    assert out["deta"] == pytest.approx(2 / 3)
    assert out["assa"] == pytest.approx(2 / 3)
    assert out["hota"] == pytest.approx(2 / 3)


@needs_trackeval
def test_hota_validation():
    with pytest.raises(ValueError, match="same frames"):
        hota([([1], BOX)], [])
    with pytest.raises(ValueError, match="unique"):
        hota([([1, 1], BOX * 2)], [([1], BOX)])
    with pytest.raises(ValueError, match="disagree"):
        hota([([1, 2], BOX)], [([1], BOX)])


def test_hota_import_error_message(monkeypatch):
    monkeypatch.setitem(sys.modules, "trackeval", None)
    monkeypatch.setitem(sys.modules, "trackeval.metrics", None)
    with pytest.raises(ImportError, match="pip install --no-deps trackeval==1.3.0"):
        hota([([1], BOX)], [([1], BOX)])


def test_track_scores_hand_computed_swap():
    # 2 gt tracks over 10 frames (20 dets). Hypothesis: ids swap after frame 5 (both tracks switch: 2 IDSW),
    # one box missing at frame 8 (1 FN), the rest 1 px shifted (IoU 0.9 >= 0.5, still matched).
    # MOTA = 1 - (FN 1 + FP 0 + IDSW 2) / 20 = 0.85 (the same case as the benchmark toolkit check).
    gt, hyp = [], []
    for t in range(10):
        boxes = [[10 + t, 10, 10, 10], [100, 50 + t, 10, 10]]
        gt.append(([1, 2], boxes))
        ids = [7, 8] if t < 5 else [8, 7]
        shifted = [[b[0] + 1, b[1], b[2], b[3]] for b in boxes]
        hyp.append((ids[:1], shifted[:1]) if t == 8 else (ids, shifted))
    out = track_scores(gt, hyp)
    assert out["mota"] == pytest.approx(0.85)
    assert out["idsw"] == 2 and out["fn"] == 1 and out["fp"] == 0
    # IDF1: the best one-to-one id assignment (1->7, 2->8, or the swapped one) has IDTP = 5 + 5 = 10
    # (frames 0-4; the other assignment gets 4 + 5 after the miss); IDFN = 20 - 10 = 10; IDFP = 19 - 10 = 9.
    # IDF1 = 2 IDTP / (2 IDTP + IDFN + IDFP) = 20 / 39.
    assert out["idf1"] == pytest.approx(20 / 39)
    perfect = track_scores(gt, gt)
    assert perfect["hota"] == pytest.approx(1.0) and perfect["mota"] == 1.0 and perfect["idf1"] == 1.0


def test_trackeval_is_installed_so_hota_tests_run():
    """The test extras install trackeval: these tracking tests must not silently skip in CI."""
    assert importlib.util.find_spec("trackeval") is not None
