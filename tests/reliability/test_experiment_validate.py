"""Experiment configs (evids train/evaluate/sweep): every referenced degradation, noise parameter,
seed and gate value is checked before any data is generated or any model trained."""
from __future__ import annotations

import copy
import time
from pathlib import Path

import pytest
import yaml

from harness.experiments.config import QUICK_CONFIG, load_experiment_config
from scenes.errors import UserInputError
from tests.reliability.helpers import evids

ROOT = Path(__file__).resolve().parents[2]


def _with(path: str, value):
    cfg = copy.deepcopy(QUICK_CONFIG)
    d = cfg
    keys = path.split(".")
    for k in keys[:-1]:
        d = d.setdefault(k, {})
    d[keys[-1]] = value
    return cfg


REFUSED = [
    ("unknown noise parameter", _with("protocol.audio", [{"name": "audio.white_noise", "params": {"snrdb": 5}}]),
     "protocol.audio[0]"),
    ("noise parameter out of domain",
     _with("protocol.video", [{"name": "video.gaussian_noise", "params": {"sigma": -1}}]),
     "sigma"),
    ("audio degradation listed under video", _with("protocol.video", [{"name": "audio.white_noise"}]),
     "acts on 'audio'"),
    ("negative noise seed", _with("protocol.noise_seeds", [-1]), "protocol.noise_seeds[0]"),
    ("seed beyond 32 bits", _with("protocol.noise_seeds", [2 ** 40]), "protocol.noise_seeds[0]"),
    ("unknown sweep degradation", _with("sweep.video", "video.nope"), "sweep.video"),
    ("sweep rf degradation of another modality", _with("sweep.rf", "video.fog"), "sweep.rf"),
    ("gate n zero and negative", _with("gate.n", [0, -1]), "gate.n[0]"),
    ("gate threshold above 1", _with("gate.tau_high", [1.5]), "gate.tau_high[0]"),
    ("empty gate grid", _with("gate.tau_low", []), "gate.tau_low"),
    ("sweep seeds beyond the noise seeds", _with("sweep.n_seeds", 9), "sweep.n_seeds"),
    ("dataset folder missing", {**copy.deepcopy(QUICK_CONFIG), "dataset": {"path": "/nonexistent/evids"}},
     "dataset.path"),
]


@pytest.mark.parametrize("case,cfg,field", REFUSED, ids=[r[0] for r in REFUSED])
def test_refused_before_any_work(case, cfg, field):
    with pytest.raises(UserInputError) as info:
        load_experiment_config(cfg)
    assert field in str(info.value)


def test_the_shipped_configs_are_valid():
    load_experiment_config(QUICK_CONFIG)
    load_experiment_config(ROOT / "examples" / "experiment.yaml")


def test_train_refuses_in_seconds_and_writes_nothing(tmp_path):
    config = tmp_path / "bad.yaml"
    config.write_text(yaml.safe_dump(_with("protocol.noise_seeds", [-1])))
    t0 = time.perf_counter()
    r = evids("train", "--config", config, "--out", tmp_path / "run", cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert "protocol.noise_seeds[0]" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "run").exists()
    assert time.perf_counter() - t0 < 60
