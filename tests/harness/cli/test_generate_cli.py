"""`evids generate/export/verify/fixture` from the shell, and the pytest plugin in a fresh test file."""
import json
import os
import subprocess
import sys
from importlib.metadata import entry_points

import pytest

from tests.simulator.dataset.gen_helpers import tree_digest, write_tiny


def _evids(*args, env=None):
    return subprocess.run([sys.executable, "-c", "from harness.cli import main; main()", *args],
                          capture_output=True, text=True, timeout=600, env=env)


def test_bad_generation_config_exits_2_naming_the_field_and_writes_nothing(tmp_path):
    config = write_tiny(tmp_path, splits={"train": 0.9, "val": 0.2, "test": 0.0})
    out = tmp_path / "out"
    result = _evids("generate", str(config), "--out", str(out))
    assert result.returncode == 2, result.stderr
    assert "splits" in result.stderr and "must be 1" in result.stderr and "Traceback" not in result.stderr
    assert not out.exists()
    result = _evids("generate", str(write_tiny(tmp_path)), "--out", str(out), "--format", "native,yolo")
    assert result.returncode == 2 and "yolo" in result.stderr and not out.exists()


def test_generate_verify_export_from_the_shell(tmp_path):
    config = write_tiny(tmp_path, sequences=2, frames=2)
    out = tmp_path / "ds"
    result = _evids("generate", str(config), "--out", str(out), "--seed", "2", "--format", "native,mot", "--quiet")
    assert result.returncode == 0, result.stderr
    assert "2 rendered" in result.stdout and (out / "mot").is_dir()
    ok = _evids("verify", str(out))
    assert ok.returncode == 0 and "ok: 2 sequences intact" in ok.stdout
    result = _evids("export", str(out), "--format", "coco,antiuav", "--out", str(tmp_path / "exp"), "--quiet")
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "exp" / "coco" / "annotations").is_dir() and (tmp_path / "exp" / "antiuav").is_dir()
    (out / "sequences" / "seq000002" / "labels.json").write_text("{}")
    bad = _evids("verify", str(out))
    assert bad.returncode == 1 and "corrupt: seq000002 (labels.json)" in bad.stdout
    again = _evids("generate", str(config), "--out", str(out), "--seed", "3", "--quiet")
    assert again.returncode == 2 and "different dataset" in again.stderr
    assert _evids("verify", str(tmp_path)).returncode == 2


def test_scene_preset_name_is_a_config(tmp_path):
    out = tmp_path / "ds"
    result = _evids("generate", "dusk_crossover", "--out", str(out), "--sequences", "1", "--frames", "1", "--quiet")
    assert result.returncode == 0, result.stderr
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["config"]["mixture"] == [{"scenario": "dusk_crossover", "weight": 1.0}]
    assert manifest["config"]["randomise"]["air_temperature_k"] is not None


def test_fixture_command_is_byte_stable(tmp_path):
    a = _evids("fixture", "mmuav", "--out", str(tmp_path / "a"))
    b = _evids("fixture", "mmuav", "--out", str(tmp_path / "b"))
    assert a.returncode == 0 and b.returncode == 0, a.stderr + b.stderr
    assert a.stdout.strip().endswith("mot/train/0001")
    assert tree_digest(tmp_path / "a") == tree_digest(tmp_path / "b")
    assert (tmp_path / "a" / "mot" / "train" / "0001" / "gt_ir" / "gt.txt").read_text().endswith(",1,0,1\n")
    assert _evids("fixture", "nope", "--out", str(tmp_path / "c")).returncode == 2


USER_TEST = '''
import json
from simulator.formats import antiuav, coco, mot


def test_mmuav(evids_mmuav_sequence):
    tracks = mot.load_sequence(evids_mmuav_sequence)
    assert set(tracks) == {"rgb", "ir"} and len(tracks["rgb"].frames) == 4 and len(tracks["ir"].gt) >= 1


def test_antiuav_and_coco(evids_antiuav_sequence, evids_coco_file):
    track = antiuav.load_sequence(evids_antiuav_sequence)["infrared"]
    assert track.exist.tolist() == [1, 1, 1, 1]
    assert coco.load_coco(evids_coco_file).tracks(1)


def test_trident(evids_trident_folder):
    assert (evids_trident_folder / "manifest.json").is_file()


def test_factory_other_preset(evids_fixture):
    path = evids_fixture("native", preset="bird_confuser", seed=3)
    assert json.loads((path / "manifest.json").read_text())["sequences"][0]["source"] == "bird_confuser"
'''


def test_pytest_plugin_fixtures_in_a_fresh_test_file(tmp_path):
    if not any(ep.name == "evids" for ep in entry_points(group="pytest11")):
        pytest.fail("the evids pytest11 entry point is not installed: reinstall the package (pip install -e .)")
    (tmp_path / "test_user.py").write_text(USER_TEST)
    cache = tmp_path / "cache"
    env = {**os.environ, "EVIDS_FIXTURE_CACHE": str(cache)}
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist", "test_user.py"]
    first = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600)
    assert first.returncode == 0, first.stdout + first.stderr
    assert "4 passed" in first.stdout
    built = sorted(p.name.split("-")[0] for p in cache.iterdir())
    assert built == ["antiuav", "coco", "mmuav", "native", "trident"]
    stamps = {p: (p / ".complete").stat().st_mtime_ns for p in cache.iterdir()}
    second = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600)
    assert second.returncode == 0 and "4 passed" in second.stdout
    assert {p: (p / ".complete").stat().st_mtime_ns for p in cache.iterdir()} == stamps  # reused, not rebuilt
