"""The Whittle likelihood: a record's periodogram against a stationary filter model's output spectrum.

The time-domain likelihood (:mod:`core_akf.filter.likelihood`) weighs every frequency of a record
alike.  When the loads have no power over most of the band (band-limited loads, the usual case),
most frequency bins hold noise only, and a force prior whose spectrum cannot fall off steeply
enough (a Matérn) is fitted to those empty bins -- at the price of the bins that matter.  The
Whittle likelihood (Whittle 1953) is the same Gaussian likelihood written bin by bin in frequency:

    l_W = - sum_k [ log det S(w_k) + y_k^H S(w_k)^-1 y_k / N ]

with ``y_k`` the discrete Fourier transform of the record (N steps, tapered by a Tukey window of
:data:`TAPER` and rescaled to its power) at ``w_k = 2 pi k / N`` and
``S(w) = H(w) Q H(w)^H + R`` the model's output spectrum per sample, ``H(w) = G (e^{iw} I - A)^-1``.
Summed over every bin it equals the time-domain likelihood for a long record; summed over the
*signal bins* only -- the bins where a Welch estimate of the record stands :data:`SIGNAL_RATIO`
times above its noise floor (the channels' noise variances R) -- it fits the model to what the
sensors saw of the loads, and nothing to the empty bins.

The spectrum comes from the filter's augmented model ``A_a = [[A, B H], [0, F]]`` (the structure's
modal transition, diagonalisable, and the force model's small blocks): one eigendecomposition of
``A`` per structural model (cached), a batched solve of the force blocks per bin.  It needs a
stationary model: a stable structure and a stationary force prior (a Matérn or Butterworth; not the
random walk).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .checks import AKFInputError

#: a frequency bin is a signal bin when a Welch estimate of some channel stands this many times
#: above that channel's noise floor (its noise variance spread over the band)
SIGNAL_RATIO = 10.0
#: the record is tapered before its Fourier transform (a Tukey window: this fraction of the record
#: in its two cosine ends).  A record's ends do not join (the velocity at its end is not the one at
#: its start), and an untapered periodogram leaks the modes' power into the lowest bins as about
#: 1/f^2: bins a stationary model can explain only with force power far below the first mode,
#: which the accelerations do not see (continuous band-limited loads on S17: the Matérn fit went to
#: 30x the loads' std and a 42 ms time scale, its forces 7-11x the loads' RMS off)
TAPER = 0.2
#: the Welch estimate that picks the signal bins: segments of about this many seconds, at most a
#: quarter of the record
WELCH_SECONDS = 0.25


@dataclass
class SignalBins:
    """The record's Fourier coefficients at its signal bins.

    Attributes
    ----------
    omega : ndarray (K,)
        The bins' angular frequencies per sample (rad/step, in (0, pi)).
    coefficients : ndarray (K, m) complex
        The record's DFT at those bins (its mean removed), SI.
    n_steps : int
        The record's length N.
    fraction : float
        The signal bins among all bins between 0 and the Nyquist frequency (exclusive).
    """

    omega: np.ndarray
    coefficients: np.ndarray
    n_steps: int
    fraction: float

    @property
    def frequencies(self):
        """The bins' frequencies in cycles per step (multiply by the sampling rate for Hz)."""
        return self.omega / (2 * np.pi)


def signal_bins(Y, noise_var, ratio: float | None = None, segment: int | None = None) -> SignalBins:
    """The bins of ``Y``'s periodogram where some channel stands ``ratio`` times above its noise.

    Parameters
    ----------
    Y : ndarray (N, m)
        The record (SI), without missing samples.
    noise_var : array_like (m,)
        Each channel's noise variance (SI^2): its floor is this variance spread evenly over the band.
    ratio : float, optional
        Default :data:`SIGNAL_RATIO`.
    segment : int, optional
        The Welch segment in steps (default a power of two near N / 4, at most 4096).

    Returns
    -------
    SignalBins
    """
    Y = np.asarray(Y, float)
    N, m = Y.shape
    ratio = SIGNAL_RATIO if ratio is None else float(ratio)
    noise_var = np.broadcast_to(np.asarray(noise_var, float), (m,))
    if segment is None:
        segment = int(2 ** np.floor(np.log2(max(N / 4, 16))))
        segment = min(segment, 4096)
    freq, P = welch_density(Y - Y.mean(axis=0), min(segment, N))
    level = P / (2 * noise_var)                              # one-sided density of white noise: 2 sigma^2 per unit
    over = np.max(level, axis=1) >= ratio
    k = np.arange(1, (N - 1) // 2 + 1)                          # 0 < w < pi
    f_k = k / N
    keep = np.interp(f_k, freq, over.astype(float)) >= 0.5
    window = tukey(N, TAPER)
    # scaled so that E|y_k|^2 / N is still the spectrum where it is smooth over the window's width
    Yf = np.fft.rfft((Y - Y.mean(axis=0)) * window[:, None], axis=0)[k[keep]] * np.sqrt(N / np.sum(window ** 2))
    return SignalBins(2 * np.pi * f_k[keep], Yf, N, float(keep.mean()) if k.size else 0.0)


def tukey(N, fraction):
    """A Tukey (tapered cosine) window of ``N`` points with ``fraction`` of them in its two cosine
    ends (``scipy.signal.windows.tukey(N, fraction)``; 0 is the rectangle, 1 the Hann window).

    Parameters
    ----------
    N : int
        Points.
    fraction : float
        The share of the points in the cosine ends, 0 to 1.

    Returns
    -------
    ndarray (N,)
    """
    n = np.arange(N, dtype=float)
    width = fraction * (N - 1) / 2
    if width <= 0:
        return np.ones(N)
    edge = np.minimum(n, N - 1 - n)
    return np.where(edge < width, 0.5 * (1 - np.cos(np.pi * edge / width)), 1.0)


def welch_density(Y, segment):
    """Welch's one-sided power spectral density of the columns of ``Y``, per unit of frequency in
    cycles per step: periodic Hann windows of ``segment`` steps overlapping by half, no detrending,
    the segments' periodograms averaged -- ``scipy.signal.welch(Y, nperseg=segment, axis=0,
    detrend=False)``, without importing :mod:`scipy.signal` (0.8 s, a tenth of a calibration).

    Parameters
    ----------
    Y : ndarray (N, m)
    segment : int
        Steps per segment, at most N.

    Returns
    -------
    freq : ndarray (segment // 2 + 1,)
        Cycles per step.
    P : ndarray (segment // 2 + 1, m)
        Units of ``Y`` squared per cycle per step.
    """
    Y = np.asarray(Y, float)
    segment = int(segment)
    window = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(segment) / segment)
    hop = segment - segment // 2
    starts = np.arange(0, Y.shape[0] - segment + 1, hop)
    P = np.zeros((segment // 2 + 1, Y.shape[1]))
    for s in starts:
        P += np.abs(np.fft.rfft(Y[s:s + segment] * window[:, None], axis=0)) ** 2
    P /= len(starts) * np.sum(window ** 2)
    P[1:segment // 2 + (segment % 2)] *= 2                  # one-sided: all but 0 and (even segment) Nyquist
    return np.fft.rfftfreq(segment), P


def stationary(A_a, nx) -> bool:
    """Whether an augmented model has a stationary output: every pole inside the unit circle, and
    no structural state driving the force states.

    Parameters
    ----------
    A_a : ndarray (n_a, n_a)
        The augmented transition ``[[A, B H], [0, F]]``.
    nx : int
        The structure's states (the first ``nx``).

    Returns
    -------
    bool
    """
    if np.any(A_a[nx:, :nx] != 0):
        return False
    return bool(np.max(np.abs(np.linalg.eigvals(A_a))) < 1.0 - 1e-12)


class _Structural:
    """One structural model's eigendecomposition, for the spectrum's structural transfer."""

    def __init__(self, A, G_x, coupling, Q_x):
        lam, V = np.linalg.eig(A)
        cond = np.linalg.cond(V)
        if not np.isfinite(cond) or cond > 1e10:
            raise AKFInputError("the structural transition matrix is not diagonalisable (repeated poles): the "
                                "Whittle likelihood needs distinct poles; use calibrate_method = \"time\"")
        Vinv = np.linalg.inv(V)
        self.lam = lam
        self.M = G_x @ V                                # (m, nx)
        self.coupling = Vinv @ coupling                 # (nx, ng): V^-1 B H
        w, U = np.linalg.eigh(0.5 * (Q_x + Q_x.T))
        keep = w > w.max() * 1e-12 if w.size and w.max() > 0 else np.zeros(w.size, bool)
        self.noise = Vinv @ (U[:, keep] * np.sqrt(w[keep]))      # (nx, r): V^-1 Q^(1/2)

    def transfer(self, z):
        """``G (zI - A)^-1 V`` at the points ``z`` (K,): (K, m, nx)."""
        return self.M[None] / (z[:, None] - self.lam[None])[:, None, :]


def output_spectrum(A_a, G, Q_a, R, nx, omega, structural=None):
    """The model's output spectrum per sample at ``omega``: ``S = H Q_a H^H + R``.

    Parameters
    ----------
    A_a, G, Q_a, R : ndarray
        The augmented model (n_a, n_a), (m, n_a), (n_a, n_a), (m, m): ``A_a = [[A, B H], [0, F]]``
        with the structure's ``nx`` states first, and ``Q_a`` block diagonal.
    nx : int
        The structure's states.
    omega : ndarray (K,)
        Angular frequencies per sample (rad/step).
    structural : optional
        A cached decomposition of the structural block (as returned by :func:`structural_part`).

    Returns
    -------
    ndarray (K, m, m) complex
        ``E[y_k y_k^H] / N`` of a long record at those bins.
    """
    part = structural if structural is not None else structural_part(A_a, G, Q_a, nx)
    z = np.exp(1j * np.asarray(omega, float))
    Tx = part.transfer(z)                                           # (K, m, nx)
    S = np.zeros((z.size,) + R.shape, complex)
    if part.noise.shape[1]:
        T = Tx @ part.noise
        S += T @ np.conj(np.swapaxes(T, 1, 2))
    F, G_f, Q_f = A_a[nx:, nx:], G[:, nx:], Q_a[nx:, nx:]
    if F.shape[0]:
        w, U = np.linalg.eigh(0.5 * (Q_f + Q_f.T))
        keep = w > 0
        root = U[:, keep] * np.sqrt(w[keep])                       # (ng, r_f)
        W = Tx @ part.coupling + G_f[None]                         # (K, m, ng)
        I = np.eye(F.shape[0])
        Rf = np.linalg.solve(z[:, None, None] * I[None] - F[None], np.broadcast_to(root, (z.size,) + root.shape))
        T = W @ Rf
        S += T @ np.conj(np.swapaxes(T, 1, 2))
    return S + R[None]


def structural_part(A_a, G, Q_a, nx):
    """The eigendecomposition of the structural block that :func:`output_spectrum` reuses.

    Parameters
    ----------
    A_a, G, Q_a : ndarray
        The augmented transition (n_a, n_a), observation (m, n_a) and process covariance (n_a, n_a).
    nx : int
        The structure's states (the first ``nx``).

    Returns
    -------
    object
        To pass as ``structural`` to :func:`output_spectrum` while only the force model changes.

    Raises
    ------
    AKFInputError
        If the structural block is not diagonalisable.
    """
    return _Structural(A_a[:nx, :nx], G[:, :nx], A_a[:nx, nx:], Q_a[:nx, :nx])


def whittle_terms(S, bins: SignalBins):
    """Each signal bin's Whittle term ``-(log det S_k + y_k^H S_k^-1 y_k / N)``.

    Parameters
    ----------
    S : ndarray (K, m, m) complex
        The model's output spectrum at the bins (:func:`output_spectrum`).
    bins : SignalBins
        The record's coefficients at the same bins.

    Returns
    -------
    ndarray (K,)
        ``-inf`` where ``S_k`` is not positive definite.
    """
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        return np.full(S.shape[0], -np.inf)
    logdet = 2 * np.sum(np.log(np.real(np.diagonal(L, axis1=1, axis2=2))), axis=1)
    v = np.linalg.solve(L, bins.coefficients[:, :, None])[..., 0]
    return -(logdet + np.sum(np.abs(v) ** 2, axis=1) / bins.n_steps)
