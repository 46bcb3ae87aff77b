"""Threads for stacks of small, independent problems, with results that do not depend on them.

The optimisers run stacks of small filters: the role splits of one candidate location, a batch
of sensor layouts.  On matrices of a few hundred rows BLAS's own threads cost more than they
bring, and with some CPU kernels they also change the last bits of a product (measured under
``OPENBLAS_CORETYPE=Prescott``), while a joblib or dask worker runs BLAS on one thread.  So the
Riccati stacks and the lifted recursions run with single-threaded BLAS everywhere and split the
stack over threads of their own instead (numpy releases the GIL in its BLAS and LAPACK calls):
every problem then gives the same bits in one thread, in several, in this process or in a worker.

``AKF_NUM_THREADS`` sets the number of threads; otherwise it is the BLAS thread limit a parallel
runner gave this process (``OPENBLAS_NUM_THREADS`` / ``OMP_NUM_THREADS``, which joblib's loky
workers and dask workers set), else the number of cores this process may use.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

_POOLS = {}
_CONTROLLER = []


def solver_threads():
    """Threads for a stack of problems (see the module docstring).

    Returns
    -------
    int
    """
    for var in ("AKF_NUM_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
        value = os.environ.get(var, "").strip()
        if value.isdigit() and int(value) >= 1:
            return int(value)
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:      # not on Linux
        return os.cpu_count() or 1


def single_threaded_blas():
    """A context in which BLAS runs on one thread.

    threadpoolctl, one controller made once, so a switch costs ~12 us.

    Returns
    -------
    contextlib.AbstractContextManager
    """
    if not _CONTROLLER:
        from threadpoolctl import ThreadpoolController
        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0].limit(limits=1, user_api="blas")


def split_stack(fn, size):
    """Run a function on parts of a stack of problems, one part per thread, single-threaded BLAS.

    Parameters
    ----------
    fn : callable
        ``fn(part)`` with ``part`` a slice of the stack; it must treat its problems independently.
    size : int
        Problems in the stack.

    Returns
    -------
    list of tuple
        ``[(part, result, exception), ...]`` in stack order (one of ``result`` and
        ``exception`` is None).
    """
    threads = max(1, min(solver_threads(), size))
    parts = [slice(int(p[0]), int(p[-1]) + 1) for p in np.array_split(np.arange(size), threads)]
    with single_threaded_blas():
        if threads == 1:
            results = [_outcome(fn, parts[0])]
        else:
            if threads not in _POOLS:
                _POOLS[threads] = ThreadPoolExecutor(threads, "akf-stack")
            futures = [_POOLS[threads].submit(_outcome, fn, part) for part in parts]
            results = [f.result() for f in futures]
    return [(part, value, exc) for part, (value, exc) in zip(parts, results)]


def _outcome(fn, part):
    """``(fn(part), None)``, or ``(None, exception)``: the caller decides what an error means."""
    try:
        return fn(part), None
    except Exception as exc:  # noqa: BLE001 -- handed to the caller
        return None, exc
