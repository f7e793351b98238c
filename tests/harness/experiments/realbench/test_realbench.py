"""`evids realbench --quick` end to end on a miniature of the Svanström layout beside a hand-written
miniature `evids sim2real` run folder (no rendering, no real data), plus known-answer tests of the
sweep-agreement statistics, the degradation wrapper and the evidential crop model."""
from __future__ import annotations

import html
import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from harness.experiments.realbench import models as M
from harness.experiments.realbench import stats
from harness.experiments.realbench.sweep import SPECS, centre_mask, degrade_audio, degrade_crops

pytest.importorskip("mcos_decoder")
pytest.importorskip("av")

CLASSES = ("AIRPLANE", "BIRD", "DRONE", "HELICOPTER")


def _write_sequence(seq: Path, rng: np.random.Generator, cls: str, n: int) -> None:
    """A native sequence as `evids sim2real` reads it: labels.json, thermal_agc/ and rgb/ frames."""
    from tests.simulator.formats.svanstrom_miniature import _clip_frames

    ir, ir_boxes = _clip_frames(rng, n, 64, 48, False, cls)
    vis, vis_boxes = _clip_frames(rng, n, 96, 80, True, cls)
    for folder, frames in (("thermal_agc", ir), ("rgb", vis)):
        (seq / folder).mkdir(parents=True)
        for i, im in enumerate(frames):
            cv2.imwrite(str(seq / folder / f"{i + 1:06d}.png"), im if im.ndim == 2 else im[..., ::-1])
    frames_json = [{"thermal": [{"id": 1, "box": list(b) if b else [0, 0, 0, 0], "exist": b is not None}],
                    "rgb": [{"id": 1, "box": list(v) if v else [0, 0, 0, 0], "exist": v is not None}]}
                   for b, v in zip(ir_boxes, vis_boxes)]
    (seq / "labels.json").write_text(json.dumps({"objects": [{"id": 1}], "frames": frames_json}))


def write_sim2real_run(root: Path, n_sequences: int = 4, n_frames: int = 5) -> Path:
    """A finished-looking `evids sim2real` folder: sim2real.json (the shipped protocol, shrunk) and
    ``n_sequences`` synthetic sequences per set of each class (the shared one and each sensor's own)."""
    from harness.experiments.sim2real.config import load_config, synthetic_set_folder

    cfg, _ = load_config()
    data = cfg.model_dump(mode="json")
    data["sensors"] = ["ir", "visible"]
    data["visual"].update(frames_per_real_clip=3, workers=1, detector_frames_per_clip=0)
    data["training"]["seeds"] = [0, 1]
    rng = np.random.default_rng(5)
    for cls, spec in cfg.visual.classes.items():
        for own in (None, *spec.sensor_generation):
            for j in range(n_sequences):
                _write_sequence(root / "synthetic" / synthetic_set_folder(cls, own) / "sequences" / f"seq{j + 1:06d}",
                                rng, cls, n_frames)
    (root / "sim2real.json").write_text(json.dumps({"config": data}))
    return root


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", "from harness.cli import main; main()", *args], capture_output=True,
                          text=True, timeout=600)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    from tests.simulator.formats.svanstrom_miniature import write_miniature

    root = tmp_path_factory.mktemp("rb")
    real = write_miniature(root / "real", numbers=(1, 2, 3, 4), n_frames=5, ir_size=(64, 48), visible_size=(96, 80))
    s2r = write_sim2real_run(root / "s2r")
    out = root / "run"
    return out, _cli("realbench", "--real", str(real), "--sim2real", str(s2r), "--out", str(out), "--quick",
                     "--no-audio", "--no-progress", "--triplets", "30")


def test_quick_run_writes_scores_sweep_and_page(quick_run):
    out, proc = quick_run
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((out / "realbench.json").read_text())
    assert set(summary["sensors"]) == {"ir", "visible"}
    for sensor, res in summary["sensors"].items():
        assert res["n_eval"]["real"]["clips"] == len(CLASSES) * 2          # even numbers 2 and 4
        assert res["n_eval"]["synthetic"]["clips"] == len(CLASSES) * 2     # seq000002, seq000004
        models = res["scores"]["models"]
        assert set(models) == {f"{c}/{h}" for c in ("a_real", "b_synthetic", "c_both") for h in M.HEADS}
        for key, m in models.items():
            assert 0.0 <= m["balanced_accuracy"]["estimate"] <= 1.0
            assert 0.0 <= m["ece"]["estimate"] <= 1.0
            if key.endswith("softmax"):
                assert m["uauc_vacuity"]["estimate"] is None       # no vacuity: NaN, written as null
        ref = res["sweep"]["clean_balanced_accuracy"]
        assert 0.0 <= ref["synthetic"]["b_synthetic"]["evidential"]["estimate"] <= 1.0
        sweep = res["sweep"]["own_domain"]["evidential"]
        assert sweep["n_cells"] == len(SPECS[sensor])                   # one severity in --quick
        assert len(sweep["cells"]) == sweep["n_cells"]
        assert set(sweep["disagreeing_cells"]) <= {c["label"] for c in sweep["cells"]}
        # the toy models (15 steps) sit at chance: the flag must say so, and the page and printout too
        expect = [d for d in ("real", "synthetic")
                  if ref[d]["a_real" if d == "real" else "b_synthetic"]["evidential"]["ci_low"] <= 1 / len(CLASSES)]
        assert sweep["at_chance"] == expect
        if expect:
            assert "NOT INFORMATIVE" in proc.stdout and "Not informative" in (out / "realbench.html").read_text()
    page = (out / "realbench.html").read_text()
    assert "Real benchmark" in page and "data:image/png;base64" in page and "Disagreeing cells" in page
    assert "Clean balanced accuracy" in page
    assert (out / "realbench_agreement.png").stat().st_size > 1000
    assert "sweep agreement (own_domain" in proc.stdout


def test_quick_run_writes_the_conflict_study_on_both_domains(quick_run):
    from harness.experiments.realbench.conflict import NOT_SYNCHRONISED, RULES

    out, proc = quick_run
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((out / "realbench.json").read_text())
    assert all("clip_opinions" not in r for r in summary["sensors"].values())     # in memory only
    res = summary["conflict"]
    assert res["programs"] == ["blind_ir", "blind_visible"]                      # --no-audio: pairs
    assert res["c_max"] == 0.95                                                 # the experiment default
    for reading in ("own_domain", "mixed"):
        for domain in ("real", "synthetic"):
            d = res["readings"][reading][domain]
            assert d["n_triplets"] == 30                                        # --triplets 30
            assert set(d["classes"]) == set(summary["sensors"]["ir"]["classes"]) and d["classes"]["DRONE"] == 15
            assert set(d["programs"]) == set(res["programs"])
            for p in d["programs"].values():
                assert 0.0 <= p["sensor_flip_rate"]["estimate"] <= 1.0 and isinstance(p["inert"], bool)
                flip = p["sensor_flip_rate"]
                assert p["inert"] == (flip["estimate"] < 0.1 or not flip["ci_low"] > 0)
                assert set(p["rules"]) == set(RULES)
                for v in p["rules"].values():
                    assert 0.0 <= v["fused_flip_rate"]["estimate"] <= 1.0 and 0.0 <= v["accuracy"]["estimate"] <= 1.0
        assert set(res["readings"][reading]["real_minus_synthetic_fused_flip_rate"]) == set(res["programs"])
    page = (out / "realbench.html").read_text()
    assert "Conflict programs on pseudo-triplets" in page and html.escape(NOT_SYNCHRONISED) in page
    assert "conflict programs on pseudo-triplets" in proc.stdout and "blind_visible" in proc.stdout


def test_at_chance_names_the_domains_whose_clean_interval_reaches_chance():
    from harness.experiments.realbench.harness import at_chance

    clean = {"real": {"estimate": 0.76, "ci_low": 0.70, "ci_high": 0.82},
             "synthetic": {"estimate": 0.27, "ci_low": 0.24, "ci_high": 0.31}}
    assert at_chance(clean, 0.25) == ["synthetic"]
    assert at_chance(clean, 0.20) == []
    assert at_chance(clean, 0.70) == ["real", "synthetic"]                       # reaching chance counts
    assert at_chance({"real": {"estimate": 0.9, "ci_low": float("nan"), "ci_high": float("nan")}}, 0.5) == ["real"]


def test_missing_sim2real_run_is_a_user_error(tmp_path):
    from harness.experiments.realbench.harness import run_realbench
    from scenes.errors import UserInputError

    with pytest.raises(UserInputError, match="sim2real.json"):
        run_realbench(tmp_path, tmp_path / "none", tmp_path / "o", quick=True, progress=False)


def _effects(drops: list[float], vac: list[float], n_boot: int = 50, spread: float = 0.1) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    d = np.array(drops)[None] + np.r_[np.zeros((1, len(drops))), rng.normal(0, spread, (n_boot, len(drops)))]
    v = np.array(vac)[None] + np.r_[np.zeros((1, len(vac))), rng.normal(0, spread / 100, (n_boot, len(vac)))]
    return {"drop_points": d, "vacuity_change": v}


def test_agreement_known_answers():
    cells = ["n@1", "n@5", "b@1", "b@5"]
    same = _effects([1.0, 10.0, 3.0, 30.0], [0.01, 0.1, 0.02, 0.2])
    res = stats.agreement(same, same, cells, {})
    assert res["spearman"]["estimate"] == pytest.approx(1.0)
    assert res["median_abs_drop_difference_points"]["estimate"] == 0.0
    assert res["vacuity_same_sign_fraction"]["estimate"] == 1.0
    assert res["disagreeing_cells"] == []
    other = _effects([1.0, 10.0, 3.0, -20.0], [0.01, 0.1, 0.02, -0.2])      # last cell: opposite effect
    res = stats.agreement(same, other, cells, {"b@5": "blur 5"})
    assert res["disagreeing_cells"] == ["blur 5"]
    assert res["vacuity_same_sign_fraction"]["estimate"] == 0.75
    assert res["median_abs_drop_difference_points"]["estimate"] == pytest.approx(0.0)
    assert res["spearman"]["estimate"] == pytest.approx(-0.2)     # ranks 1 3 2 4 vs 2 4 3 1: 1 - 6 * 12 / 60


def test_inert_flags_only_a_degradation_without_effect():
    e = _effects([0.0, 0.0, 5.0, 40.0], [0.0, 0.0, 0.05, 0.3], spread=1.0)
    assert stats.inert(e, ["n@1", "n@5", "b@1", "b@5"], {"noise": "n@5", "blur": "b@5"}) == ["noise"]


def test_cell_table_balanced_accuracy_and_stratified_weights():
    y = np.array([0, 0, 0, 1, 1])
    clip = np.array(["a", "a", "b", "c", "c"])
    t = stats.CellTable(y, clip, ["clean", "x"])
    t.add("evidential", "clean", np.array([1, 1, 1, 1, 1]), np.full(5, 0.2), 1)
    t.add("evidential", "x", np.array([1, 0, 0, 1, 0]), np.full(5, 0.6), 1)
    w = t.weights(np.random.default_rng(0), 20)
    assert np.all(w[1:, t.cls == 1].sum(axis=1) == 1) and np.all(w[1:, t.cls == 0].sum(axis=1) == 2)
    eff = stats.sweep_effects(t, "clean", w)["evidential"]
    # class 0: 1 of 3 correct, class 1: 1 of 2 -> balanced 0.4167; drop 58.3 points; vacuity +0.4
    assert eff["drop_points"][0, 1] == pytest.approx(100 * (1 - (1 / 3 + 1 / 2) / 2))
    assert eff["vacuity_change"][0, 1] == pytest.approx(0.4)


def test_degradations_are_paired_deterministic_and_bite():
    rng = np.random.default_rng(1)
    grey = rng.integers(60, 200, (4, 32, 32)).astype(np.uint8)
    rgb = rng.integers(60, 200, (4, 32, 32, 3)).astype(np.uint8)
    for sensor, x in (("ir", grey), ("visible", rgb)):
        for _, name in SPECS[sensor]:
            assert np.array_equal(degrade_crops(x, sensor, name, 0.0, 3), x)
            y5 = degrade_crops(x, sensor, name, 5.0, 3)
            assert y5.shape == x.shape and y5.dtype == np.uint8
            assert np.array_equal(y5, degrade_crops(x, sensor, name, 5.0, 3)), name
            assert not np.array_equal(y5, x), name
    audio = (0.1 * rng.standard_normal(8000)).astype(np.float32)
    for _, name in SPECS["audio"]:
        y = degrade_audio(audio, 8000, name, 5.0, 2)
        assert y.shape == audio.shape and not np.array_equal(y, audio), name
    assert centre_mask(32, 2.0).sum() == 16 * 16


def test_evidential_crop_model_learns_and_reports_vacuity():
    rng = np.random.default_rng(0)
    y = rng.integers(0, 3, 300)
    x = (rng.normal(0, 0.1, (300, 1, 32, 32)) + (y[:, None, None, None] - 1) * 0.3).astype(np.float32)
    for head in M.HEADS:
        net = M.train(M.crop_net(1, 3, head), x, y, M.class_balanced_weights(y, 3), head=head, n_classes=3, seed=0,
                      steps=40, batch_size=32, learning_rate=5e-3, flips=True)
        s = M.predict(net, x, head)
        assert np.allclose(s.probs.sum(1), 1.0)
        assert (s.probs.argmax(1) == y).mean() > 0.9, head
        if head == "evidential":
            assert s.vacuity is not None and np.all((s.vacuity > 0) & (s.vacuity <= 1))
        else:
            assert s.vacuity is None


def test_results_do_not_depend_on_the_order_forked_jobs_finish_in(quick_run, tmp_path, reverse_forked_map):
    """``forked_map`` yields in completion order (timing), and a worker runs its jobs one after the
    other: the synthetic samples must still reach the models in call order, and a model's initial
    weights must not come from the global RNG state the previous job left. The quick run redone
    in-process (other jobs before each, another global RNG state) with every forked map delivering
    its results in reverse order gives the same realbench.json (timings aside)."""
    import torch

    from harness.experiments.realbench.harness import run_realbench

    out, proc = quick_run
    assert proc.returncode == 0, proc.stderr[-3000:]
    threads = torch.get_num_threads()
    try:
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(12345)            # not the state a fresh process starts from
            run_realbench(out.parent / "real", out.parent / "s2r", tmp_path / "rerun", quick=True, audio=False,
                          n_triplets=30, progress=False, log=lambda _: None)
    finally:
        torch.set_num_threads(threads)
    first, second = (json.loads((d / "realbench.json").read_text()) for d in (out, tmp_path / "rerun"))
    for summary in (first, second):
        summary.pop("timings_s")

    def differ(a, b, at=""):
        if isinstance(a, dict) and isinstance(b, dict) and a.keys() == b.keys():
            return [d for k in a for d in differ(a[k], b[k], f"{at}/{k}")]
        if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
            return [d for i, (u, v) in enumerate(zip(a, b)) for d in differ(u, v, f"{at}[{i}]")]
        return [] if a == b else [f"{at}: {a!r} != {b!r}"]

    assert differ(first, second) == []
