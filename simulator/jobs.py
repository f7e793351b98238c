"""The one executor: run ``fn(*call)`` for every call, in-process or on a pool of processes (or Ray).

Every place that fans work out over processes (dataset generation, TRIDENT clip sets, the E2
training and evaluation jobs, the detection experiment) goes through :func:`run_jobs` (results in
call order) or :func:`iter_jobs` (results as they finish), so that one module owns:

- the start method: ``inline`` (in this process), ``fork`` (workers inherit this process's
  memory, so large inputs are never pickled), ``forkserver`` / ``spawn`` (fresh interpreters:
  safe after threads have started), ``ray`` (a local or remote Ray cluster);
- die-with-driver: pool workers are killed when the driver dies, even by SIGKILL
  (:func:`die_with_driver`), so no orphan keeps writing files or holding memory;
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
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable, Generator, Iterable, Iterator, Literal, Sequence

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
    if not ray.is_initialized():
        kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        if address:
            kwargs["address"] = address
        else:
            kwargs["num_cpus"] = max(1, workers)
        ray.init(**kwargs)
        started = True
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(fn)
        pending = {remote.remote(*call): i for i, call in enumerate(calls)}
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
