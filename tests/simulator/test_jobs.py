"""simulator.jobs, the one executor: call order, collect vs raise, a worker that dies, the context
slot, die-with-driver, and the same results in-process and on a pool."""
from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from simulator import jobs
from simulator.jobs import JobError, iter_jobs, job_context, run_jobs, threads_per_worker


def _square_slowly(x: int) -> int:
    time.sleep(0.01 * (3 - x % 3))  # later calls often finish first
    return x * x


def _fail_on_three(x: int) -> int:
    if x == 3:
        raise ValueError("three")
    return x


def _die_on_two(x: int) -> int:
    if x == 2:
        os.kill(os.getpid(), signal.SIGKILL)
    return x


def _scaled(x: int) -> int:
    return x * job_context()["scale"]


def _pid(_: int) -> int:
    time.sleep(0.05)
    return os.getpid()


@pytest.mark.parametrize("start", ["inline", "fork", "spawn"])
def test_results_come_back_in_call_order_and_equal_inline(start):
    calls = [(x,) for x in range(7)]
    assert run_jobs(_square_slowly, calls, workers=2, start=start) == [x * x for x in range(7)]


def test_iter_jobs_yields_every_index_once_with_its_own_result():
    got = dict(iter_jobs(_square_slowly, [(x,) for x in range(6)], workers=2, start="fork"))
    assert got == {x: x * x for x in range(6)}


@pytest.mark.parametrize("start", ["inline", "fork"])
def test_collect_puts_the_error_in_the_failed_calls_place(start):
    out = run_jobs(_fail_on_three, [(x,) for x in range(5)], workers=2, start=start, on_error="collect")
    assert out[:3] == [0, 1, 2] and out[4] == 4
    assert isinstance(out[3], JobError) and out[3].index == 3 and not out[3].died
    assert out[3].message == "ValueError: three"


@pytest.mark.parametrize("start", ["inline", "fork"])
def test_raise_stops_at_the_failed_call(start):
    with pytest.raises(ValueError, match="three"):
        run_jobs(_fail_on_three, [(x,) for x in range(5)], workers=2, start=start, on_error="raise")


def test_a_worker_that_dies_is_reported_as_died_and_the_driver_survives():
    out = run_jobs(_die_on_two, [(x,) for x in range(4)], workers=2, start="fork", on_error="collect")
    assert isinstance(out[2], JobError) and out[2].died
    # the broken pool fails the calls still running with it; every call has a result or an error
    assert all(r == x or (isinstance(r, JobError) and r.died) for x, r in enumerate(out))


def test_a_worker_that_dies_raises_with_on_error_raise():
    from concurrent.futures.process import BrokenProcessPool

    with pytest.raises(BrokenProcessPool):
        run_jobs(_die_on_two, [(x,) for x in range(4)], workers=2, start="fork", on_error="raise")


@pytest.mark.parametrize("start", ["inline", "fork", "spawn"])
def test_the_context_reaches_every_call_and_is_cleared_afterwards(start):
    assert run_jobs(_scaled, [(x,) for x in range(4)], workers=2, start=start, context={"scale": 10}) == [0, 10, 20, 30]
    with pytest.raises(RuntimeError, match="outside run_jobs"):
        job_context()


def test_pool_calls_run_in_other_processes_and_inline_in_this_one():
    assert set(run_jobs(_pid, [(x,) for x in range(4)], start="inline")) == {os.getpid()}
    pids = set(run_jobs(_pid, [(x,) for x in range(4)], workers=2, start="fork"))
    assert os.getpid() not in pids and 1 <= len(pids) <= 2


def test_progress_callback_sees_every_result():
    seen = []
    run_jobs(_square_slowly, [(x,) for x in range(5)], workers=2, start="fork", progress=lambda i,
             r: seen.append((i, r)))
    assert sorted(seen) == [(x, x * x) for x in range(5)]


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match="start"):
        run_jobs(_pid, [(1,)], start="threads")
    with pytest.raises(ValueError, match="on_error"):
        run_jobs(_pid, [(1,)], on_error="ignore")


def test_threads_per_worker_shares_the_cores_out():
    cores = os.cpu_count() or 1
    assert threads_per_worker(1) == cores
    assert threads_per_worker(cores * 4) == 1


def test_killing_the_driver_kills_its_workers(tmp_path):
    """A driver killed by SIGKILL takes its pool workers along (prctl PDEATHSIG + watchdog)."""
    pid_file = tmp_path / "pids"
    script = textwrap.dedent(f"""
        import os, time
        from simulator.jobs import run_jobs

        def work(i):
            with open({str(pid_file)!r}, "a") as f:
                f.write(f"{{os.getpid()}}\\n")
            time.sleep(60)

        if __name__ == "__main__":
            run_jobs(work, [(0,), (1,)], workers=2, start="forkserver")
    """)
    (tmp_path / "driver.py").write_text(script)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    driver = subprocess.Popen([sys.executable, str(tmp_path / "driver.py")], env=env, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and (not pid_file.exists() or len(pid_file.read_text().split()) < 2):
            time.sleep(0.1)
        workers = [int(p) for p in pid_file.read_text().split()]
        assert len(workers) == 2
        driver.kill()
        driver.wait()

        def alive(pid: int) -> bool:  # running, not a zombie waiting to be reaped
            try:
                return open(f"/proc/{pid}/stat").read().split()[2] != "Z"
            except FileNotFoundError:
                return False

        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and any(alive(p) for p in workers):
            time.sleep(0.1)
        assert not any(alive(p) for p in workers)
    finally:
        if driver.poll() is None:
            driver.kill()


def test_the_reaper_keeps_the_last_snapshot_taken_while_the_driver_ran(monkeypatch):
    """A dead driver's children are handed to init at once, so a snapshot taken while it dies is empty:
    the reaper must kill the one before it (this race left Ray's agents running under load)."""
    state = {"alive": True, "calls": 0}
    tree = {10: "t10", 11: "t11"}

    def fake_descendants(pid, table=None):
        state["calls"] += 1
        if state["calls"] == 1:      # the baseline, before Ray started
            return {}
        if state["calls"] == 3:      # the driver dies while this snapshot is taken
            state["alive"] = False
            return {}
        return dict(tree)

    killed = []
    monkeypatch.setattr(jobs, "descendants", fake_descendants)
    monkeypatch.setattr(jobs, "pid_running", lambda pid: state["alive"])
    monkeypatch.setattr(jobs, "_process_table", lambda: {p: (1, t) for p, t in tree.items()})
    monkeypatch.setattr(jobs.os, "kill", lambda pid, sig: killed.append(pid))
    ready = io.StringIO()
    jobs.reap_when_gone(12345, interval_s=0.0, ready=ready)
    assert sorted(killed) == [10, 11]
    assert ready.getvalue() == "ready\n"
