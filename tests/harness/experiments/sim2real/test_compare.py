"""Paired before / after comparison of two sim2real runs (`evids sim2real-compare`): known answers on
hand-made predictions, the file round trip, bad input naming the field, and the CLI on miniature run
folders (nothing written on failure; an existing output is not replaced)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from harness.experiments.sim2real import compare
from scenes.errors import UserInputError

CONDS = ["a_real", "b_synthetic"]


def _crops(n_clips: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """Every clip holds one crop of each of the two classes, so every bootstrap resample has both."""
    y = np.tile([0, 1], n_clips)
    clip = np.repeat([f"c{i}" for i in range(n_clips)], 2)
    return y, clip


def _run(folder: Path, y: np.ndarray, clip: np.ndarray, predicted: np.ndarray, sensor: str = "ir") -> Path:
    folder.mkdir(parents=True)
    (folder / "sim2real.json").write_text("{}")
    compare.write_predictions(compare.predictions_path(folder, sensor), y, clip, CONDS, [0, 1], predicted)
    return folder


def test_paired_difference_known_answer_and_zero_for_the_same_predictions():
    y, clip = _crops()
    always_0 = np.zeros((2, len(y)), int)                     # balanced accuracy 0.5 on every resample
    perfect = np.stack([y, y])                                # 1.0 on every resample
    before = {"y": y, "clip": clip, "conditions": np.array(CONDS), "predicted": np.stack([perfect, always_0])}
    after = {"y": y, "clip": clip, "conditions": np.array(CONDS), "predicted": np.stack([perfect, perfect])}
    res = compare.compare_sensor(before, after, bootstrap=200, rng_seed=0)
    b = res["conditions"]["b_synthetic"]
    assert (b["before"], b["after"], b["difference"]) == (0.5, 1.0, 0.5)
    assert b["ci_low"] == b["ci_high"] == 0.5 and b["mde"] == 0.0
    a = res["conditions"]["a_real"]
    assert a["difference"] == a["ci_low"] == a["ci_high"] == 0.0
    assert res["n_test_crops"] == 12 and res["n_test_clips"] == 6
    assert b["recall_before"] == [1.0, 0.0] and b["recall_after"] == [1.0, 1.0]   # class 1 is where it moved
    assert res["classes"] == ["class 0", "class 1"]


def test_class_recall_is_the_seed_mean_and_none_for_an_absent_class():
    y = np.array([0, 0, 2, 2])
    predicted = np.array([[0, 1, 2, 2], [0, 0, 0, 2]])
    assert compare.class_recall(y, predicted) == [0.75, None, 0.75]


def test_one_seed_better_half_the_difference_and_an_interval_that_needs_resampling():
    """After: seed 0 perfect, seed 1 always class 0 -> mean 0.75; before always class 0 -> 0.5: +0.25. With one
    clip's class-1 crop wrong in seed 0, the resamples that draw that clip more often move the estimate: the
    interval opens and the MDE is positive."""
    y, clip = _crops()
    wrong_once = y.copy()
    wrong_once[1] = 0
    always_0 = np.zeros(len(y), int)
    before = {"y": y, "clip": clip, "conditions": np.array(CONDS[1:]), "predicted": np.stack([[always_0, always_0]])}
    after = {"y": y, "clip": clip, "conditions": np.array(CONDS[1:]), "predicted": np.stack([[y, always_0]])}
    assert compare.compare_sensor(before, after, bootstrap=200, rng_seed=0)["conditions"]["b_synthetic"][
        "difference"] == pytest.approx(0.25)
    after["predicted"] = np.stack([[wrong_once, always_0]])
    r = compare.compare_sensor(before, after, bootstrap=500, rng_seed=0)["conditions"]["b_synthetic"]
    assert r["difference"] == pytest.approx(((1 + 5 / 6) / 2 + 0.5) / 2 - 0.5)   # seed 0: class-1 recall 5/6
    assert r["ci_low"] < r["difference"] < r["ci_high"] and r["mde"] > 0


def test_predictions_round_trip_and_byte_identical_rewrite(tmp_path):
    y, clip = _crops()
    pred = np.stack([np.stack([y, 1 - y]), np.stack([1 - y, y])])
    path = compare.predictions_path(tmp_path, "visible")
    compare.write_predictions(path, y, clip, CONDS, [0, 1], pred)
    first = path.read_bytes()
    compare.write_predictions(path, y, clip, CONDS, [0, 1], pred)
    assert path.read_bytes() == first
    got = compare.read_predictions(path)
    assert np.array_equal(got["predicted"], pred) and list(got["conditions"]) == CONDS
    assert np.array_equal(got["clip"], clip) and list(got["seeds"]) == [0, 1]
    with pytest.raises(ValueError, match="shape"):
        compare.write_predictions(path, y, clip, CONDS, [0], pred)


def test_bad_input_names_the_field(tmp_path):
    y, clip = _crops()
    pred = np.stack([np.stack([y, y])] * 2)
    before = _run(tmp_path / "before", y, clip, pred)
    with pytest.raises(UserInputError, match="--after.*holds no predictions"):
        compare.compare_runs(before, tmp_path / "nowhere")
    other = _run(tmp_path / "other", y[:-2], clip[:-2], pred[:, :, :-2])
    with pytest.raises(UserInputError, match="ir: the two runs' real evaluation crops differ"):
        compare.compare_runs(before, other)
    (tmp_path / "junk" / "predictions").mkdir(parents=True)
    (tmp_path / "junk" / "predictions" / "ir.npz").write_bytes(b"not a zip")
    with pytest.raises(UserInputError, match="--after.*not a predictions file"):
        compare.compare_runs(before, tmp_path / "junk")
    good = compare.predictions_path(before, "ir").read_bytes()
    (tmp_path / "junk" / "predictions" / "ir.npz").write_bytes(good[: len(good) // 2])   # a truncated zip
    with pytest.raises(UserInputError, match="--after.*not a predictions file"):
        compare.compare_runs(before, tmp_path / "junk")
    vis_only = _run(tmp_path / "vis", y, clip, pred, sensor="visible")
    with pytest.raises(UserInputError, match="no sensor in common"):
        compare.compare_runs(before, vis_only)


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", "from harness.cli import main; main()", *args], capture_output=True,
                          text=True, timeout=300)


def test_cli_prints_writes_json_and_refuses_bad_input(tmp_path):
    y, clip = _crops()
    always_0 = np.zeros(len(y), int)
    before = _run(tmp_path / "before", y, clip, np.stack([np.stack([y, y]), np.stack([always_0, always_0])]))
    after = _run(tmp_path / "after", y, clip, np.stack([np.stack([y, y]), np.stack([y, y])]))
    out = tmp_path / "cmp" / "b_vs_a.json"
    proc = _cli("sim2real-compare", "--before", str(before), "--after", str(after), "--json", str(out),
                "--bootstrap", "200")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "(b) synthetic only" in proc.stdout and "+50.0 [+50.0, +50.0] pt" in proc.stdout
    assert "recall class 0 100 -> 100, class 1 0 -> 100 %" in proc.stdout
    (before / "sim2real.json").write_text(json.dumps({"sensors": {"ir": {"classes": ["DRONE", "BIRD"]}}}))
    named = _cli("sim2real-compare", "--before", str(before), "--after", str(after), "--bootstrap", "200")
    assert "recall drone 100 -> 100, bird 0 -> 100 %" in named.stdout
    saved = json.loads(out.read_text())
    assert saved["sensors"]["ir"]["conditions"]["b_synthetic"]["difference"] == 0.5
    again = _cli("sim2real-compare", "--before", str(before), "--after", str(after), "--json", str(out))
    assert again.returncode == 2 and "--json" in again.stderr and json.loads(out.read_text()) == saved
    (after / "sim2real.json").unlink()
    missing = _cli("sim2real-compare", "--before", str(before), "--after", str(after), "--json",
                   str(tmp_path / "new.json"))
    assert missing.returncode == 2 and "--after" in missing.stderr and not (tmp_path / "new.json").exists()


def _audio_run(folder: Path, scores: np.ndarray, *, n_clips: int = 4) -> Path:
    """A run folder holding only audio scores: ``n_clips`` drone and ``n_clips`` helicopter recordings, two
    windows each; ``scores``: models x conditions x seeds x windows."""
    folder.mkdir(parents=True)
    (folder / "sim2real.json").write_text("{}")
    clip = np.repeat([f"d{i}" for i in range(n_clips)] + [f"h{i}" for i in range(n_clips)], 2)
    cls = np.where(np.char.startswith(clip, "d"), "DRONE", "HELICOPTER")
    compare.write_audio_scores(compare.predictions_path(folder, compare.AUDIO), (cls == "DRONE").astype(int), clip,
                               cls, ["cnn"], CONDS, [0, 1], scores)
    return folder


def test_audio_paired_auc_difference_known_answer(tmp_path):
    """Before: condition b scores every window 0.5 (AUC 0.5, no window called drone); after: drones 0.9,
    helicopters 0.2 (AUC 1.0, none called drone), on every resample: +0.5 with a closed interval, MDE 0.
    Condition a is the same in both runs: 0. A visual-only run on one side is skipped, not an error."""
    y = np.repeat([1, 0], 8)
    flat = np.full((1, 2, 2, 16), 0.5)
    good = flat.copy()
    good[0, 1] = np.where(y == 1, 0.9, 0.2)
    before, after = _audio_run(tmp_path / "b", flat), _audio_run(tmp_path / "a", good)
    res = compare.compare_runs(before, after, bootstrap=200)
    b = res["audio"]["models"]["cnn"]["b_synthetic"]
    assert (b["before"], b["after"], b["difference"]) == (0.5, 1.0, 0.5)
    assert b["ci_low"] == b["ci_high"] == 0.5 and b["mde"] == 0.0
    assert b["helicopter_called_drone"] == [0.0, 0.0] and b["background_called_drone"] == [None, None]
    a = res["audio"]["models"]["cnn"]["a_real"]
    assert a["difference"] == a["ci_low"] == a["ci_high"] == 0.0
    assert res["audio"]["n_test_clips"] == 8 and res["audio"]["n_test_windows"] == 16
    assert "+50.0 [+50.0, +50.0] pt" in compare.format_comparison(res)


def test_audio_interval_opens_when_one_recording_decides(tmp_path):
    """After: one drone recording scored under every helicopter (the others perfect): AUC 1 - 2/16 per seed on
    the full set; resamples that draw that recording more or less often move it, so the interval is open and the
    MDE positive; every resample keeps both classes (drawn per class)."""
    y = np.repeat([1, 0], 8)
    before = np.full((1, 2, 2, 16), 0.5)
    after = before.copy()
    s = np.where(y == 1, 0.9, 0.2)
    s[:2] = 0.1                                             # recording d0: both windows under every helicopter
    after[0, 1] = s
    res = compare.compare_runs(_audio_run(tmp_path / "b", before), _audio_run(tmp_path / "a", after), bootstrap=300)
    b = res["audio"]["models"]["cnn"]["b_synthetic"]
    assert b["after"] == pytest.approx(1 - 16 / 64)          # 2 of 8 drone windows x 8 helicopter windows: 16 of 64
    assert b["ci_low"] < b["difference"] < b["ci_high"] and b["mde"] > 0
    assert np.isfinite(b["ci_low"])


def test_audio_runs_of_other_recordings_refuse_to_pair(tmp_path):
    scores = np.full((1, 2, 2, 16), 0.5)
    before = _audio_run(tmp_path / "b", scores)
    after = _audio_run(tmp_path / "a", np.full((1, 2, 2, 12), 0.5), n_clips=3)
    with pytest.raises(UserInputError, match="audio: the two runs' real evaluation windows differ"):
        compare.compare_runs(before, after, bootstrap=100)
    with pytest.raises(ValueError, match="scores has shape"):
        compare.write_audio_scores(tmp_path / "x.npz", np.zeros(4), ["c"] * 4, ["DRONE"] * 4, ["cnn"], CONDS, [0],
                                   np.zeros((1, 2, 2, 4)))
