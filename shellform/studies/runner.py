"""Where the independent tasks of a sweep or a study run, yielding each result as it finishes.

- ``workers=1`` (or a single task): one after the other in this process;
- ``workers=N``: on a pool of N processes started afresh (``spawn``: no
  state, lock or thread of this process is copied into a worker);
- ``scheduler=ADDRESS``: on a Dask cluster (the optional extra
  ``pip install shellform[sweep]``; Dask is imported only then).

A task is a module-level function and its arguments, so that a spawned
worker or a Dask worker finds it by name. The function should hand back a
result whatever happens in it; a worker that dies under it (killed, out of
memory) becomes the result ``died(why)``, ``why`` the exception's text. An interrupted run does not
start the tasks still queued.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

from ..errors import SceneError

#: a task: its key (handed back with its result) and the arguments of the function
Task = tuple[object, tuple]


@dataclass(frozen=True)
class Runner:
    """How tasks run: ``workers`` local processes, or a Dask ``scheduler`` address."""

    #: local processes; 1 runs the tasks in this process, one after the other
    workers: int = 2
    #: address of a Dask scheduler (``tcp://host:8786``); then ``workers`` is not used
    scheduler: str | None = None

    def __post_init__(self):
        if isinstance(self.workers, bool) or not isinstance(self.workers, int) or self.workers < 1:
            raise SceneError("--workers", f"the number of worker processes must be a whole number >= 1, "
                                          f"got {self.workers!r}")

    def where(self, n_tasks: int) -> str:
        """Where ``n_tasks`` tasks run, in words."""
        if self.scheduler:
            return f"on {self.scheduler}"
        if self.workers == 1 or n_tasks <= 1:
            return "in this process"
        return f"on {min(self.workers, n_tasks)} processes"

    def run(self, fn: Callable, tasks: Sequence[Task], died: Callable[[str], object]) -> Iterator[tuple]:
        """Run ``fn(*args)`` for every task; yields ``(key, result)`` as the tasks finish."""
        tasks = list(tasks)
        if not tasks:
            return iter(())
        if self.scheduler:
            return _on_dask(fn, tasks, self.scheduler, died)
        if self.workers == 1 or len(tasks) == 1:
            return _in_process(fn, tasks)
        return _on_pool(fn, tasks, min(self.workers, len(tasks)), died)


def _in_process(fn, tasks) -> Iterator[tuple]:
    for key, args in tasks:
        yield key, fn(*args)


def _on_pool(fn, tasks, workers: int, died) -> Iterator[tuple]:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))
    try:
        futures = {pool.submit(fn, *args): key for key, args in tasks}
        for fut in as_completed(futures):
            yield futures[fut], _result(fut, died)
    finally:
        # an interrupted run does not start the tasks still queued
        pool.shutdown(wait=True, cancel_futures=True)


def _on_dask(fn, tasks, scheduler: str, died) -> Iterator[tuple]:
    try:
        from dask.distributed import Client, as_completed
    except ImportError:
        raise SceneError("--scheduler", "a Dask scheduler needs Dask: pip install 'shellform[sweep]'") from None
    client = Client(scheduler)
    try:
        # pure=False: a task writes files, so two runs of the same task are two tasks, never one shared result
        futures = {client.submit(fn, *args, pure=False): key for key, args in tasks}
        for fut in as_completed(futures):
            yield futures[fut], _result(fut, died)
    finally:
        client.close()


def _result(future, died):
    """A future's result; a worker that died (killed, out of memory) makes ``died(why)``."""
    try:
        return future.result()
    except Exception as exc:  # noqa: BLE001 (the other tasks go on)
        return died(f"{type(exc).__name__}: {exc}")
