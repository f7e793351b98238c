"""The metric path runs the field's own tools on exported files: COCOeval AP50 on a COCO-video
ground truth, TrackEval (MM-UAV classes) on a MOTChallenge layout, the Anti-UAV state accuracy
on an IR_label.json; each is checked against a hand-computed value or an independent implementation."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from evids.metrics import average_precision, hota, mot_metrics
from harness.experiments.detection import metrics as M


def _coco_gt(path: Path, boxes: list[list[float] | None]) -> dict[str, int]:
    images, anns = [], []
    for i, b in enumerate(boxes):
        images.append({"id": i + 1, "file_name": f"v/rgb_frame/{i + 1:04d}.jpg", "frame_id": i + 1, "video_id": 1,
                       "width": 320, "height": 256})
        if b is not None:
            anns.append({"id": len(anns) + 1, "image_id": i + 1, "category_id": 1, "track_id": 1, "bbox": b,
                         "area": b[2] * b[3], "iscrowd": 0})
    path.write_text(json.dumps({"images": images, "annotations": anns, "videos": [{"id": 1, "file_name": "v"}],
                                "categories": [{"id": 1, "name": "drone"},
                                               {"id": 2, "name": "bird", "distractor": True}]}))
    return {f"v/{i}": i + 1 for i in range(len(boxes))}


def test_coco_ap50_matches_hand_value_and_our_ap(tmp_path):
    gt = [[10, 10, 20, 20], [50, 50, 20, 20], [100, 100, 20, 20], None]
    ids = _coco_gt(tmp_path / "gt.json", gt)
    # frame 0: exact hit (0.9); frame 1: miss-located (0.8, FP); frame 2: hit (0.7); frame 3: FP (0.6)
    dets = [("v", 0, np.array([[10, 10, 20, 20]]), np.array([0.9])),
            ("v", 1, np.array([[200, 50, 20, 20]]), np.array([0.8])),
            ("v", 2, np.array([[101, 100, 20, 20]]), np.array([0.7])),
            ("v", 3, np.array([[5, 5, 10, 10]]), np.array([0.6]))]
    ap = M.coco_ap50(tmp_path / "gt.json", tmp_path / "res" / "r.json", dets, ids)
    ours = average_precision([(d[2], d[3], np.array([g]) if g else np.zeros((0, 4))) for d, g in zip(dets, gt)],
                             interpolation="coco101")
    assert ap == pytest.approx(ours, abs=1e-9)
    # precision envelope: 1.0 up to recall 1/3, then 2/3 up to recall 2/3; COCO's 101-point sampling
    assert ap == pytest.approx((34 * 1.0 + 33 * 2 / 3) / 101, abs=1e-9)
    assert json.loads((tmp_path / "res" / "r.json").read_text())[0]["category_id"] == 1
    assert M.coco_ap50(tmp_path / "gt.json", tmp_path / "res" / "e.json", [], ids) == 0.0


def _mot_layout(root: Path, gt_rows: list[str], trk_rows: list[str], n: int) -> None:
    from simulator.formats.mot import seqinfo_text

    d = root / "gt" / "RGB-s" / "seqA"
    (d / "gt").mkdir(parents=True)
    (d / "gt" / "gt.txt").write_text("".join(r + "\n" for r in gt_rows))
    (d / "seqinfo.ini").write_text(seqinfo_text("seqA", "img1", 25, n, 320, 256))
    (root / "gt" / "seqmaps").mkdir()
    (root / "gt" / "seqmaps" / "RGB-s.txt").write_text("name\nseqA\n")
    t = root / "trk" / "RGB-s" / "mine" / "data"
    t.mkdir(parents=True)
    (t / "seqA.txt").write_text("".join(r + "\n" for r in trk_rows))


def test_trackeval_mmuav_classes_match_hand_mota_and_our_hota(tmp_path):
    # 4 frames, one drone (class 0 = MM-UAV drone); a bird row (class 1, consider 0) is ignored
    gt = [f"{f},1,{10 + 5 * f},20,10,10,1,0,1" for f in range(1, 5)] + ["2,2,200,200,10,10,0,1,1"]
    boxes = {1: [15, 20, 10, 10], 2: [20, 20, 10, 10], 4: [100, 100, 10, 10]}  # frame 3 missed, frame 4 wrong
    trk = [f"{f},1,{b[0]},{b[1]},{b[2]},{b[3]},0.9,-1,-1,-1" for f, b in boxes.items()]
    _mot_layout(tmp_path, gt, trk, 4)
    res = M.trackeval_mot(tmp_path / "gt", tmp_path / "trk", "RGB", "s", ["mine"])
    r = res["mine"]["seqA"]
    # 4 GT, TP 2, FN 2 (frames 3 and 4), FP 1 (frame 4), IDSW 0: MOTA = 1 - (2 + 1) / 4
    assert r["mota"] == pytest.approx(0.25)
    gt_frames = [([1], [[10 + 5 * f, 20, 10, 10]]) for f in range(1, 5)]
    hyp_frames = [([1], [boxes[f]]) if f in boxes else ([], np.zeros((0, 4))) for f in range(1, 5)]
    assert r["hota"] == pytest.approx(hota(gt_frames, hyp_frames)["hota"], abs=1e-9)
    assert r["mota"] == pytest.approx(mot_metrics(gt_frames, hyp_frames)["mota"], abs=1e-9)


def test_state_accuracy_both_variants_from_label_file(tmp_path):
    f = tmp_path / "IR_label.json"
    f.write_text(json.dumps({"exist": [1, 1, 0, 0], "gt_rect": [[0, 0, 10, 10], [0, 0, 10, 10], [], [0]]}))
    pred = [[0, 0, 10, 10], None, None, [5, 5, 2, 2]]
    r = M.antiuav_state_accuracy(f, pred)
    assert r["plain"] == pytest.approx((1 + 0 + 1 + 0) / 4)
    assert r["penalised"] == pytest.approx(0.5 - 0.2 * 0.5 ** 0.3)
    np.testing.assert_allclose(M.per_frame_state_values(pred, [[0, 0, 10, 10], [0, 0, 10, 10], None, None]),
                               [1, 0, 1, 0])


def test_paired_comparison_exact_sign_flip_and_mde():
    a = np.array([0.6, 0.7, 0.8, 0.9])
    b = np.array([0.5, 0.5, 0.5, 0.5])
    c = M.paired_comparison(a, b, seed=0, n_resamples=500)
    d = a - b
    assert c["diff"] == pytest.approx(d.mean())
    assert c["p"] == pytest.approx(2 / 16)  # only all-plus and all-minus reach |mean| of the data
    assert c["mde"] == pytest.approx(2.8 * d.std(ddof=1) / 2)
    same = M.paired_comparison(a, a, seed=0, n_resamples=500)
    assert same["diff"] == 0.0 and same["p"] == 1.0


def test_clustered_uauc_perfect_and_inverted():
    unc = np.array([0.9, 0.8, 0.1, 0.2])
    err = np.array([True, True, False, False])
    cl = np.array([0, 1, 0, 1])
    assert M.clustered_uauc(unc, err, cl, 0, 200)["uauc"] == 1.0
    assert M.clustered_uauc(-unc, err, cl, 0, 200)["uauc"] == 0.0
    assert np.isnan(M.clustered_uauc(unc, np.zeros(4, bool), cl, 0, 200)["uauc"])


def test_area_strata_edges():
    assert M.area_stratum(np.array([0.0, 199.9, 200.0, 999.0, 1000.0])).tolist() == [
        "small <200", "small <200", "medium 200-1000", "medium 200-1000", "large >1000"]
