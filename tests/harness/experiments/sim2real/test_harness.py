"""`evids sim2real --quick` end to end on a miniature of the Svanström layout (no real data): the run
folder holds the summary, the report page and the sheets; a damaged real clip is skipped and listed
(or stops the run with --strict); bad input exits 2. Plus known-answer tests of the statistics and of
the classifier bookkeeping."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from harness.experiments.sim2real import classify, samples
from harness.experiments.sim2real.harness import statistics_table

pytest.importorskip("mcos_decoder")
pytest.importorskip("av")


def _cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", "from harness.cli import main; main()", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=900)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    from tests.simulator.formats.svanstrom_miniature import write_miniature

    root = tmp_path_factory.mktemp("s2r")
    real = write_miniature(root / "real", numbers=(1, 2, 3, 4), n_frames=6, ir_size=(64, 48), visible_size=(96, 80),
                           audio_s=2.0)
    (real / "Data" / "Video_IR" / "IR_BIRD_004_LABELS.mat").unlink()      # a damaged clip: no labels
    out = root / "run"
    proc = _cli("sim2real", "--real", str(real), "--out", str(out), "--quick", "--no-progress")
    return real, out, proc


def test_quick_run_writes_summary_page_and_sheets(quick_run):
    real, out, proc = quick_run
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((out / "sim2real.json").read_text())
    assert summary["quick"] is True and set(summary["sensors"]) == {"ir", "visible", "audio"}
    for sensor in ("ir", "visible"):
        res = summary["sensors"][sensor]
        conds = res["classifier"]["conditions"]
        assert list(conds) == list(classify.CONDITIONS)
        assert all(0.0 <= c["estimate"] <= 1.0 and c["ci_low"] <= c["estimate"] <= c["ci_high"] for c in conds.values())
        a_real = conds["a_real"]     # per-class recall: its mean over the classes present is the balanced accuracy
        assert len(a_real["recall"]) == len(res["classes"]) and len(a_real["confusion"]) == len(res["classes"])
        present = [r for r in a_real["recall"] if r is not None]
        assert np.mean(present) == pytest.approx(np.mean(a_real["per_seed"]))
        # reverse transfer: every synthetic crop classified once per seed by the real-trained model
        rev = res["classifier"]["reverse_transfer"]
        assert np.sum(rev["confusion"]) == rev["n_crops"] * len(conds["a_real"]["per_seed"])
        assert rev["n_crops"] == res["classifier"]["train_sizes"]["b_synthetic"] == len(rev["majority"])
        assert res["sheets"]["reverse"] == f"{sensor}_reverse.png"
        assert res["n_clips"]["real_evaluation"] == (7 if sensor == "ir" else 8) and res["n_clips"]["synthetic"] == 4
        # the calibration half trains, the evaluation half tests: no clip in both
        assert res["classifier"]["train_clips"]["a_real"] == res["n_clips"]["real_calibration"]
        assert res["statistics"]["DRONE"]["background"]["real_evaluation"]["n"] > 0
        for name in res["sheets"].values():
            assert (out / "sheets" / name).stat().st_size > 1000
    # IR_BIRD_004 (even: evaluation half) lost its labels: skipped and listed
    assert "IR_BIRD_004" in (out / "skipped.txt").read_text() and len(summary["skipped_clips"]) == 1
    page = (out / "sim2real.html").read_text()
    assert "Sim-to-real" in page and "(b) synthetic only" in page and "data:image/png;base64" in page
    assert "ratio (b)/(a)" in proc.stdout and "recall drone" in proc.stdout and "recall per class" in page
    assert "(a) on the synthetic crops (reverse)" in proc.stdout and "called drone" in page
    assert "grouped by what the real-trained model (a) calls them" in page
    audio = summary["sensors"]["audio"]
    assert set(audio["classifier"]) == {"cnn", "logreg"} and audio["n_clips"]["evaluation"] == 6
    assert (out / "sheets" / audio["figure"]).stat().st_size > 1000 and "helicopter windows called drone" in page


def test_strict_stops_at_the_damaged_clip_and_bad_input_exits_2(quick_run, tmp_path):
    real, _, _ = quick_run
    proc = _cli("sim2real", "--real", str(real), "--out", str(tmp_path / "strict"), "--quick", "--strict",
                "--no-progress")
    assert proc.returncode == 2 and "IR_BIRD_004" in proc.stderr
    proc = _cli("sim2real", "--real", str(tmp_path / "nowhere"), "--out", str(tmp_path / "x"))
    assert proc.returncode == 2 and "--real" in proc.stderr
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nvisual: {classes: {DRONE: {generation: {}, sequences: 1}, KITE: {generation: {}, "
                   "sequences: 1}}}\n")
    proc = _cli("sim2real", "--real", str(real), "--out", str(tmp_path / "y"), "--config", str(bad))
    assert proc.returncode == 2 and "KITE" in proc.stderr
    proc = _cli("sim2real", "--real", str(real), "--out", str(tmp_path / "z"), "--reuse-renders", str(real))
    assert proc.returncode == 2 and "--reuse-renders" in proc.stderr and not (tmp_path / "z").exists()


def test_frame_statistics_known_answers():
    img = np.full((40, 40), 100, np.uint8)
    img[30:] = 140                                 # warm ground in the bottom quarter
    img[10:14, 10:14] = 160                        # a 4x4 target, 60 above its ring
    prev = img.copy()
    prev[0, 0] = 110                               # one changed pixel: the robust temporal noise stays 0
    st = samples.frame_statistics(img, (10, 10, 4, 4), prev)
    assert st["contrast"] == pytest.approx(60.0) and st["peak"] == pytest.approx(60.0)
    assert st["background"] == 100.0 and st["row_gradient"] == pytest.approx(40.0)
    assert st["temporal_noise"] == 0.0 and st["box_w_px"] == 4.0
    rng = np.random.default_rng(0)
    noisy = np.clip(100 + rng.normal(0, 4, (200, 200)), 0, 255).astype(np.uint8)
    noisy2 = np.clip(100 + rng.normal(0, 4, (200, 200)), 0, 255).astype(np.uint8)
    assert samples.frame_statistics(noisy2, None, noisy)["temporal_noise"] == pytest.approx(4.0, rel=0.1)


def test_crop_is_centred_and_edges_replicated():
    img = np.zeros((20, 20), np.uint8)
    img[9:11, 9:11] = 255
    crop = samples.target_crop(img, (9, 9, 2, 2), out_px=8, context=4.0, min_side_px=8)
    assert crop.shape == (8, 8) and crop[3:5, 3:5].min() == 255 and crop[0, 0] == 0
    edge = samples.crop_around(np.arange(100, dtype=np.uint8).reshape(10, 10), (0, 0), 4, 4)
    assert edge.shape == (4, 4) and edge[0, 0] == 0


def test_balanced_accuracy_and_statistics_table_inside_flag():
    y = np.array([0, 0, 0, 0, 1, 1])
    assert classify.balanced_accuracy(y, np.array([0, 0, 0, 0, 0, 1])) == pytest.approx(0.75)
    mk = lambda domain, half, v: samples.FrameSample(domain, "ir", "DRONE", f"{domain}{v}", half, 0,  # noqa: E731
                                                     np.zeros((2, 2), np.uint8), None, {"contrast": v})
    rows = [mk("real", "evaluation", v) for v in (1.0, 2.0, 3.0, 4.0, 5.0)] + [mk("synthetic", "synthetic", 3.5)]
    table = statistics_table(rows, [], "ir", ["DRONE"])
    assert table["DRONE"]["contrast"]["inside"] is True
    assert table["DRONE"]["contrast"]["real_evaluation"]["q25"] == 2.0
    assert table["DRONE"]["contrast"]["calibration_inside"] is None   # no calibration crops: no null reference
    rows[-1] = mk("synthetic", "synthetic", 50.0)
    assert statistics_table(rows, [], "ir", ["DRONE"])["DRONE"]["contrast"]["inside"] is False
    # the null reference: the real calibration half's median against the same evaluation IQR [2, 4]
    cal = [mk("real", "calibration", v) for v in (3.0, 9.0, 9.5)]      # median 9: outside
    assert statistics_table(rows + cal, [], "ir", ["DRONE"])["DRONE"]["contrast"]["calibration_inside"] is False
    cal = [mk("real", "calibration", v) for v in (1.0, 2.5, 9.5)]      # median 2.5: inside
    assert statistics_table(rows + cal, [], "ir", ["DRONE"])["DRONE"]["contrast"]["calibration_inside"] is True


def test_per_class_recall_and_confusion_known_answer():
    y = np.array([0, 0, 1, 1, 2])
    preds = np.array([[0, 1, 1, 1, 0],      # seed 0: class 0 half right, class 1 right, class 2 wrong
                      [0, 0, 0, 1, 0]])     # seed 1: class 0 right, class 1 half right, class 2 wrong
    out = classify.per_class(y, preds, 4)
    assert out["recall"] == [pytest.approx(0.75), pytest.approx(0.75), 0.0, None]
    assert out["confusion"] == [[3, 1, 0, 0], [1, 3, 0, 0], [2, 0, 0, 0], [0, 0, 0, 0]]


def test_few_shot_takes_a_fraction_of_each_class_at_least_one():
    rows = [samples.FrameSample("real", "ir", cls, f"{cls}{k}", "calibration", 0, np.zeros(1, np.uint8), None)
            for cls, n in (("DRONE", 20), ("BIRD", 3)) for k in range(n)]
    chosen = classify.few_shot_clips(rows, 0.1, np.random.default_rng(0))
    assert sum(c.startswith("DRONE") for c in chosen) == 2 and sum(c.startswith("BIRD") for c in chosen) == 1


@pytest.mark.parametrize("n_crops", [5, 300])
def test_every_condition_gets_the_same_number_of_optimiser_steps(n_crops, monkeypatch):
    """Counted in steps, not epochs: a few-shot set of 5 crops and a set of 300 both get ``steps``
    updates (counted in epochs, the small set got a tenth of the training)."""
    import torch

    from harness.experiments.sim2real import classify

    calls = []
    original = torch.optim.Adam.step

    def counting_step(self, *args, **kwargs):
        calls.append(1)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(torch.optim.Adam, "step", counting_step)
    rng = np.random.default_rng(0)
    crops = classify.CropSet(rng.normal(size=(n_crops, 1, 16, 16)).astype(np.float32),
                             rng.integers(0, 2, n_crops), np.array([f"c{i % 3}" for i in range(n_crops)]))
    classify.train_cnn(crops, 2, seed=0, steps=7, batch_size=64, learning_rate=1e-3)
    assert len(calls) == 7


def test_outputs_do_not_depend_on_the_order_forked_jobs_finish_in(quick_run, tmp_path, monkeypatch, reverse_forked_map):
    """``forked_map`` yields in completion order, which depends on timing (how long the other
    sensor's jobs take, the machine's load): the run must put the results back in call order. The
    quick run's folder rerun in-process (real and synthetic caches reused) with every forked map
    delivering its results in reverse order gives the same numbers, detector outputs and sheets.
    (Appending the synthetic samples in completion order made an IR-only change move the visible
    results, and two runs on identical inputs differ.)"""
    import shutil

    import torch

    from harness.experiments.sim2real import harness

    real, out, proc = quick_run
    assert proc.returncode == 0, proc.stderr[-3000:]
    rerun = tmp_path / "rerun"
    shutil.copytree(out, rerun)
    for stale in ("sim2real.json", "sim2real.html", "sheets", "detector"):
        path = rerun / stale
        shutil.rmtree(path) if path.is_dir() else path.unlink()
    monkeypatch.setattr(harness, "_audio_track", lambda *a, **k: {})      # no forked jobs, not under test
    threads = torch.get_num_threads()
    try:
        harness.run_sim2real(real, rerun, quick=True, progress=False, log=lambda _: None)
    finally:
        torch.set_num_threads(threads)
    first, second = (json.loads((d / "sim2real.json").read_text())["sensors"] for d in (out, rerun))
    for sensor in ("ir", "visible"):
        assert second[sensor] == first[sensor], sensor
    files = sorted(p.relative_to(out) for d in ("sheets", "detector") for p in (out / d).rglob("*")
                   if p.is_file() and not p.name.startswith("audio"))
    assert files
    differ = [str(f) for f in files if (out / f).read_bytes() != (rerun / f).read_bytes()]
    assert not differ, differ


def test_contact_sheets_are_written_with_a_label_bar_over_every_row(tmp_path):
    """Each row of the crop and background sheets sits under a bar naming its class and source (real
    calibration half or synthetic); the whole-frame sheet is still written."""
    import cv2

    from harness.experiments.sim2real.harness import ROW_LABELS, labelled_sheet, write_sheets

    rng = np.random.default_rng(0)
    crop = rng.integers(0, 255, (32, 32), dtype=np.uint8)
    pool = [samples.FrameSample(domain=d, sensor="ir", cls=c, clip=f"{c}_{d}", half=h, frame=0, crop=crop,
                                background=crop)
            for c in ("DRONE", "BIRD") for (d, h) in ROW_LABELS]
    clips = [samples.ClipSummary(domain=d, sensor="ir", cls=c, clip=f"{c}_{d}", half=h, n_frames=1,
                                 absent_fraction=0.0, thumbnail=np.zeros((48, 64), np.uint8))
             for c in ("DRONE", "BIRD") for (d, h) in ROW_LABELS]
    files = write_sheets(pool, clips, "ir", ["DRONE", "BIRD"], tmp_path, np.random.default_rng(0))
    assert set(files) == {"crops", "backgrounds", "frames"}
    sheet = cv2.imread(str(tmp_path / files["crops"]))
    bar, row = 18, 64
    assert sheet.shape[0] == 4 * (bar + row)
    for k in range(4):
        top = sheet[k * (bar + row): k * (bar + row) + bar]
        assert (top < 128).any() and (top == 255).mean() > 0.8          # dark text on a white bar
    assert (tmp_path / files["frames"]).stat().st_size > 1000
    # rows of different widths are padded to the widest, with the gap between rows
    out = labelled_sheet([("a", np.zeros((10, 20), np.uint8)), ("b", np.zeros((10, 30, 3), np.uint8))], gap_px=2)
    assert out.shape == (2 * (bar + 10) + 2, 30, 3)


def test_reverse_transfer_counts_what_the_real_trained_model_calls_each_synthetic_crop(monkeypatch):
    """A stub network that always answers class 1: the real-trained models call every synthetic crop
    class 1 (rows = synthetic class), once per seed; the other conditions' models are not asked."""
    asked = []

    class Net:
        def __init__(self, name):
            self.name = name

    def fake_train(train, n_classes, **kw):
        return Net(len(train.y))

    def fake_predict(net, x, batch_size=1024):
        asked.append((net.name, len(x)))
        out = np.zeros((len(x), 3), np.float32)
        out[:, 1] = 1.0
        return out

    monkeypatch.setattr(classify, "train_cnn", fake_train)
    monkeypatch.setattr(classify, "predict", fake_predict)
    mk = lambda y, tag: classify.CropSet(np.zeros((len(y), 1, 4, 4), np.float32), np.array(y),  # noqa: E731
                                         np.array([f"{tag}{i}" for i in range(len(y))]))
    real, syn, test = mk([0, 0, 1, 2], "r"), mk([0, 0, 0, 2, 2], "s"), mk([0, 1, 2], "t")
    out = classify.evaluate_conditions({"a_real": real, "b_synthetic": syn}, test, 3, seeds=[0, 1], steps=1,
                                       batch_size=2, learning_rate=1e-3, bootstrap=20, rng_seed=0, reverse=syn)
    rev = out["reverse_transfer"]
    assert rev["confusion"] == [[0, 6, 0], [0, 0, 0], [0, 4, 0]] and rev["recall"] == [0.0, None, 0.0]
    assert rev["n_crops"] == 5 and rev["n_sequences"] == 5 and rev["majority"] == [1, 1, 1, 1, 1]
    # the synthetic set (5 crops) was predicted only by the real-trained models (trained on 4 crops)
    assert sorted(n for trained_on, n in asked if n == 5) == [5, 5]
    assert all(trained_on == 4 for trained_on, n in asked if n == 5)
    assert "reverse_transfer" not in classify.evaluate_conditions(
        {"b_synthetic": syn}, test, 3, seeds=[0], steps=1, batch_size=2, learning_rate=1e-3, bootstrap=20, rng_seed=0,
        reverse=syn)


def test_crop_set_images_give_back_the_8_bit_crops():
    """CropSet.images inverts crop_set's scaling, grey and colour (what the reverse sheet shows)."""
    from types import SimpleNamespace

    rng = np.random.default_rng(0)
    for shape in ((32, 32), (32, 32, 3)):
        crops = [rng.integers(0, 256, shape, dtype=np.uint8) for _ in range(3)]
        got = classify.crop_set([SimpleNamespace(crop=c, background=None, cls="DRONE", clip="c") for c in crops],
                                ["DRONE"])
        assert np.array_equal(got.images(), np.stack(crops))


def test_majority_vote_takes_the_most_common_class_and_the_lowest_on_a_tie():
    preds = np.array([[0, 2, 1, 3],
                      [2, 2, 0, 3],
                      [2, 1, 1, 0]])
    assert classify.majority_vote(preds, 4).tolist() == [2, 2, 1, 3]
    assert classify.majority_vote(np.array([[1, 0], [0, 1]]), 2).tolist() == [0, 0]     # ties: lowest index


def test_reverse_sheet_has_one_labelled_row_per_called_class(tmp_path):
    import cv2

    from harness.experiments.sim2real.harness import reverse_sheet

    x = np.zeros((5, 1, 8, 8), np.float32) - 0.5
    x[:, :, 3:5, 3:5] = 0.5                                         # a white 2x2 target on black
    crops = classify.CropSet(x, np.array([0, 0, 0, 1, 1]), np.array(list("abcde")))
    path = tmp_path / "ir_reverse.png"
    reverse_sheet(crops, [0, 1, 1, 1, 1], ["DRONE", "BIRD"], path, np.random.default_rng(0), per_row=4)
    sheet = cv2.imread(str(path))
    # three rows (DRONE called DRONE, DRONE called BIRD, BIRD called BIRD): 3 x (18 px label bar + 64 px tiles)
    assert sheet.shape[:2] == (3 * (18 + 64), 4 * 64)
    assert sheet[18 + 32, 32].min() == 255 and sheet[18 + 2, 2].max() == 0      # the target is white, the sky black


def test_quick_run_keeps_its_predictions_for_paired_comparisons(quick_run, tmp_path):
    """predictions/<sensor>.npz hold what the summary's per-seed balanced accuracies were computed from; the
    run compared with itself (`evids sim2real-compare`) differs by exactly zero in every condition."""
    from harness.experiments.sim2real import compare

    _, out, proc = quick_run
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((out / "sim2real.json").read_text())
    for sensor in ("ir", "visible"):
        got = compare.read_predictions(compare.predictions_path(out, sensor))
        conds = summary["sensors"][sensor]["classifier"]["conditions"]
        assert list(got["conditions"]) == list(conds)
        for k, name in enumerate(got["conditions"]):
            assert [classify.balanced_accuracy(got["y"], p) for p in got["predicted"][k]] == \
                pytest.approx(conds[name]["per_seed"])
    from harness.experiments.sim2real.audio import roc_auc

    scores = compare.read_audio_scores(compare.predictions_path(out, compare.AUDIO))   # the audio track's too
    for i, model in enumerate(scores["models"]):
        per_model = summary["sensors"]["audio"]["classifier"][model]
        for k, name in enumerate(scores["conditions"]):
            assert [roc_auc(scores["y"], s) for s in scores["scores"][i, k]] == \
                pytest.approx(per_model[name]["roc_auc_per_seed"], nan_ok=True)
    same = _cli("sim2real-compare", "--before", str(out), "--after", str(out), "--json", str(tmp_path / "same.json"),
                "--bootstrap", "100")
    assert same.returncode == 0, same.stderr[-2000:]
    res = json.loads((tmp_path / "same.json").read_text())
    assert set(res["sensors"]) == {"ir", "visible"}
    assert all(c["difference"] == c["ci_low"] == c["ci_high"] == 0.0
               for s in res["sensors"].values() for c in s["conditions"].values())
    assert set(res["audio"]["models"]) == {"cnn", "logreg"}
    assert all(c["difference"] == c["ci_low"] == c["ci_high"] == 0.0
               for rows in res["audio"]["models"].values() for c in rows.values())
    assert "audio: drone ROC-AUC" in same.stdout


def test_domain_balanced_weights_known_answer():
    """Two domains (3 + 5 crops): each domain half the total, inside it each present label equal."""
    y = np.array([0, 0, 2, 0, 1, 1, 1, 2])
    d = np.array([0, 0, 0, 1, 1, 1, 1, 1])
    w = classify.domain_balanced_weights(y, d)
    # domain 0: labels {0, 2} -> 1/4 each of the total; domain 1: labels {0, 1, 2} -> 1/6 each; mean 1
    expected = np.array([1 / 8, 1 / 8, 1 / 4, 1 / 6, 1 / 18, 1 / 18, 1 / 18, 1 / 6]) * 8
    np.testing.assert_allclose(w, expected)
    assert w.mean() == pytest.approx(1.0)
    one = classify.domain_balanced_weights(np.array([0, 0, 0, 1]), np.zeros(4))      # one domain: class balance
    np.testing.assert_allclose(one, [2 / 3, 2 / 3, 2 / 3, 2.0])


def test_concat_gives_each_set_its_own_domain_and_keeps_nested_ones():
    mk = lambda n, tag: classify.CropSet(np.zeros((n, 1, 2, 2), np.float32), np.zeros(n, np.int64),  # noqa: E731
                                         np.array([tag] * n))
    ab = classify.concat(mk(2, "a"), mk(0, "empty"), mk(1, "b"))
    assert ab.domain.tolist() == [0, 0, 1]                 # an empty set takes no domain number
    assert classify.concat(ab, mk(2, "c")).domain.tolist() == [0, 0, 1, 2, 2]


def test_mixed_training_weights_the_small_real_set_like_the_large_synthetic_one():
    """800 synthetic crops whose brightness rule is the reverse of the 40 real crops' (the synthetic ones
    also carry a cue of their own, a bright left half). Pooled with class balance only, the network learns
    the synthetic rule and gets every real crop wrong; domain-balanced, the real crops weigh as much as
    the synthetic ones and the real rule is learnt."""
    rng = np.random.default_rng(0)

    def crops(n: int, sign: float, cue: float, tag: str) -> classify.CropSet:
        y = rng.integers(0, 2, n)
        level = np.where(y == 1, sign * 0.15, -sign * 0.15).astype(np.float32)[:, None, None, None]
        x = rng.normal(0, 0.1, (n, 1, 16, 16)).astype(np.float32) + level
        x[:, :, :, :8] += np.where(y == 1, cue, -cue).astype(np.float32)[:, None, None, None]
        return classify.CropSet(x, y, np.array([f"{tag}{i}" for i in range(n)]))

    real, synthetic, test = crops(40, 1.0, 0.0, "r"), crops(800, -1.0, 0.2, "s"), crops(300, 1.0, 0.0, "t")
    mixed = classify.concat(synthetic, real)
    pooled = classify.CropSet(mixed.x, mixed.y, mixed.clip)              # the same crops, one domain
    acc = {}
    for name, train in (("mixed", mixed), ("pooled", pooled)):
        net = classify.train_cnn(train, 2, seed=0, steps=40, batch_size=64, learning_rate=2e-3)
        acc[name] = classify.balanced_accuracy(test.y, classify.predict(net, test.x).argmax(1))
    assert acc["mixed"] > 0.9 and acc["pooled"] < 0.1, acc


def test_shrink_averages_frames_and_scales_boxes():
    from harness.experiments.sim2real import detect
    from harness.experiments.sim2real.samples import ClipSummary

    frame = np.zeros((4, 6), np.uint8)
    frame[0:2, 2:4] = 200                                   # one 2x2 block: a single 100 %-covered pixel after /2
    frame[2:4, 4:6] = [[100, 0], [0, 100]]                  # a checker: its mean, 50, after /2
    clip = ClipSummary("real", "ir", "DRONE", "c1", "calibration", 1, 0.0,
                       frames=[(0, frame, (2.0, 0.0, 2.0, 2.0)), (1, frame, None)])
    small = detect.shrink(clip, 2)
    assert small.frames[0][1].tolist() == [[0, 200, 0], [0, 0, 50]]
    assert small.frames[0][2] == (1.0, 0.0, 1.0, 1.0) and small.frames[1][2] is None
    assert clip.frames[0][1].shape == (4, 6)                # the input is not touched
    assert detect.shrink(clip, 1) is clip


def test_detections_of_shrunk_frames_come_back_in_recorded_pixels_against_recorded_labels():
    import torch

    from evids.models.detector import STRIDE, DetectorOutput
    from harness.experiments.sim2real import detect
    from harness.experiments.sim2real.samples import ClipSummary

    def model(x):       # one peak at cell (2, 3), box 6 x 4 px centred on the cell
        b, _, h, w = x.shape
        prob = torch.zeros(b, h // STRIDE, w // STRIDE)
        prob[:, 2, 3] = 0.9
        box = torch.zeros(b, 4, h // STRIDE, w // STRIDE)
        box[:, 2], box[:, 3] = float(np.log(6.0)), float(np.log(4.0))
        return DetectorOutput(prob=prob, box=box)

    frame = np.full((64, 96), 30, np.uint8)
    clip = ClipSummary("real", "ir", "DRONE", "c1", "evaluation", 1, 0.0, frames=[(0, frame, (10.0, 12.0, 8.0, 6.0))])
    native = detect.detect(model, [detect.to_sequence(clip, 0)], "ir")[0][0]["boxes"]
    shrunk = detect.detect(model, [detect.to_sequence(detect.shrink(clip, 2), 0)], "ir", downscale=2)[0][0]["boxes"]
    np.testing.assert_allclose(native, [[3.5 * STRIDE - 3, 2.5 * STRIDE - 2, 6, 4]])
    np.testing.assert_allclose(shrunk, native * 2)
    gt, ids = detect.coco_ground_truth([clip])
    assert (gt["images"][0]["width"], gt["images"][0]["height"]) == (96, 64)
    assert gt["annotations"][0]["bbox"] == [10.0, 12.0, 8.0, 6.0] and ids == {(0, 0): 1}


def test_detector_downscale_is_checked_naming_the_field():
    import pydantic

    from harness.experiments.sim2real.config import VisualProtocol

    base = {"classes": {"DRONE": {"generation": {}, "sequences": 1}, "BIRD": {"generation": {}, "sequences": 1}}}
    assert VisualProtocol.model_validate(base).detector_downscale == {"ir": 1, "visible": 2}
    for bad, word in (({"radar": 2}, "radar"), ({"visible": 0}, "1-8")):
        with pytest.raises(pydantic.ValidationError, match=word) as err:
            VisualProtocol.model_validate({**base, "detector_downscale": bad})
        assert "detector_downscale" in str(err.value)


def test_cross_fitting_scores_each_fold_with_the_other_folds_models_and_trains_a_shared_set_once(monkeypatch):
    """Tuning (``--tune``): a stub network answers the number of crops it was trained on (mod 3), so
    each test crop's prediction names the model that scored it: fold 0's crops get the models trained
    on fold 1's real crops and vice versa; the synthetic set, the same object in both folds, is
    trained once per seed and scores every crop."""
    trained = []

    def fake_train(train, n_classes, seed, **kw):
        trained.append((len(train.y), seed))
        return len(train.y)

    def fake_predict(net, x, batch_size=1024):
        out = np.zeros((len(x), 3), np.float32)
        out[:, net % 3] = 1.0
        return out

    monkeypatch.setattr(classify, "train_cnn", fake_train)
    monkeypatch.setattr(classify, "predict", fake_predict)
    mk = lambda n, tag: classify.CropSet(np.zeros((n, 1, 4, 4), np.float32), np.arange(n) % 3,  # noqa: E731
                                         np.array([f"{tag}{i}" for i in range(n)]))
    syn, real_fold1, real_fold0 = mk(6, "s"), mk(4, "f1_"), mk(5, "f0_")   # 6 % 3 = 0, 4 % 3 = 1, 5 % 3 = 2
    test = mk(6, "t")
    held0 = np.array([True, True, False, False, True, False])
    fit = classify.CrossFit([{"a_real": real_fold1, "b_synthetic": syn}, {"a_real": real_fold0, "b_synthetic": syn}],
                            [held0, ~held0])
    out = classify.evaluate_conditions(fit, test, 3, seeds=[0, 1], steps=1, batch_size=2, learning_rate=1e-3,
                                       bootstrap=20, rng_seed=0)
    conf_a = np.array(out["conditions"]["a_real"]["confusion"])   # rows true class, columns predicted
    predicted_a = conf_a.sum(axis=0)
    assert predicted_a.tolist() == [0, 2 * 3, 2 * 3]     # fold 0's 3 crops called 1, fold 1's 3 called 2; 2 seeds
    assert np.array(out["conditions"]["b_synthetic"]["confusion"]).sum(axis=0).tolist() == [12, 0, 0]
    assert sorted(trained) == sorted([(6, 0), (6, 1), (4, 0), (4, 1), (5, 0), (5, 1)])   # (b) once per seed
    assert out["cross_fit"]["folds"] == 2 and out["cross_fit"]["test_crops"] == [3, 3]
    with pytest.raises(ValueError, match="exactly one fold"):
        classify.CrossFit([{"a_real": syn}, {"a_real": syn}], [held0, held0])
    with pytest.raises(ValueError, match="same conditions"):
        classify.CrossFit([{"a_real": syn}, {"b_synthetic": syn}], [held0, ~held0])


def test_tune_run_reads_only_the_calibration_half_and_cross_fits(quick_run, tmp_path):
    """``evids sim2real --tune`` on a miniature whose evaluation clips are all damaged (no labels):
    the run succeeds and skips nothing (the evaluation half is never read); the classifiers are tested
    on the calibration clips of both tuning folds (1 = fold 0, 11 = fold 1), each trained on the other
    fold; the statistics are judged against the calibration IQR; a tune run and an evaluation run
    refuse to be compared."""
    import shutil

    from simulator.formats.svanstrom import tuning_fold
    from tests.simulator.formats.svanstrom_miniature import write_miniature

    assert [tuning_fold(n) for n in (1, 9, 11, 19, 21)] == [0, 0, 1, 1, 0]
    with pytest.raises(ValueError, match="evaluation clip"):
        tuning_fold(2)
    _, quick_out, proc = quick_run
    assert proc.returncode == 0, proc.stderr[-3000:]
    real = write_miniature(tmp_path / "real", numbers=(1, 2, 11), n_frames=6, ir_size=(64, 48),
                           visible_size=(96, 80), audio_s=2.0)
    for label in (real / "Data").rglob("*_002_LABELS.mat"):
        label.unlink()                                  # the evaluation half: unreadable, and never read
    out = tmp_path / "tune"
    shutil.copytree(quick_out, out)           # the renders do not depend on the real data: keep them, drop the rest
    for path in out.iterdir():
        if path.name != "synthetic" and not path.name.startswith("."):
            shutil.rmtree(path) if path.is_dir() else path.unlink()
    proc = _cli("sim2real", "--real", str(real), "--out", str(out), "--quick", "--tune", "--no-progress")
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((out / "sim2real.json").read_text())
    assert summary["test_half"] == "calibration" and summary["skipped_clips"] == []
    for sensor in ("ir", "visible"):
        res = summary["sensors"][sensor]
        assert res["n_clips"]["real_evaluation"] == 0
        c = res["classifier"]
        assert c["n_test_clips"] == res["n_clips"]["real_calibration"] and c["cross_fit"]["folds"] == 2
        # each fold's real training set holds the other fold's clips only
        assert [f["a_real"] for f in c["cross_fit"]["train_clips"]] == [c["n_test_clips"] // 2] * 2
        assert all(row["real_evaluation"] is None and row["calibration_inside"] is None
                   for rows in res["statistics"].values() for row in rows.values())
        assert any(row["inside"] is not None for rows in res["statistics"].values() for row in rows.values())
        assert set(res["detector"]["conditions"]) == {"synthetic"}
    audio = summary["sensors"]["audio"]
    assert audio["n_clips"]["evaluation"] == 3 and audio["n_clips"]["calibration"] == 3   # fold 0 / fold 1
    assert "calibration half (--tune" in proc.stdout
    assert "Tuning run" in (out / "sim2real.html").read_text()
    proc = _cli("sim2real-compare", "--before", str(quick_out), "--after", str(out))
    assert proc.returncode == 2 and "compare runs of the same kind" in proc.stderr
    proc = _cli("sim2real-compare", "--before", str(out), "--after", str(out))
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "calibration half (--tune: cross-fitted)" in proc.stdout


def test_sensor_generation_merges_into_the_class_generation_known_answer():
    """A sensor's own set: mappings merged key by key, lists and values replaced, the name suffixed
    with the sensor; a sensor without one reads the shared set; unknown sensors are refused by name."""
    from pydantic import ValidationError

    from harness.experiments.sim2real.config import SyntheticClass, merge_mappings, synthetic_set_folder

    base = {"name": "air", "spp": 2, "randomise": {"target_size_scale": [0.5, 1.5], "speed_mps": [80, 230],
                                                    "distance_bins": [{"weight": 1, "range_m": [450, 8500]}]}}
    near = [{"weight": 2, "range_m": [180, 3400]}]
    spec = SyntheticClass(generation=base, sequences=4, sensor_generation={
        "ir": {"randomise": {"target_size_scale": [0.2, 0.6], "distance_bins": near}}})
    ir = spec.generation_for("ir")
    assert ir == {"name": "air_ir", "spp": 2,
                  "randomise": {"target_size_scale": [0.2, 0.6], "speed_mps": [80, 230], "distance_bins": near}}
    assert spec.generation_for("visible") == base == spec.generation_for(None)
    assert spec.generation_for("visible") is not spec.generation          # a copy: the caller may edit it
    assert base["randomise"]["target_size_scale"] == [0.5, 1.5]           # the class's own mapping untouched
    assert (spec.set_of("ir"), spec.set_of("visible")) == ("ir", None)
    assert spec.sets_read_by(["ir", "visible"]) == [None, "ir"] and spec.sets_read_by(["visible"]) == [None]
    assert spec.sets_read_by(["ir"]) == ["ir"]                              # the shared set is not rendered
    assert (synthetic_set_folder("AIRPLANE", "ir"), synthetic_set_folder("AIRPLANE", None)) == ("AIRPLANE_ir",
                                                                                                "AIRPLANE")
    assert merge_mappings({"a": {"b": 1, "c": [1]}}, {"a": {"c": [2]}, "d": 3}) == {"a": {"b": 1, "c": [2]}, "d": 3}
    with pytest.raises(ValidationError, match="audio"):
        SyntheticClass(generation=base, sequences=4, sensor_generation={"audio": {}})


def _recording_synthetic_job(calls: Path, seq_dir: str, params: dict):
    """The harness's synthetic job, noting (sensor, class, set folder) in ``calls`` (it runs in worker processes)."""
    with open(calls, "a") as f:
        f.write(f"{params['sensor']} {params['cls']} {Path(seq_dir).parent.parent.name}\n")
    return samples.synthetic_sequence_samples(Path(seq_dir), **params)


def test_a_sensors_own_synthetic_set_is_rendered_apart_and_read_by_that_sensor_alone(quick_run, tmp_path,
                                                                                      monkeypatch):
    """The quick run's protocol with an IR-only BIRD set (birds three times larger), rerun in-process
    into a new folder with ``reuse_renders`` = the quick run: only BIRD_ir renders (every other set and
    the real samples are hard-linked from the quick run), the IR BIRD crops come from it and every other
    crop from the shared sets, and the visible results are the quick run's to the byte. A bad merged
    value stops the run before any work, naming the field."""
    import functools

    import torch
    import yaml

    from harness.experiments.sim2real import harness
    from harness.experiments.sim2real.config import DEFAULT_CONFIG
    from scenes.errors import UserInputError

    real, out, proc = quick_run
    assert proc.returncode == 0, proc.stderr[-3000:]
    protocol = yaml.safe_load(DEFAULT_CONFIG.read_text())
    for spec in protocol["visual"]["classes"].values():     # same scenario paths: the shared renders are reused
        for entry in spec["generation"]["mixture"]:
            entry["scenario"] = str((DEFAULT_CONFIG.parent / entry["scenario"]).resolve())
    protocol["visual"]["classes"]["BIRD"]["sensor_generation"] = {"ir": {"randomise": {"target_size_scale": [3, 3]}}}
    config = tmp_path / "protocol.yaml"
    config.write_text(yaml.safe_dump(protocol, sort_keys=False))   # the class order sets the seeds
    rerun = tmp_path / "rerun"
    rerun.mkdir()
    calls = tmp_path / "calls.txt"
    monkeypatch.setattr(harness, "_synthetic_job", functools.partial(_recording_synthetic_job, calls))
    monkeypatch.setattr(harness, "_audio_track", lambda *a, **k: {})
    shared = {p.relative_to(out): p.stat().st_ino for p in (out / "synthetic").glob("*/sequences/**/*")
              if p.is_file() and not p.name.startswith(".")}     # content, not evids's bookkeeping marker
    assert shared
    threads = torch.get_num_threads()
    try:
        summary = harness.run_sim2real(real, rerun, config_path=config, quick=True, progress=False,
                                       log=lambda _: None, reuse_renders=out)
    finally:
        torch.set_num_threads(threads)
    assert {p: (rerun / p).stat().st_ino for p in shared} == shared     # every shared file linked, none rendered
    assert set(summary["synthetic_linked"]) == {p.parts[1] for p in shared}
    assert (rerun / "cache" / "real_samples.pkl").read_bytes() == (out / "cache" / "real_samples.pkl").read_bytes()
    assert sorted((rerun / "synthetic" / "BIRD_ir" / "sequences").glob("seq*"))
    assert not (out / "synthetic" / "BIRD_ir").exists()
    read = sorted(set(calls.read_text().split("\n")) - {""})
    own = {(s, c) for c, spec in protocol["visual"]["classes"].items() for s in spec.get("sensor_generation", {})}
    assert ("ir", "BIRD") in own and len(own) > 1          # the shipped protocol's own sets are read too
    assert read == sorted(f"{s} {c} {c}_{s}" if (s, c) in own else f"{s} {c} {c}"
                          for s in ("ir", "visible") for c in ("DRONE", "BIRD", "AIRPLANE", "HELICOPTER"))
    first, second = (json.loads((d / "sim2real.json").read_text())["sensors"] for d in (out, rerun))
    assert second["visible"] == first["visible"]
    bad = yaml.safe_load(config.read_text())
    bad["visual"]["classes"]["BIRD"]["sensor_generation"]["ir"]["randomise"]["target_size_scale"] = [-1, 2]
    config.write_text(yaml.safe_dump(bad, sort_keys=False))
    before = sorted(p.relative_to(rerun) for p in rerun.rglob("*"))
    with pytest.raises(UserInputError, match=r"BIRD\.sensor_generation\.ir.*target_size_scale"):
        harness.run_sim2real(real, rerun, config_path=config, quick=True, progress=False, log=lambda _: None)
    assert sorted(p.relative_to(rerun) for p in rerun.rglob("*")) == before
