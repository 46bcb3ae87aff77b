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
import os

from core_akf.checks import AKFInputError, install_hint

#: how to get dask
INSTALL_HINT = "the dask scheduler needs dask.distributed: " + install_hint("dask")


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
            probe_scheduler(spec)
            try:
                client = stack.enter_context(Client(spec, timeout=f"{CONNECT_TIMEOUT:g}s"))
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


#: a local cluster has at most this many single-threaded workers per core of the machine
LOCAL_WORKERS_PER_CORE = 4
#: seconds to connect to a scheduler and hear it answer
CONNECT_TIMEOUT = 10.0
#: the address schemes of dask's comms
SCHEMES = ("tcp", "tls", "inproc", "ucx", "ws", "wss")


def check_address(spec):
    """A scheduler address checked before any connection: ``[tcp://]HOST:PORT`` or another dask
    scheme; a dashboard URL (http), a missing port or ``tls://`` without certificates are clear
    errors."""
    scheme, sep, rest = spec.partition("://")
    if not sep:
        scheme, rest = "tcp", spec
    if scheme in ("http", "https"):
        raise AKFInputError(f"--scheduler {spec!r} is a web address (the dashboard?); the scheduler's own address is "
                            "tcp://HOST:PORT (port 8786 by default; the dashboard shows it under Info)")
    if scheme not in SCHEMES:
        raise AKFInputError(f"--scheduler {spec!r}: unknown address scheme {scheme!r}; give tcp://HOST:PORT (or "
                            f"{', '.join(s + '://' for s in SCHEMES[1:])})")
    if scheme in ("tcp", "tls", "ws", "wss"):
        host, colon, port = rest.rstrip("/").rpartition(":")
        if not colon or not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise AKFInputError(f"--scheduler {spec!r} needs a host and a port: {scheme}://HOST:PORT (the dask "
                                "scheduler listens on 8786 by default)")
    if scheme in ("tls", "wss"):
        import dask

        if not dask.config.get("distributed.comm.tls.client.cert", None):
            raise AKFInputError(f"--scheduler {spec!r} is a TLS address but no client certificate is configured: set "
                                "distributed.comm.tls.ca-file, .client.cert and .client.key in the dask configuration "
                                "(or DASK_DISTRIBUTED__COMM__TLS__CLIENT__CERT, ...)")


def probe_scheduler(spec, timeout=CONNECT_TIMEOUT):
    """Ask the process at ``spec`` who it is, within ``timeout`` seconds: a port that does not
    answer like a dask scheduler (another server, a dask worker) is a clear error, never a hang
    (a dask Client waits for ever on a port that accepts and says nothing)."""
    import asyncio
    import concurrent.futures

    from distributed.core import rpc

    async def identity():
        r = rpc(spec, timeout=timeout)
        try:
            return await asyncio.wait_for(r.identity(), timeout)
        finally:
            await r.close_rpc()

    with concurrent.futures.ThreadPoolExecutor(1) as pool:       # its own event loop, also under Jupyter's
        try:
            who = pool.submit(asyncio.run, identity()).result()
        except (TimeoutError, asyncio.TimeoutError):
            raise AKFInputError(f"--scheduler {spec!r}: something listens there but did not answer as a dask "
                                f"scheduler within {timeout:g} s (another server, or the dashboard's port?)") from None
        except OSError as exc:
            raise AKFInputError(f"cannot reach the dask scheduler at {spec!r}: {exc}") from None
        except Exception as exc:  # noqa: BLE001 -- a reply that is not dask's protocol
            raise AKFInputError(f"--scheduler {spec!r} does not speak dask's protocol ({type(exc).__name__}: {exc})") \
                from None
    kind = who.get("type") if isinstance(who, dict) else None
    if kind != "Scheduler":
        raise AKFInputError(f"--scheduler {spec!r} is a dask {kind or 'process'}, not the scheduler; give the "
                            "scheduler's address (tcp://HOST:8786 by default)")


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
        cores = os.cpu_count() or 1
        if int(n) > LOCAL_WORKERS_PER_CORE * cores:
            raise AKFInputError(f"--scheduler {spec} would start {n} worker processes on this machine of {cores} "
                                f"core(s); give at most local:{LOCAL_WORKERS_PER_CORE * cores} (one per core is "
                                "fastest), or the address of a cluster for more")
        return int(n)
    check_address(spec)
    return 0


def add_scheduler_option(parser):
    """``--scheduler`` for a sub-command that spreads work with joblib."""
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="run the parallel work on a dask cluster: local:N (a new local cluster of N workers) "
                             "or a scheduler address such as tcp://host:8786; --n-jobs then defaults to every worker")


def workers(args):
    """``--n-jobs`` with its default: 1 on this machine, every worker (-1) on a dask scheduler.

    On this machine it is capped at the cores this process may use (``--n-jobs 1000`` starts no
    more processes than there are cores; -1 is every core, -2 all but one, as in joblib); 0 is an
    error.  On a dask scheduler the cluster decides, and the work is capped by what there is
    (:func:`at_most`)."""
    n = args.n_jobs
    if n is None:
        return -1 if getattr(args, "scheduler", None) else 1
    if n == 0:
        raise AKFInputError("--n-jobs 0 runs nothing: give the number of processes (1 runs in this one), or -1 for "
                            "every core")
    if getattr(args, "scheduler", None):
        return n
    cores = usable_cores()
    return max(1, min(n, cores) if n > 0 else cores + 1 + n)


def usable_cores():
    """The cores this process may run on (its CPU affinity; a BLAS thread limit does not count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:      # not on Linux
        return os.cpu_count() or 1


def at_most(n_jobs, work):
    """``n_jobs`` (joblib's: -1 every worker) capped at ``work`` tasks: no process waits idle.

    Parameters
    ----------
    n_jobs : int
    work : int
        Tasks there are.

    Returns
    -------
    int
    """
    return max(1, min(work, n_jobs) if n_jobs > 0 else work)
