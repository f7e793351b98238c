"""Svanström reader on a miniature of the layout (folder and bare git mirror), the split rule, and bad
input; a `real_data` test runs the reader on the real release when EVIDS_SVANSTROM points to it."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from simulator.formats import svanstrom
from simulator.formats.validation import FormatError, Skipped
from tests.simulator.formats.svanstrom_miniature import label_mat_bytes, mirror_of, write_miniature

pytest.importorskip("mcos_decoder")
pytest.importorskip("av")
pytest.importorskip("openpyxl")


@pytest.fixture(scope="module")
def mini(tmp_path_factory) -> Path:
    return write_miniature(tmp_path_factory.mktemp("svanstrom"), numbers=(1, 2, 3), n_frames=5)


def test_split_rule_odd_calibrates_even_evaluates():
    assert [svanstrom.split_of(n) for n in (1, 2, 3, 100, 101)] == [
        "calibration", "evaluation", "calibration", "evaluation", "calibration"]


def test_listing_halves_and_description(mini):
    bench = svanstrom.open_benchmark(mini)
    ir = bench.clips("ir")
    assert len(ir) == 4 * 3 and {c.cls for c in ir} == set(svanstrom.VIDEO_CLASSES)
    cal, ev = bench.clips("ir", "calibration"), bench.clips("ir", "evaluation")
    assert {c.number for c in cal} == {1, 3} and {c.number for c in ev} == {2}
    assert all(c.half == "calibration" for c in cal) and not set(cal) & set(ev)
    drone = bench.clips("visible", classes=["drone"])
    assert [c.name for c in drone] == ["V_DRONE_001", "V_DRONE_002", "V_DRONE_003"]
    assert drone[0].distance_bin == "MEDIUM" and drone[0].drone_type == "F450"   # row (V, DRONE, 1)
    assert drone[2].distance_bin == "CLOSE"
    assert len(bench.clips("audio")) == 9 and bench.clips("audio")[0].labels is None


def test_labels_frames_and_audio_round_trip(mini):
    bench = svanstrom.open_benchmark(mini)
    clip = bench.clips("ir", classes=["DRONE"])[0]
    labels = bench.aligned_labels(clip)
    assert len(labels) == 5 and labels[-1] is None and labels[0] is not None
    x, y, w, h = labels[0]
    assert w == pytest.approx(8.0) and h == pytest.approx(8.0) and x == pytest.approx(6 - 4)
    frames = dict(bench.frames(clip, indices=[0, 4]))
    assert sorted(frames) == [0, 4] and frames[0].shape == (48, 64) and frames[0].dtype == np.uint8
    # the blob (+60 above a ~90 sky) sits inside the box; the lossy codec keeps it clearly visible
    cx, cy = int(x + w / 2), int(y + h / 2)
    assert frames[0][cy, cx] > frames[0][5:10, 40:60].mean() + 25
    vis = dict(bench.frames(bench.clips("visible")[0], indices=[1]))[1]
    assert vis.shape == (48, 64, 3)
    samples, rate = bench.audio(bench.clips("audio", classes=["DRONE"])[0])
    assert rate == 44_100 and samples.shape == (44_100,) and samples.dtype == np.float32
    spectrum = np.abs(np.fft.rfft(samples))
    assert abs(np.argmax(spectrum) * rate / samples.size - 400) < 2      # the 400 Hz fundamental


def test_git_mirror_reads_the_same_bytes_without_checkout(mini, tmp_path):
    folder = tmp_path / "repo"
    shutil.copytree(mini, folder)
    mirror = mirror_of(folder, tmp_path / "mirror.git")
    a, b = svanstrom.open_benchmark(mini), svanstrom.open_benchmark(mirror)
    assert [c.name for c in a.clips("ir")] == [c.name for c in b.clips("ir")]
    clip = b.clips("visible", classes=["BIRD"])[1]
    assert a.labels(clip) == b.labels(clip)
    fa, fb = dict(a.frames(clip, [2])), dict(b.frames(clip, [2]))
    assert np.array_equal(fa[2], fb[2])
    assert b.clips("visible", classes=["BIRD"])[1].distance_bin is not None
    assert not (mirror / "Data").exists()
    b.close()


def test_label_count_tolerance_and_alignment():
    box = (1.0, 2.0, 3.0, 4.0)
    assert svanstrom.align_labels([None, box, box], 2, "x") == [box, box]     # extra leading slot
    assert svanstrom.align_labels([box, box], 3, "x") == [box, box, None]
    with pytest.raises(FormatError, match="4 label entries for 2 video frames"):
        svanstrom.align_labels([box] * 4, 2, "x")


@pytest.mark.parametrize("damage, match", [
    ("no_labels", "label file of .* is missing"),
    ("count", "label entries for 5 video frames"),
    ("truncated", "video|decod"),
    ("bad_mat", "not a readable MATLAB file|no __function_workspace__"),
])
def test_bad_clip_names_the_file_strict_and_is_skipped_otherwise(mini, tmp_path, damage, match):
    root = tmp_path / "copy"
    shutil.copytree(mini, root)
    video = root / "Data" / "Video_IR" / "IR_BIRD_002.mp4"
    labels = root / "Data" / "Video_IR" / "IR_BIRD_002_LABELS.mat"
    if damage == "no_labels":
        labels.unlink()
    elif damage == "count":
        labels.write_bytes(label_mat_bytes([(1.0, 1.0, 2.0, 2.0)] * 9))
    elif damage == "truncated":
        video.write_bytes(video.read_bytes()[: 400])
    else:
        labels.write_bytes(b"not a mat file at all" * 10)
    bench = svanstrom.open_benchmark(root)
    clip = next(c for c in bench.clips("ir") if c.name == "IR_BIRD_002")
    with pytest.raises(FormatError, match=match) as err:
        bench.check(clip)
    assert "IR_BIRD_002" in str(err.value)
    skipped = Skipped()
    assert bench.check(clip, strict=False, skipped=skipped) is False and len(skipped) == 1
    good = next(c for c in bench.clips("ir") if c.name == "IR_BIRD_001")
    assert bench.check(good)


def test_unknown_class_and_not_a_benchmark(mini, tmp_path):
    root = tmp_path / "copy"
    shutil.copytree(mini, root)
    for ext in (".mp4", "_LABELS.mat"):
        shutil.copy(root / "Data" / "Video_IR" / f"IR_BIRD_001{ext}", root / "Data" / "Video_IR" / f"IR_KITE_001{ext}")
    bench = svanstrom.open_benchmark(root)
    kite = next(c for c in bench.clips("ir") if c.cls == "KITE")
    with pytest.raises(FormatError, match="unknown class 'KITE'"):
        bench.check(kite)
    with pytest.raises(FormatError, match="not the Svanström layout"):
        svanstrom.open_benchmark(tmp_path)
    with pytest.raises(FormatError, match="unknown sensor"):
        bench.clips("radar")  # type: ignore[arg-type]


@pytest.mark.real_data
@pytest.mark.skipif(not os.environ.get("EVIDS_SVANSTROM"), reason="EVIDS_SVANSTROM does not point to the real data")
def test_real_release_counts_and_one_clip_per_sensor():
    bench = svanstrom.open_benchmark()
    assert len(bench.clips("ir")) == 365 and len(bench.clips("visible")) == 285 and len(bench.clips("audio")) == 90
    clip = bench.clips("ir", "calibration", classes=["DRONE"])[0]
    labels = bench.aligned_labels(clip)
    assert any(b is not None for b in labels)
    frame = next(bench.frames(clip, [0]))[1]
    assert frame.shape == (256, 320)
    samples, rate = bench.audio(bench.clips("audio", "calibration")[0])
    assert rate == 44_100 and 9.5 < samples.size / rate < 10.5
