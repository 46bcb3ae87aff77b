"""Where the parallel work runs: this machine's processes (joblib's loky, the default) or a dask
cluster.

Every optimiser spreads its work with joblib (``n_jobs``), so a dask cluster takes the work by
making joblib's backend ``"dask"``.  Results do not depend on the backend: the GA engine draws its
random numbers from its own seeded streams and evaluates fixed-size batches, and the location scan
has no randomness, so a seed gives the same placement logbook, location ranking and tuned
covariances on loky, on threads and on a dask cluster (``tests/test_dask.py``).

>>> with scheduler("local:2"):                       # doctest: +SKIP
...     res = place(objective, encoding, seed=0, n_jobs=-1)
"""
from __future__ import annotations

import contextlib

from core_akf.exceptions import AKFInputError

#: how to get dask
INSTALL_HINT = 'the dask scheduler needs dask.distributed: python -m pip install "akf-toolkit[dask]"'


@contextlib.contextmanager
def scheduler(spec=None, resume=None):
    """Run the joblib work inside the ``with`` block on ``spec``:

    * ``None``: joblib's default (loky processes on this machine);
    * ``"local:N"``: a new :class:`dask.distributed.LocalCluster` of N single-threaded worker
      processes, closed at the end;
    * ``"tcp://HOST:PORT"`` (or any scheduler address): an existing dask cluster;
    * a :class:`dask.distributed.Client`: that client's cluster.

    Yields the dask ``Client`` (or None).  Inside, call the optimisers with ``n_jobs=-1`` (every
    worker); ``n_jobs=1`` runs in this process and sends nothing to the cluster.

    A worker that dies is replaced (a local cluster restarts it) and its tasks run again on the
    others, with the same result.  If the cluster cannot finish -- a task kills its worker more
    often than the scheduler allows, or the cluster goes away -- :class:`ClusterError` says so,
    followed by ``resume`` (how to continue, e.g. from the GA checkpoint) when given.
    """
    n_local = check_scheduler(spec)
    if spec is None:
        yield None
        return
    from distributed import Client, LocalCluster
    from joblib import parallel_config

    with contextlib.ExitStack() as stack:
        if isinstance(spec, Client):
            client = spec
        elif n_local:
            cluster = stack.enter_context(LocalCluster(n_workers=n_local, threads_per_worker=1, processes=True,
                                                      dashboard_address=":0"))   # any free port
            client = stack.enter_context(Client(cluster))
        else:
            try:
                client = stack.enter_context(Client(spec, timeout="10s"))
            except (OSError, TimeoutError) as exc:
                raise AKFInputError(f"cannot reach the dask scheduler at {spec!r}: {exc}") from None
        stack.enter_context(parallel_config(backend=_dask_backend()))
        try:
            yield client
        except Exception as exc:
            lost = _lost_work(exc)
            if lost is None:
                raise
            raise ClusterError(f"the dask cluster lost the work: {lost}" + (f"; {resume}" if resume else "")) from exc


def _dask_backend():
    """Name of the joblib backend for a dask cluster: joblib's own ``"dask"``, made to report a
    task that the scheduler gave up on.  joblib 1.6 sets that task's error on a future nobody
    waits for and never calls the task's callback, so ``Parallel`` waits for ever after a
    ``KilledWorker``; the subclass here passes the error to the callback, which raises it in the
    caller."""
    from joblib import register_parallel_backend
    from joblib._dask import DaskDistributedBackend

    if not all(hasattr(DaskDistributedBackend, a) for a in ("_collect", "submit", "retrieve_result_callback")):
        return "dask"     # another joblib: its own behaviour

    class ReportingDaskBackend(DaskDistributedBackend):
        async def _collect(self):
            import asyncio

            while self._continue:
                async for future, result in self.waiting_futures:
                    done = self._results.pop(future)
                    callback = self._callbacks.pop(future)
                    if future.status == "error":
                        exc = result[1]
                        done.set_exception(exc)
                        if callback is not None:
                            callback(exc)       # retrieve_result_callback raises it: Parallel stops
                    else:
                        done.set_result(result)
                        if callback is not None:
                            callback(result)
                await asyncio.sleep(0.01)

    register_parallel_backend("akf-dask", ReportingDaskBackend)
    return "akf-dask"


class ClusterError(RuntimeError):
    """The dask cluster could not finish the work: a task ended its worker process more often than
    the scheduler allows (``distributed.scheduler.allowed-failures``, 3 by default), or the
    cluster went away.  A single lost worker is not an error: its tasks run again on the others."""


def _lost_work(exc):
    """A plain-language reason if ``exc`` means that the cluster lost the work, else None."""
    from distributed import KilledWorker
    from distributed.comm.core import CommClosedError

    if isinstance(exc, KilledWorker):
        return (f"task {exc.task!r} ended its worker process again and again (out of memory or a crash in "
                f"native code?) and the scheduler gave up on it")
    if isinstance(exc, CommClosedError) or type(exc).__name__ in ("CancelledError", "FutureCancelledError"):
        return f"the connection to the scheduler or its workers broke ({type(exc).__name__}: {exc})"
    return None


def check_scheduler(spec):
    """Check a scheduler before any work starts: dask.distributed is installed and ``spec`` is
    None, ``"local:N"`` (N >= 1), an address or a ``Client``.  Returns N for ``"local:N"``, else 0."""
    if spec is None:
        return 0
    try:
        from distributed import Client
    except ImportError:
        raise AKFInputError(INSTALL_HINT) from None
    if isinstance(spec, Client):
        return 0
    if not isinstance(spec, str) or not spec:
        raise AKFInputError(f"a scheduler is 'local:N', a dask scheduler address or a dask Client; got {spec!r}")
    if spec.startswith("local:"):
        n = spec.split(":", 1)[1]
        if not n.isdigit() or int(n) < 1:
            raise AKFInputError(f"--scheduler local:N needs a number of workers N >= 1, got {spec!r}")
        return int(n)
    return 0


def add_scheduler_option(parser):
    """``--scheduler`` for a sub-command that spreads work with joblib."""
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run the parallel work on a dask cluster: local:N (a new local cluster of N workers) "
                             "or a scheduler address such as tcp://host:8786; --n-jobs then defaults to every worker")


def workers(args):
    """``--n-jobs`` with its default: 1 on this machine, every worker (-1) on a dask scheduler."""
    if args.n_jobs is not None:
        return args.n_jobs
    return -1 if getattr(args, "scheduler", None) else 1
