"""Discrete algebraic Riccati equation of the Kalman filter, batched.

The filter DARE for the prior (one-step predicted) covariance ``P``::

    P = A P A^T - A P G^T (G P G^T + R)^-1 G P A^T + Q

is solved by the structure-preserving doubling algorithm (SDA; Chu, Fan & Lin 2005) on
the dual control problem ``(A^T, G^T)``.  Each doubling step costs one inverse and a few
matrix products and squares the convergence factor, so ~10-25 steps reach machine
precision even for lightly damped structures.  The algorithm runs on a stack of
problems at once (leading batch axis); each problem stops iterating when it has converged, so
its solution does not depend on what else shares the stack, and a stack of small problems is
split over threads (:mod:`core_akf.filter.recursion`) with the same result.  A solution whose residual
is above rounding level is polished by Newton (Hewer) steps; one that still fails, or did not converge, is re-solved
with :func:`scipy.linalg.solve_discrete_are` and a :class:`RiccatiWarning`, and that
solution's residual is checked too: a :class:`RiccatiError` names the problems without an
accurate solution.
"""
from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg
from scipy.linalg.lapack import dgetrf as _getrf
from scipy.linalg.lapack import dgetri as _getri

from ..checks import AKFInputError
from .recursion import split_stack


class RiccatiError(AKFInputError):
    """The filter DARE has no accurate stabilising solution (typically an undetectable sensor set).

    Parameters
    ----------
    message : str
    problems : sequence of int
        The indices of the failing problems in the (flattened) batch.
    """

    def __init__(self, message, problems=()):
        super().__init__(message)
        self.problems = tuple(int(b) for b in problems)


class RiccatiWarning(RuntimeWarning):
    """The doubling solver fell back to scipy for at least one problem."""


def _solve_each(S, B):
    """``S^-1 B`` for a stack; a singular or non-finite problem gives NaN instead of failing the
    whole stack."""
    try:
        return np.linalg.solve(S, B)
    except np.linalg.LinAlgError:
        if S.ndim == 2:
            return np.full(np.broadcast_shapes(S.shape[:-1] + (1,), B.shape), np.nan)
        out = np.full(np.broadcast_shapes(S.shape[:-2], B.shape[:-2]) + B.shape[-2:], np.nan)
        for b in range(out.shape[0]):
            try:
                out[b] = np.linalg.solve(S[b], B[b] if B.ndim == S.ndim else B)
            except np.linalg.LinAlgError:
                pass
        return out


def frobenius(X):
    """Frobenius norms of a stack of matrices, ``sqrt(sum x_ij^2)`` (as :func:`numpy.linalg.norm`
    computes it, unscaled, at a tenth of its time on stacks of small matrices).

    Parameters
    ----------
    X : ndarray (..., n, k)

    Returns
    -------
    ndarray (...)
    """
    return np.sqrt(np.einsum("...ij,...ij->...", X, X))


def inverse_stack(W):
    """Inverses of a stack of matrices by LAPACK's ``getrf`` + ``getri``, one matrix at a time.

    Twice as fast as :func:`numpy.linalg.inv` on a stack of 67 x 67 matrices (2.5 against 5.3 ms
    for 35 of them on one thread) and 1.4x at 162 x 162: numpy inverts by ``gesv`` with n
    right-hand sides, whose small triangular solves run at a tenth of the product rate.

    Parameters
    ----------
    W : ndarray (B, n, n)

    Returns
    -------
    ndarray (B, n, n)

    Raises
    ------
    numpy.linalg.LinAlgError
        For a singular matrix (a non-finite one gives a non-finite inverse, as numpy's does).
    """
    out = np.empty_like(W)
    for b in range(W.shape[0]):
        lu, piv, info = _getrf(W[b], overwrite_a=False)
        if info == 0:
            out[b], info = _getri(lu, piv, overwrite_lu=True)
        if info != 0:
            raise np.linalg.LinAlgError(f"singular matrix in a stack (problem {b})")
    return out


def dare_residual(A, G, Q, R, P):
    """Relative residual of the filter DARE for each problem in a stack.

    Parameters
    ----------
    A : ndarray (..., n, n)
    G : ndarray (..., m, n)
    Q : ndarray (..., n, n)
    R : ndarray (..., m, m)
    P : ndarray (..., n, n)
        The candidate prior covariance.

    Returns
    -------
    ndarray (...)
        ``inf`` where ``P`` makes the innovation covariance singular or is not finite.
    """
    APGt = A @ P @ np.swapaxes(G, -1, -2)
    S = G @ P @ np.swapaxes(G, -1, -2) + R
    with np.errstate(all="ignore"):
        rhs = A @ P @ np.swapaxes(A, -1, -2) - APGt @ _solve_each(S, np.swapaxes(APGt, -1, -2)) + Q
        num = frobenius(rhs - P)
        den = np.maximum(frobenius(P), np.finfo(float).tiny)
        res = num / den
    return np.where(np.isfinite(res), res, np.inf)


def _scale(A, G, Q):
    """Diagonal state scaling ``x = T z`` that brings the states to comparable size: the
    process-noise standard deviations, or for noise-free states the inverse size of their
    observation columns; returns the diagonal of T, shape (..., n)."""
    q = np.sqrt(np.abs(np.diagonal(Q, axis1=-2, axis2=-1)))
    g = np.linalg.norm(G, axis=-2)
    t = np.where(q > 0, q, 1.0)
    # states without process noise: scale by the observation column size instead
    t = np.where((q == 0) & (g > 0), 1.0 / np.where(g > 0, g, 1.0), t)
    return t


def solve_filter_dare(A, G, Q, R, tol=1e-13, max_iter=80, check=True, newton_steps=3):
    """Stabilising solution ``P`` (prior covariance) of the filter DARE.

    Parameters
    ----------
    A : ndarray (..., n, n)
    G : ndarray (..., m, n)
    Q : ndarray (..., n, n), symmetric PSD
    R : ndarray (..., m, m), symmetric PD
        Leading axes broadcast against each other (a batch of problems).
    tol, max_iter : convergence of the doubling iteration
    check : bool
        Check the DARE residual of each solution; polish a poor one with up to
        ``newton_steps`` Newton (Hewer) steps, and re-solve one that is still poor with scipy.
    newton_steps : int
        See ``check``.

    Returns
    -------
    P : ndarray (..., n, n)
    """
    A, G, Q, R = (np.asarray(x, dtype=float) for x in (A, G, Q, R))
    batch = np.broadcast_shapes(A.shape[:-2], G.shape[:-2], Q.shape[:-2], R.shape[:-2])
    n, m = A.shape[-1], G.shape[-2]
    nb = int(np.prod(batch, dtype=int))
    A = np.broadcast_to(A, batch + (n, n)).reshape(nb, n, n)
    G = np.broadcast_to(G, batch + (m, n)).reshape(nb, m, n)
    Q = np.broadcast_to(Q, batch + (n, n)).reshape(nb, n, n)
    R = np.broadcast_to(R, batch + (m, m)).reshape(nb, m, m)
    if n > _OWN_THREADS_UP_TO:          # large problems: BLAS's threads share the work
        return _solve_stack(A, G, Q, R, tol, max_iter, check, newton_steps).reshape(batch + (n, n))
    # small problems: BLAS on one thread, the stack split over threads (core_akf.filter.recursion).  The
    # problems are independent and each is iterated on its own (see _solve_stack), so every
    # split gives the same bits -- also in a joblib or dask worker
    outcomes = split_stack(lambda i: _solve_stack(A[i], G[i], Q[i], R[i], tol, max_iter, check, newton_steps), nb)
    P = np.empty((nb, n, n))
    failed = []
    for i, part, exc in outcomes:
        if isinstance(exc, RiccatiError):
            failed.append((i, exc))
        elif exc is not None:
            raise exc
        else:
            P[i] = part
    if failed:
        problems = [i.start + j for i, exc in failed for j in exc.problems]
        raise RiccatiError(str(failed[0][1]).replace(str(list(failed[0][1].problems)), str(problems)), problems)
    return P.reshape(batch + (n, n))


#: up to this many states a stack runs with single-threaded BLAS, split over threads of its own
#: (measured on 70 states: 1.6x faster than multi-threaded BLAS; at 162 states the same)
_OWN_THREADS_UP_TO = 256


def accurate_filter_dare(A, G, Q, R, newton_steps=3):
    """The filter DARE of one problem by doubling and Newton polishing only, or None where its
    solution is not accurate (relative residual above ``_RESIDUAL_OK``): no scipy fall-back and no
    warning, for a caller that has a slower exact path of its own (a cycle of observation patterns,
    :func:`core_akf.filter.kernels._periodic_riccati`).

    Parameters
    ----------
    A : ndarray (n, n)
    G : ndarray (m, n)
    Q : ndarray (n, n), symmetric PSD
    R : ndarray (m, m), symmetric PD
    newton_steps : int
        Newton (Hewer) steps at most on a solution above rounding level.

    Returns
    -------
    ndarray (n, n) or None
    """
    A, G, Q, R = (np.asarray(x, dtype=float)[None] for x in (A, G, Q, R))
    with np.errstate(all="ignore"):
        P = _solve_stack(A, G, Q, R, 1e-13, 80, False, newton_steps)
        ok = np.all(np.isfinite(P), axis=(-2, -1))
        res = _polish(A, G, Q, R, P, ok, newton_steps)
    return P[0] if res[0] < _RESIDUAL_OK else None


def _solve_stack(A, G, Q, R, tol, max_iter, check, newton_steps):
    """:func:`solve_filter_dare` on a flat stack (nb, n, n)."""
    nb, n = A.shape[0], A.shape[-1]
    t = _scale(A, G, Q)                          # x = diag(t) z
    As = A * t[..., None, :] / t[..., :, None]   # T^-1 A T
    Gs = G * t[..., None, :]                     # G T
    Qs = Q / t[..., :, None] / t[..., None, :]   # T^-1 Q T^-T
    # SDA on the dual: Ak = A^T, Gk = G^T R^-1 G, Hk = Q
    Ak = np.swapaxes(As, -1, -2).copy()
    RiG = np.linalg.solve(R, Gs)
    Gk = np.swapaxes(Gs, -1, -2) @ RiG
    Gk = 0.5 * (Gk + np.swapaxes(Gk, -1, -2))
    Hk = Qs.copy()
    eye = np.eye(n)
    converged = np.zeros(nb, dtype=bool)
    # the problems still iterating, kept packed (A_k, G_k, H_k): a converged one leaves the pack
    # with its solution and is not touched again, so each result is the same whatever else shares
    # its batch, and no iteration gathers or scatters the whole stack
    active = np.arange(nb)
    A_k, G_k, H_k = Ak, Gk, Hk.copy()
    for _ in range(max_iter):
        try:
            # the explicit inverse and two products: 1.5x faster than a solve with 2n right-hand
            # sides for these sizes (OpenBLAS's small triangular solves are slow), as accurate
            # (W = I + G H has eigenvalues >= 1), and checked by the DARE residual below
            Wi = inverse_stack(eye + G_k @ H_k)
        except np.linalg.LinAlgError:
            break
        A_kt = np.swapaxes(A_k, -1, -2)
        WiA = Wi @ A_k
        H_new = H_k + A_kt @ H_k @ WiA
        G_new = G_k + A_k @ (Wi @ (G_k @ A_kt))
        A_k = A_k @ WiA
        H_new = 0.5 * (H_new + np.swapaxes(H_new, -1, -2))
        G_k = 0.5 * (G_new + np.swapaxes(G_new, -1, -2))
        with np.errstate(over="ignore", invalid="ignore"):     # a diverging problem: caught just below
            diff = frobenius(H_new - H_k)
            size = frobenius(H_new)
        H_k = H_new
        if not np.all(np.isfinite(H_new)):
            break
        done = diff <= tol * np.maximum(size, np.finfo(float).tiny)
        if np.any(done):
            Hk[active[done]] = H_new[done]
            converged[active[done]] = True
            keep = ~done
            active, A_k, G_k, H_k = active[keep], A_k[keep], G_k[keep], H_k[keep]
        if not active.size:
            break
    Hk[active] = H_k                     # the problems that did not converge: their last iterate
    P = Hk * t[..., :, None] * t[..., None, :]
    if check:
        ok = converged & np.all(np.isfinite(P), axis=(-2, -1))
        res = _polish(A, G, Q, R, P, ok, newton_steps)
        _fall_back(A, G, Q, R, P, res)
    return P


def _polish(A, G, Q, R, P, ok, newton_steps):
    """The relative DARE residual of every solution (inf where ``ok`` is False), after Newton steps
    on those above rounding level (``P`` is changed in place where a step lowers the residual)."""
    res = np.full(P.shape[0], np.inf)
    if not np.any(ok):
        return res
    res[ok] = dare_residual(A[ok], G[ok], Q[ok], R[ok], P[ok])
    # polish whenever the residual is above rounding level: a Newton step costs about as
    # much as the doubling and brings e.g. 6.5e-10 to 1e-16; a step is kept only where it
    # lowers the residual
    for _ in range(newton_steps):
        idx = np.flatnonzero(ok & (res > _RESIDUAL_POLISH))
        if not idx.size:
            break
        with np.errstate(all="ignore"):
            P_new = newton_step(A[idx], G[idx], Q[idx], R[idx], P[idx])
        finite = np.all(np.isfinite(P_new), axis=(-2, -1))
        res_new = np.full(idx.size, np.inf)
        if np.any(finite):
            res_new[finite] = dare_residual(A[idx[finite]], G[idx[finite]], Q[idx[finite]], R[idx[finite]],
                                            P_new[finite])
        better = res_new < res[idx]
        P[idx[better]] = P_new[better]
        res[idx[better]] = res_new[better]
        if not np.any(better):
            break
    return res


def _fall_back(A, G, Q, R, P, res):
    """scipy's solver for the problems whose residual is not accepted (``P`` changed in place);
    a :class:`RiccatiError` naming those it cannot solve either."""
    nb = P.shape[0]
    bad = np.flatnonzero(~(res < _RESIDUAL_OK))
    if not bad.size:
        return
    warnings.warn(f"doubling Riccati solver did not converge for {bad.size} of {nb} problem(s); "
                  "falling back to scipy.linalg.solve_discrete_are", RiccatiWarning, stacklevel=3)
    for b in bad:
        try:
            P[b] = scipy.linalg.solve_discrete_are(A[b].T, G[b].T, Q[b], R[b])
            res[b] = dare_residual(A[b], G[b], Q[b], R[b], P[b])
        except (np.linalg.LinAlgError, ValueError):
            res[b] = np.inf
    failed = bad[~(res[bad] < _RESIDUAL_OK)]
    if failed.size:
        worst = res[failed[0]]
        raise RiccatiError(
            f"no accurate stabilising steady-state gain for problem(s) {failed.tolist()} of the batch "
            f"(relative DARE residual {worst:.2g} after doubling, Newton polishing and scipy; accepted "
            f"below {_RESIDUAL_OK:g}); the sensor set is probably undetectable or nearly so, or the covariance "
            "levels are far from the data's scale (check model_error_cov, force_increment_cov and "
            "noise_cov) -- run the time-varying filter (steady=False) to see the drift", problems=failed)


#: relative DARE residual accepted (after polishing) without falling back to scipy, and accepted
#: from scipy: above it the gain is wrong in its 8th digit, far beyond the rounding of the data
_RESIDUAL_OK = 1e-8
#: relative DARE residual above which a solution is polished by Newton steps: a few hundred eps,
#: the rounding level of the residual itself for the model sizes here (n_a <= ~1000)
_RESIDUAL_POLISH = 1e-13


def stein_doubling(F, E, tol=1e-14, max_iter=60):
    """Solution ``X`` of the Stein equation ``X = F X F^T + E`` (``rho(F) < 1``) by Smith's doubling.

    ``X <- X + F_j X F_j^T``, ``F_j <- F_j^2``: every term is added, none subtracted, so nothing
    cancels.

    Parameters
    ----------
    F : ndarray (..., n, n)
    E : ndarray (..., n, n)
    tol : float
        Relative size of the last term added.
    max_iter : int
        Doublings at most.

    Returns
    -------
    ndarray (..., n, n)
    """
    X = np.array(E, dtype=float)
    Fj = np.array(F, dtype=float)
    if X.ndim == 2:
        return stein_doubling(Fj[None], X[None], tol, max_iter)[0]
    Fj = np.broadcast_to(Fj, X.shape).copy()
    active = np.arange(X.shape[0])      # a converged problem is left as it is (batch-independent)
    for _ in range(max_iter):
        F_a = Fj[active]
        inc = F_a @ X[active] @ np.swapaxes(F_a, -1, -2)
        X[active] += inc
        Fj[active] = F_a @ F_a
        done = frobenius(inc) <= tol * frobenius(X[active])
        active = active[~done]
        if not active.size:
            break
    return 0.5 * (X + np.swapaxes(X, -1, -2))


def newton_step(A, G, Q, R, P):
    """One Newton (Hewer) step for the filter DARE from a stabilising estimate ``P``.

    With the gain ``K = P G^T (G P G^T + R)^-1`` and ``F = A (I - K G)`` the Joseph form
    ``P = F P F^T + A K R K^T A^T + Q`` holds at the solution; the correction ``D`` solves
    ``D = F D F^T + (Joseph residual)``, so P converges quadratically and the large terms of
    the DARE never cancel.

    Parameters
    ----------
    A : ndarray (..., n, n)
    G : ndarray (..., m, n)
    Q : ndarray (..., n, n)
    R : ndarray (..., m, m)
    P : ndarray (..., n, n)
        The estimate.

    Returns
    -------
    ndarray (..., n, n)
        The improved estimate.
    """
    n = A.shape[-1]
    Gt = np.swapaxes(G, -1, -2)
    S = G @ P @ Gt + R
    K = np.swapaxes(_solve_each(S, G @ P), -1, -2)
    F = A @ (np.eye(n) - K @ G)
    AK = A @ K
    W = F @ P @ np.swapaxes(F, -1, -2) + AK @ R @ np.swapaxes(AK, -1, -2) + Q
    return P + stein_doubling(F, 0.5 * (W + np.swapaxes(W, -1, -2)) - P)


def steady_gain(A, G, Q, R, **kwargs):
    """Steady-state prior covariance and Kalman gain of a stack of filters.

    Parameters
    ----------
    A : ndarray (..., n, n)
    G : ndarray (..., m, n)
    Q : ndarray (..., n, n)
    R : ndarray (..., m, m)
    **kwargs
        Options of :func:`solve_filter_dare` (``tol``, ``max_iter``, ``check``, ``newton_steps``).

    Returns
    -------
    P : ndarray (..., n, n)
        The prior covariance.
    L : ndarray (..., n, m)
        ``P G^T (G P G^T + R)^-1``.
    """
    P = solve_filter_dare(A, G, Q, R, **kwargs)
    S = G @ P @ np.swapaxes(G, -1, -2) + R
    L = np.swapaxes(np.linalg.solve(S, G @ P), -1, -2)  # S symmetric
    return P, L
