"""Scene-disjoint splits, the shortcut audit (flags a confounded fixture, passes a balanced one)
and the bad-input paths of both (one message naming the field, exit 2, nothing written)."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from harness.experiments.audit import audit_clips, dataset_split
from harness.experiments.config import AuditConfig, SplitConfig
from harness.experiments.data import check_scene_disjoint, split_clips
from scenes.errors import UserInputError
from tests.harness.experiments.fixtures import make_clips


def test_split_keeps_every_scene_in_one_split_and_is_seeded():
    clips = make_clips(12, seed=1)
    s1 = split_clips(clips, SplitConfig(source="fractions", seed=3, val_fraction=0.25, test_fraction=0.25))
    assert s1 == split_clips(clips, SplitConfig(source="fractions", seed=3, val_fraction=0.25, test_fraction=0.25))
    scene_of = {s: {clips[i].scene for i in idx} for s, idx in s1.items()}
    assert not (scene_of["train"] & scene_of["test"]) and not (scene_of["train"] & scene_of["val"])
    assert not (scene_of["val"] & scene_of["test"])
    assert sorted(sum(s1.values(), [])) == list(range(len(clips)))
    for idx in s1.values():                      # twins: both labels in every split
        assert {clips[i].label for i in idx} == {0, 1}


def test_dataset_split_is_used_and_a_leak_is_refused():
    clips = make_clips(6, seed=2, splits=(3, 1, 2))
    s = split_clips(clips, SplitConfig(source="dataset"))
    assert [clips[i].scene for i in s["test"]] == ["scene_004"] * 2 + ["scene_005"] * 2
    clips[0].split = "test"                      # one twin of scene_000 moved: the scene leaks
    with pytest.raises(UserInputError, match="scene 'scene_000' appears in both"):
        check_scene_disjoint(clips, {"train": [1], "test": [0]})
    with pytest.raises(UserInputError, match="scene-disjoint"):
        split_clips(clips, SplitConfig(source="dataset"))


def test_too_few_scenes_for_disjoint_splits_names_the_field():
    with pytest.raises(UserInputError, match=r"split\.unit: 'scene' splits need >= 3 scene groups.*has 2"):
        split_clips(make_clips(2), SplitConfig(source="fractions"))


def test_audit_passes_a_balanced_twin_fixture():
    clips = make_clips(40, seed=4, splits=(24, 0, 16))
    res = audit_clips(clips, dataset_split(clips), AuditConfig(seed=0, n_resamples=300, min_segments=4))
    video = [r for r in res["baselines"] if r["feature"].startswith("video")]
    assert video and all(r["score"] is not None for r in video)
    assert not res["shortcut"], [(r["feature"], r["model"], r["score"], r["ci_low"]) for r in res["baselines"]]
    for r in video:                  # same scenes in both classes: exactly at chance for the median colour
        assert r["ci_low"] <= 0.5 <= r["ci_high"]


def test_audit_flags_a_confounded_fixture():
    clips = make_clips(60, seed=5, confounded=True, twins=False, splits=(36, 0, 24))
    res = audit_clips(clips, dataset_split(clips), AuditConfig(seed=0, n_resamples=300, min_segments=4))
    colour = [r for r in res["baselines"] if r["feature"] == "video_median_colour"]
    assert res["shortcut"] and all(r["beats_chance"] for r in colour), colour
    assert all(r["score"] > 0.65 for r in colour)


def test_audit_without_splits_names_the_field():
    with pytest.raises(UserInputError, match=r"split: 4 of 4 clips carry no train/val/test split"):
        dataset_split(make_clips(2))


def test_audit_cli_on_a_folder_without_splits_exits_2_and_writes_nothing(tmp_path):
    out = tmp_path / "audit.json"
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    r = subprocess.run([sys.executable, "-c", "from harness.cli import main; main()", "audit", str(tmp_path / "nope"),
                        "--json", str(out)], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 2 and "DATASET" in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()
