"""Dataset generation: manifest, resume after SIGKILL, verify, corrupt-sequence regeneration,
manifest mismatch, per-sequence failures, process pool and Ray give identical bytes."""
import json
import os
import re
import signal
import subprocess
import sys
import time

import pytest

from scenes.errors import UserInputError
from simulator.dataset import generate as gen
from simulator.dataset.driver import GenerationFailed
from simulator.dataset.generate import (
    generate_dataset,
    load_manifest,
    verify_dataset,
)
from simulator.files import verify_hashes
from tests.simulator.dataset.gen_helpers import tree_digest, write_tiny


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    base = tmp_path_factory.mktemp("gen")
    config = write_tiny(base)
    out = base / "ds"
    generate_dataset(config, out, 5, progress=False)
    return config, out


def test_manifest_records_config_seeds_versions_splits_and_hashes(tiny):
    config, out = tiny
    m = load_manifest(out)
    assert m["complete"] is True and m["seed"] == 5 and m["config"]["sequences"] == 4
    assert "mitsuba" in m["versions"] and "evids" in m["versions"]
    names = [s["name"] for s in m["sequences"]]
    assert names == ["seq000001", "seq000002", "seq000003", "seq000004"]
    assert sorted(sum(m["splits"].values(), [])) == names
    assert [len(m["splits"][k]) for k in ("train", "val", "test")] == [2, 1, 1]
    for s in m["sequences"]:
        seq = out / "sequences" / s["name"]
        assert verify_hashes(seq) == [] and gen.sequence_hash(seq) == s["content_sha256"]
        assert json.loads((seq / "meta.json").read_text())["seed"] == s["seed"]
    assert len({s["seed"] for s in m["sequences"]}) == 4
    assert not re.search(r"\d{4}-\d\d-\d\dT\d\d:|created|timestamp", json.dumps(m))  # nothing run-specific
    assert verify_dataset(out).ok


def test_reuse_from_links_the_same_datasets_intact_sequences_and_nothing_else(tiny, tmp_path):
    """An earlier folder of the same dataset: its sequences are hard-linked, not rendered, and the result is
    the same bytes; a corrupt one there is rendered anew; another dataset (another seed) lends nothing."""
    import shutil

    config, reference = tiny
    first = gen.generate_dataset(config, tmp_path / "linked", 5, progress=False, reuse_from=reference)
    assert first.linked == ["seq000001", "seq000002", "seq000003", "seq000004"] and first.rendered == []
    assert tree_digest(tmp_path / "linked") == tree_digest(reference)
    frame = next((reference / "sequences" / "seq000002").rglob("*.png"))
    assert (tmp_path / "linked" / frame.relative_to(reference)).stat().st_ino == frame.stat().st_ino
    damaged = tmp_path / "damaged"
    shutil.copytree(reference, damaged)
    with open(damaged / "sequences" / "seq000003" / "labels.json", "a") as fh:
        fh.write(" ")
    second = gen.generate_dataset(config, tmp_path / "partly", 5, progress=False, reuse_from=damaged)
    assert second.linked == ["seq000001", "seq000002", "seq000004"] and second.rendered == ["seq000003"]
    assert tree_digest(tmp_path / "partly") == tree_digest(reference)
    other = gen.generate_dataset(config, tmp_path / "other", 6, progress=False, reuse_from=reference)
    assert other.linked == [] and len(other.rendered) == 4


def _default_sigint() -> None:
    """In the child: SIGINT back to its default. A pytest-xdist worker ignores SIGINT and a child
    inherits an ignored signal, so Python would never raise KeyboardInterrupt (the Ctrl-C test then
    saw the run finish with exit 0 in the full parallel suite while passing alone)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _run_cli(config, out, *extra):
    return subprocess.Popen([sys.executable, "-c", "from harness.cli import main; main()", "generate", str(config),
                             "--out", str(out), "--seed", "5", "--quiet", *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_default_sigint)


def test_sigkill_leaves_no_partial_sequence_and_resume_is_byte_identical(tiny, tmp_path):
    config, reference = tiny
    out = tmp_path / "killed"
    proc = _run_cli(config, out)
    seqs = out / "sequences"
    deadline = time.time() + 120
    while time.time() < deadline:
        done = [p for p in seqs.iterdir() if not p.name.startswith(".")] if seqs.is_dir() else []
        if done:
            break
        time.sleep(0.02)
    assert proc.poll() is None, "the run finished before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not load_manifest(out)["complete"]
    visible = [p for p in seqs.iterdir() if not p.name.startswith(".")]
    assert 1 <= len(visible) < 4
    for p in visible:
        assert verify_hashes(p) == [], p  # whatever is visible is whole
    report = verify_dataset(out)
    assert not report.ok and report.incomplete
    proc = _run_cli(config, out)
    stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 0, stderr
    assert "already complete" in stdout and f"{4 - len(visible)} rendered" in stdout
    assert tree_digest(out) == tree_digest(reference)


def test_verify_detects_a_flipped_byte_and_the_next_run_regenerates_only_it(tiny, tmp_path):
    import shutil

    config, reference = tiny
    out = tmp_path / "copy"
    shutil.copytree(reference, out)
    victim = out / "sequences" / "seq000003" / "thermal" / "000002.png"
    data = bytearray(victim.read_bytes())
    data[len(data) // 2] ^= 0x01
    victim.write_bytes(bytes(data))
    report = verify_dataset(out)
    assert not report.ok and list(report.corrupt) == ["seq000003"]
    assert report.corrupt["seq000003"] == ["thermal/000002.png"]
    shutil.rmtree(out / "sequences" / "seq000001")
    assert verify_dataset(out).missing == ["seq000001"]
    result = generate_dataset(config, out, 5, progress=False)
    assert result.rendered == ["seq000001", "seq000003"]
    assert tree_digest(out) == tree_digest(reference)


def test_a_different_dataset_in_out_is_refused_unless_overwrite(tiny, tmp_path):
    import shutil

    config, reference = tiny
    out = tmp_path / "other"
    shutil.copytree(reference, out)
    before = tree_digest(out)
    with pytest.raises(UserInputError, match="different dataset"):
        generate_dataset(config, out, 6, progress=False, sequences=1)
    with pytest.raises(UserInputError, match="different dataset"):
        generate_dataset(config, out, 5, progress=False, frames=2)
    assert tree_digest(out) == before
    generate_dataset(config, out, 6, progress=False, sequences=1, frames=2, overwrite=True)
    m = load_manifest(out)
    assert m["seed"] == 6 and [s["name"] for s in m["sequences"]] == ["seq000001"]
    assert sorted(p.name for p in (out / "sequences").iterdir()) == ["seq000001"]
    stray = tmp_path / "stray"
    stray.mkdir()
    (stray / "notes.txt").write_text("mine")
    with pytest.raises(UserInputError, match="holds no evids dataset"):
        generate_dataset(config, stray, 5, progress=False, overwrite=True)
    assert (stray / "notes.txt").read_text() == "mine"


def test_a_failing_sequence_fails_alone_with_a_clear_message(tmp_path, monkeypatch):
    import simulator.dataset.sequence as sequence

    config = write_tiny(tmp_path, sequences=3, frames=2)
    real = sequence.render_sequence

    def flaky(scenario, seed, out_dir, **kwargs):
        if scenario.name == "seq000002":
            raise OSError(28, "No space left on device")
        return real(scenario, seed, out_dir, **kwargs)

    monkeypatch.setattr(sequence, "render_sequence", flaky)
    out = tmp_path / "ds"
    with pytest.raises(GenerationFailed) as info:
        generate_dataset(config, out, 5, progress=False)
    assert list(info.value.failures) == ["seq000002"]
    assert "No space left on device" in str(info.value) and "seq000002" in str(info.value)
    assert sorted(p.name for p in (out / "sequences").iterdir()) == ["seq000001", "seq000003"]
    assert all(verify_hashes(p) == [] for p in (out / "sequences").iterdir())
    assert not load_manifest(out)["complete"]
    monkeypatch.setattr(sequence, "render_sequence", real)
    assert generate_dataset(config, out, 5, progress=False).rendered == ["seq000002"]
    assert verify_dataset(out).ok


def test_process_pool_gives_the_same_bytes(tiny, tmp_path):
    config, reference = tiny
    out = tmp_path / "pool"
    generate_dataset(config, out, 5, workers=2, progress=False)
    assert tree_digest(out) == tree_digest(reference)


def test_ray_executor_gives_the_same_hashes(tiny, tmp_path):
    pytest.importorskip("ray",
                        reason="Ray is an optional extra (pip install 'evids[ray]'); the Ray path is untested here")
    config, reference = tiny
    out = tmp_path / "ray"
    generate_dataset(config, out, 5, workers=2, executor="ray", progress=False, sequences=2)  # first 2 of 4
    ray_hashes = {s["name"]: s["content_sha256"] for s in load_manifest(out)["sequences"]}
    local_hashes = {s["name"]: s["content_sha256"] for s in load_manifest(reference)["sequences"][:2]}
    assert ray_hashes == local_hashes and len(ray_hashes) == 2
    for name in ray_hashes:
        assert tree_digest(out / "sequences" / name) == tree_digest(reference / "sequences" / name)


def test_ctrl_c_stops_a_pool_run_promptly_and_keeps_finished_sequences(tmp_path):
    config = write_tiny(tmp_path, sequences=8, frames=6)
    out = tmp_path / "ds"
    proc = _run_cli(config, out, "--workers", "2")
    seqs = out / "sequences"
    deadline = time.time() + 120
    while time.time() < deadline and not (seqs.is_dir() and any(not p.name.startswith(".") for p in seqs.iterdir())):
        time.sleep(0.02)
    assert proc.poll() is None, "the run finished before it could be interrupted"
    t0 = time.time()
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "run the same command again" in stderr
    assert time.time() - t0 < 10
    visible = [p for p in seqs.iterdir() if not p.name.startswith(".")]
    assert 1 <= len(visible) < 8 and all(verify_hashes(p) == [] for p in visible)
    assert not load_manifest(out)["complete"]
