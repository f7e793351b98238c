"""Concurrency and crashes of `evids generate`: two writers on one dataset, and kill -9 of the driver
of a two-worker pool (no process may survive; the resumed dataset equals the uninterrupted one)."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest
import yaml

from simulator.dataset.generate import generate_dataset, verify_dataset
from simulator.files import LOCK_FILE
from tests.reliability.conftest import TINY2
from tests.reliability.helpers import ROOT, evids, tree_digest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and prctl")


def _tagged(tag: str) -> list[int]:
    """Pids of live processes whose environment carries ``EVIDS_TEST_TAG=tag``."""
    found = []
    needle = f"EVIDS_TEST_TAG={tag}".encode()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            if needle in (entry / "environ").read_bytes().split(b"\0"):
                state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
                if state != "Z":
                    found.append(int(entry.name))
        except OSError:
            continue
    return found


def _start(config: Path, out: Path, tag: str, *extra: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "EVIDS_TEST_TAG": tag}
    return subprocess.Popen([sys.executable, "-c", "from harness.cli import main; main()", "generate", str(config),
                             "--out", str(out), "--seed", "3", "--quiet", *extra], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait(predicate, timeout_s: float, what: str) -> None:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if predicate():
            return
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


@pytest.fixture
def config(tmp_path) -> Path:
    path = tmp_path / "tiny2.yaml"
    path.write_text(yaml.safe_dump(TINY2))
    return path


def test_a_second_writer_refuses_while_the_first_finishes_intact(config, tmp_path, tiny_dataset):
    out = tmp_path / "ds"
    first = _start(config, out, uuid.uuid4().hex)
    try:
        _wait(lambda: (out / LOCK_FILE).is_file() and (out / LOCK_FILE).read_text().strip(), 120,
              "the first run's lock")
        assert json.loads((out / LOCK_FILE).read_text())["pid"] == first.pid
        second = evids("generate", config, "--out", out, "--seed", "3", "--quiet")
        assert second.returncode == 2, second.stderr
        assert f"locked by another evids run (pid {first.pid}" in second.stderr
        assert first.wait(timeout=600) == 0, first.stderr.read()
    finally:
        if first.poll() is None:
            first.kill()
    assert verify_dataset(out).ok
    assert tree_digest(out) == tree_digest(tiny_dataset)


def test_kill_9_of_the_driver_takes_its_workers_along_and_resume_is_byte_identical(config, tmp_path, tiny_dataset):
    out = tmp_path / "ds"
    tag = uuid.uuid4().hex
    driver = _start(config, out, tag, "--workers", "2")
    try:
        # kill while both workers are rendering: their temporaries exist, nothing is published yet
        _wait(lambda: len(_tagged(tag)) >= 3 and any((out / "sequences").glob(".tmp-*")) if (out / "sequences").is_dir()
              else False, 300, "two busy workers")
        workers = [p for p in _tagged(tag) if p != driver.pid]
        assert len(workers) >= 2
        os.kill(driver.pid, signal.SIGKILL)
        driver.wait(timeout=30)
        _wait(lambda: not _tagged(tag), 20, f"the workers {workers} to die with their driver")
    finally:
        if driver.poll() is None:
            driver.kill()
        for pid in _tagged(tag):
            os.kill(pid, signal.SIGKILL)
    assert not verify_dataset(out).ok  # killed mid-run: nothing certified
    published = sorted(p.name for p in (out / "sequences").iterdir() if not p.name.startswith("."))
    time.sleep(1.5)  # a surviving orphan would publish now
    assert sorted(p.name for p in (out / "sequences").iterdir() if not p.name.startswith(".")) == published
    result = generate_dataset(config, out, 3, progress=False)
    assert result.notes and "stale lock" in result.notes[0]
    assert verify_dataset(out).ok
    assert tree_digest(out) == tree_digest(tiny_dataset)
