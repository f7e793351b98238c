"""`evids detect`: bad input gets one message naming the field, exit status 2 and nothing written;
a tiny end-to-end run (generate, train a few steps, evaluate, report) works and is seeded."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from harness.cli import main
from harness.experiments.detection.config import TINY_CONFIG


def _run(argv: list[str]) -> int:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    return int(exc.value.code or 0)


def _fake_dataset(root: Path, thermal: bool, splits: tuple[str, ...]) -> Path:
    seqs = []
    for i, split in enumerate(splits):
        name = f"seq{i + 1:06d}"
        d = root / "sequences" / name
        d.mkdir(parents=True)
        cams = {"rgb": {"width_px": 32, "height_px": 32}}
        if thermal:
            cams["thermal"] = {"width_px": 32, "height_px": 32, "netd_k": 0.05, "kelvin_per_count": 0.01}
            (d / "thermal").mkdir()
        (d / "meta.json").write_text(json.dumps({"cameras": cams, "n_frames": 2}))
        seqs.append({"name": name, "index": i, "split": split, "source": "det_control_a", "seed": 1, "n_frames": 2,
                     "content_sha256": "0"})
    (root / "manifest.json").write_text(json.dumps({"format": "evids-native-dataset", "complete": True,
                                                    "sequences": seqs}))
    return root


def _config(tmp_path: Path, train: Path, test: Path, **extra) -> Path:
    import yaml

    cfg = {"data": {"train": {"path": str(train)}, "test": {"crossover": {"path": str(test)}}}, **extra}
    p = tmp_path / f"cfg_{train.name}_{len(list(tmp_path.glob('cfg_*')))}.yaml"
    p.write_text(yaml.safe_dump(cfg))
    return p


def test_bad_inputs_exit_2_and_write_nothing(tmp_path, capsys):
    good_train = _fake_dataset(tmp_path / "train", True, ("train", "val"))
    good_test = _fake_dataset(tmp_path / "test", True, ("test",))
    cases = {
        "thermal": _config(tmp_path, _fake_dataset(tmp_path / "nothermal", False, ("train", "val")), good_test),
        "'val' split": _config(tmp_path, _fake_dataset(tmp_path / "nosplit", True, ("train", "train")), good_test),
        "conditions": _config(tmp_path, good_train, good_test, conditions=["e_ds", "z_magic"]),
    }
    for needle, cfg in cases.items():
        out = tmp_path / f"run_{abs(hash(needle))}"
        assert _run(["detect", "train", "--config", str(cfg), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert needle in err and err.count("\n") == 1, err
        assert not out.exists()
    assert _run(["detect", "evaluate", str(tmp_path / "missing")]) == 2
    assert "detect train" in capsys.readouterr().err
    cfg = _config(tmp_path, good_train, good_test, crossover_set="nope")
    assert _run(["detect", "train", "--config", str(cfg), "--out", str(tmp_path / "r")]) == 2
    assert "crossover_set" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["detect", "train", "--config", "tiny"], ["detect", "run", "--config", "tiny"],
                                  ["demo", "--detection"]], ids=["detect train", "detect run", "demo --detection"])
def test_detection_commands_keep_the_safe_output_rule(tmp_path, capsys, monkeypatch, argv):
    """`evids detect` and `evids demo --detection` create their run folder through the same checked
    path as every other command: a user's folder, the current folder or the input is refused with
    exit status 2 before any work, and not one byte of it changes."""
    user = tmp_path / "mine"
    user.mkdir()
    (user / "keep.txt").write_text("precious")
    assert _run([*argv, "--out", str(user)]) == 2
    assert "not written by evids" in capsys.readouterr().err
    assert sorted(p.name for p in user.iterdir()) == ["keep.txt"] and (user / "keep.txt").read_text() == "precious"
    monkeypatch.chdir(user)
    assert _run([*argv, "--out", "."]) == 2
    assert "current folder" in capsys.readouterr().err
    assert sorted(p.name for p in user.iterdir()) == ["keep.txt"]


def test_detect_train_refuses_an_out_inside_its_input_dataset(tmp_path, capsys):
    train = _fake_dataset(tmp_path / "train", True, ("train", "val"))
    cfg = _config(tmp_path, train, _fake_dataset(tmp_path / "test", True, ("test",)))
    assert _run(["detect", "train", "--config", str(cfg), "--out", str(train / "run")]) == 2
    assert "inside the input" in capsys.readouterr().err
    assert not (train / "run").exists()


def test_unknown_named_config_is_refused(tmp_path, capsys):
    assert _run(["detect", "train", "--config", "enormous", "--out", str(tmp_path / "r")]) == 2
    assert "full, demo, tiny" in capsys.readouterr().err


def test_tiny_end_to_end(tmp_path):
    """Generate 4 + 2 sequences of 4 frames, train every detector 3 steps, evaluate all eight
    conditions through COCOeval / TrackEval / the Anti-UAV labels, and write the report."""
    out = tmp_path / "run"
    assert _run(["detect", "run", "--config", "tiny", "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert set(m["headline"]) == {"q1_ds_through_crossover", "q2_thermal_vacuity_vs_dT",
                                  "q3_anchor_inversion_crop_recovery", "q4_gating_saves_cpu"}
    keys = {r["key"] for r in m["table"]}
    assert {"a_sigmoid/rgb", "a_sigmoid/thermal", "e_ds/fused", "f_ds_gated/fused", "h_feature_fusion_ts/fused"} <= keys
    fitted = json.loads((out / "fitted.json").read_text())
    assert all(v["fitted_on"] == "val" for v in fitted["tracking"].values())
    assert fitted["temperature"] > 0
    for f in ("exports/coco/crossover_rgb.json", "exports/mot/gt/seqmaps/RGB-crossover.txt", "detection.html",
              "example_crossover.npz", "tables/per_sequence.csv"):
        assert (out / f).is_file(), f
    assert "Headline questions" in (out / "detection.html").read_text()
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["train"]["steps"] == TINY_CONFIG["train"]["steps"] and cfg["train"]["seed"] == 0
    # the same seed gives the same degraded inputs
    from harness.experiments.detection.config import load_detection_config
    from harness.experiments.detection.runner import load_split

    data = json.loads((out / "data.json").read_text())
    c = load_detection_config(cfg)
    a, b = load_split(data, c, "val")[0], load_split(data, c, "val")[0]
    assert np.array_equal(a.rgb, b.rgb) and np.array_equal(a.thermal_k, b.thermal_k)
