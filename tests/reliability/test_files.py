"""simulator/files.py: the safe-output rule, atomic folders, run-id temporaries, the dataset lock and
the link-refusing copy. Table-driven: each row is one careless or hostile output choice."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scenes.errors import UserInputError
from simulator import files
from simulator.files import (
    LOCK_FILE,
    MARKER_FILE,
    DatasetLock,
    atomic_folder,
    atomic_path,
    check_output,
    clean_dead_temps,
    copy_tree_no_symlinks,
    hash_tree,
    is_evids_output,
    write_marker,
)

ROOT = Path(__file__).resolve().parents[2]


def _user_folder(path: Path) -> Path:
    path.mkdir(parents=True)
    (path / "keep.txt").write_text("precious")
    return path


def _evids_folder(path: Path) -> Path:
    path.mkdir(parents=True)
    (path / "a.txt").write_text("ours")
    write_marker(path, "test")
    return path


# (case, setup(tmp) -> (out, inputs), overwrite, allow_resume, expected error fragment or None)
CASES = [
    ("new folder", lambda t: (t / "new", []), False, False, None),
    ("empty folder", lambda t: ((t / "e").mkdir() or t / "e", []), False, False, None),
    ("user folder", lambda t: (_user_folder(t / "u"), []), False, False, "not written by evids"),
    ("user folder with --overwrite", lambda t: (_user_folder(t / "u"), []), True, False, "not written by evids"),
    ("evids folder without --overwrite", lambda t: (_evids_folder(t / "o"), []), False, False, "--overwrite"),
    ("evids folder with --overwrite", lambda t: (_evids_folder(t / "o"), []), True, False, None),
    ("evids folder resumed", lambda t: (_evids_folder(t / "o"), []), False, True, None),
    ("the current folder", lambda t: (Path("."), []), True, True, "current folder"),
    ("a parent of the current folder", lambda t: (Path(".."), []), True, True, "current folder"),
    ("the root", lambda t: (Path("/"), []), True, True, "current folder or one of its parents|root"),
    ("equal to the input", lambda t: (_evids_folder(t / "d"), [t / "d"]), True, False, "is the input"),
    ("ancestor of the input", lambda t: (t / "d", [_evids_folder(t / "d" / "sequences")]), True, False,
     "contains the input"),
    ("descendant of the input", lambda t: (t / "d" / "sequences" / "x", [_evids_folder(t / "d" / "sequences")]), True,
     False, "inside the input"),
    ("a file", lambda t: ((t / "f").write_text("x") and t / "f", []), True, False, "not a folder"),
    ("a symlink to a user folder", lambda t: ((t / "l").symlink_to(_user_folder(t / "u")) or t / "l", []), True, False,
     "symbolic link"),
    ("only a stale lock inside",
     lambda t: ((t / "s").mkdir() or (t / "s" / LOCK_FILE).write_text("{}") and t / "s", []),
     False, False, None),
]


@pytest.mark.parametrize("case,setup,overwrite,resume,error", CASES, ids=[c[0] for c in CASES])
def test_safe_output_rule(tmp_path, monkeypatch, case, setup, overwrite, resume, error):
    monkeypatch.chdir(tmp_path)
    out, inputs = setup(tmp_path)
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file() and not p.is_symlink()}
    if error is None:
        check_output(out, inputs=inputs, overwrite=overwrite, allow_resume=resume)
    else:
        with pytest.raises(UserInputError, match=error):
            check_output(out, inputs=inputs, overwrite=overwrite, allow_resume=resume)
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file() and not p.is_symlink()} == before


def test_atomic_folder_never_replaces_a_user_folder_even_with_overwrite(tmp_path):
    target = _user_folder(tmp_path / "victim")
    with pytest.raises(FileExistsError, match="did not write"):
        with atomic_folder(target, overwrite=True) as tmp:
            (tmp / "x").write_text("new")
    assert (target / "keep.txt").read_text() == "precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["victim"]  # no temporary left


def test_atomic_folder_replaces_its_own_output_only_when_asked_and_marks_it(tmp_path):
    target = tmp_path / "out"
    with atomic_folder(target, kind="unit") as tmp:
        (tmp / "v").write_text("1")
    assert json.loads((target / MARKER_FILE).read_text()) == {"kind": "unit", "written_by": "evids"}
    with pytest.raises(FileExistsError, match="overwrite"):
        with atomic_folder(target) as tmp:
            (tmp / "v").write_text("2")
    with atomic_folder(target, overwrite=True) as tmp:
        (tmp / "v").write_text("3")
    assert (target / "v").read_text() == "3"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_atomic_path_publishes_only_a_complete_file_and_keeps_the_suffix(tmp_path):
    import numpy as np

    target = tmp_path / "sub" / "arrays.npz"
    with atomic_path(target, suffix=".npz") as tmp:
        assert tmp.parent == target.parent and tmp.name.startswith(".arrays.npz.tmp-") and tmp.suffix == ".npz"
        np.savez_compressed(tmp, a=np.arange(3))  # adds no second ".npz": the suffix is already there
        assert not target.exists()
    assert np.load(target)["a"].tolist() == [0, 1, 2]
    assert sorted(p.name for p in target.parent.iterdir()) == ["arrays.npz"]


def test_torch_save_through_atomic_path_is_byte_identical_to_a_direct_save(tmp_path):
    """torch.save names the archive inside the file after the file name: the temporary's name
    must not leak into the bytes (models.pt is byte-identical run to run)."""
    import torch

    state = {"w": torch.arange(4.0)}
    torch.save(state, tmp_path / "direct.pt.tmp-1234")   # how models.pt was written before the helper
    (tmp_path / "direct.pt.tmp-1234").rename(tmp_path / "direct.pt")
    (tmp_path / "a").mkdir()
    with atomic_path(tmp_path / "a" / "direct.pt", hidden=False) as tmp:
        torch.save(state, tmp)
    assert (tmp_path / "a" / "direct.pt").read_bytes() == (tmp_path / "direct.pt").read_bytes()


def test_atomic_path_leaves_the_old_file_untouched_and_no_temporary_on_failure(tmp_path):
    target = tmp_path / "run.json"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("writer crashed")
    assert target.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["run.json"]


def test_no_rename_into_place_outside_the_atomic_write_helper():
    """Every file is published through simulator.files (write_atomic / atomic_path / atomic_folder)."""
    root = Path(__file__).resolve().parents[2]
    offenders = [f"{p.relative_to(root)}:{n}" for pkg in ("scenes", "simulator", "degradations", "evids", "harness")
                 for p in sorted((root / pkg).rglob("*.py")) if p != root / "simulator" / "files.py"
                 for n, line in enumerate(p.read_text().splitlines(), 1)
                 if "os.replace(" in line or "tmp.replace(" in line]
    assert offenders == []


def test_marker_and_lock_are_not_content(tmp_path):
    (tmp_path / "a").write_text("x")
    before = hash_tree(tmp_path)
    write_marker(tmp_path, "t")
    (tmp_path / LOCK_FILE).write_text("{}")
    assert hash_tree(tmp_path) == before


def test_hash_tree_records_a_link_as_a_link(tmp_path):
    (tmp_path / "outside.txt").write_text("secret")
    seq = tmp_path / "seq"
    seq.mkdir()
    (seq / "frame.png").symlink_to(tmp_path / "outside.txt")
    assert hash_tree(seq) == {"frame.png": f"symlink:{tmp_path / 'outside.txt'}"}


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_temporaries_of_dead_runs_are_cleaned_and_live_ones_kept(tmp_path):
    host = files._host_tag()
    dead = tmp_path / f".tmp-seq-r{_dead_pid()}-{host}-abcdef"
    live = tmp_path / f".tmp-seq-r{os.getpid()}-{host}-abcdef"
    other_host = tmp_path / f".tmp-seq-r{_dead_pid()}-00000000-abcdef"
    foreign = tmp_path / ".tmp-seq-12345"  # not our naming: never touched
    for d in (dead, live, other_host, foreign):
        d.mkdir()
    assert clean_dead_temps(tmp_path, "seq") == [dead]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in (live, other_host, foreign))


def test_copy_refuses_links_instead_of_following_them(tmp_path):
    (tmp_path / "secret.txt").write_text("do not copy")
    src = tmp_path / "src"
    (src / "rgb").mkdir(parents=True)
    (src / "rgb" / "000001.png").write_bytes(b"png")
    (src / "rgb" / "000002.png").symlink_to(tmp_path / "secret.txt")
    with pytest.raises(UserInputError, match="symbolic link"):
        copy_tree_no_symlinks(src, tmp_path / "dst")
    assert not any(p.read_bytes() == b"do not copy" for p in (tmp_path / "dst").rglob("*") if p.is_file()) \
        if (tmp_path / "dst").exists() else True


def test_hard_link_copy_shares_the_files_and_still_refuses_links(tmp_path):
    src = tmp_path / "src"
    (src / "rgb").mkdir(parents=True)
    (src / "rgb" / "000001.png").write_bytes(b"png")
    copy_tree_no_symlinks(src, tmp_path / "linked", hard_link=True)
    copy_tree_no_symlinks(src, tmp_path / "copied")
    assert (tmp_path / "linked" / "rgb" / "000001.png").stat().st_ino == (src / "rgb" / "000001.png").stat().st_ino
    assert (tmp_path / "copied" / "rgb" / "000001.png").stat().st_ino != (src / "rgb" / "000001.png").stat().st_ino
    (src / "rgb" / "000002.png").symlink_to(src / "rgb" / "000001.png")
    with pytest.raises(UserInputError, match="symbolic link"):
        copy_tree_no_symlinks(src, tmp_path / "again", hard_link=True)


def test_is_evids_output_recognises_only_our_layouts(tmp_path):
    assert not is_evids_output(_user_folder(tmp_path / "u"))
    ds = tmp_path / "ds"
    ds.mkdir()
    (ds / "manifest.json").write_text(json.dumps({"format": "evids-native-dataset"}))
    assert is_evids_output(ds)
    other = tmp_path / "other"
    other.mkdir()
    (other / "manifest.json").write_text(json.dumps({"format": "someone-else"}))
    assert not is_evids_output(other)


_HOLD = textwrap.dedent("""
    import sys, time
    sys.path.insert(0, {root!r})
    from simulator.files import DatasetLock
    lock = DatasetLock(sys.argv[1], "generate").acquire()
    print("locked", flush=True)
    time.sleep(60)
""")


def test_a_second_writer_is_refused_and_a_dead_holder_is_detected(tmp_path):
    folder = tmp_path / "ds"
    proc = subprocess.Popen([sys.executable, "-c", _HOLD.format(root=str(ROOT)), str(folder)], stdout=subprocess.PIPE,
                            text=True)
    try:
        assert proc.stdout.readline().strip() == "locked"
        with pytest.raises(UserInputError, match=rf"locked by another evids run \(pid {proc.pid} on host"):
            DatasetLock(folder).acquire()
    finally:
        proc.kill()
        proc.wait()
    # the holder was killed -9: its lock file is still there, but the OS lock died with it
    holder = json.loads((folder / LOCK_FILE).read_text())
    assert holder["pid"] == proc.pid
    with DatasetLock(folder) as lock:
        assert lock.stale is not None and lock.stale["pid"] == proc.pid
        assert json.loads((folder / LOCK_FILE).read_text())["pid"] == os.getpid()
    assert not (folder / LOCK_FILE).exists()


def test_a_reader_lock_on_a_read_only_dataset_is_skipped_not_fatal(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        if os.access(ro, os.W_OK):  # root ignores permissions
            pytest.skip("running as root: cannot make a read-only folder")
        with DatasetLock(ro, "export", required=False):
            pass
        with pytest.raises(PermissionError):
            DatasetLock(ro, "generate").acquire()
    finally:
        ro.chmod(0o755)


_PARTS = st.sampled_from(["a", "b", "ds", "sequences", "..", "."])


@settings(max_examples=200, deadline=None)
@given(st.lists(_PARTS, min_size=0, max_size=5), st.lists(_PARTS, min_size=1, max_size=4))
def test_any_out_that_passes_is_disjoint_from_the_input_and_below_the_cwd(out_parts, in_parts):
    """Property over relative paths: whatever --out a user types, a passing check means the output
    neither is, contains nor lies inside the input, and is not the current folder or above it."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        cwd = Path(tmp) / "work" / "here"
        cwd.mkdir(parents=True)
        old = Path.cwd()
        os.chdir(cwd)
        try:
            out, inp = Path(*out_parts) if out_parts else Path("."), Path(*in_parts)
            try:
                check_output(out, inputs=[inp])
            except UserInputError:
                return
            o, i, c = out.resolve(), inp.resolve(), cwd.resolve()
            assert o != i and o not in i.parents and i not in o.parents
            assert o != c and o not in c.parents
        finally:
            os.chdir(old)
