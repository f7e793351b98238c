"""A TRIDENT-layout folder written by the exporter (simulator.dataset.trident.generate_trident), stripped
to what the public release carries (no labels/, rf_iq/, manifest), trains and evaluates through
the same CLI path as generated data; bad input exits 2 and writes nothing."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
import yaml

from simulator.dataset.trident import generate_trident


def _evids(*args):
    env = {**os.environ, "OMP_NUM_THREADS": "1"}      # another pytest worker shares the two cores
    return subprocess.run([sys.executable, "-c", "from harness.cli import main; main()", *args],
                          capture_output=True, text=True, timeout=600, env=env)


def _frames(scenario, seed, n_frames, width_px, height_px, layout=None):
    """Cheap stand-in for the renderer: sky gradient + a dark blob for drone scenarios."""
    rng = np.random.default_rng(seed)
    img = np.zeros((n_frames, height_px, width_px, 3), np.uint8)
    img[...] = np.linspace(150, 220, height_px, dtype=np.uint8)[None, :, None, None]
    if any(t.kind != "bird" and t.kind != "airliner" for t in scenario.targets):
        y, x = rng.integers(20, height_px - 20, 2)
        img[:, y:y + 4, x:x + 6] = 40
    return img


@pytest.fixture(scope="module")
def public_style_folder(tmp_path_factory):
    root = tmp_path_factory.mktemp("trident") / "export"
    cfg = yaml.safe_load(open("scenes/generation/trident_mini.yaml"))
    cfg["clip_duration_s"] = 1.0
    cfg["clips"] = [{**c, "count": 2} for c in cfg["clips"]]
    generate_trident(cfg, root, seed=3, progress=False, render_frames=_frames)
    for extra in ("labels", "rf_iq"):
        shutil.rmtree(root / extra)
    (root / "manifest.json").unlink()
    return root


def _config(path, tmp_path):
    cfg = {"name": "folder", "dataset": {"path": str(path)}, "split": {"seed": 1},
           "models": {"train": {"epochs": 1, "patience": 1}, "fusion_epochs": 5, "width": 4, "embedding": 8},
           "protocol": {"noise_seeds": [42]}, "gate": {"tau_high": [0.5], "tau_low": [0.2], "n": [1]},
           "bootstrap": {"n_resamples": 100}}
    p = tmp_path / "exp.yaml"
    p.write_text(yaml.safe_dump(cfg))
    return p


def test_exported_folder_trains_and_evaluates_through_the_cli(public_style_folder, tmp_path):
    run = tmp_path / "run"
    r = _evids("train", "--config", str(_config(public_style_folder, tmp_path)), "--out", str(run), "--no-progress")
    assert r.returncode == 0, r.stderr[-3000:]
    train = json.loads((run / "train.json").read_text())
    assert train["generated"] is False and train["dataset_root"] == str(public_style_folder)
    assert sum(train["segments"].values()) == 10 * 4
    assert not (run / "data").exists()                          # a given folder is read in place, not copied
    r = _evids("evaluate", str(run), "--no-progress")
    assert r.returncode == 0, r.stderr[-3000:]
    ev = json.loads((run / "evaluate.json").read_text())
    keys = {c["key"] for c in ev["conditions"]}
    assert {"b", "c", "d", "e", "f", "g"} <= keys and "i" not in keys      # no I/Q: (i) skipped with a reason
    assert any(s["condition"] == "i" and "rf_iq" in s["reason"] for s in ev["skipped"])
    r = _evids("sweep", str(run), "--only", "gate", "--no-progress")
    assert r.returncode == 0, r.stderr[-3000:]
    r = _evids("report", str(run))
    assert r.returncode == 0 and (run / "report.html").is_file()


def test_bad_input_exits_2_and_writes_nothing(tmp_path):
    run = tmp_path / "run"
    r = _evids("train", "--config", str(_config(tmp_path / "missing", tmp_path)), "--out", str(run))
    assert r.returncode == 2 and "dataset.path" in r.stderr and "Traceback" not in r.stderr
    assert not run.exists()
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"dataset": {"generate": "trident_mini"}, "models": {"width": 1}}))
    r = _evids("train", "--config", str(bad), "--out", str(run))
    assert r.returncode == 2 and "models.width" in r.stderr and not run.exists()
    r = _evids("evaluate", str(tmp_path))
    assert r.returncode == 2 and "not a run folder" in r.stderr
    r = _evids("sweep", str(tmp_path), "--only", "bogus")
    assert r.returncode == 2 and "bogus" in r.stderr
