"""What a sensor layout can see: the steady filter's transfer function from the true forces to
their estimates, ``F_hat(f) = T(f) F(f)``.

The structure's forces reach the sensors through ``P(z) = G (zI - A)^-1 B + D`` (the filter's own
model, the noise left out); the steady filter, which first updates with ``y_k`` and then predicts,
turns the measurements into force estimates through ``H_f (zI - M)^-1 z K`` with ``M = (I - K G_a)
A_a``.  Their product at ``z = exp(2 pi i f dt)`` is ``T(f)`` (n_p x n_p per frequency): where
``|T_jj| ~ 1`` force j is recovered, where it falls towards 0 the layout does not see it (an
accelerometer below the first mode: the static part of a load), and off-diagonal terms are forces
mistaken for one another.  The test checks ``T`` against the filter run on sinusoidal loads.
"""
from __future__ import annotations

import numpy as np

from ..checks import AKFInputError, ArrayLike
from ..forcemodels import ForceModel
from .model import Filter, FilterModel
from .riccati import RiccatiError, steady_gain

#: frequencies per batched solve (bounds the (chunk, n_a, n_a) complex arrays)
_CHUNK = 32


def _plant(f: Filter):
    """``(A, B, G, D)`` of the structure from the forces to the filter's channels (dummies read 0),
    in the filter's modal states."""
    unit = ForceModel("random_walk", increment_cov=0.0, hold=f.force_model.hold)
    fm = FilterModel(f.model.full, f.locs, f.dt, f.model.n_modes, force_model=unit)
    nx = fm.n_states
    G = np.stack([fm.observation(list(layout) + f.dummy_layout) for layout in f.layouts])
    G[:, f.m:] = 0.0                          # a dummy channel is a zero, whatever the forces do
    return fm.A_a[:nx, :nx], fm.A_a[:nx, nx:], G[..., :nx], G[..., nx:]


def force_transfer(f: Filter, frequencies: ArrayLike) -> np.ndarray:
    """The steady filter's transfer from the true forces to their estimates.

    Parameters
    ----------
    f : Filter
        A filter of one or more layouts (its steady gain is used, whatever ``f.steady``).
    frequencies : array_like (n_f,)
        Frequencies (Hz), from 0 up to the Nyquist frequency ``0.5 / dt``.

    Returns
    -------
    ndarray (B, n_f, n_p, n_p), complex
        ``T[b, i, j, l]``: the estimate of force j from a unit sinusoid of force l at frequency i,
        layout b.

    Raises
    ------
    AKFInputError
        For frequencies outside ``[0, 0.5 / dt]``, or a layout without a steady filter.

    Examples
    --------
    >>> import numpy as np
    >>> from core_akf.filter import Filter
    >>> from core_akf.models import s17_truss
    >>> f = Filter(s17_truss(), [["strain:13", "acc:8:y"]], ["8:y"], 1e-3, model_error_cov=1e-16,
    ...            force_increment_cov=1e4, noise_cov={"strain": 1e-14, "acc": 1e-4})
    >>> round(abs(complex(force_transfer(f, [0.0])[0, 0, 0, 0])), 6)       # a static load, seen by the gauge
    1.0
    """
    freq = np.atleast_1d(np.asarray(frequencies, float))
    if freq.ndim != 1 or not np.all(np.isfinite(freq)) or np.any(freq < 0) or np.any(freq > 0.5 / f.dt * (1 + 1e-12)):
        raise AKFInputError(f"frequencies must lie from 0 to the Nyquist frequency {0.5 / f.dt:.6g} Hz")
    if not all(r.detectable for r in f.reports):
        raise AKFInputError("the transfer function is the steady filter's, and an undetectable sensor set has none "
                            "(" + "; ".join(", ".join(s.label for s in lay) for lay, r in zip(f.layouts, f.reports)
                                            if not r.detectable) + ")")
    B = len(f.layouts)
    try:
        _, K = steady_gain(np.broadcast_to(f.A_a, (B,) + f.A_a.shape), f.G_a,
                           np.broadcast_to(f.Q_a, (B,) + f.Q_a.shape), f.R)
    except RiccatiError as exc:
        raise f.riccati_error(exc) from None
    A, Bp, Gp, Dp = _plant(f)
    n_a, nx = f.A_a.shape[0], A.shape[0]
    M = (np.eye(n_a) - K @ f.G_a) @ f.A_a                  # (B, n_a, n_a)
    rows = f.model.force_rows()                               # (n_p, n_a)
    out = np.empty((B, freq.size, rows.shape[0], Bp.shape[1]), complex)
    for start in range(0, freq.size, _CHUNK):
        z = np.exp(2j * np.pi * freq[start:start + _CHUNK] * f.dt)[:, None, None]
        plant = Gp[:, None] @ np.linalg.solve(z * np.eye(nx) - A, Bp)[None] + Dp[:, None]      # (B, c, m, n_p)
        est = np.linalg.solve(z[None] * np.eye(n_a) - M[:, None], z[None] * K[:, None])        # (B, c, n_a, m)
        out[:, start:start + _CHUNK] = rows @ est @ plant
    return out


def recovered_band(frequencies: ArrayLike, gain: ArrayLike, tolerance: float = np.sqrt(2.0)):
    """The widest band of contiguous frequencies where ``1 / tolerance <= |gain| <= tolerance``.

    Parameters
    ----------
    frequencies : array_like (n_f,)
        Increasing frequencies (Hz).
    gain : array_like (n_f,)
        ``|T_jj|`` at them.
    tolerance : float
        The factor allowed either way (default sqrt 2, 3 dB).

    Returns
    -------
    tuple of float or None
        ``(f_low, f_high)`` (Hz), or None where the force is recovered at no frequency.
    """
    freq, g = np.asarray(frequencies, float), np.abs(np.asarray(gain))
    ok = (g >= 1.0 / tolerance) & (g <= tolerance)
    best, start = None, None
    for i, flag in enumerate(np.r_[ok, False]):
        if flag and start is None:
            start = i
        elif not flag and start is not None:
            if best is None or freq[i - 1] - freq[start] > best[1] - best[0]:
                best = (float(freq[start]), float(freq[i - 1]))
            start = None
    return best


__all__ = ["force_transfer", "recovered_band"]
