"""Fast responses of linear time-invariant recursions: the inner loop of every steady-state AKF.

The steady-state filter is ``x_k = F x_{k-1} + L y_k`` with a constant ``F`` (n x n) and a
constant gain ``L`` (n x m, m << n).  Run step by step, one step is one small matrix-vector
product and the time goes into Python and BLAS call overhead, not arithmetic.  The *lifted*
form here cuts the record into chunks of ``K`` steps and works on all chunks at once:

1. Markov parameters ``F^d L`` (d < K): K small products;
2. the zero-state response of every chunk, from a block-Toeplitz matrix of those parameters:
   one large product over all chunks;
3. the states at the chunk boundaries, ``s_{c+1} = F^K s_c + e_c``: a recursion of N/K steps
   (run chunked, :func:`recursion_chunked`, when long);
4. the free response ``F^(j+1) s_c`` added back: one large product.

The time-varying filter's covariance update ``A P A^T`` is cheap for the transition of a
classically damped structure in modal coordinates (:class:`ModalBlockTransition`).

Outputs ``H x_k`` of a few rows (the AD sensors of a location scan) come straight from the
output Markov parameters ``H F^d L``, without ever forming the n states per step, at
``O(N (K m k + n m + n k))`` instead of ``O(N n^2)`` operations.  Everything is batched over a
leading axis of independent systems.  Results equal the plain recursion to rounding; the plain
recursion stays as :func:`recursion_stepwise`, the reference in the tests.

**Threads.** Stacks of small, independent problems split over threads, with results that do not depend on them.

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

#: below this many steps the plain recursion is used (the lifted set-up does not pay off)
_LIFT_FROM = 64
#: boundary recursions shorter than this run step by step
_BOUNDARY_STEPWISE = 48
#: bytes of one per-step array (B, N, channels) a stack works on at once.  New arrays of tens of MB
#: are fresh pages the kernel zeroes on first touch: on the ambient calibration (61 states, 10
#: channels, 61440 steps, stacks of 57 filters) that system time was half the fit (10.7 s; 5.7 s
#: in pieces of 4 MB, 1.8 GB of memory down to 0.43 GB); so long records run piece by piece
_PIECE_BYTES = 4 * 2 ** 20


# ------------------------------------------------------------------- threads for stacks
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


# ---------------------------------------------------------------- LTI recursions
def recursion_stepwise(F, U, x_first):
    """Reference: all states of ``x_k = F x_{k-1} + U_k`` (k >= 1), ``x_0 = x_first``, one step at a time.

    Parameters
    ----------
    F : ndarray (B, n, n)
    U : ndarray (B, N, n)
    x_first : ndarray (B, n)
        ``x_0``.

    Returns
    -------
    ndarray (B, N, n)
    """
    B, N, n = U.shape
    out = np.empty((B, N, n))
    out[:, 0] = x_first
    Ft = np.ascontiguousarray(np.swapaxes(F, -1, -2))
    if B == 1:
        f, u, o, x = Ft[0], U[0], out[0], out[0, 0]
        for k in range(1, N):
            x = x @ f + u[k]
            o[k] = x
        return out
    x = out[:, 0][:, None, :]
    for k in range(1, N):
        x = np.matmul(x, Ft) + U[:, k, None, :]
        out[:, k] = x[:, 0]
    return out


def recursion_chunked(F, U, x_first):
    """All states of ``x_k = F x_{k-1} + U_k``, with the record cut into ~sqrt(N) chunks run as one batch.

    Each chunk's zero-state response, then the chunk-boundary states in sequence, then their free
    response added back -- about 3 sqrt(N) matrix products instead of N (twice the arithmetic;
    used for the boundary recursion of :func:`lti_response`, whose input has full rank).

    Parameters
    ----------
    F : ndarray (B, n, n)
    U : ndarray (B, N, n)
    x_first : ndarray (B, n)
        ``x_0``.

    Returns
    -------
    ndarray (B, N, n)
    """
    B, N, n = U.shape
    out = np.empty((B, N, n))
    out[:, 0] = x_first
    steps = N - 1
    if steps < 1:
        return out
    K = max(1, int(np.sqrt(steps)))            # chunk length
    C = -(-steps // K)                          # number of chunks
    V = np.zeros((B, C * K, n))
    V[:, :steps] = U[:, 1:]
    V = V.reshape(B, C, K, n)
    Ft = np.ascontiguousarray(np.swapaxes(F, -1, -2))
    Z = np.empty((B, C, K, n))
    z = np.zeros((B, C, n))
    for j in range(K):                          # zero-state response inside every chunk at once
        z = z @ Ft + V[:, :, j]
        Z[:, :, j] = z
    FKt = np.swapaxes(np.linalg.matrix_power(F, K), -1, -2)
    S = np.empty((B, C, n))                     # state just before each chunk
    s = np.asarray(x_first, float)
    for c in range(C):
        S[:, c] = s
        s = np.einsum("bi,bij->bj", s, FKt) + Z[:, c, K - 1]
    T = S
    for j in range(K):                          # free response of the boundary states
        T = T @ Ft
        Z[:, :, j] += T
    out[:, 1:] = Z.reshape(B, C * K, n)[:, :steps]
    return out


def _chunk_length(n, m, k, N):
    """Chunk length K: the Toeplitz product costs ~K m k per step, the free response n k and
    the boundary recursion ~n^2 / K; K ~ sqrt(n^2 / (m k)) balances them, kept between 4 and
    sqrt(N) so that neither loop gets long."""
    K = int(np.sqrt(n * n / max(m * k, 1)))
    return int(min(max(K, 4), max(4, int(np.sqrt(N))), 64))


def _powers_times(F, E, K):
    """``[F^0 E, F^1 E, ..., F^(K-1) E]`` stacked on axis 1: (B, K, n, m)."""
    B, n, m = E.shape
    out = np.empty((B, K, n, m))
    out[:, 0] = E
    for d in range(1, K):
        np.matmul(F, out[:, d - 1], out=out[:, d])
    return out


def _left_powers(H, F, K):
    """``[H F^1, ..., H F^K]`` stacked on axis 1: (B, K, k, n)."""
    B, k, n = H.shape
    out = np.empty((B, K, k, n))
    prev = H
    for d in range(K):
        prev = np.matmul(prev, F, out=out[:, d])
    return out


def lti_response(F, Bu, Y, x_first, H=None):
    """Outputs of ``x_k = F x_{k-1} + Bu y_k`` (k >= 1), ``x_0 = x_first``.

    The systems of a stack are independent: they run with single-threaded BLAS, split over
    threads (:mod:`core_akf.filter.recursion`), and each gives the same bits whatever else is in the stack.

    Parameters
    ----------
    F : ndarray (B, n, n) -- transition, spectral radius < 1 for a long record
    Bu : ndarray (B, n, m) -- input matrix (the Kalman gain)
    Y : ndarray (B, N, m) -- inputs (measurements); ``y_0`` is not used (it is in ``x_first``)
    x_first : ndarray (B, n) -- the state at step 0
    H : ndarray (B, k, n) or (k, n), optional -- output rows; None returns the states

    Returns
    -------
    ndarray (B, N, k) -- ``H x_k``, or (B, N, n) the states ``x_k`` without ``H``
    """
    F = np.asarray(F, float)
    Bu = np.asarray(Bu, float)
    Y = np.asarray(Y, float)
    x_first = np.asarray(x_first, float)
    B = Y.shape[0]
    if H is not None:
        H = np.broadcast_to(np.asarray(H, float), (B,) + np.shape(H)[-2:])
    outcomes = split_stack(lambda i: _in_pieces(F[i], Bu[i], Y[i], x_first[i], None if H is None else H[i]), B)
    for _, _, exc in outcomes:
        if exc is not None:
            raise exc
    return outcomes[0][1] if len(outcomes) == 1 else np.concatenate([part for _, part, _ in outcomes])


def stack_pieces(size, system_bytes, multiple=1):
    """Slices of a stack of ``size`` problems, each piece holding at most :data:`_PIECE_BYTES` of
    per-step arrays (``system_bytes`` per problem) and a multiple of ``multiple`` problems (at
    least ``multiple``): big stacks of long records run piece by piece, so that their arrays are
    reused memory instead of fresh pages (the kernel's page faults cost more than the arithmetic).

    Parameters
    ----------
    size : int
        Problems in the stack.
    system_bytes : int
        Bytes of one problem's per-step array.
    multiple : int
        Each piece holds a multiple of this many problems (the threads that split it).

    Returns
    -------
    list of slice
    """
    per = max(1, _PIECE_BYTES // max(int(system_bytes), 1))
    per = max(multiple, per // multiple * multiple)
    return [slice(i, min(i + per, size)) for i in range(0, size, per)]


def _in_pieces(F, Bu, Y, x_first, H=None):
    """:func:`_lti_response` on one part of a stack, piece by piece (:func:`stack_pieces`; each
    system's bits are the same either way)."""
    B, N, m = Y.shape
    n = F.shape[-1]
    k = n if H is None else H.shape[-2]
    K = _chunk_length(n, m, k, N)
    pieces = stack_pieces(B, 8 * N * max(m, k, -(-n // K)))
    if len(pieces) == 1:
        return _lti_response(F, Bu, Y, x_first, H)
    return np.concatenate([_lti_response(F[i], Bu[i], Y[i], x_first[i], None if H is None else H[i])
                           for i in pieces])


def _lti_response(F, Bu, Y, x_first, H=None):
    """:func:`lti_response` on one part of a stack, in the calling thread."""
    B, N, m = Y.shape
    n = F.shape[-1]
    if H is not None and H.shape[1] >= n:   # as many outputs as states: the states, then one projection
        return _lti_response(F, Bu, Y, x_first) @ np.swapaxes(H, -1, -2)
    k = n if H is None else H.shape[1]
    steps = N - 1
    if steps < _LIFT_FROM:
        X = recursion_stepwise(F, Y @ np.swapaxes(Bu, -1, -2), x_first)
        return X if H is None else X @ np.swapaxes(H, -1, -2)
    K = _chunk_length(n, m, k, steps)
    C = -(-steps // K)
    Yc = np.zeros((B, C * K, m))
    Yc[:, :steps] = Y[:, 1:]
    Yc = Yc.reshape(B, C, K * m)                            # chunk c, step j, channel i -> [c, j*m + i]
    E = _powers_times(F, Bu, K)                             # (B, K, n, m): F^d Bu
    # chunk-end zero-state states: e_c = sum_j F^(K-1-j) Bu y_(cK+j+1)
    E_rev = np.ascontiguousarray(np.swapaxes(E[:, ::-1], 1, 2)).reshape(B, n, K * m)
    ends = Yc @ np.swapaxes(E_rev, -1, -2)                  # (B, C, n)
    # boundary states s_c = x_(cK): s_0 = x_first, s_(c+1) = F^K s_c + e_c
    FK = np.linalg.matrix_power(F, K)
    U = np.zeros((B, C, n))
    U[:, 1:] = ends[:, :-1]
    S = recursion_stepwise(FK, U, x_first) if C < _BOUNDARY_STEPWISE else recursion_chunked(FK, U, x_first)
    # zero-state response inside each chunk, output j of chunk c = sum_(i<=j) M_(j-i) y_i
    M = E if H is None else H[:, None] @ E                  # (B, K, k, m) Markov parameters
    lag = np.subtract.outer(np.arange(K), np.arange(K))    # j - i
    T = M[:, np.maximum(lag, 0)]                            # (B, K, K, k, m): block (j, i) = M_(j-i)
    T[:, lag < 0] = 0.0
    T = np.ascontiguousarray(T.transpose(0, 1, 3, 2, 4)).reshape(B, K * k, K * m)
    out_c = Yc @ np.swapaxes(T, -1, -2)                     # (B, C, K*k)
    # free response of the boundary states: [H F^1 ... H F^K] s_c
    Phi = _left_powers(np.broadcast_to(np.eye(n), (B, n, n)) if H is None else H, F, K).reshape(B, K * k, n)
    out_c += S @ np.swapaxes(Phi, -1, -2)
    out = np.empty((B, N, k))
    out[:, 0] = x_first if H is None else np.einsum("bkn,bn->bk", H, x_first)
    out[:, 1:] = out_c.reshape(B, C * K, k)[:, :steps]
    return out


class ModalBlockTransition:
    """The augmented transition of a classically damped structure in modal coordinates.

    ``A_a = [[A_z, B_z], [0, F_d]]`` whose structural part ``A_z`` consists of four diagonal
    blocks -- the ZOH transition in modal coordinates ``z = [omega q; q']`` (see
    :func:`core_akf.statespace.modal_state_transform`).  :meth:`left` applies ``A_a`` from the
    left in ``O(n_a (1 + n_p))`` operations per column instead of ``O(n_a^2)``, which makes the
    time-varying covariance update ``A_a P A_a^T`` ``O(n_a^2)`` instead of ``O(n_a^3)`` per step.

    Parameters
    ----------
    A_a : ndarray (n_a, n_a)
        The augmented transition, ``n_a = 2 n_modes + n_p``.
    n_modes : int
        Modes of the structural part.
    rtol : float
        Tolerance of the structure test (:meth:`detect`).
    """

    def __init__(self, A_a, n_modes, rtol=1e-12):
        n = int(n_modes)
        nx = 2 * n
        blocks = [np.diag(A_a[i * n:(i + 1) * n, j * n:(j + 1) * n]).copy() for i in (0, 1) for j in (0, 1)]
        rebuilt = np.zeros((nx, nx))
        for (i, j), d in zip(((0, 0), (0, 1), (1, 0), (1, 1)), blocks):
            rebuilt[i * n:(i + 1) * n, j * n:(j + 1) * n] = np.diag(d)
        self.error = float(np.max(np.abs(A_a[:nx, :nx] - rebuilt)) / max(np.max(np.abs(A_a[:nx, :nx])), 1e-300))
        lower = A_a[nx:]
        if self.error > rtol or not np.array_equal(lower, np.eye(A_a.shape[0])[nx:]):
            raise ValueError(f"A_a has no modal block structure (relative off-block size {self.error:.1e})")
        self.n, self.nx = n, nx
        self.d11, self.d12, self.d21, self.d22 = (d[:, None] for d in blocks)
        self.B = A_a[:nx, nx:].copy()

    @classmethod
    def detect(cls, A_a, n_modes, rtol=1e-12):
        """The structured form of ``A_a`` if it has it.

        Parameters
        ----------
        A_a : ndarray (n_a, n_a)
            An augmented transition.
        n_modes : int
            Modes of its structural part.
        rtol : float
            Largest entry outside the four diagonal blocks, relative to the largest entry.

        Returns
        -------
        ModalBlockTransition or None
        """
        try:
            return cls(A_a, n_modes, rtol)
        except ValueError:
            return None

    def left(self, X):
        """``A_a @ X``.

        Parameters
        ----------
        X : ndarray (..., n_a, k)

        Returns
        -------
        ndarray (..., n_a, k)
        """
        n, nx = self.n, self.nx
        q, v, f = X[..., :n, :], X[..., n:nx, :], X[..., nx:, :]
        out = np.empty(X.shape)
        np.matmul(self.B, f, out=out[..., :nx, :])
        out[..., :n, :] += self.d11 * q
        out[..., :n, :] += self.d12 * v
        out[..., n:nx, :] += self.d21 * q
        out[..., n:nx, :] += self.d22 * v
        out[..., nx:, :] = f
        return out

    def propagate(self, P, Q):
        """``A_a P A_a^T + Q``, symmetrised.

        Two left products on contiguous data (``A (A P)^T`` is the transpose of the wanted
        symmetric matrix).

        Parameters
        ----------
        P : ndarray (B, n_a, n_a)
            Posterior covariances.
        Q : ndarray (B, n_a, n_a)
            Process covariances.

        Returns
        -------
        ndarray (B, n_a, n_a)
            The prior covariances of the next step.
        """
        out = self.left(np.ascontiguousarray(np.swapaxes(self.left(P), -1, -2)))
        out += np.swapaxes(out, -1, -2)
        out *= 0.5
        out += Q
        return out
