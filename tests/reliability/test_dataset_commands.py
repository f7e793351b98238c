"""The dataset commands (export, verify, degrade, generate, fixture, render) as a careless user or a
hostile file would drive them. Every row is one of the reproduced failures of issue 15: each must
be refused with exit status 2 and a one-line reason, leaving every byte of the input (and of any
user folder) as it was."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from harness.cli import main
from simulator import files
from simulator.dataset.driver import MANIFEST, write_manifest
from simulator.dataset.generate import verify_dataset
from simulator.files import MARKER_FILE, write_hashes
from tests.reliability.helpers import tree_digest


def run(capsys, *args) -> tuple[int, str]:
    try:
        main([str(a) for a in args])
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    err = capsys.readouterr().err
    return code, err


def _user(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "keep.txt").write_text("precious")
    return folder


EXPORT_REFUSED = [
    ("--out DATASET", lambda ds, t: ds, "contains the input"),
    ("--out DATASET/sequences", lambda ds, t: ds / "sequences", "is the input"),
    ("--out inside a sequence", lambda ds, t: ds / "sequences" / "seq000001" / "mot", "inside the input"),
    ("--out a user folder", lambda ds, t: _user(t / "mine"), "not written by evids"),
    ("--out .", lambda ds, t: Path("."), "current folder"),
]


@pytest.mark.parametrize("case,out,reason", EXPORT_REFUSED, ids=[r[0] for r in EXPORT_REFUSED])
@pytest.mark.parametrize("overwrite", [False, True], ids=["plain", "--overwrite"])
def test_export_never_destroys(dataset, tmp_path, monkeypatch, capsys, case, out, reason, overwrite):
    (tmp_path / "cwd").mkdir()
    _user(tmp_path / "cwd")
    monkeypatch.chdir(tmp_path / "cwd")
    target = out(dataset, tmp_path)
    before = tree_digest(tmp_path)
    code, err = run(capsys, "export", dataset, "--format", "mot", "--out", target, "--quiet",
                    *(["--overwrite"] if overwrite else []))
    assert code == 2 and reason in err and "Traceback" not in err
    assert tree_digest(tmp_path) == before


def test_export_replaces_its_own_output_only_with_overwrite_and_cleans_dead_temps(dataset, tmp_path, capsys):
    out = tmp_path / "mot"
    assert run(capsys, "export", dataset, "--format", "mot", "--out", out, "--quiet")[0] == 0
    assert (out / MARKER_FILE).is_file()
    code, err = run(capsys, "export", dataset, "--format", "mot", "--out", out, "--quiet")
    assert code == 2 and "--overwrite" in err
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".tmp-mot-r{dead.pid}-{files._host_tag()}-abcdef"
    stale.mkdir()
    assert run(capsys, "export", dataset, "--format", "mot", "--out", out, "--quiet", "--overwrite")[0] == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds", "mot"]


@pytest.mark.parametrize("field,value", [("split", "/abs/dir"), ("split", "../x"), ("name", "../../x"),
                                         ("name", "/abs/victim")])
def test_a_tampered_manifest_cannot_point_outside(dataset, tmp_path, capsys, field, value):
    value = value.replace("/abs", str(tmp_path / "abs"))
    _user(tmp_path / "abs" / "dir" / "0001")
    _user(tmp_path / "abs" / "victim")
    manifest = json.loads((dataset / MANIFEST).read_text())
    manifest["sequences"][0][field] = value
    write_manifest(dataset, manifest)
    before = tree_digest(tmp_path / "abs")
    code, err = run(capsys, "export", dataset, "--format", "mot", "--out", tmp_path / "exp", "--quiet")
    assert code == 2 and field in err
    assert tree_digest(tmp_path / "abs") == before and not (tmp_path / "exp").exists()


def _swap(a: Path, b: Path) -> None:
    tmp = a.with_name("swap")
    a.rename(tmp)
    b.rename(a)
    tmp.rename(b)


def test_verify_catches_null_hashes_with_swapped_sequences(dataset):
    manifest = json.loads((dataset / MANIFEST).read_text())
    for s in manifest["sequences"]:
        s["content_sha256"] = None
    write_manifest(dataset, manifest)
    _swap(dataset / "sequences" / "seq000001", dataset / "sequences" / "seq000002")
    report = verify_dataset(dataset)
    assert not report.ok and set(report.corrupt) == {"seq000001", "seq000002"}


def test_verify_catches_null_hashes_alone(dataset):
    manifest = json.loads((dataset / MANIFEST).read_text())
    manifest["sequences"][1]["content_sha256"] = None
    write_manifest(dataset, manifest)
    report = verify_dataset(dataset)
    assert not report.ok and list(report.corrupt) == ["seq000002"]


def test_verify_catches_a_dropped_manifest_entry(dataset):
    manifest = json.loads((dataset / MANIFEST).read_text())
    manifest["sequences"] = manifest["sequences"][:1]
    write_manifest(dataset, manifest)
    report = verify_dataset(dataset)
    assert not report.ok and "seq000002" in report.corrupt


def test_verify_never_certifies_a_sequence_missing_planned_frames(dataset):
    """The race of issue 15: frames deleted, files.sha256 and the manifest hash rewritten to match."""
    from simulator.dataset.generate import sequence_hash

    seq = dataset / "sequences" / "seq000001"
    for d in ("rgb", "thermal", "thermal_agc", "masks/rgb", "masks/thermal"):
        (seq / d / "000002.png").unlink()
    write_hashes(seq)
    manifest = json.loads((dataset / MANIFEST).read_text())
    manifest["sequences"][0]["content_sha256"] = sequence_hash(seq)
    write_manifest(dataset, manifest)
    report = verify_dataset(dataset)
    assert not report.ok and any("rgb/000002.png" in f for f in report.corrupt["seq000001"])


def test_verify_a_manifest_without_sequences_is_a_friendly_error(dataset, capsys):
    manifest = json.loads((dataset / MANIFEST).read_text())
    del manifest["sequences"]
    write_manifest(dataset, manifest)
    code, err = run(capsys, "verify", dataset)
    assert code == 2 and "sequences" in err and "Traceback" not in err


SPEC = {"version": 1, "degradations": [{"name": "thermal.netd_noise", "severity": 1}]}


def _spec(tmp_path: Path, spec=SPEC) -> Path:
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def test_degrade_refuses_a_link_inside_a_sequence(dataset, tmp_path, capsys):
    secret = tmp_path / "secret.bin"
    secret.write_bytes(b"\x89PNG not yours")
    seq = dataset / "sequences" / "seq000001"
    (seq / "extra.png").symlink_to(secret)
    code, err = run(capsys, "degrade", seq, "--spec", _spec(tmp_path), "--out", tmp_path / "deg")
    assert code == 2 and "symbolic link" in err
    assert not any(p.is_file() and p.read_bytes() == secret.read_bytes() for p in (tmp_path / "deg").rglob("*")) \
        if (tmp_path / "deg").exists() else True
    assert not (tmp_path / "deg" / "seq000001").exists()


@pytest.mark.parametrize("out", ["dataset", "sequences", "sequence", "user"])
def test_degrade_never_writes_over_its_input_or_user_files(dataset, tmp_path, capsys, out):
    target = {"dataset": dataset, "sequences": dataset / "sequences",
              "sequence": dataset / "sequences" / "seq000001", "user": tmp_path / "user"}[out]
    if out == "user":
        _user(target / "seq000001")
    spec = _spec(tmp_path)
    before = tree_digest(tmp_path)
    code, err = run(capsys, "degrade", dataset / "sequences", "--spec", spec, "--out", target, "--overwrite")
    assert code == 2 and "Traceback" not in err
    assert tree_digest(tmp_path) == before


def test_degrade_output_is_marked_complete_and_replaced_only_with_overwrite(dataset, tmp_path, capsys):
    spec = _spec(tmp_path)
    assert run(capsys, "degrade", dataset / "sequences", "--spec", spec, "--out", tmp_path / "deg")[0] == 0
    for name in ("seq000001", "seq000002"):
        out = tmp_path / "deg" / name
        assert json.loads((out / MARKER_FILE).read_text())["kind"] == "degrade"
        assert files.verify_hashes(out) == []
        assert json.loads((out / "degradation_record.json").read_text())["streamed"] is True
    code, err = run(capsys, "degrade", dataset / "sequences", "--spec", spec, "--out", tmp_path / "deg")
    assert code == 2 and "--overwrite" in err
    first = tree_digest(tmp_path / "deg")
    assert run(capsys, "degrade", dataset / "sequences", "--spec", spec, "--out", tmp_path / "deg",
               "--overwrite")[0] == 0
    assert tree_digest(tmp_path / "deg") == first  # same seed: byte-identical
    assert sorted(p.name for p in (tmp_path / "deg").iterdir()) == ["seq000001", "seq000002"]


def test_degrade_with_an_infinite_parameter_exits_2_and_writes_nothing(dataset, tmp_path, capsys):
    spec = tmp_path / "inf.yaml"
    spec.write_text("version: 1\ndegradations:\n  - {name: video.gaussian_noise, params: {sigma: .inf}}\n")
    code, err = run(capsys, "degrade", dataset / "sequences", "--spec", spec, "--out", tmp_path / "deg")
    assert code == 2 and "sigma" in err and "Traceback" not in err
    assert not (tmp_path / "deg").exists()


def test_generate_and_fixture_refuse_a_user_folder(tmp_path, capsys):
    user = _user(tmp_path / "mine")
    before = tree_digest(user)
    code, err = run(capsys, "generate", "clear_day_quad", "--out", user, "--sequences", "1", "--frames", "1",
                    "--overwrite", "--quiet")
    assert code == 2 and "holds no evids dataset" in err
    code, err = run(capsys, "fixture", "native", "--out", user, "--overwrite")
    assert code == 2 and "not written by evids" in err
    assert tree_digest(user) == before


@pytest.mark.parametrize("name", ["/abs/victim", ".", "../../x"])
def test_render_refuses_a_scene_name_that_is_a_path(tmp_path, capsys, name):
    from scenes.loader import LIBRARY_DIR

    data = yaml.safe_load((LIBRARY_DIR / "clear_day_quad.yaml").read_text())
    data["name"] = name.replace("/abs", str(tmp_path / "abs"))
    _user(tmp_path / "abs" / "victim")
    scene = tmp_path / "scene.yaml"
    scene.write_text(yaml.safe_dump(data))
    before = tree_digest(tmp_path / "abs")
    code, err = run(capsys, "render", scene, "--out", tmp_path / "out", "--quiet")
    assert code == 2 and "name" in err
    assert tree_digest(tmp_path / "abs") == before and not (tmp_path / "out").exists()


def test_trident_inline_scenario_name_cannot_escape_out(tmp_path, capsys):
    from scenes.loader import LIBRARY_DIR

    scene = yaml.safe_load((LIBRARY_DIR / "clear_day_quad.yaml").read_text())
    scene["name"] = "../../escaped"
    config = tmp_path / "t.yaml"
    config.write_text(yaml.safe_dump({"name": "t", "clip_duration_s": 0.25, "save_iq": False,
                                      "clips": [{"scenario": scene}]}))
    code, err = run(capsys, "generate", config, "--format", "trident", "--out", tmp_path / "a" / "b" / "out", "--quiet")
    assert code == 2 and "name" in err
    assert not (tmp_path / "escaped").exists() and not (tmp_path / "a").exists()


def test_a_killed_runs_lock_is_reported_and_the_resume_completes(dataset, tmp_path, capsys):
    from tests.reliability.conftest import TINY2

    (dataset / files.LOCK_FILE).write_text(json.dumps({"pid": 999999, "host": "elsewhere", "run_id": "x"}))
    config = tmp_path / "tiny2.yaml"
    config.write_text(yaml.safe_dump(TINY2))
    code, err = run(capsys, "generate", config, "--out", dataset, "--seed", "3", "--quiet")
    assert code == 0 and "stale lock" in err and "999999" in err
    assert not (dataset / files.LOCK_FILE).exists()
    assert verify_dataset(dataset).ok


def test_markers_do_not_change_sequence_hashes(tiny_dataset):
    assert verify_dataset(tiny_dataset).ok
    assert os.path.exists(tiny_dataset / "sequences" / "seq000001" / MARKER_FILE)


def test_trident_resumes_after_a_killed_run_whose_lock_is_stale(tmp_path):
    """A TRIDENT dataset goes through the one dataset driver: a dead writer's lock is cleared, the
    clip it had recorded is kept, the rest is written, and the result equals an uninterrupted run."""
    import numpy as np

    from simulator.dataset.trident import generate_trident

    def frames(scenario, seed, n, w, h, layout=None):
        return np.zeros((n, h, w, 3), np.uint8)

    config = {"name": "t", "clip_duration_s": 0.25, "save_iq": False,
              "clips": [{"scenario": "clear_day_quad", "count": 2}]}
    ref = generate_trident(config, tmp_path / "ref", 0, progress=False, render_frames=frames)
    tri = tmp_path / "tri"
    shutil.copytree(ref, tri)
    manifest = json.loads((tri / "manifest.json").read_text())
    manifest.update(complete=False, content_sha256=None)
    manifest["clips"][1]["content_sha256"] = None            # the killed run had recorded clip 1 only
    (tri / "manifest.json").write_text(json.dumps(manifest))
    for path in (tri / "rf").rglob("2_rf_*.png"):
        path.write_bytes(b"half-written")
    (tri / files.LOCK_FILE).write_text(json.dumps({"pid": 999999, "host": "elsewhere", "run_id": "x"}))
    generate_trident(config, tri, 0, progress=False, render_frames=frames)
    assert not (tri / files.LOCK_FILE).exists()
    assert verify_dataset(tri).ok
    names = sorted(p.relative_to(ref) for p in ref.rglob("*") if p.is_file())
    assert names == sorted(p.relative_to(tri) for p in tri.rglob("*") if p.is_file())
    assert [n for n in names if (ref / n).read_bytes() != (tri / n).read_bytes()] == []


def test_trident_generate_and_verify_from_the_command_line(tmp_path, capsys):
    config = tmp_path / "t.yaml"
    config.write_text(yaml.safe_dump({"name": "t", "clip_duration_s": 0.25, "save_iq": False,
                                      "clips": [{"scenario": "clear_day_quad"}]}))
    out = tmp_path / "tri"
    code, err = run(capsys, "generate", config, "--format", "trident", "--out", out, "--sequences", "3", "--quiet")
    assert code == 2 and "--sequences" in err and not out.exists()
    code, err = run(capsys, "generate", config, "--format", "trident", "--out", out, "--quiet", "--workers", "2")
    assert code == 0, err
    code, _ = run(capsys, "verify", out)
    assert code == 0
    wav = next((out / "audio").rglob("1.wav"))
    wav.write_bytes(wav.read_bytes()[:-2])
    try:
        main(["verify", str(out)])
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    assert code == 1 and "corrupt: clip000001 (content differs from manifest.json)" in capsys.readouterr().out
    code, err = run(capsys, "generate", config, "--format", "trident", "--out", out, "--quiet")  # repairs it
    assert code == 0 and verify_dataset(out).ok
