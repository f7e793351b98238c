"""The committed lock (lock/, installed by run.sh) agrees with pyproject.toml: every direct dependency
of the base and of the extras the lock was compiled with is pinned in it, with a version its bound
allows, and every pin carries a sha256 hash. Refresh: `bash lock/refresh`."""
from __future__ import annotations

import re
from pathlib import Path

import pytest
import tomllib
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

ROOT = Path(__file__).resolve().parent.parent


def _pins(path: Path) -> dict[str, tuple[Version, int]]:
    """name -> (pinned version, number of hashes) from a `uv pip compile --generate-hashes` file."""
    pins: dict[str, tuple[Version, int]] = {}
    name = None
    for line in path.read_text().splitlines():
        head = re.match(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==(\S+)", line)
        if head:
            name = canonicalize_name(head.group(1))
            pins[name] = (Version(head.group(2)), 0)
        elif name and line.strip().startswith("--hash=sha256:"):
            pins[name] = (pins[name][0], pins[name][1] + 1)
    return pins


def _extras(path: Path) -> list[str]:
    command = next(line for line in path.read_text().splitlines() if "uv pip compile" in line)
    return re.findall(r"--extra (\S+)", command)


def _direct(extras: list[str]) -> list[Requirement]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = [Requirement(r) for r in project["dependencies"]]
    for extra in extras:
        reqs += [Requirement(r) for r in project["optional-dependencies"][extra]]
    return reqs


def test_pin_parser_reads_versions_and_hashes(tmp_path):
    f = tmp_path / "l.txt"
    f.write_text("Foo_Bar==1.2.0+cpu \\\n    --hash=sha256:aa \\\n    --hash=sha256:bb\n    # via x\nbaz==3 \\\n"
                 "    --hash=sha256:cc\n")
    assert _pins(f) == {"foo-bar": (Version("1.2.0+cpu"), 2), "baz": (Version("3"), 1)}


def test_lock_satisfies_every_direct_bound():
    lock = ROOT / "lock" / "requirements.txt"
    extras = _extras(lock)
    assert {"audio", "dev", "ray", "tracking"} <= set(extras)  # what run.sh installs
    pins = _pins(lock)
    bad = []
    for req in _direct(extras):
        if req.marker is not None and not req.marker.evaluate({"python_version": "3.11"}):
            continue
        pinned = pins.get(canonicalize_name(req.name))
        if pinned is None or not req.specifier.contains(pinned[0], prereleases=True):
            bad.append(f"{req} -> {pinned[0] if pinned else 'not in the lock'}")
    assert not bad, f"lock and pyproject.toml disagree (run `bash lock/refresh`): {bad}"


@pytest.mark.parametrize("name", ["requirements.txt", "nodeps.txt"])
def test_every_pin_has_a_hash(name):
    pins = _pins(ROOT / "lock" / name)
    assert pins and all(n >= 1 for _, n in pins.values())


def test_torch_is_the_cpu_build_and_trackeval_is_locked():
    pins = _pins(ROOT / "lock" / "requirements.txt")
    assert pins["torch"][0].local == "cpu"
    assert canonicalize_name("trackeval") in _pins(ROOT / "lock" / "nodeps.txt")
    assert canonicalize_name("opencv-python") not in pins  # the GUI build would replace the headless cv2


def test_run_folders_record_commit_lock_hash_and_numeric_versions(tmp_path):
    import hashlib
    import json

    from harness.runfolder import mark_stage
    from simulator.files import NUMERIC_PACKAGES, environment_record

    mark_stage(tmp_path, "train", 1.0)
    env = json.loads((tmp_path / "run.json").read_text())["environment"]
    assert env == json.loads(json.dumps(environment_record()))
    assert env["lock_sha256"] == hashlib.sha256((ROOT / "lock" / "requirements.txt").read_bytes()).hexdigest()
    assert set(NUMERIC_PACKAGES) >= {"numpy", "scipy", "torch", "drjit", "mitsuba", "opencv-python-headless",
                                     "scikit-learn"}
    assert all(env["versions"][p] != "not installed" for p in NUMERIC_PACKAGES)
    if (ROOT / ".git").exists():
        assert re.fullmatch(r"[0-9a-f]{40}(\+dirty)?", env["git_commit"])
