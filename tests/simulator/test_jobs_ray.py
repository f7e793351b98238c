"""simulator/jobs.py on Ray: a driver killed by SIGKILL leaves no Ray process of its run (GCS, raylet,
agents, workers) running. Needs the ``ray`` extra (skipped without it) and Linux /proc."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

pytest.importorskip("ray", reason="Ray is an optional extra (pip install 'evids[ray]')")
pytestmark = pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads the process table from /proc (Linux)")


def _table() -> dict[int, tuple[int, str, str]]:
    """pid -> (parent pid, state, command line) of every process."""
    out = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text().rpartition(")")[2].split()
            cmd = Path(f"/proc/{entry}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        out[int(entry)] = (int(stat[1]), stat[0], cmd)
    return out


def _tree(root: int) -> dict[int, str]:
    """pid -> command line of every live descendant of ``root``."""
    table = _table()
    out: dict[int, str] = {}
    stack = [root]
    while stack:
        parent = stack.pop()
        for pid, (ppid, _, cmd) in table.items():
            if ppid == parent and pid not in out:
                out[pid] = cmd
                stack.append(pid)
    return out


def running(pids) -> list[int]:
    """The pids still running (gone and zombie processes do not count)."""
    table = _table()
    return [p for p in pids if p in table and table[p][1] != "Z"]


DRIVER = textwrap.dedent("""
    import os, sys, time
    from simulator.jobs import run_jobs

    def slow(path):
        with open(path, "w") as f:
            f.write(str(os.getpid()))
        time.sleep(300)

    run_jobs(slow, [(sys.argv[1],)], start="ray", workers=1)
""")


def test_killing_the_driver_ends_every_ray_process_of_its_run(tmp_path):
    pid_file = tmp_path / "worker.pid"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p), "RAY_USAGE_STATS_ENABLED": "0"}
    driver = subprocess.Popen([sys.executable, "-c", DRIVER, str(pid_file)], env=env, cwd=tmp_path,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline and not (pid_file.is_file() and pid_file.read_text()):
            assert driver.poll() is None, "the driver ended before its Ray task started"
            time.sleep(0.2)
        worker = int(pid_file.read_text())
        ray_procs = {p: c for p, c in _tree(driver.pid).items() if "ray" in c}
        assert worker in ray_procs
        assert any("raylet" in c for c in ray_procs.values()) and any("gcs_server" in c for c in ray_procs.values())
        driver.kill()
        driver.wait()
        t0 = time.monotonic()
        while time.monotonic() - t0 < 30 and running(ray_procs):
            time.sleep(0.2)
        left = {p: ray_procs[p][:80] for p in running(ray_procs)}
        assert not left, f"Ray processes outlived their driver: {left}"
        assert time.monotonic() - t0 < 15
    finally:
        if driver.poll() is None:
            driver.kill()
            driver.wait()
