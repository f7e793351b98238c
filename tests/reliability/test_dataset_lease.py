"""The dataset lock across hosts (simulator/files.py DatasetLock): the lease file ``.evids.lease`` with owner
host/pid and an expiry, renewed while the run lives. Two hosts are simulated by monkeypatching the host name
(and, for a host that died, a separate process whose flock cannot reach this host: shared storage often does
not carry flock between hosts, which is why the lease exists)."""
from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from scenes.errors import UserInputError
from simulator.files import LEASE_FILE, LOCK_FILE, DatasetLock, hash_tree, is_evids_output

ROOT = Path(__file__).resolve().parents[2]


def _as_host(monkeypatch, name: str) -> None:
    monkeypatch.setattr(socket, "gethostname", lambda: name)


def _lease(folder: Path) -> dict:
    """The lease record (read again if caught half-way through an in-place renewal)."""
    for _ in range(50):
        try:
            return json.loads((folder / LEASE_FILE).read_text())
        except ValueError:
            time.sleep(0.01)
    raise AssertionError("the lease file stayed unreadable")


def test_a_live_lease_of_another_host_refuses_and_names_it(tmp_path, monkeypatch):
    folder = tmp_path / "ds"
    _as_host(monkeypatch, "host-a")
    with DatasetLock(folder, "generate") as held:
        lease = _lease(folder)
        assert lease["host"] == "host-a" and lease["pid"] == os.getpid() and lease["expires_unix"] > time.time()
        _as_host(monkeypatch, "host-b")
        with pytest.raises(UserInputError, match=r"pid \d+ on host host-a, generate; its lease \.evids\.lease "
                                                 r"expires in \d+ s"):
            DatasetLock(folder, "export").acquire()
        assert _lease(folder)["run_id"] == held._lease["run_id"]  # the refused run left the lease alone
    assert not (folder / LEASE_FILE).exists() and not (folder / LOCK_FILE).exists()


def test_an_expired_lease_of_another_host_is_taken_over(tmp_path, monkeypatch):
    folder = tmp_path / "ds"
    folder.mkdir()
    dead = {"host": "host-b", "pid": os.getpid(), "run_id": "r1-deadbeef-000000", "purpose": "generate",
            "expires_unix": time.time() - 1.0}
    (folder / LEASE_FILE).write_text(json.dumps(dead))
    _as_host(monkeypatch, "host-a")
    with DatasetLock(folder, "generate") as lock:
        assert lock.stale is not None and lock.stale["host"] == "host-b" and "expired" in lock.stale["note"]
        assert _lease(folder)["host"] == "host-a"
    # the same lease not yet expired refuses, though its pid (ours) is alive only on "host-b"
    (folder / LEASE_FILE).write_text(json.dumps({**dead, "expires_unix": time.time() + 30}))
    with pytest.raises(UserInputError, match="on host host-b"):
        DatasetLock(folder).acquire()


def test_a_dead_pid_on_this_host_frees_its_lease_at_once(tmp_path, monkeypatch):
    folder = tmp_path / "ds"
    folder.mkdir()
    proc = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead_pid = int(proc.stdout)
    (folder / LEASE_FILE).write_text(json.dumps({"host": socket.gethostname(), "pid": dead_pid, "run_id": "x",
                                                 "expires_unix": time.time() + 600}))
    with DatasetLock(folder) as lock:
        assert lock.stale is not None and lock.stale["pid"] == dead_pid


def test_the_lease_is_renewed_while_held_and_a_lost_lease_is_left_to_its_new_owner(tmp_path):
    folder = tmp_path / "ds"
    lock = DatasetLock(folder, lease_s=0.6).acquire()
    try:
        first = _lease(folder)["expires_unix"]
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and _lease(folder)["expires_unix"] <= first:
            time.sleep(0.05)
        assert _lease(folder)["expires_unix"] > first  # the renewal thread pushed it forward
        assert time.time() < _lease(folder)["expires_unix"]
        # another run took the lease over (this one stalled past its expiry): renewal stops, release leaves it
        (folder / LEASE_FILE).write_text(json.dumps({"host": "host-b", "pid": 1, "run_id": "other",
                                                     "expires_unix": time.time() + 60}))
        assert lock.renew() is False and lock.lost
    finally:
        lock.release()
    assert _lease(folder)["run_id"] == "other"


def test_release_waits_for_a_renewal_caught_half_way(tmp_path, monkeypatch):
    """A renewal between its truncate and its write when the run releases must not leave a lease behind
    (seen in CI under load: the next run found an empty, fresh lease and refused the folder)."""
    import threading

    folder = tmp_path / "ds"
    in_renewal = threading.Event()

    def slow_renew(self):                       # DatasetLock.renew's in-place rewrite, slowed down
        self._lease = {**self._lease, "expires_unix": round(time.time() + self.lease_s, 3)}
        with open(self.lease_path, "r+") as f:
            f.truncate(0)
            f.flush()
            in_renewal.set()
            time.sleep(0.5)                     # the release arrives while the lease is empty
            f.write(json.dumps(self._lease, sort_keys=True) + "\n")
        return True

    monkeypatch.setattr(DatasetLock, "renew", slow_renew)
    lock = DatasetLock(folder, lease_s=0.3).acquire()
    assert in_renewal.wait(10)
    lock.release()
    assert not (folder / LEASE_FILE).exists()
    DatasetLock(folder, lease_s=0.3).acquire().release()   # the next run gets the folder


def test_the_lease_is_bookkeeping_not_content(tmp_path):
    folder = tmp_path / "ds"
    with DatasetLock(folder):
        (folder / "a.txt").write_text("x")
        assert set(hash_tree(folder)) == {"a.txt"}
    (folder / "a.txt").unlink()
    (folder / LEASE_FILE).write_text("{}")
    assert is_evids_output(folder)


_OTHER_HOST = textwrap.dedent("""
    import fcntl, socket, sys, time
    sys.path.insert(0, {root!r})
    socket.gethostname = lambda: "host-b"
    fcntl.flock = lambda fd, op: None  # shared storage that does not carry flock between hosts
    from simulator.files import DatasetLock
    DatasetLock(sys.argv[1], "generate", lease_s=float(sys.argv[2])).acquire()
    print("locked", flush=True)
    time.sleep(120)
""")


def test_a_host_that_dies_holding_the_lease_blocks_until_the_lease_expires(tmp_path):
    """Host B (another process, its flock invisible here) takes the lease and is killed -9: this host cannot
    see B's pid, so it must refuse until B's last renewal expires, then take over."""
    folder = tmp_path / "ds"
    lease_s = 3.0
    proc = subprocess.Popen([sys.executable, "-c", _OTHER_HOST.format(root=str(ROOT)), str(folder), str(lease_s)],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "locked"
    finally:
        proc.kill()
        proc.wait()
    killed_at = time.time()
    expires = _lease(folder)["expires_unix"]
    assert _lease(folder)["host"] == "host-b" and expires > killed_at
    with pytest.raises(UserInputError, match="on host host-b"):
        DatasetLock(folder).acquire()
    while time.time() <= expires + 0.05:
        time.sleep(0.1)
    with DatasetLock(folder) as lock:
        assert lock.stale is not None and lock.stale["host"] == "host-b"
        assert _lease(folder)["host"] == socket.gethostname()
