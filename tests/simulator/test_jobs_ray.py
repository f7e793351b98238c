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


# --------------------------------------------------------------------------------------------
# A real two-node Ray cluster on this host: two raylets, each with its own temp dir and resources
# --------------------------------------------------------------------------------------------

#: Ray maps 127.0.0.1 to the host's outward address for multi-node use (services.resolve_ip_for_localhost);
#: the test keeps every connection on loopback by turning that off in the CLI and the driver (a real cluster
#: uses the hosts' own addresses and needs none of this)
LOOPBACK = ("import ray._private.services as s; s.resolve_ip_for_localhost = lambda h: h; "
            "s.get_node_ip_address = lambda address=None: '127.0.0.1'")
RAY_CLI = LOOPBACK + "; import sys; from ray.scripts.scripts import main; sys.argv[0] = 'ray'; main()"

CLUSTER_DRIVER = textwrap.dedent("""
    import sys
    {loopback}
    from simulator.dataset.generate import generate_dataset
    generate_dataset(sys.argv[1], sys.argv[2], 5, workers=2, executor="ray", ray_address=sys.argv[3],
                     progress=False)
""")


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _kill_node(temp_dir: str) -> list[int]:
    """SIGKILL every process of the Ray node whose temp dir is ``temp_dir`` (its command line names it)
    and all their descendants. Never `ray stop`, which stops every Ray node on the host."""
    import signal

    table = _table()
    roots = [p for p, (_, _, cmd) in table.items() if temp_dir in cmd and p != os.getpid()]
    victims = set(roots)
    for root in roots:
        victims |= set(_tree(root))
    for pid in victims:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return sorted(victims)


def _ray_start(env: dict, *args: str) -> None:
    subprocess.run([sys.executable, "-c", RAY_CLI, "start", "--node-ip-address", "127.0.0.1", "--num-cpus", "1",
                    "--disable-usage-stats", *args], env=env, check=True, timeout=240, capture_output=True)


@pytest.fixture
def two_nodes(tmp_path):
    """A head node A and a second node B joined to it, each 1 CPU with its own temp dir and resource;
    yields (address, env, node B's temp dir); every process of both is killed afterwards."""
    import tempfile

    dirs = [tempfile.mkdtemp(prefix="evr", dir="/tmp") for _ in range(2)]  # short: raylet socket paths <= 107
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p), "RAY_USAGE_STATS_ENABLED": "0",
           "RAY_AUTH_MODE": "disabled", "RAY_health_check_period_ms": "1000", "RAY_health_check_failure_threshold": "3"}
    port = _free_port()
    try:
        _ray_start(env, "--head", "--port", str(port), "--include-dashboard", "false", "--temp-dir", dirs[0],
                   "--resources", '{"evids_node_a": 1}')
        _ray_start(env, "--address", f"127.0.0.1:{port}", "--temp-dir", dirs[1], "--resources", '{"evids_node_b": 1}')
        yield f"127.0.0.1:{port}", env, dirs[1]
    finally:
        import shutil

        for d in dirs:
            _kill_node(d)
            shutil.rmtree(d, ignore_errors=True)


def test_a_two_node_cluster_survives_a_killed_node_and_resumes_to_the_local_bytes(tmp_path, two_nodes):
    """generate on two real raylets; node B is killed -9 while it renders a sequence; the run fails only
    that work, a rerun on the surviving node finishes it, and the dataset equals a local run byte for byte."""
    from simulator.dataset.generate import generate_dataset, load_manifest
    from simulator.jobs import descendants
    from tests.simulator.dataset.gen_helpers import tree_digest, write_tiny

    address, env, node_b = two_nodes
    config = write_tiny(tmp_path, sequences=4, frames=2)
    t0 = time.monotonic()
    reference = tmp_path / "local"
    generate_dataset(config, reference, 5, progress=False)
    print(f"local reference: {time.monotonic() - t0:.0f} s")  # phase times: shown with -s
    out = tmp_path / "cluster"
    cmd = [sys.executable, "-c", CLUSTER_DRIVER.format(loopback=LOOPBACK), str(config), str(out), address]
    first = subprocess.Popen(cmd, env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        b_raylet = next(p for p, (_, _, c) in _table().items() if "raylet/raylet" in c and node_b in c)
        on_b: int | None = None
        deadline = time.monotonic() + 240
        while on_b is None and time.monotonic() < deadline and first.poll() is None:
            b_procs = descendants(b_raylet)
            seqs = out / "sequences"
            for tmp in (seqs.iterdir() if seqs.is_dir() else []):
                if tmp.name.startswith(".tmp-seq"):
                    pid = int(tmp.name.rsplit("-r", 1)[1].split("-")[0])
                    if pid in b_procs:
                        on_b = pid
            time.sleep(0.05)
        assert on_b is not None, "no sequence was seen rendering on node B before the run ended"
        print(f"node B seen rendering: {time.monotonic() - t0:.0f} s")
        killed = _kill_node(node_b)
        assert b_raylet in killed and on_b in killed
        log, _ = first.communicate(timeout=300)
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
    print(f"first run failed: {time.monotonic() - t0:.0f} s")
    assert first.returncode != 0 and "GenerationFailed" in log, log[-2000:]
    manifest = load_manifest(out)
    assert not manifest["complete"]
    done = [p.name for p in (out / "sequences").iterdir() if not p.name.startswith(".")]
    assert len(done) < 4
    resumed = subprocess.run(cmd, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=600)
    print(f"resumed: {time.monotonic() - t0:.0f} s")
    assert resumed.returncode == 0, resumed.stdout[-2000:] + resumed.stderr[-2000:]
    assert load_manifest(out)["complete"]
    assert tree_digest(out) == tree_digest(reference)
