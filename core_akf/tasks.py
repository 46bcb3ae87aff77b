"""Independent tasks spread over processes with joblib (``n_jobs``), the one place a lost worker
is handled.

A worker process that dies mid-run (killed, out of memory, a crash in native code) makes joblib's
loky backend raise ``TerminatedWorkerError``, and the whole map fails.  The tasks here are pure
functions of their inputs, so the map is run once more; a second loss is a
:class:`WorkerLostError` that says what to do, never an internal error.  On a dask cluster
(:func:`akf.parallel.scheduler`) the cluster itself reruns a lost worker's tasks.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable

from .checks import as_n_jobs


class WorkerLostError(RuntimeError):
    """A worker process died twice while running tasks (out of memory or killed)."""


def run_tasks(fn: Callable, items: Iterable, n_jobs: int) -> list:
    """``[fn(x) for x in items]`` on ``n_jobs`` joblib workers (in this process for 1), in order.

    Parameters
    ----------
    fn : callable
        A picklable function of one item, without side effects (it may run twice).
    items : iterable
        Its arguments.
    n_jobs : int
        Workers, as joblib takes them (-1: every core).

    Returns
    -------
    list
        The results, in the order of ``items``.

    Raises
    ------
    WorkerLostError
        When a worker process died in two attempts.

    Examples
    --------
    >>> run_tasks(abs, [-1, 2, -3], 1)
    [1, 2, 3]
    """
    n_jobs = as_n_jobs(n_jobs)
    items = list(items)
    if n_jobs == 1 or len(items) <= 1:
        return [fn(x) for x in items]
    from joblib import Parallel, delayed
    from joblib.externals.loky.process_executor import TerminatedWorkerError

    for attempt in (1, 2):
        try:
            return Parallel(n_jobs=n_jobs)(delayed(fn)(x) for x in items)
        except TerminatedWorkerError as exc:
            if attempt == 2:
                raise WorkerLostError(f"a worker process died twice while running {len(items)} tasks on {n_jobs} "
                                      f"workers (killed, or out of memory: {str(exc).splitlines()[0][:200]}); run "
                                      "again with fewer workers (n_jobs), or n_jobs=1 to run in this process") from None
    raise AssertionError("unreachable")
