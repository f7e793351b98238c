"""The `evids` CLI: exit status 2 with field-named errors and nothing written; render + degrade."""
import json
import subprocess
import sys

import numpy as np
import yaml

from scenes import load_scenario
from scenes.loader import LIBRARY_DIR
from simulator.dataset.sequence import render_sequence
from simulator.files import verify_hashes
from simulator.formats.native import load_mask, load_thermal_kelvin
from simulator.render.labels import local_contrast_k, tight_box
from tests.conftest import shrink


def _evids(*args, cwd=None):
    return subprocess.run([sys.executable, "-c", "from harness.cli import main; main()", *args],
                          capture_output=True, text=True, cwd=cwd, timeout=300)


def test_invalid_field_exits_2_names_the_field_and_writes_nothing(tmp_path):
    data = yaml.safe_load((LIBRARY_DIR / "clear_day_quad.yaml").read_text())
    data["atmosphere"]["relative_humidity"] = 1.7
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    out = tmp_path / "out"
    result = _evids("render", str(bad), "--out", str(out))
    assert result.returncode == 2
    assert "atmosphere.relative_humidity" in result.stderr and "1.7" in result.stderr
    assert "Traceback" not in result.stderr
    assert not out.exists()


def test_broken_yaml_and_unknown_preset_exit_2(tmp_path):
    broken = tmp_path / "broken.yaml"
    broken.write_text("name: [unclosed\n")
    result = _evids("scenes", "validate", str(broken))
    assert result.returncode == 2 and "not valid YAML" in result.stderr
    result = _evids("render", "no_such_scene", "--out", str(tmp_path / "o"))
    assert result.returncode == 2 and "dusk_crossover" in result.stderr


def test_scenes_list_and_show():
    listed = _evids("scenes", "list")
    assert listed.returncode == 0 and "bird_confuser" in listed.stdout
    shown = _evids("scenes", "show", "swarm_3")
    assert shown.returncode == 0 and yaml.safe_load(shown.stdout)["name"] == "swarm_3"


def test_degrade_ir_blind_labels_the_conflict_on_a_rendered_sequence(tmp_path):
    scenario = shrink(load_scenario("clear_day_quad"), 320, 256)
    # ideal sensor: thermal.crossover moves the mask's pixels only, so the camera model's PSF halo
    # around the target would keep ~0.2 K of contrast (a limit of that degradation, not of the CLI)
    scenario = scenario.model_copy(update={"duration_s": 1.6,
                                           "camera_rig": scenario.camera_rig.model_copy(update={"sensor": "ideal"})})
    native = render_sequence(scenario, 7, tmp_path / "data", progress=False)["native"]
    spec = tmp_path / "spec.yaml"
    spec.write_text(yaml.safe_dump({"version": 1,
                                    "programs": [{"name": "ir_blind", "onset_s": 0.4, "duration_s": 0.8}]}))
    result = _evids("degrade", str(native), "--spec", str(spec), "--out", str(tmp_path / "deg"))
    assert result.returncode == 0, result.stderr
    degraded = tmp_path / "deg" / native.name
    assert verify_hashes(degraded) == []
    record = json.loads((degraded / "degradation_record.json").read_text())
    t = np.asarray(record["t_s"])
    inside = (t >= 0.4) & (t < 1.2)
    assert np.array_equal(np.asarray(record["compromised"]["thermal"]), inside)
    assert not any(record["compromised"]["rgb"])
    netd = scenario.camera_rig.thermal.netd_k
    for i in np.flatnonzero(inside)[::5]:
        mask = load_mask(degraded, "thermal", int(i))
        box = tight_box(mask == 1)
        if box is None:
            continue
        before = local_contrast_k(load_thermal_kelvin(native, int(i)), mask, 1, box)
        after = local_contrast_k(load_thermal_kelvin(degraded, int(i)), mask, 1, box)
        # thermal.crossover zeroes the contrast against its own 5-px ring; this label ring is wider,
        # and across the LOWTRAN7 sky's elevation gradient the two ring means differ by ~0.07 K
        assert before > 1.0 and abs(after) < max(netd, 0.01 * before)
    bad_spec = tmp_path / "bad_spec.yaml"
    bad_spec.write_text(yaml.safe_dump({"version": 1, "degradations": [{"name": "video.fog", "severity": 9}]}))
    result = _evids("degrade", str(native), "--spec", str(bad_spec), "--out", str(tmp_path / "deg2"))
    assert result.returncode == 2 and "severity" in result.stderr
    assert not (tmp_path / "deg2").exists()


def test_unwritable_output_is_one_line_and_exit_1(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    result = _evids("render", "clear_day_quad", "--out", str(blocker / "out"), "--frames", "1", "--quiet")
    assert result.returncode == 1
    assert result.stderr.startswith("error: ") and "a_file" in result.stderr
    assert "Traceback" not in result.stderr
