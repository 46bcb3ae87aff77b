"""Operational modal analysis: natural frequencies, damping ratios and mode shapes from an ambient
record alone (no FE model, no force prior), by covariance-driven stochastic subspace
identification (SSI-cov) with a stabilisation diagram.

The output covariances ``R_i = E[y_(k+i) y_k^T]`` of the record fill a block Hankel matrix of
``block_rows`` future and ``block_rows`` past lags; its SVD gives the observability matrix
``O = [C; C A; C A^2; ...]`` of the stochastic state-space model, and for each model order ``n``
the shift structure of ``O`` gives ``A`` (least squares) and ``C``.  The eigenvalues ``mu`` of
``A`` are the discrete poles: ``lambda = ln(mu) / dt``, ``f = |lambda| / 2 pi``,
``zeta = -Re(lambda) / |lambda|``, mode shape ``C psi``.  A pole is *stable* when the next lower
order has one within ``stable_frequency`` (relative) in frequency, ``stable_damping`` in damping
and a mode-shape MAC above ``stable_mac``; stable poles are grouped by frequency and MAC into
modes, each reported by its median.  The conventions (Hankel, SVD split, least-squares ``A``) are
pyOMA2's SSI-cov, which the tests use as a reference.

Use it as a cross-check of a calibration: :func:`pair_modes` matches the identified modes to an
FE model's by MAC and frequency.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .checks import AKFInputError, as_count, as_time_step, check_numeric_kind

#: a mode is kept when it is stable in at least this share of the model orders scanned
MIN_SHARE = 0.3


@dataclass
class OMAResult:
    """The outcome of :func:`ssi_cov`.

    Attributes
    ----------
    modes : pandas.DataFrame
        One row per identified mode, by frequency: ``frequency_hz``, ``damping``, ``orders``
        (model orders in which it is stable), ``frequency_spread`` (relative standard deviation of
        its frequency over those orders).
    shapes : ndarray (n_modes, n_channels)
        Real mode shapes (largest component +1).
    poles : pandas.DataFrame
        The stabilisation table: every physical pole of every order (``order``, ``frequency_hz``,
        ``damping``, ``stable``).
    channels : list of str
        The channels, in the order of the shapes' columns.
    notes : list of str
        What a user should know (no stable mode found).
    """

    modes: object
    shapes: np.ndarray
    poles: object
    channels: list
    notes: list


#: samples per stretch of the Hankel matrix's sum (its products stay a few MB)
HANKEL_CHUNK = 4096


def hankel(Y: np.ndarray, block_rows: int) -> np.ndarray:
    """The block Hankel matrix of output covariances of SSI-cov.

    Parameters
    ----------
    Y : ndarray (N, l)
        The record, one column per channel.
    block_rows : int
        Lags in the future (and the past) half.

    Returns
    -------
    ndarray (block_rows l, block_rows l)
        Block (i, j) is ``sum_k y_(k+i+1) y_(k-j)^T / M`` over the ``M = N - 2 block_rows + 1``
        samples all lags share.
    """
    Y = np.asarray(Y, float).T                  # (l, N)
    br = int(block_rows)
    M = Y.shape[1] - 2 * br + 1
    H = np.zeros((br * Y.shape[0], br * Y.shape[0]))
    for k in range(0, M, HANKEL_CHUNK):         # over stretches of samples: small arrays, reused memory
        c = min(HANKEL_CHUNK, M - k)
        future = np.vstack([Y[:, k + br + i: k + br + i + c] for i in range(br)])
        past = np.vstack([Y[:, k + br - 1 - j: k + br - 1 - j + c] for j in range(br)])
        H += future @ past.T
    return H / M


def ssi_cov(Y: np.ndarray, dt: float, *, channels: list[str] | None = None, block_rows: int | None = None,
            max_order: int | None = None, max_damping: float = 0.1, stable_frequency: float = 0.01,
            stable_damping: float = 0.05, stable_mac: float = 0.98, min_periods: float = 20.0) -> OMAResult:
    """SSI-cov with a stabilisation diagram.

    Parameters
    ----------
    Y : ndarray (N, l)
        An ambient record (SI), at least two channels, no missing samples.
    dt : float
        Sampling step (s).
    channels : list of str, optional
        Channel names (default ``ch1, ch2, ...``).
    block_rows : int, optional
        Lags of each half of the Hankel matrix (default 20, or ``max_order / l + 1`` when that is
        more, at most 100).
    max_order : int, optional
        The highest model order (even; default 60 or ``block_rows l``, the lower).
    max_damping : float
        Poles with more damping (or not positive) are dropped as not physical.
    stable_frequency, stable_damping, stable_mac : float
        Stability against the next lower order: relative frequency and damping change, least MAC.
    min_periods : float
        The record must hold this many periods of the lowest identified mode (else an error: its
        covariances cannot identify it).

    Returns
    -------
    OMAResult

    Examples
    --------
    Two lightly damped modes at 5 and 12 Hz, seen by two channels, driven by white noise:

    >>> import scipy.signal
    >>> rng = np.random.default_rng(0)
    >>> dt, N = 0.01, 20000
    >>> def mode(f, zeta, e):
    ...     w = 2 * np.pi * f
    ...     b, a = scipy.signal.cont2discrete(([1.0], [1.0, 2 * zeta * w, w * w]), dt)[:2]
    ...     return scipy.signal.lfilter(b.ravel(), a, e)
    >>> q1, q2 = mode(5.0, 0.02, rng.normal(size=N)), mode(12.0, 0.01, rng.normal(size=N))
    >>> Y = np.column_stack([q1 + q2, q1 - 0.5 * q2]) + 1e-4 * rng.normal(size=(N, 2))
    >>> res = ssi_cov(Y, dt, block_rows=30, max_order=20)
    >>> np.round(res.modes["frequency_hz"].to_numpy(), 1).tolist()
    [5.0, 12.0]
    """
    import pandas as pd

    check_numeric_kind(Y, "the record for modal analysis")
    Y = np.asarray(Y, float)
    if Y.ndim != 2 or Y.shape[1] < 2:
        raise AKFInputError(f"operational modal analysis needs at least 2 channels (got {Y.shape[-1] if Y.ndim == 2 else 1})")
    if not np.all(np.isfinite(Y)):
        raise AKFInputError("the record for modal analysis has missing (NaN) or infinite samples: give a stretch "
                            "without holes")
    dt = as_time_step(dt, "dt")
    N, l = Y.shape
    if channels is not None and (not isinstance(channels, (list, tuple)) or not all(isinstance(c, str) for c in channels)):
        raise AKFInputError(f"channels must be a list of channel names, got {type(channels).__name__}")
    channels = list(channels) if channels is not None else [f"ch{i + 1}" for i in range(l)]
    if len(channels) != l:
        raise AKFInputError(f"{len(channels)} channel names for {l} channels")
    flat = [c for c, span in zip(channels, np.ptp(Y, axis=0)) if span == 0]
    if flat:
        raise AKFInputError(f"channel(s) {flat} are constant: they hold no vibration to identify modes from (a "
                            "disconnected sensor?); leave them out")
    if max_order is not None:
        max_order = as_count(max_order, "max_order", 2)
    if block_rows is None:
        block_rows = int(min(100, max(np.ceil((max_order or 60) / l) + 1, 20)))
    br = as_count(block_rows, "block_rows", 2)
    if br < 2 or N < 4 * br * 10:
        raise AKFInputError(f"the record ({N} samples) is too short for {br} block rows: it needs at least "
                            f"{40 * br} samples")
    # the shifted observability matrix has (block_rows - 1) x channels rows: no higher order fits in it
    top = (br - 1) * l
    max_order = int(min(60, top) if max_order is None else max_order)
    if not 2 <= max_order <= top:
        raise AKFInputError(f"max_order must be between 2 and (block_rows - 1) x channels = {top}, got {max_order}")
    Y = Y - Y.mean(axis=0)
    H = hankel(Y, br)
    U, s, _ = np.linalg.svd(H)
    O = U[:, :max_order] * np.sqrt(s[:max_order])          # observability matrix, (br l, max_order)
    Q, Rq = np.linalg.qr(O[:-l])                           # A of order n: least squares on the first n columns
    S = Q.T @ O[l:]
    rows, previous = [], None
    for n in range(2, max_order + 1, 2):
        A = np.linalg.solve(Rq[:n, :n], S[:n, :n])
        mu, psi = np.linalg.eig(A)
        keep = (np.abs(mu) > 0) & (mu.imag > 0)            # one of each conjugate pair; real poles are not modes
        lam = np.log(mu[keep].astype(complex)) / dt
        f = np.abs(lam) / (2 * np.pi)
        zeta = -lam.real / np.abs(lam)
        phi = O[:l, :n] @ psi[:, keep]
        ok = (zeta > 0) & (zeta < max_damping)
        f, zeta, phi = f[ok], zeta[ok], phi[:, ok]
        stable = np.zeros(f.size, bool)
        if previous is not None and previous[0].size:
            pf, pz, pphi = previous
            for i in range(f.size):
                j = int(np.argmin(np.abs(pf - f[i])))
                stable[i] = (abs(pf[j] - f[i]) <= stable_frequency * f[i]
                             and abs(pz[j] - zeta[i]) <= stable_damping * zeta[i]
                             and mac(phi[:, i], pphi[:, j]) >= stable_mac)
        rows += [(n, f[i], zeta[i], stable[i], phi[:, i]) for i in range(f.size)]
        previous = (f, zeta, phi)
    poles = pd.DataFrame([r[:4] for r in rows], columns=["order", "frequency_hz", "damping", "stable"])
    shapes_all = [r[4] for r in rows]
    modes, shapes = _cluster(poles, shapes_all, stable_frequency, stable_mac, max_order)
    if len(modes) and modes["frequency_hz"].iat[0] * N * dt < min_periods:
        f = modes["frequency_hz"].iat[0]
        raise AKFInputError(f"the record ({N * dt:.4g} s) holds fewer than {min_periods:g} periods of its lowest "
                            f"mode ({f:.4g} Hz, {f * N * dt:.3g} periods): its covariances cannot identify it; "
                            f"record at least {min_periods / f:.3g} s")
    notes = [] if len(modes) else ["no mode is stable over the model orders: record longer, or raise max_order"]
    return OMAResult(modes, shapes, poles, channels, notes)


def _cluster(poles, shapes, tol, min_mac, max_order):
    """Stable poles grouped into modes: each stable pole joins the first group within ``2 tol``
    of its median frequency and MAC ``min_mac`` with its first shape; a group stable in at least
    :data:`MIN_SHARE` of the orders is a mode."""
    import pandas as pd

    groups = []
    for i in np.flatnonzero(poles["stable"].to_numpy()):
        f = poles["frequency_hz"].iat[i]
        for g in groups:
            if abs(np.median(g["f"]) - f) <= 2 * tol * f and mac(g["shape"], shapes[i]) >= min_mac:
                g["f"].append(f)
                g["z"].append(poles["damping"].iat[i])
                g["orders"].add(int(poles["order"].iat[i]))
                g["shapes"].append(shapes[i])
                break
        else:
            groups.append({"f": [f], "z": [poles["damping"].iat[i]], "orders": {int(poles["order"].iat[i])},
                           "shape": shapes[i], "shapes": [shapes[i]]})
    kept = [g for g in groups if len(g["orders"]) >= MIN_SHARE * (max_order // 2)]
    kept.sort(key=lambda g: np.median(g["f"]))
    rows, out = [], []
    for g in kept:
        f = np.array(g["f"])
        k = int(np.argmin(np.abs(f - np.median(f))))
        rows.append({"frequency_hz": float(np.median(f)), "damping": float(np.median(g["z"])),
                     "orders": len(g["orders"]), "frequency_spread": float(f.std() / np.median(f))})
        out.append(real_shape(g["shapes"][k]))
    return pd.DataFrame(rows, columns=["frequency_hz", "damping", "orders", "frequency_spread"]), \
        np.array(out).reshape(len(out), -1)


def mac(a: np.ndarray, b: np.ndarray) -> float:
    """The modal assurance criterion of two (complex) shapes: 1 for parallel, 0 for orthogonal.

    Parameters
    ----------
    a, b : ndarray (l,)

    Returns
    -------
    float
    """
    a, b = np.asarray(a), np.asarray(b)
    den = np.real(np.vdot(a, a) * np.vdot(b, b))
    return float(np.abs(np.vdot(a, b)) ** 2 / den) if den > 0 else 0.0


def real_shape(phi: np.ndarray) -> np.ndarray:
    """A complex mode shape rotated to its best real approximation, largest component +1.

    Parameters
    ----------
    phi : ndarray (l,)

    Returns
    -------
    ndarray (l,)
    """
    phi = np.asarray(phi, complex)
    k = int(np.argmax(np.abs(phi)))
    out = (phi / phi[k]).real
    return out / np.max(np.abs(out))


def pair_modes(result: OMAResult, frequencies_hz: np.ndarray, shapes: np.ndarray, min_mac: float = 0.8):
    """Pair identified modes with a model's by MAC, the nearest in frequency among those above
    ``min_mac``.

    Parameters
    ----------
    result : OMAResult
    frequencies_hz : ndarray (k,)
        The model's frequencies.
    shapes : ndarray (k, l)
        The model's mode shapes at the record's channels (the same channels and order).
    min_mac : float

    Returns
    -------
    pandas.DataFrame
        Per identified mode: ``model_mode`` (1-based, or None), ``model_frequency_hz``, ``mac``,
        ``frequency_ratio`` (identified / model).
    """
    import pandas as pd

    shapes = np.asarray(shapes, float)
    frequencies_hz = np.asarray(frequencies_hz, float)
    if shapes.shape != (frequencies_hz.size, result.shapes.shape[1]):
        raise AKFInputError(f"the model's shapes must be (modes, channels) = ({frequencies_hz.size}, "
                            f"{result.shapes.shape[1]}), got {shapes.shape}")
    rows = []
    for f, phi in zip(result.modes["frequency_hz"], result.shapes):
        macs = np.array([mac(phi, s) for s in shapes])
        cands = np.flatnonzero(macs >= min_mac)
        if cands.size == 0:
            rows.append({"model_mode": None, "model_frequency_hz": np.nan, "mac": float(macs.max(initial=0.0)),
                         "frequency_ratio": np.nan})
            continue
        j = int(cands[np.argmin(np.abs(frequencies_hz[cands] - f))])
        rows.append({"model_mode": j + 1, "model_frequency_hz": float(frequencies_hz[j]), "mac": float(macs[j]),
                     "frequency_ratio": float(f / frequencies_hz[j])})
    return pd.concat([result.modes, pd.DataFrame(rows)], axis=1)
