"""Where the independent tasks of a sweep or a study run, yielding each result as it finishes.

- ``workers=1`` (or a single task): one after the other in this process;
- ``workers=N``: on a pool of N local processes (how they start: below);
- ``scheduler=ADDRESS``: on a Dask cluster (the optional extra
  ``pip install shellform[sweep]``; Dask is imported only then).

How a local pool's processes start (:func:`start_method`):

- ``fork`` on Linux when this process runs no thread but its own and the
  idle thread pools of OpenBLAS (which OpenBLAS stops across a fork): the
  workers are copies of this process, with everything a task needs imported
  beforehand (:data:`PRELOAD`), so they run their first task as fast as
  their last;
- ``forkserver`` on Linux when other threads are live (a Dask client, an
  executor, a notebook kernel, the OpenMP pool gmsh starts): copying a
  process while another thread may hold a lock is not safe, so the workers
  are forked from a fresh single-purpose server process that imports
  :data:`PRELOAD` once;
- ``spawn`` elsewhere (macOS, Windows): fresh interpreters, each importing
  what it needs.

The environment variable ``SHELLFORM_START_METHOD`` (``fork``,
``forkserver``, ``spawn``) overrides the choice.

A task is a module-level function and its arguments, so that a worker or a
Dask worker finds it by name. The function should hand back a result
whatever happens in it; a worker that dies under it (killed, out of memory)
becomes the result ``died(why)``, ``why`` the exception's text. An
interrupted run does not start the tasks still queued.
"""

from __future__ import annotations

import importlib
import os
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

from ..errors import SceneError

#: a task: its key (handed back with its result) and the arguments of the function
Task = tuple[object, tuple]

#: what the tasks of sweeps and studies import: loaded once before a pool's workers start
#: (``fork``: in this process; ``forkserver``: in the server), so that no worker imports
#: them again. Matplotlib and h5py alone cost a fresh interpreter 0.7 s on its first case.
PRELOAD = (
    "shellform.analyses",
    "shellform.analyses.static",
    "shellform.analyses.dynamics",
    "shellform.analyses.continuation",
    "shellform.analyses.form_finding",
    "shellform.analyses.form_and_buckle",
    "shellform.analyses.indentation",
    "shellform.solvers.continuation",
    "shellform.solvers.implicit_euler",
    "shellform.studies.sample",
    "shellform.io.xdmf",
    "scipy.sparse.linalg",
    "h5py",
    "qdldl",
    "cvxopt.cholmod",
    "matplotlib.figure",
    "matplotlib.backends.backend_agg",
    "mpl_toolkits.mplot3d",
)

#: the environment variable that overrides the start method of local pools
START_METHOD_VARIABLE = "SHELLFORM_START_METHOD"


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


def start_method() -> str:
    """How a local pool's processes start: ``fork``, ``forkserver`` or ``spawn`` (see the module's text).

    On Linux this imports :data:`PRELOAD` first: a forked worker inherits it,
    and the threads its imports start (OpenBLAS's) are counted.
    """
    import multiprocessing

    methods = multiprocessing.get_all_start_methods()
    forced = os.environ.get(START_METHOD_VARIABLE, "").strip()
    if forced:
        if forced not in methods:
            raise SceneError(START_METHOD_VARIABLE, f"{forced!r} is not a start method here; "
                                                    f"one of {', '.join(methods)}")
        return forced
    if not sys.platform.startswith("linux"):
        return "spawn"
    preload()
    if "fork" in methods and only_blas_threads():
        return "fork"
    return "forkserver" if "forkserver" in methods else "spawn"


def preload() -> None:
    """Import :data:`PRELOAD` into this process."""
    for name in PRELOAD:
        importlib.import_module(name)


def only_blas_threads() -> bool:
    """Whether this process runs no thread but its own and OpenBLAS's idle pools (Linux).

    OpenBLAS (the pthreads build NumPy and SciPy ship) stops its pool before a
    fork (``pthread_atfork``) and starts it again when it is next needed, so
    its threads do not make a fork unsafe. Any other thread might: a Python
    thread (``threading``), an OpenMP pool (libgomp, which gmsh loads, does not
    survive a fork), a library's own. The count of the process's threads
    (``/proc/self/task``) must be exactly one more than OpenBLAS's pools
    (threadpoolctl): anything else, even a count that cannot be read, says no.
    (Python 3.12 and later warn of any fork of a process with more than one
    thread, a ``DeprecationWarning`` that OpenBLAS's pools set off too.)
    """
    if threading.active_count() > 1:
        return False
    try:
        threads = len(os.listdir("/proc/self/task"))
    except OSError:
        return False
    if threads == 1:
        return True
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return False
    pools = sum(max(int(lib.get("num_threads") or 1) - 1, 0) for lib in threadpool_info()
                if lib.get("internal_api") == "openblas" and lib.get("threading_layer") == "pthreads")
    return threads == 1 + pools


def _context(method: str):
    import multiprocessing

    context = multiprocessing.get_context(method)
    if method == "forkserver":
        # takes effect when the server starts (once per process); "__main__" as by default
        context.set_forkserver_preload(["__main__", *PRELOAD])
    return context


def _on_pool(fn, tasks, workers: int, died) -> Iterator[tuple]:
    from concurrent.futures import ProcessPoolExecutor, as_completed

    pool = ProcessPoolExecutor(max_workers=workers, mp_context=_context(start_method()))
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
