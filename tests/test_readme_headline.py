"""docs/make_readme_headline.py: the README's headline answers are rewritten from demo run folders (their
metrics.json headline sentences, the commit and lock hash of train.json), with the spread over several runs.
Run folders here are small hand-made ones in the layout `evids evaluate` writes (only the fields used)."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("make_readme_headline", ROOT / "docs" / "make_readme_headline.py")
assert _spec is not None and _spec.loader is not None
mh = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(mh)


def _run(folder: Path, delta_pp: float, verdict: str, commit: str = "a" * 40, lock: str = "b" * 64) -> Path:
    folder.mkdir(parents=True)
    metrics = {"headline": [f"<b>DS vs averaging:</b> &Delta; = {delta_pp:+.2f} pp; {verdict}.",
                            "<b>Gating:</b> &tau;<sub>high</sub>=0.3"],
               "comparisons": [{"comparison": "DS (e) vs average (d)", "delta_accuracy": delta_pp / 100,
                                "verdict": verdict},
                               {"comparison": "gated (f) vs DS (e)", "delta_accuracy": -0.01, "verdict": "undecided"}]}
    (folder / "metrics.json").write_text(json.dumps(metrics))
    (folder / "train.json").write_text(json.dumps({"environment": {"git_commit": commit, "lock_sha256": lock},
                                                   "training_seeds": [0, 1, 2], "noise_seeds": [7],
                                                   "n_scenes": {"train": 24, "val": 8, "test": 33}}))
    return folder


def _readme(tmp_path: Path) -> Path:
    path = tmp_path / "README.md"
    path.write_text(f"# title\nbefore\n{mh.BEGIN}\nold hand-written answers\n{mh.END}\nafter\n")
    return path


def test_the_headline_is_rewritten_from_the_run_between_the_markers_only(tmp_path):
    readme = _readme(tmp_path)
    run = _run(tmp_path / "demo", 2.7, "DS beats averaging")
    assert mh.main([str(run), "--readme", str(readme)]) == 0
    text = readme.read_text()
    assert text.startswith("# title\nbefore\n") and text.endswith("\nafter\n") and "old hand-written" not in text
    assert f"commit `{'a' * 12}`" in text and f"sha256 `{'b' * 16}`" in text
    assert "- **DS vs averaging:** Δ = +2.70 pp; DS beats averaging." in text and "τ_high=0.3" in text
    assert "24 train, 8 val, 33 test" in text and "not measured for this run" in text
    assert mh.main([str(run), "--readme", str(readme), "--check"]) == 0
    other = _run(tmp_path / "demo2", -1.0, "undecided")
    assert mh.main([str(other), "--readme", str(readme), "--check"]) == 1  # another run's answers differ


def test_the_spread_over_five_seeds_lists_every_run_and_the_range(tmp_path):
    readme = _readme(tmp_path)
    deltas = [2.7, 1.4, 3.1, 0.2, 2.0]
    runs = [_run(tmp_path / f"s{i}", d, "DS beats averaging" if d > 1 else "undecided", commit=f"{i}" * 40)
            for i, d in enumerate(deltas)]
    assert mh.main([*map(str, runs), "--readme", str(readme)]) == 0
    text = readme.read_text()
    assert "Spread over 5 runs" in text and f"`{'4' * 12}`" in text
    row = next(line for line in text.splitlines() if line.startswith("| DS (e) vs average (d)"))
    assert row == ("| DS (e) vs average (d) | +2.70, +1.40, +3.10, +0.20, +2.00 | 2.90 | "
                   "DS beats averaging x4, undecided x1 |")


@pytest.mark.parametrize("broken, message", [
    (lambda run: (run / "train.json").write_text(json.dumps({"environment": {}})), "git_commit"),
    (lambda run: (run / "metrics.json").unlink(), "metrics.json missing"),
])
def test_a_run_without_what_the_headline_needs_is_refused(tmp_path, capsys, broken, message):
    readme = _readme(tmp_path)
    run = _run(tmp_path / "demo", 1.0, "undecided")
    broken(run)
    before = readme.read_text()
    assert mh.main([str(run), "--readme", str(readme)]) == 2
    assert message in capsys.readouterr().err and readme.read_text() == before


def test_the_readme_holds_the_markers_once():
    text = (ROOT / "README.md").read_text()
    assert text.count(mh.BEGIN) == 1 and text.count(mh.END) == 1 and text.index(mh.BEGIN) < text.index(mh.END)
