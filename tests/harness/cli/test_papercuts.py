"""Newcomer papercuts (issue 28): the README's example file ships and validates, --help shows no
<bool> placeholder for flags, `scenes list` cuts no description, TRIDENT exports keep every label
in every split, optional dependencies are named at a command's start, `report` takes --no-progress."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from harness.cli import main, require_module
from scenes.errors import UserInputError
from simulator.formats.trident import assign_splits

ROOT = Path(__file__).resolve().parents[3]


def _run(capsys, *args: str) -> tuple[int, str, str]:
    try:
        main(list(args))
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 0
    out = capsys.readouterr()
    return code, out.out, out.err


def test_readme_scene_example_ships_and_validates(capsys):
    assert "scenes validate examples/my_scene.yaml" in (ROOT / "README.md").read_text()
    code, out, _ = _run(capsys, "scenes", "validate", str(ROOT / "examples" / "my_scene.yaml"))
    assert code == 0 and out.startswith("ok: my_scene")


def test_missing_scene_file_is_not_called_a_preset_file(capsys):
    code, _, err = _run(capsys, "scenes", "validate", "no_such_file.yaml")
    assert code == 2 and "scene file 'no_such_file.yaml' does not exist" in err and "preset file" not in err


def test_help_shows_no_bool_placeholder(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "120")
    code, out, _ = _run(capsys, "export", "--help")
    assert code == 0 and "--distractors" in out and "<bool>" not in out and "range>" not in out


def test_scenes_list_keeps_whole_descriptions(capsys):
    code, out, _ = _run(capsys, "scenes", "list")
    block = out.split("dusk_crossover", 1)[1].split("\nfixed_wing_pass", 1)[0]
    assert code == 0 and "crossover" in block and "60 % of the clip" in " ".join(block.split())


def test_report_accepts_no_progress(capsys, tmp_path):
    code, _, err = _run(capsys, "report", str(tmp_path / "missing"), "--no-progress")
    assert code == 2 and "does not exist" in err   # the flag parsed; the folder check answered


def _clips(n_drone: int, n_background: int) -> list:
    return ([SimpleNamespace(label="Drone", clip_id=f"d{i}") for i in range(n_drone)]
            + [SimpleNamespace(label="Background", clip_id=f"b{i}") for i in range(n_background)])


@pytest.mark.parametrize("fraction", [0.1, 0.2, 0.5, 0.9])
def test_trident_every_split_holds_every_label(fraction):
    splits = assign_splits(_clips(10, 2), fraction)
    for label in ("d", "b"):
        assert {v for k, v in splits.items() if k.startswith(label)} == {"Train", "Test"}


def test_trident_split_rule_unchanged_where_it_already_held_every_label():
    splits = assign_splits(_clips(10, 10), 0.2)
    assert sorted(k for k, v in splits.items() if v == "Test") == ["b2", "b7", "d2", "d7"]
    assert set(assign_splits(_clips(3, 3), 0.0).values()) == {"Train"}   # 0: no Test split at all


def test_trident_single_clip_label_is_refused():
    with pytest.raises(UserInputError, match="'Background' has 1 clip"):
        assign_splits(_clips(5, 1), 0.2)


def test_optional_dependency_named_at_start():
    require_module("json", "anything", "n/a")
    with pytest.raises(UserInputError,
                       match="evids demo --detection needs the Python package 'no_such_mod_x'.*--no-deps"):
        require_module("no_such_mod_x", "evids demo --detection", "pip install --no-deps trackeval==1.3.0")
