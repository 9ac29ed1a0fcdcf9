"""Spreading tasks over worker processes or a Dask cluster, as the profile builder does.

`spread(function, tasks, ...)` gives `function(task)` for every task, in the order the tasks
finish: in this process (one worker, no executor), on a pool of local processes, or on any
`concurrent.futures.Executor` (a Dask cluster's: `anytime.measure.builder.dask_executor`).
The workers ignore Ctrl-C (the terminal sends it to them too): the caller stops them, cancels
what has not started and re-raises, so no worker outlives an interrupted command. A worker also
dies with the thread that started it (Linux: `PR_SET_PDEATHSIG`), so that a caller killed
outright (`kill -9`) leaves no worker behind.

Local workers are forks of the caller. `initializer(*initargs)` runs in each when it starts,
and with the fork start method its arguments reach it without being pickled: a caller can hand
every worker something large, or something that does not pickle, once, and send only small
tasks (`anytime.verification` hands its workers the compiled program so). Tasks and results
are pickled; on a Dask cluster the tasks must carry everything themselves.

The profile builder spreads its chunks of trials with it, `anytime verify` its runs.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from anytime.errors import AnytimeError
from anytime.isolation import die_with_parent

__all__ = ["WorkerDied", "spread"]


class WorkerDied(AnytimeError):
    """A local worker process died while it ran a task (a task that ends its process takes its
    worker with it): the pool is broken, and the tasks that had not come back are lost."""


T = TypeVar("T")
R = TypeVar("R")


def _worker_starts(parent: int, initializer: Callable[..., None] | None, *initargs: Any) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # a forked worker must die of the parent's stop
    die_with_parent(parent)  # and of its parent's death: a `kill -9` of it must not orphan it
    if initializer is not None:
        initializer(*initargs)


def _context() -> Any:
    """Fork where there is fork (initializer arguments are then inherited, not pickled)."""
    if "fork" in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("fork")
    return multiprocessing.get_context()


def spread(
    function: Callable[[T], R],
    tasks: Sequence[T],
    *,
    executor: Executor | None = None,
    workers: int = 1,
    initializer: Callable[..., None] | None = None,
    initargs: tuple[Any, ...] = (),
) -> Iterator[R]:
    """`function(task)` for each of `tasks`, as they finish (in any order).

    Args:
        function: what to run; it must pickle (a top-level function) unless it runs here.
        tasks: its arguments, one per call; pickled to reach a worker.
        executor: where to run them (left running); None: here, or a local pool.
        workers: without an executor, this many local processes (1: run here, in order).
        initializer: run with `initargs` in each local worker as it starts (and here, once,
            when the tasks run here); not run on an executor's workers.
    """
    if executor is None and workers == 1:
        if initializer is not None:
            initializer(*initargs)
        for task in tasks:
            yield function(task)
        return
    own: ProcessPoolExecutor | None = None
    pool: Executor
    if executor is None:
        pool = own = ProcessPoolExecutor(
            workers,
            mp_context=_context(),
            initializer=_worker_starts,
            initargs=(os.getpid(), initializer, *initargs),
        )
    else:
        pool = executor
    futures: list[Future[R]] = []
    try:
        futures = [pool.submit(function, task) for task in tasks]
        for future in as_completed(futures):
            yield future.result()
    except BrokenProcessPool:  # a user's failure (a task's crash), not a bug: one line
        raise WorkerDied(
            "a worker process died: a task ended the process it ran in; the tasks that had not"
            " finished are lost"
        ) from None
    except (KeyboardInterrupt, GeneratorExit):
        if own is not None:  # stop the running tasks now rather than wait for them
            processes = list((own._processes or {}).values())
            own.shutdown(wait=False, cancel_futures=True)
            for process in processes:
                process.terminate()
        raise
    finally:
        # After an error, drop what has not started. Our own pool cancels its queued tasks
        # itself: a future cancelled from outside while the pool breaks (its workers ended
        # above) makes the pool's manager thread fail (InvalidStateError, Python 3.11).
        if own is not None:
            own.shutdown(wait=True, cancel_futures=True)
        else:
            for future in futures:
                future.cancel()
