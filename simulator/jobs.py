"""The one executor: run ``fn(*call)`` for every call, in-process or on a pool of processes (or Ray).

Every place that fans work out over processes (dataset generation, TRIDENT clip sets, the E2
training and evaluation jobs, the detection experiment) goes through :func:`run_jobs` (results in
call order) or :func:`iter_jobs` (results as they finish), so that one module owns:

- the start method: ``inline`` (in this process), ``fork`` (workers inherit this process's
  memory, so large inputs are never pickled), ``forkserver`` / ``spawn`` (fresh interpreters:
  safe after threads have started), ``ray`` (a local or remote Ray cluster);
- die-with-driver: pool workers are killed when the driver dies, even by SIGKILL
  (:func:`die_with_driver`), so no orphan keeps writing files or holding memory; so are the
  processes of a local Ray instance the driver started (:func:`reap_when_gone`) and Ray tasks on
  the driver's host (:func:`_ray_call`);
- interrupts and failures: Ctrl-C (or any error in the driver) terminates the workers at once and
  starts none of the queued calls; ``on_error="raise"`` stops at the first failed call,
  ``on_error="collect"`` returns a :class:`JobError` in that call's place and goes on;
- threads per worker (:func:`threads_per_worker`: the cores shared out, at least one each);
- the one context slot (:func:`job_context`): an object the caller hands to ``context=`` and every
  call reads back; with ``fork`` it is inherited (never pickled), with ``spawn``/``forkserver``
  it is pickled once per worker, inline it is simply set; cleared when the run ends.

The results never depend on the start method or the worker count: each call must depend only on
its own arguments and the context.
"""
from __future__ import annotations

import os
import socket
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable, Generator, Iterable, Iterator, Literal, Sequence

from simulator.files import pid_running

Start = Literal["inline", "fork", "forkserver", "spawn", "ray"]
START_METHODS: tuple[str, ...] = ("inline", "fork", "forkserver", "spawn", "ray")
PR_SET_PDEATHSIG = 1

_CONTEXT: list[Any] = []  # the one context slot: empty, or [the context object] while a run is on


@dataclass(frozen=True)
class JobError:
    """In ``on_error="collect"`` mode, the result of a call that failed: ``died`` when its worker
    process died (killed, out of memory) rather than the call raising."""

    index: int
    error: BaseException
    died: bool = False

    @property
    def message(self) -> str:
        return f"{type(self.error).__name__}: {self.error}"


def job_context() -> Any:
    """The object passed as ``context=`` to the running :func:`run_jobs` (in a worker or inline)."""
    if not _CONTEXT:
        raise RuntimeError("job_context() called outside run_jobs (no context was given)")
    return _CONTEXT[0]


def threads_per_worker(workers: int) -> int:
    """This machine's cores shared out over ``workers`` processes (at least one thread each)."""
    return max(1, (os.cpu_count() or 1) // max(1, workers))


def die_with_driver(driver_pid: int) -> None:
    """Make this (worker) process die with its driver. On Linux the kernel sends SIGKILL when the
    parent (the driver, or the forkserver, which exits when the driver does) dies
    (prctl PR_SET_PDEATHSIG); everywhere a daemon thread also polls the driver's pid once a
    second. So a kill -9 of the driver never leaves workers publishing files or holding memory."""
    import signal

    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the watchdog below still applies
        pass

    def driver_alive() -> bool:
        try:
            os.kill(driver_pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        return True

    if not driver_alive():  # the driver died before prctl took effect
        os._exit(1)

    def watchdog() -> None:
        while driver_alive():
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watchdog, name="evids-driver-watchdog", daemon=True).start()


def _worker_init(driver_pid: int, send_context: bool, context: Any, initializer: Callable | None,
                 initargs: tuple) -> None:
    die_with_driver(driver_pid)
    if send_context:
        _CONTEXT[:] = [context]
    if initializer is not None:
        initializer(*initargs)


def terminate_pool(pool: Any) -> None:
    """Stop a ProcessPoolExecutor's workers now and drop its queued jobs (no public terminate
    before Python 3.14)."""
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        proc.terminate()
    pool.shutdown(wait=False, cancel_futures=True)


def _progress_bar(label: str, total: int):
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    bar = Progress(TextColumn(label), BarColumn(), MofNCompleteColumn(), TextColumn("elapsed"), TimeElapsedColumn(),
                   TextColumn("eta"), TimeRemainingColumn())
    task = bar.add_task("jobs", total=total)
    bar.start()
    return bar, task


def iter_jobs(fn: Callable, calls: Iterable[Sequence[Any]], *, workers: int = 1, start: Start = "inline",
              context: Any = None, progress: str | Callable[[int, Any], None] | None = None,
              on_error: Literal["collect", "raise"] = "raise", initializer: Callable | None = None,
              initargs: tuple = (), ray_address: str | None = None) -> Iterator[tuple[int, Any]]:
    """Yield ``(i, fn(*calls[i]))`` for every call as it finishes (completion order).

    ``workers``: pool size (at most one process per call). ``progress``: a label (a progress bar on
    the terminal) or a function called with ``(i, result)`` as each call finishes. ``initializer``
    runs once in each pool worker (not inline, not on Ray), after die-with-driver and the context
    are set up. ``ray_address``: the Ray cluster for ``start="ray"`` (default: a local one with
    ``workers`` CPUs, started and shut down here)."""
    calls_: list[tuple] = [tuple(c) for c in calls]
    if start not in START_METHODS:
        raise ValueError(f"start must be one of {START_METHODS}, got {start!r}")
    if on_error not in ("collect", "raise"):
        raise ValueError(f"on_error must be 'collect' or 'raise', got {on_error!r}")
    bar = task = None
    if isinstance(progress, str) and calls_:
        bar, task = _progress_bar(progress, len(calls_))
    previous = list(_CONTEXT)
    _CONTEXT[:] = [context] if context is not None else []
    gen: Generator[tuple[int, Any], None, None] | None = None
    try:
        if start == "inline":
            gen = _inline(fn, calls_, on_error)
        elif start == "ray":
            gen = _ray(fn, calls_, workers, on_error, ray_address)
        else:
            gen = _pool(fn, calls_, workers, start, on_error, context, initializer, initargs)
        for i, result in gen:
            if bar is not None:
                bar.advance(task)
            elif callable(progress):
                progress(i, result)
            yield i, result
    finally:
        if gen is not None:
            gen.close()  # a consumer that stopped early: terminate the pool now, not at garbage collection
        _CONTEXT[:] = previous
        if bar is not None:
            bar.stop()


def run_jobs(fn: Callable, calls: Iterable[Sequence[Any]], **kwargs: Any) -> list[Any]:
    """``[fn(*call) for call in calls]`` on the chosen executor (see :func:`iter_jobs` for the
    options); results in call order whatever order they finished in."""
    calls_ = [tuple(c) for c in calls]
    out: list[Any] = [None] * len(calls_)
    for i, result in iter_jobs(fn, calls_, **kwargs):
        out[i] = result
    return out


def _inline(fn: Callable, calls: list[tuple], on_error: str) -> Generator[tuple[int, Any], None, None]:
    for i, call in enumerate(calls):
        if on_error == "raise":
            result = fn(*call)
        else:
            try:
                result = fn(*call)
            except Exception as exc:  # collected: the caller reports it with the other results
                result = JobError(i, exc)
        yield i, result


def _pool(fn: Callable, calls: list[tuple], workers: int, start: str, on_error: str, context: Any,
          initializer: Callable | None, initargs: tuple) -> Generator[tuple[int, Any], None, None]:
    if not calls:
        return
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    if start == "forkserver" and "forkserver" not in mp.get_all_start_methods():
        start = "spawn"
    send_context = start != "fork" and context is not None  # fork: inherited, never pickled
    pool = ProcessPoolExecutor(max_workers=max(1, min(workers, len(calls))), mp_context=mp.get_context(start),
                               initializer=_worker_init,
                               initargs=(os.getpid(), send_context, context if send_context else None,
                                         initializer, tuple(initargs)))
    try:
        futures = {pool.submit(fn, *call): i for i, call in enumerate(calls)}
        for future in as_completed(futures):
            i = futures[future]
            try:
                result = future.result()
            except BrokenProcessPool as exc:
                if on_error == "raise":
                    raise
                result = JobError(i, exc, died=True)
            except Exception as exc:
                if on_error == "raise":
                    raise
                result = JobError(i, exc)
            yield i, result
    except BaseException:
        # Ctrl-C, a failed call with on_error="raise", or the consumer stopped early: stop the
        # workers now and start none of the queued calls
        terminate_pool(pool)
        raise
    pool.shutdown(wait=True)


def _ray(fn: Callable, calls: list[tuple], workers: int, on_error: str,
         address: str | None) -> Generator[tuple[int, Any], None, None]:
    try:
        import ray
    except ImportError:
        from scenes.errors import UserInputError

        raise UserInputError("--executor ray needs Ray: pip install 'evids[ray]'") from None
    started = False
    reaper = None
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        if address:
            kwargs["address"] = address
        else:
            kwargs["num_cpus"] = max(1, workers)
            reaper = start_reaper()  # before ray.init: every process Ray starts here is new to it
        ray.init(**kwargs)
        started = True
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(_ray_call)
        driver = (socket.gethostname(), os.getpid())
        pending = {remote.remote(driver, fn, *call): i for i, call in enumerate(calls)}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                i = pending.pop(ref)
                try:
                    result = ray.get(ref)
                except Exception as exc:  # a crashed Ray worker fails only its own call
                    if on_error == "raise":
                        raise
                    result = JobError(i, exc)
                yield i, result
    finally:
        if started:
            ray.shutdown()
        if reaper is not None:
            reaper.kill()
            reaper.wait()


_RAY_WATCHED: list[int] = []  # the driver pid this Ray worker already watches (a worker serves one job)


def _ray_call(driver: tuple[str, int], fn: Callable, *args: Any) -> Any:
    """One call on a Ray worker. On the driver's host the worker also watches the driver's pid (Ray
    ends a dead driver's workers itself, through its cluster's job table, within seconds; this makes
    it one second wherever the driver's pid is visible)."""
    host, pid = driver
    if host == socket.gethostname() and pid not in _RAY_WATCHED and pid_running(pid):
        _RAY_WATCHED.append(pid)

        def watchdog() -> None:
            while pid_running(pid):
                time.sleep(1.0)
            os._exit(1)

        threading.Thread(target=watchdog, name="evids-driver-watchdog", daemon=True).start()
    return fn(*args)


def _process_table() -> dict[int, tuple[int, str]]:
    """pid -> (parent pid, start time in clock ticks) of every process, from /proc (Linux)."""
    table = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    fields = f.read().rpartition(")")[2].split()
            except OSError:
                continue
            table[int(entry)] = (int(fields[1]), fields[19])
    return table


def descendants(pid: int, table: dict[int, tuple[int, str]] | None = None) -> dict[int, str]:
    """pid -> start time of every descendant of ``pid`` (Linux /proc; empty elsewhere)."""
    table = _process_table() if table is None else table
    children: dict[int, list[int]] = {}
    for child, (parent, _) in table.items():
        children.setdefault(parent, []).append(child)
    out: dict[int, str] = {}
    stack = [pid]
    while stack:
        for child in children.get(stack.pop(), []):
            if child not in out:
                out[child] = table[child][1]
                stack.append(child)
    return out


def reap_when_gone(driver_pid: int, interval_s: float = 0.25, ready=None) -> None:
    """Run in a small watcher process: snapshot the driver's descendants (those started after this
    watcher) every ``interval_s``; when the driver dies, SIGKILL every one of the last snapshot still
    running under the same start time. Ray's own processes (GCS, raylet, agents, workers) fate-share
    with a driver that started them, but its agents take up to a minute to notice.

    A snapshot counts only if the driver still runs after it was taken: a dead driver's children are
    handed to init at once, so a snapshot taken while it dies misses them (under load this left Ray's
    agents running). ``ready`` (a writable file) gets one line once the baseline is taken, so the
    caller can start Ray only after it."""
    import signal

    me = os.getpid()
    before = set(descendants(driver_pid))
    if ready is not None:
        ready.write("ready\n")
        ready.flush()
    tree: dict[int, str] = {}
    while True:
        snapshot = {p: t for p, t in descendants(driver_pid).items() if p != me and p not in before}
        if not pid_running(driver_pid):
            break
        tree = snapshot
        time.sleep(interval_s)
    table = _process_table()
    for pid, started in tree.items():
        if table.get(pid, (0, ""))[1] == started:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


def start_reaper() -> Any:
    """Start :func:`reap_when_gone` for this process in a watcher process (Linux; None elsewhere)."""
    import subprocess
    import sys

    if not os.path.isdir("/proc"):
        return None
    code = f"import sys; from simulator.jobs import reap_when_gone; reap_when_gone({os.getpid()}, ready=sys.stdout)"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    reaper = subprocess.Popen([sys.executable, "-c", code], env=env, stdin=subprocess.DEVNULL,
                              stdout=subprocess.PIPE, start_new_session=True)
    if reaper.stdout is not None:
        reaper.stdout.readline()  # its baseline is taken: every process started from here on is new to it
        reaper.stdout.close()
    return reaper
