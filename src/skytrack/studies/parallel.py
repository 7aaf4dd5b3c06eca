"""Parallel sweeps (issue 11 item 6): map pure tasks over any ``concurrent.futures`` executor.

A study's Monte Carlo work is cut into pure tasks (a configuration and its ``SeedSequence``
children in, a result out; no callbacks, no shared lists), and :func:`map_tasks` maps a
module-level function over them on whatever executor it is given:

* ``None``: in this process, one task after the other (no pickling, the reference);
* a local :class:`~concurrent.futures.ProcessPoolExecutor` (``spawn`` start method: numba's
  and rich's threads do not survive a ``fork``);
* a Dask cluster through ``distributed.Client(address).get_executor()`` (the optional extra
  ``skytrack[dask]``).

:func:`make_executor` turns the CLI's ``--workers N`` / ``--scheduler ADDRESS`` into one of them.
Results come back in task order whatever the order of completion, and the cut into tasks is
fixed by the study (runs per batch, cells), never by the number of workers, so a seed gives
bit-identical numbers on every executor.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing
import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any, TypeVar

Task = TypeVar("Task")
Result = TypeVar("Result")

#: seconds to wait for a Dask scheduler before giving up with a clear error
SCHEDULER_TIMEOUT_S = 10.0
#: runs per task where a study batches runs in one numpy call: fixed, so results do not depend on workers
RUNS_PER_TASK = 64


class ExecutorError(RuntimeError):
    """The requested executor cannot be set up (Dask missing, scheduler unreachable, bad worker count)."""


def map_tasks(function: Callable[[Task], Result], tasks: Iterable[Task], executor: cf.Executor | None = None,
              progress: Callable[[int, int], None] | None = None) -> list[Result]:
    """``[function(task) for task in tasks]``, computed on ``executor`` (``None``: here, in order).

    ``progress(done, total)`` is called once before the first task and after every task completes
    (in completion order); the results are returned in task order.  ``function`` and the tasks
    must pickle for a process pool or Dask (module-level functions, plain data).  The first
    task that raises cancels the tasks not yet started and its exception propagates.
    """
    tasks = list(tasks)
    total = len(tasks)
    if progress is not None:
        progress(0, total)
    if executor is None:
        results = []
        for task in tasks:
            results.append(function(task))
            if progress is not None:
                progress(len(results), total)
        return results
    futures = {executor.submit(function, task): index for index, task in enumerate(tasks)}
    results: list[Any] = [None] * total
    done = 0
    try:
        for future in cf.as_completed(futures):
            results[futures[future]] = future.result()
            done += 1
            if progress is not None:
                progress(done, total)
    except BaseException:
        for future in futures:
            future.cancel()
        raise
    return results


def batches(count: int, size: int = RUNS_PER_TASK) -> list[range]:
    """``range(count)`` cut into consecutive ranges of ``size`` (the last may be shorter)."""
    if count < 0 or size < 1:
        raise ValueError(f"need count >= 0 and size >= 1, got count={count}, size={size}")
    return [range(start, min(start + size, count)) for start in range(0, count, size)]


#: environment variable that sets the default of ``--workers`` (the test suite sets it to 1: in process)
WORKERS_ENV = "SKYTRACK_WORKERS"


def default_workers() -> int:
    """Worker processes of the default pool: ``$SKYTRACK_WORKERS`` if set, else the CPUs this process may run on."""
    text = os.environ.get(WORKERS_ENV, "").strip()
    if text:
        try:
            value = int(text)
        except ValueError:
            raise ExecutorError(f"{WORKERS_ENV} must be a positive integer, got {text!r}") from None
        if value < 1:
            raise ExecutorError(f"{WORKERS_ENV} must be a positive integer, got {text!r}")
        return value
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


@contextlib.contextmanager
def make_executor(workers: int | None = None, scheduler: str | None = None,
                  timeout_s: float | None = None) -> Iterator[cf.Executor | None]:
    """The executor of ``--workers``/``--scheduler``, shut down on exit.

    ``scheduler`` (a Dask scheduler address such as ``tcp://127.0.0.1:8786``) wins over
    ``workers``; else ``workers == 1`` gives ``None`` (in-process) and any other count (``None``:
    :func:`default_workers`) a process pool of that many workers.  ``timeout_s`` (default
    :data:`SCHEDULER_TIMEOUT_S`) bounds the wait for the scheduler.
    """
    if scheduler:
        with _dask_executor(scheduler, SCHEDULER_TIMEOUT_S if timeout_s is None else timeout_s) as executor:
            yield executor
        return
    if workers is not None and workers < 1:
        raise ExecutorError(f"--workers must be at least 1, got {workers}")
    count = default_workers() if workers is None else int(workers)
    if count == 1:
        yield None
        return
    pool = cf.ProcessPoolExecutor(max_workers=count, mp_context=multiprocessing.get_context("spawn"))
    try:
        yield pool
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


@contextlib.contextmanager
def _dask_executor(scheduler: str, timeout_s: float) -> Iterator[cf.Executor]:
    try:
        from distributed import Client  # the optional extra: imported only when asked for
    except ImportError:
        raise ExecutorError(f"--scheduler {scheduler} needs Dask: install skytrack[dask] "
                            "(pip install 'skytrack[dask]')") from None
    try:
        client = Client(scheduler, timeout=f"{timeout_s}s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as error:
        raise ExecutorError(f"cannot reach the Dask scheduler at {scheduler} within {timeout_s:g} s: {error}") from None
    try:
        yield client.get_executor(pure=False)
    finally:
        client.close()


def describe_executor(workers: int | None, scheduler: str | None) -> str:
    """A short text for the CLI: where the tasks run."""
    if scheduler:
        return f"on the Dask scheduler {scheduler}"
    count = default_workers() if workers is None else workers
    return "in process" if count == 1 else f"on {count} worker processes"


def spawn_seeds(seed: int, count: int) -> Sequence:
    """``numpy.random.SeedSequence(seed).spawn(count)``: child i is task i's (or run i's) seed."""
    import numpy as np

    return np.random.SeedSequence(int(seed)).spawn(int(count))
