"""The steady-state AKF over a record in pieces, the pieces filtered at the same time.

With a constant gain the filtered state obeys ``x_k = F x_k-1 + L y_k`` (``F = (I - L G) A``, the
closed loop of :func:`core_akf.filter.kernels.closed_loop`), so a piece's states are its
zero-state response plus the free response of the state it starts from: :class:`TimeParallel`
finds every piece's start state from the pieces' zero-state ends (:func:`zero_state_end`) and then
filters each piece with the sequential stream's :class:`~core_akf.filter.streaming.Estimator`;
:func:`estimate_in_parallel` does the three steps with any ``map`` (one process, joblib, dask).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..checks import AKFInputError, ArrayLike, as_finite_array
from .kernels import closed_loop

if TYPE_CHECKING:
    from .results import Estimate
    from .streaming import Estimator


def zero_state_end(F: ArrayLike, L: ArrayLike, Y: ArrayLike, block: int = 256) -> np.ndarray:
    """The last state of ``x_k = F x_k-1 + L y_k`` over ``Y`` from ``x_-1 = 0``.

    ``x_N-1 = sum_i F^(N-1-i) L y_i``, summed block by block: the Markov parameters
    ``[L, F L, ..., F^(b-1) L]`` of one block meet every block of the record in one matrix
    product (about ``n m`` operations per step instead of the recursion's ``n^2``), and the
    blocks are joined by Horner's rule with ``F^b``.

    Parameters
    ----------
    F : ndarray (n, n)
        The closed-loop transition.
    L : ndarray (n, m)
        The input matrix (the gain).
    Y : ndarray (N, m)
        The inputs.
    block : int
        Steps per block.

    Returns
    -------
    ndarray (n,)

    Examples
    --------
    >>> import numpy as np
    >>> F, L = np.array([[0.5]]), np.array([[1.0]])
    >>> float(zero_state_end(F, L, np.ones((3, 1)))[0])      # 0.25 + 0.5 + 1
    1.75
    """
    F, L, Y = (np.asarray(a, float) for a in (F, L, Y))
    n, m = L.shape
    N = Y.shape[0]
    if N == 0:
        return np.zeros(n)
    b = max(1, min(int(block), N))
    markov = np.empty((b, n, m))                        # F^d L, d = 0 .. b-1
    markov[0] = L
    for d in range(1, b):
        markov[d] = F @ markov[d - 1]
    pad = (-N) % b
    blocks = np.vstack([np.zeros((pad, m)), Y]).reshape(-1, b, m)[:, ::-1]     # newest step first in each block
    parts = np.einsum("qdm,dnm->qn", blocks, markov)                            # each block's own contribution
    Fb = np.linalg.matrix_power(F, b)
    x = np.zeros(n)
    for v in parts:                                     # oldest block first: x <- F^b x + v
        x = Fb @ x + v
    return x


class TimeParallel:
    """The steady-state AKF over a record in pieces, the pieces filtered at the same time.

    With a constant gain the filtered state obeys ``x_k = F x_k-1 + L y_k`` (``F = (I - L G) A``),
    so a piece's states are its zero-state response plus the free response of the state it starts
    from.  Three steps:

    1. every piece's zero-state end state (:meth:`end_state`, :func:`zero_state_end`), in parallel;
    2. the start state of every piece, a short pass over the pieces' ends (:meth:`starts`);
    3. every piece filtered from its start state (:meth:`run`), in parallel: exactly the
       :class:`Estimator` of the sequential stream, restored at that step.

    Rainflow counts of the pieces merge as exactly
    (:meth:`core_akf.fatigue.FatigueAccumulator.merge`).

    Parameters
    ----------
    estimator : Estimator
        A steady-state estimator at the record's start (its matrices and prior are used; it is
        not changed).

    Examples
    --------
    >>> import numpy as np
    >>> from core_akf import simulate
    >>> from core_akf.filter import Estimator
    >>> from core_akf.models import s17_truss
    >>> sensors, R = ["strain:13", "acc:8:y"], {"strain": 1e-14, "acc": 1e-4}
    >>> Y = simulate(s17_truss(), sensors, ["8:y"], np.full((300, 1), 100.0), 1e-3, relative_noise=0.02,
    ...              seed=0).measurements
    >>> est = Estimator(s17_truss(), sensors, ["8:y"], 1e-3, model_error_cov=1e-16, force_increment_cov=1e4,
    ...                 noise_cov=R, steady=True)
    >>> tp = TimeParallel(est)
    >>> pieces = [Y[:100], Y[100:220], Y[220:]]
    >>> starts = tp.starts([tp.end_state(p) for p in pieces])           # 1 and 2
    >>> forces = np.vstack([tp.run(s, p).forces for s, p in zip(starts, pieces)])     # 3
    >>> whole = est.update(Y).forces
    >>> bool(np.allclose(forces, whole, rtol=1e-9, atol=1e-9 * np.abs(whole).max()))
    True
    """

    def __init__(self, estimator: Estimator):
        if not estimator.steady or estimator.lagged is not None:
            raise AKFInputError("the time-parallel filter needs the steady-state estimator (steady=True) without "
                                "fixed-lag smoothing")
        if estimator.n_steps:
            raise AKFInputError("the time-parallel filter starts from an estimator at the record's start")
        self.estimator = estimator
        f = estimator.filter
        self.L = estimator.gain
        self.I_LG, self.F = closed_loop(f.A_a, f.G_a[0], self.L)

    def end_state(self, Y: ArrayLike) -> tuple[np.ndarray, int]:
        """Step 1 for one piece: its zero-state end state and its length.

        Parameters
        ----------
        Y : ndarray (K, m)
            The piece's measurements (SI).

        Returns
        -------
        tuple
            ``(z_end (n_a,), K)``.
        """
        Y = self.estimator.filter.extend(as_finite_array(Y, "measurements", ndim=2))   # with the dummies' zeros
        return zero_state_end(self.F, self.L, Y), Y.shape[0]

    def starts(self, ends: list) -> list:
        """Step 2: the state before each piece (None for the first: the record's prior).

        Parameters
        ----------
        ends : list of (ndarray (n_a,), int)
            :meth:`end_state` of every piece, in record order.

        Returns
        -------
        list
            ``(state or None, first step)`` per piece.
        """
        x, step, out = None, 0, []
        f = self.estimator.filter
        A = f.A_a
        for z, K in ends:
            out.append((x, step))
            if K:
                # the prior's part: x_-1 is not a filtered state; the first step starts from the prior mean
                prior = np.zeros(A.shape[0]) if x is None and f.z0 is None else (f.z0 if x is None else A @ x)
                free = self.I_LG @ prior            # F x_-1, or (I - L G) prior
                x = z + np.linalg.matrix_power(self.F, K - 1) @ free
            step += K
        return out

    def run(self, start: tuple, Y: ArrayLike) -> Estimate:
        """Step 3 for one piece: its estimate from its start state.

        Parameters
        ----------
        start : (ndarray or None, int)
            The piece's entry of :meth:`starts`.
        Y : ndarray (K, m)
            The piece's measurements.

        Returns
        -------
        Estimate
            With the piece's time.
        """
        state, step = start
        return self.estimator.started_at(state, step).update(Y)


def estimate_in_parallel(estimator: Estimator, pieces: list, map_pieces=map, on_piece=None) -> list:
    """Filter a record's pieces at the same time (:class:`TimeParallel`) with any ``map``.

    Parameters
    ----------
    estimator : Estimator
        A steady-state estimator at the record's start.
    pieces : list
        The record's pieces in order: arrays (K, m), or callables returning them (a file reader
        each, so that a worker reads its own piece).
    map_pieces : callable
        ``map_pieces(function, list) -> iterable`` in order: the builtin ``map`` (one process),
        joblib, or a dask client's ``lambda f, xs: client.gather(client.map(f, xs))``.
    on_piece : callable, optional
        ``on_piece(estimate, index) -> result``, run where the piece is filtered (the outputs of a
        piece: written files, fatigue counts, summaries), so that the estimates of months of data
        never travel; default the estimate itself.

    Returns
    -------
    list
        ``on_piece``'s result per piece, in record order.

    Examples
    --------
    >>> import numpy as np
    >>> from core_akf import simulate
    >>> from core_akf.filter import Estimator
    >>> from core_akf.models import s17_truss
    >>> sensors, R = ["strain:13", "acc:8:y"], {"strain": 1e-14, "acc": 1e-4}
    >>> Y = simulate(s17_truss(), sensors, ["8:y"], np.full((300, 1), 100.0), 1e-3, relative_noise=0.02,
    ...              seed=0).measurements
    >>> est = Estimator(s17_truss(), sensors, ["8:y"], 1e-3, model_error_cov=1e-16, force_increment_cov=1e4,
    ...                 noise_cov=R, steady=True)
    >>> peaks = estimate_in_parallel(est, [Y[:150], Y[150:]], on_piece=lambda e, i: float(e.forces.max()))
    >>> len(peaks)
    2
    """
    tp = TimeParallel(estimator)
    ends = list(map_pieces(_PieceEnd(tp), list(pieces)))
    starts = tp.starts(ends)
    return list(map_pieces(_PieceRun(tp, on_piece), [(i, s, p) for i, (s, p) in enumerate(zip(starts, pieces))]))


def _load(piece):
    return piece() if callable(piece) else piece


class _PieceEnd:
    """Step 1 on a worker (a picklable callable)."""

    def __init__(self, tp):
        self.tp = tp

    def __call__(self, piece):
        return self.tp.end_state(_load(piece))


class _PieceRun:
    """Step 3 on a worker."""

    def __init__(self, tp, on_piece):
        self.tp, self.on_piece = tp, on_piece

    def __call__(self, item):
        i, start, piece = item
        est = self.tp.run(start, _load(piece))
        return est if self.on_piece is None else self.on_piece(est, i)
