"""Every YAML entry point (scene, generation, TRIDENT, experiment config, degradation spec) under
hostile input: duplicate keys, alias bombs, deep nesting, huge values, junk bytes. Each must fail
fast with a short, friendly error (UserInputError / SpecError), never a traceback or a long stall."""
from __future__ import annotations

import time
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from degradations.errors import SpecError
from degradations.spec import load_spec
from harness.experiments.config import load_experiment_config
from scenes.errors import UserInputError
from scenes.loader import load_scenario
from scenes.yaml_safe import MAX_DEPTH, load_yaml
from simulator.dataset.config import load_generation_config
from simulator.dataset.trident import load_trident_config


def billion_laughs(levels: int = 9) -> str:
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, levels + 1):
        lines.append(f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]")
    lines.append(f"name: *a{levels}")
    return "\n".join(lines) + "\n"


SCENE_OK = Path(__file__).resolve().parents[2] / "scenes" / "library" / "clear_day_quad.yaml"

ENTRY_POINTS = {
    "scene": (load_scenario, UserInputError),
    "generation": (load_generation_config, UserInputError),
    "trident": (load_trident_config, UserInputError),
    "experiment": (load_experiment_config, UserInputError),
    "spec": (load_spec, SpecError),
}

HOSTILE = {
    "billion laughs (1.2 KB, 10^10 nodes)": (billion_laughs(), "alias bomb"),
    "10^4-deep flow nesting": ("[" * 10_000 + "]" * 10_000, f"deeper than {MAX_DEPTH}"),
    "500-deep block nesting": ("".join(" " * i + "a:\n" for i in range(500)) + " " * 500 + "a: 1\n",
                                f"deeper than {MAX_DEPTH}"),
    "duplicate top-level key": ("name: a\nname: b\n", "duplicate key 'name'"),
    "not YAML": ("name: [unclosed\n", "not valid YAML"),
    "not a mapping": ("- 1\n- 2\n", "mapping"),
}


@pytest.mark.parametrize("entry", ENTRY_POINTS)
@pytest.mark.parametrize("case", HOSTILE)
def test_hostile_yaml_fails_fast_and_friendly(tmp_path, entry, case):
    load, error = ENTRY_POINTS[entry]
    text, fragment = HOSTILE[case]
    path = tmp_path / "input.yaml"
    path.write_text(text)
    t0 = time.perf_counter()
    with pytest.raises(error) as info:
        load(path)
    assert time.perf_counter() - t0 < 5.0
    message = str(info.value)
    assert len(message) < 2000 and "Traceback" not in message
    assert fragment in message


def test_duplicate_degradations_key_is_refused_not_silently_dropped(tmp_path):
    spec = tmp_path / "spec.yaml"
    spec.write_text("version: 1\ndegradations:\n  - {name: video.fog, severity: 2}\n"
                    "degradations:\n  - {name: video.gaussian_noise, severity: 1}\n")
    with pytest.raises(SpecError, match="line 4: duplicate key 'degradations'"):
        load_spec(spec)


def test_duplicate_nested_key_names_its_line(tmp_path):
    text = SCENE_OK.read_text().replace("camera_rig:", "camera_rig:\n  position_m: [0, 0, 9]", 1)
    path = tmp_path / "dup.yaml"
    path.write_text(text)
    with pytest.raises(UserInputError, match=r"duplicate key 'position_m'"):
        load_scenario(path)


def test_merge_keys_still_work():
    assert load_yaml("base: &b {x: 1, y: 2}\nc:\n  <<: *b\n  x: 3\n", "m") == {"base": {"x": 1, "y": 2},
                                                                             "c": {"x": 3, "y": 2}}


def test_error_text_truncates_a_huge_input(tmp_path):
    data = yaml.safe_load(SCENE_OK.read_text())
    data["duration_s"] = ["x" * 1000] * 1000
    path = tmp_path / "big.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(UserInputError) as info:
        load_scenario(path)
    assert "duration_s" in str(info.value) and len(str(info.value)) < 500


def test_a_giant_file_is_refused_before_reading(tmp_path):
    path = tmp_path / "huge.yaml"
    with open(path, "wb") as fh:
        fh.truncate(64 * 1024 * 1024)
    with pytest.raises(UserInputError, match="larger than"):
        load_scenario(path)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.text(alphabet=st.sampled_from(list("ab:-[]{}&*!|>'\"#\n ,.0123456789%@`?")), max_size=200))
def test_any_text_gives_data_or_a_user_error(text):
    try:
        load_yaml(text, "fuzz")
    except UserInputError as exc:
        assert str(exc).startswith("fuzz:")


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=300))
def test_any_bytes_as_a_spec_file_give_a_spec_error_or_a_spec(tmp_path_factory, blob):
    path = tmp_path_factory.mktemp("fuzz") / "spec.yaml"
    path.write_bytes(blob)
    try:
        load_spec(path)
    except SpecError:
        pass
