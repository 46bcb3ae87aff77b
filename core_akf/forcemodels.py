"""Force models: the prior the filter puts on each unknown force.

``random_walk`` (the papers' model, S17 eq. 14): ``f_k+1 = f_k + w_k`` with ``Var w = S``.  It
has a pole at 1: a force is only pinned down by sensors that see the static response (strain,
displacement).  Accelerations do not, so an accelerometer-only set drifts.

``matern12``, ``matern32``, ``matern52``: a stationary Gaussian process with a Matérn covariance
of smoothness ``nu = 1/2, 3/2, 5/2`` (the Gaussian-process latent force model, GPLFM; Hartikainen &
Särkkä 2010, Nayek, Chakraborty & Narasimhan 2019).  Each force gets ``p + 1`` states (``nu = p +
1/2``), the force and its first ``p`` derivatives, driven by white noise through the SDE
``d xi/dt = F xi + L w``; the force is ``f = H xi``.  The process has its poles at ``-lambda``
(``lambda = sqrt(2 nu) / timescale``): a force forgets its past after a few time scales, so
accelerations alone make the augmented model detectable.  The parameters are ``std`` (N, the
standard deviation of the force) and ``timescale`` (s, the Matérn length scale ``l``).

The states are scaled, ``xi = [f, f'/lambda, f''/lambda^2]``: every state then has the force's
size, ``F = lambda N_p`` with a constant companion matrix ``N_p``, and the stationary covariance is
``std^2`` times a constant matrix.  Discretisation is exact for any time step: ``F_d = expm(F dt)``
and ``Q_d`` by Van Loan's integral, so ``H F_d^j P_inf H^T`` is the Matérn kernel at lag ``j dt``.

``butterworth``: white noise through an analog Butterworth filter of order ``n`` (2-8): a low-pass
of corner ``f_high`` (``band = (0, f_high)``), whose spectrum is ``1 / (1 + (f / f_high)^(2n))``,
or a band-pass (``f_low > 0``; ``2 n`` states per force), ``1 / (1 + ((f^2 - f_0^2) / (f B))^(2n))``
with ``f_0 = sqrt(f_low f_high)`` and ``B = f_high - f_low``.  Its spectrum is flat in the band and
falls by ``20 n`` dB per decade outside it, so a prior for band-limited loads need not put power
where they have none (a Matérn process can only fall off steeply by moving its corner down).  It
is realised as a cascade of second-order sections in scaled states (each of the force's size),
with the noise intensity set so that the force's standard deviation is ``std``.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from math import comb, gamma, sqrt
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg

from .checks import AKFInputError, ArrayLike, Layout

if TYPE_CHECKING:
    from .structure import Structure

#: the force models, by name; the value is the Matérn order ``p`` (states per force ``p + 1``),
#: None for the random walk and the Butterworth model
FORCE_MODELS = {"random_walk": None, "matern12": 0, "matern32": 1, "matern52": 2, "butterworth": None}
#: the orders a Butterworth force model may have
BUTTERWORTH_ORDERS = range(2, 9)


#: how a load goes from one sample to the next: held over the step, or linear between samples
LOAD_HOLDS = ("zero", "linear")


def check_load_hold(hold):
    """``hold`` if it is one of :data:`LOAD_HOLDS`, else an :class:`AKFInputError` naming them.

    Parameters
    ----------
    hold : str
        ``"zero"`` or ``"linear"``.

    Returns
    -------
    str
    """
    if hold not in LOAD_HOLDS:
        raise AKFInputError(f"load_hold must be one of {list(LOAD_HOLDS)}, got {hold!r}")
    return hold


def _positive(value, name, n_p, unit):
    """One positive finite value per force (a scalar or a sequence of n_p)."""
    try:
        arr = np.asarray(value, float)
    except (TypeError, ValueError):
        raise AKFInputError(f"{name} must be a positive number ({unit}) or one per force, got {value!r}") from None
    if arr.ndim > 1 or (arr.ndim == 1 and arr.size != n_p):
        raise AKFInputError(f"{name} must be one value or one per force ({n_p}), got {arr.size} values")
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise AKFInputError(f"{name} must be positive and finite ({unit}), got {value!r}")
    return np.broadcast_to(arr, (n_p,)).astype(float)


def _companion(p):
    """``N_p`` and the unit noise intensity of a Matérn-(p+1/2) process with ``lambda = 1``, ``std = 1``,
    in the scaled states: ``F = lambda N_p``, ``Q_c = std^2 lambda q_p e_p e_p^T``."""
    N = np.diag(np.ones(p), 1)
    N[p, :] = -np.array([comb(p + 1, k) for k in range(p + 1)], float)
    q = 2.0 * sqrt(np.pi) * gamma(p + 1) / gamma(p + 0.5)
    return N, q


def _band(value, n_p):
    """One band ``(f_low, f_high)`` (Hz) per force, checked: ``0 <= f_low < f_high``, finite."""
    try:
        arr = np.asarray(value, float)
    except (TypeError, ValueError):
        raise AKFInputError(f"force_band must be [f_low, f_high] in Hz (or one per force), got {value!r}") from None
    if arr.shape not in ((2,), (n_p, 2)):
        raise AKFInputError(f"force_band must be [f_low, f_high] in Hz, or one such pair per force ({n_p}); "
                            f"got shape {arr.shape}")
    arr = np.broadcast_to(arr, (n_p, 2)).astype(float)
    if not np.all(np.isfinite(arr)) or np.any(arr[:, 0] < 0) or np.any(arr[:, 1] <= arr[:, 0]):
        raise AKFInputError(f"force_band must satisfy 0 <= f_low < f_high (Hz, finite), got {value!r}: "
                            "f_low = 0 is a low-pass, f_low > 0 a band-pass")
    return arr


def _butterworth_system(order, f_low, f_high):
    """One force's Butterworth shaping filter, driven by unit white noise: ``(F, b, h)`` with
    ``d xi/dt = F xi + b w``, ``f = h xi = xi_0``; a cascade of sections in states ``[v, v'/omega]``,
    the last section's output (the force) moved to the first state, and every state scaled to
    the force's stationary variance."""
    proto = np.exp(1j * np.pi * (2 * np.arange(1, order + 1) + order - 1) / (2 * order))   # left half plane
    if f_low == 0:
        poles, zeros = 2 * np.pi * f_high * proto, 0
    else:
        w0, bw = 2 * np.pi * np.sqrt(f_low * f_high), 2 * np.pi * (f_high - f_low)
        half = proto * bw / 2
        root = np.sqrt(half ** 2 - w0 ** 2 + 0j)
        poles, zeros = np.r_[half + root, half - root], order
    upper = poles[poles.imag > 1e-9 * np.abs(poles)]
    real = np.sort(poles[np.abs(poles.imag) <= 1e-9 * np.abs(poles)].real)
    sections = [(abs(p), -p.real / abs(p)) for p in upper]        # (omega, zeta) of a second-order section
    if zeros and real.size:                                        # a band-pass's real poles come in pairs
        sections += [(np.sqrt(a * b), -(a + b) / (2 * np.sqrt(a * b))) for a, b in real.reshape(-1, 2)]
        real = real[:0]
    sections.sort(key=lambda sec: sec[1])        # the least damped first: the best-conditioned cascade
    n = 2 * len(sections) + real.size
    F, b, h = np.zeros((n, n)), np.zeros(n), np.zeros(n)
    i, previous = 0, None            # previous: the index of the last section's output
    for k, (w, z) in enumerate(sections):
        F[i:i + 2, i:i + 2] = w * np.array([[0.0, 1.0], [-1.0, -2.0 * z]])
        if previous is None:
            b[i + 1] = w
        else:
            F[i + 1, previous] = w
        previous = i + 1 if k < zeros else i      # a band-pass section's output is v'/omega: one zero at s = 0
        i += 2
    for p in real:                                 # a low-pass of odd order: one first-order section
        F[i, i] = p.real
        if previous is None:
            b[i] = -p.real
        else:
            F[i, previous] = -p.real
        previous = i
        i += 1
    order_ = [previous] + [j for j in range(n) if j != previous]     # the force first, as every force model has it
    h[0] = 1.0
    F, b = F[np.ix_(order_, order_)], b[order_]
    P = scipy.linalg.solve_continuous_lyapunov(F, -np.outer(b, b))
    if not (np.all(np.isfinite(P)) and np.all(np.diag(P) > 0)):
        raise AKFInputError(f"force_band [{f_low:g}, {f_high:g}] Hz is too narrow or too wide for a Butterworth filter "
                            f"of order {order} to be computed accurately: use a lower force_band_order")
    d = np.sqrt(P[0, 0] / np.diag(P))          # every state with the force's variance: a balanced cascade
    return d[:, None] * F / d[None, :], d * b, h


def butterworth_psd(frequencies: ArrayLike, order: int, f_low: float, f_high: float) -> np.ndarray:
    """The two-sided power spectral density of a unit-variance Butterworth process, in closed form:
    ``c / (1 + u^(2 n))`` with ``u = f / f_high`` (low-pass) or ``(f^2 - f_0^2) / (f B)``
    (band-pass), ``c = n sin(pi / 2n) / (pi B)`` so that it integrates to 1 (``B = f_high`` for
    a low-pass).

    Parameters
    ----------
    frequencies : array_like (L,)
        (Hz), not zero for a band-pass.
    order : int
    f_low, f_high : float
        The band (Hz).

    Returns
    -------
    ndarray (L,)
        (1/Hz).
    """
    f = np.abs(np.asarray(frequencies, float))
    if f_low == 0:
        u, width = f / f_high, f_high
    else:
        width = f_high - f_low
        u = (f ** 2 - f_low * f_high) / (f * width)
    return order * np.sin(np.pi / (2 * order)) / (np.pi * width) / (1.0 + u ** (2 * order))


#: the largest relative error of a Butterworth realisation's spectrum (at the band's edges and
#: centre) against the closed form; beyond it the band is too narrow or too wide for its order
BUTTERWORTH_TOLERANCE = 1e-8


@dataclass(frozen=True, eq=False)        # parameters may be arrays: compared by identity, not element-wise
class ForceModel:
    """The prior of the unknown forces.

    Parameters
    ----------
    kind : str
        One of :data:`FORCE_MODELS`: ``"random_walk"`` (default), ``"matern12"``, ``"matern32"``,
        ``"matern52"``, ``"butterworth"``.
    increment_cov : float or array_like (n_p,) or (n_p, n_p), optional
        Random walk: ``S``, the variance of the force increment per step (N^2), one for all
        forces, one per force or the matrix.
    std : float or array_like (n_p,), optional
        Matérn and Butterworth: the standard deviation of each force (N).
    timescale : float or array_like (n_p,), optional
        Matérn: the length scale ``l`` of the covariance (s); a force is correlated over about
        ``l`` and forgets its past after a few ``l``.
    band : array_like (2,) or (n_p, 2), optional
        Butterworth: ``(f_low, f_high)`` (Hz), the pass band; ``f_low = 0`` is a low-pass.
        ``f_high`` must lie below the Nyquist frequency of the time step it is used at.
    band_order : int
        Butterworth: the filter's order, 2-8 (default 4); the spectrum falls by ``20 band_order``
        dB per decade outside the band.
    hold : str
        How a force goes from one sample to the next, one of :data:`LOAD_HOLDS`: ``"zero"``
        (default; held over the step, the papers' filter) or ``"linear"`` (linear between samples,
        a continuous load; the filter then runs the first-order hold of the structure).  A filter
        whose hold differs from the loads' is wrong by the load's change over a step
        (``docs/guide/forcemodels.md``).

    Examples
    --------
    >>> fm = ForceModel("matern32", std=600.0, timescale=2e-3)
    >>> fm.states_per_force, fm.stationary
    (2, True)
    >>> round(float(fm.kernel([0.0, 2e-3])[0, 1] / 600.0 ** 2), 4)   # (1 + sqrt 3) exp(-sqrt 3)
    0.4834
    >>> bw = ForceModel("butterworth", std=500.0, band=(0.0, 120.0))
    >>> bw.states_per_force, round(float(bw.psd([0.0, 120.0])[0, 1] / bw.psd([0.0])[0, 0]), 6)   # -3 dB at f_high
    (4, 0.5)
    """

    kind: str = "random_walk"
    increment_cov: object = None
    std: object = None
    timescale: object = None
    band: object = None
    band_order: int = 4
    hold: str = "zero"

    def __post_init__(self):
        check_load_hold(self.hold)
        if not isinstance(self.kind, str) or self.kind not in FORCE_MODELS:
            raise AKFInputError(f"unknown force model {self.kind!r}; the force models are {list(FORCE_MODELS)}")
        if self.kind != "butterworth" and self.band is not None:
            raise AKFInputError(f"force_band belongs to the Butterworth force model; the {self.kind} force model "
                                "does not take it")
        if self.kind == "random_walk":
            if self.increment_cov is None:
                raise AKFInputError("the random-walk force model needs force_increment_cov (S, N^2 per step)")
            if self.std is not None or self.timescale is not None:
                raise AKFInputError("force_std and force_timescale belong to a Matérn force model (matern12, matern32, "
                                    "matern52); the random walk has force_increment_cov only")
        elif self.kind == "butterworth":
            if self.std is None or self.band is None:
                raise AKFInputError("the butterworth force model needs force_std (N) and force_band ([f_low, f_high], Hz)")
            if self.timescale is not None:
                raise AKFInputError("force_timescale belongs to a Matérn force model; the butterworth model has "
                                    "force_band ([f_low, f_high], Hz) instead")
            if isinstance(self.band_order, bool) or not isinstance(self.band_order, (int, np.integer)) \
                    or self.band_order not in BUTTERWORTH_ORDERS:
                raise AKFInputError(f"force_band_order must be an integer from {BUTTERWORTH_ORDERS.start} to "
                                    f"{BUTTERWORTH_ORDERS.stop - 1}, got {self.band_order!r}")
            _positive(self.std, "force_std", np.size(self.std), "N")
            _band(self.band, len(self.band) if np.ndim(self.band) == 2 else 1)
        else:
            if self.std is None or self.timescale is None:
                raise AKFInputError(f"the {self.kind} force model needs force_std (N) and force_timescale (s)")
            _positive(self.std, "force_std", np.size(self.std), "N")
            _positive(self.timescale, "force_timescale", np.size(self.timescale), "s")

    @property
    def order(self):
        """The Matérn order ``p`` (``nu = p + 1/2``); None for the random walk."""
        return FORCE_MODELS[self.kind]

    @property
    def stationary(self):
        """Whether the force is a stationary process (Matérn and Butterworth); the random walk is not."""
        return self.kind != "random_walk"

    @property
    def states_per_force(self):
        """The filter states each force takes: 1 for the random walk, ``p + 1`` for a Matérn model,
        the order for a Butterworth low-pass and twice it for a band-pass."""
        if self.kind == "butterworth":
            low = np.asarray(self.band, float).reshape(-1, 2)[:, 0]
            return self.band_order * (1 if np.all(low == 0) else 2)
        return 1 if self.order is None else self.order + 1

    def n_states(self, n_p: int) -> int:
        """The force states for ``n_p`` forces.

        Parameters
        ----------
        n_p : int
            Forces.

        Returns
        -------
        int
        """
        return self.states_per_force * int(n_p)

    def parameters(self, n_p: int) -> tuple:
        """The parameters, one per force, checked.

        Parameters
        ----------
        n_p : int
            Forces.

        Returns
        -------
        tuple
            ``(S,)`` for the random walk, S (n_p, n_p) (N^2 per step); ``(std, timescale, lambda)``,
            each (n_p,) (N, s, 1/s), for a Matérn model; ``(std, band)``, (n_p,) and (n_p, 2)
            (N, Hz), for the Butterworth model.
        """
        if self.kind == "random_walk":
            from .covariances import diag_levels

            return (diag_levels(self.increment_cov, n_p, "force_increment_cov"),)
        if self.kind == "butterworth":
            band = _band(self.band, n_p)
            if np.any(band[:, 0] == 0) and not np.all(band[:, 0] == 0):
                raise AKFInputError(f"force_band: either every force has a low-pass (f_low = 0) or none; got {band.tolist()}")
            return _positive(self.std, "force_std", n_p, "N"), band
        std = _positive(self.std, "force_std", n_p, "N")
        ell = _positive(self.timescale, "force_timescale", n_p, "s")
        return std, ell, sqrt(2 * self.order + 1) / ell

    def output(self, n_p: int) -> np.ndarray:
        """``H``: the forces from the force states, ``f = H xi``.

        Parameters
        ----------
        n_p : int
            Forces.

        Returns
        -------
        ndarray (n_p, n_g)
        """
        k = self.states_per_force
        H = np.zeros((n_p, k * n_p))
        H[np.arange(n_p), k * np.arange(n_p)] = 1.0
        return H

    def continuous(self, n_p: int) -> tuple:
        """The continuous-time force model ``d xi/dt = F xi + w``, ``E[w w^T] = Q_c delta``.

        Parameters
        ----------
        n_p : int
            Forces.

        Returns
        -------
        F : ndarray (n_g, n_g)
            Zero for the random walk (1/s).
        Q_c : ndarray (n_g, n_g) or None
            The white-noise intensity (N^2/s); None for the random walk, whose ``S`` is per step.
        """
        k = self.states_per_force
        if self.kind == "random_walk":
            return np.zeros((n_p, n_p)), None
        if self.kind == "butterworth":
            std, band = self.parameters(n_p)
            F, Qc = np.zeros((k * n_p, k * n_p)), np.zeros((k * n_p, k * n_p))
            for j in range(n_p):
                s = slice(k * j, k * (j + 1))
                Fj, b, h = _butterworth_system(self.band_order, *band[j])
                P1 = scipy.linalg.solve_continuous_lyapunov(Fj, -np.outer(b, b))
                var = float(h @ P1 @ h)
                probe = np.array([band[j, 1], np.sqrt(band[j, 0] * band[j, 1]) or 0.5 * band[j, 1], band[j, 0] or 1.0])
                eye = np.eye(len(b))
                got = np.array([abs(h @ np.linalg.solve(2j * np.pi * f * eye - Fj, b)) ** 2 for f in probe]) / var
                if not np.allclose(got, butterworth_psd(probe, self.band_order, *band[j]), rtol=BUTTERWORTH_TOLERANCE,
                                   atol=0):
                    raise AKFInputError(f"force_band {band[j].tolist()} Hz is too narrow or too wide for a Butterworth "
                                        f"filter of order {self.band_order} to be computed accurately: use a lower "
                                        "force_band_order")
                F[s, s] = Fj
                Qc[s, s] = std[j] ** 2 / var * np.outer(b, b)
            return F, Qc
        std, _, lam = self.parameters(n_p)
        N, q = _companion(self.order)
        F, Qc = np.zeros((k * n_p, k * n_p)), np.zeros((k * n_p, k * n_p))
        for j in range(n_p):
            s = slice(k * j, k * (j + 1))
            F[s, s] = lam[j] * N
            Qc[k * j + k - 1, k * j + k - 1] = std[j] ** 2 * lam[j] * q
        return F, Qc

    def discrete(self, n_p: int, dt: float) -> tuple:
        """The exact discretisation over one step ``dt``: ``xi_k+1 = F_d xi_k + w_k``, ``Var w_k = Q_d``.

        Parameters
        ----------
        n_p : int
            Forces.
        dt : float
            Time step (s).

        Returns
        -------
        F_d : ndarray (n_g, n_g)
        Q_d : ndarray (n_g, n_g)
            (N^2); ``S`` for the random walk.
        """
        if self.kind == "random_walk":
            return np.eye(n_p), self.parameters(n_p)[0]
        if self.kind == "butterworth":
            top = float(np.max(self.parameters(n_p)[1][:, 1]))
            if not top < 0.5 / float(dt):
                raise AKFInputError(f"force_band reaches {top:.4g} Hz, at or above the Nyquist frequency "
                                    f"{0.5 / float(dt):.4g} Hz of the time step {float(dt):.4g} s: the filter cannot "
                                    "resolve that band; give f_high below it")
        F, Qc = self.continuous(n_p)
        k = self.states_per_force
        F_d, Q_d = np.zeros_like(F), np.zeros_like(F)
        for j in range(n_p):              # block by block: each force on its own time scale
            s = slice(k * j, k * (j + 1))
            F_d[s, s] = scipy.linalg.expm(F[s, s] * dt)
            Q_d[s, s] = van_loan(F[s, s], Qc[s, s], dt)
        return F_d, Q_d

    def stationary_covariance(self, n_p: int) -> np.ndarray:
        """``P_inf``, the stationary covariance of the force states (a Matérn model).

        Parameters
        ----------
        n_p : int
            Forces.

        Returns
        -------
        ndarray (n_g, n_g)
            (N^2); solves ``F P + P F^T + Q_c = 0``.

        Raises
        ------
        AKFInputError
            For the random walk, which has none.
        """
        if not self.stationary:
            raise AKFInputError("the random-walk force model is not stationary: it has no stationary covariance")
        F, Qc = self.continuous(n_p)
        P = scipy.linalg.solve_continuous_lyapunov(F, -Qc)
        return 0.5 * (P + P.T)

    def kernel(self, lags: ArrayLike, n_p: int = 1) -> np.ndarray:
        """The covariance function ``k(tau) = E[f(t) f(t + tau)]`` of each force: the Matérn
        kernel in closed form; for the Butterworth model ``h expm(F tau) P_inf h^T``.

        Parameters
        ----------
        lags : array_like (L,)
            Time lags ``tau`` (s).
        n_p : int
            Forces.

        Returns
        -------
        ndarray (n_p, L)
            (N^2).
        """
        if not self.stationary:
            raise AKFInputError("the random-walk force model is not stationary: it has no covariance function")
        if self.kind == "butterworth":
            F, _ = self.continuous(n_p)
            P, H = self.stationary_covariance(n_p), self.output(n_p)
            taus = np.abs(np.asarray(lags, float))
            return np.stack([np.einsum("ij,jk,ik->i", H, scipy.linalg.expm(F * t) @ P, H) for t in taus], axis=1)
        std, _, lam = self.parameters(n_p)
        r = lam[:, None] * np.abs(np.asarray(lags, float))[None, :]
        poly = {0: 1.0, 1: 1.0 + r, 2: 1.0 + r + r ** 2 / 3.0}[self.order]
        return std[:, None] ** 2 * poly * np.exp(-r)

    def sample(self, n_steps: int, dt: float, n_p: int = 1, seed: int | np.random.Generator | None = None) -> np.ndarray:
        """Force histories drawn from this prior (a stationary model): its exact discretisation
        started from the stationary distribution -- loads for which the prior is right.

        Parameters
        ----------
        n_steps : int
            Steps.
        dt : float
            Time step (s).
        n_p : int
            Forces.
        seed : int or numpy.random.Generator, optional

        Returns
        -------
        ndarray (n_steps, n_p)
            (N).

        Examples
        --------
        >>> f = ForceModel("matern12", std=100.0, timescale=0.01).sample(20000, 1e-3, seed=0)
        >>> 80 < float(f.std()) < 120
        True
        """
        if not self.stationary:
            raise AKFInputError("the random-walk force model is not stationary: draw its increments instead")
        F_d, Q_d = self.discrete(n_p, dt)
        rng = np.random.default_rng(seed)
        L = np.linalg.cholesky(Q_d)
        xi = rng.multivariate_normal(np.zeros(F_d.shape[0]), self.stationary_covariance(n_p))
        H = self.output(n_p)
        loads = np.empty((int(n_steps), n_p))
        for k in range(int(n_steps)):
            loads[k] = H @ xi
            xi = F_d @ xi + L @ rng.standard_normal(F_d.shape[0])
        return loads

    def scaled(self, std_factor: ArrayLike = 1.0, timescale_factor: ArrayLike = 1.0) -> ForceModel:
        """The same kind with its std and time scale multiplied (a stationary model; calibration).

        A Butterworth model's time scale is the inverse of its band: a time-scale factor ``t``
        divides both band edges by ``t``.

        Parameters
        ----------
        std_factor, timescale_factor : float or array_like (n_p,)
            Factors on ``std`` and ``timescale``.

        Returns
        -------
        ForceModel
        """
        if not self.stationary:
            raise AKFInputError("force_std and force_timescale belong to a stationary force model (Matérn, Butterworth)")
        std = np.asarray(self.std, float) * std_factor
        if self.kind == "butterworth":
            t = np.asarray(timescale_factor, float)
            band = np.asarray(self.band, float) / (t[:, None] if t.ndim else t)
            return replace(self, std=std, band=band)
        return replace(self, std=std, timescale=np.asarray(self.timescale, float) * timescale_factor)

    def with_std(self, std: ArrayLike) -> ForceModel:
        """The same stationary model with another standard deviation.

        Parameters
        ----------
        std : float or array_like (n_p,)
            (N).

        Returns
        -------
        ForceModel
        """
        if not self.stationary:
            raise AKFInputError("force_std belongs to a stationary force model (Matérn, Butterworth)")
        return replace(self, std=std)

    def psd(self, frequencies: ArrayLike, n_p: int = 1) -> np.ndarray:
        """The two-sided power spectral density of each force, from the state space:
        ``H (i w - F)^-1 Q_c (i w - F)^-H H^T`` at ``w = 2 pi f``; ``k(0) = int S(f) df``.

        Parameters
        ----------
        frequencies : array_like (L,)
            (Hz).
        n_p : int
            Forces.

        Returns
        -------
        ndarray (n_p, L)
            (N^2/Hz).
        """
        if not self.stationary:
            raise AKFInputError("the random-walk force model is not stationary: it has no spectral density")
        F, Qc = self.continuous(n_p)
        H = self.output(n_p)
        eye = np.eye(F.shape[0])
        out = np.empty((n_p, np.size(frequencies)))
        for i, f in enumerate(np.atleast_1d(np.asarray(frequencies, float))):
            T = H @ np.linalg.solve(2j * np.pi * f * eye - F, eye)
            out[:, i] = np.einsum("ij,jk,ik->i", T, Qc, T.conj()).real
        return out

    def describe(self) -> str:
        """A one-line description with the parameters, for reports.

        Returns
        -------
        str
        """
        def fmt(v):
            a = np.atleast_1d(np.asarray(v, float))
            if a.ndim == 2:
                a = np.diag(a)
            return f"{a[0]:.4g}" if np.all(a == a[0]) else "[" + ", ".join(f"{x:.4g}" for x in a) + "]"
        if self.kind == "random_walk":
            return f"random walk, S = {fmt(self.increment_cov)} N^2 per step"
        if self.kind == "butterworth":
            band = np.asarray(self.band, float).reshape(-1, 2)
            edges = ", ".join(f"{lo:.4g}-{hi:.4g}" for lo, hi in (band[:1] if np.all(band == band[0]) else band))
            return f"butterworth (order {self.band_order}), std = {fmt(self.std)} N, band = {edges} Hz"
        return f"{self.kind}, std = {fmt(self.std)} N, time scale = {fmt(self.timescale)} s"


def van_loan(A_c: ArrayLike, Q_c: ArrayLike, dt: float) -> np.ndarray:
    """Discrete process-noise covariance ``Q = int_0^dt e^{A t} Q_c e^{A^T t} dt`` (Van Loan).

    Parameters
    ----------
    A_c : ndarray (n, n)
    Q_c : ndarray (n, n)
        Continuous-time noise intensity.
    dt : float
        Time step (s).

    Returns
    -------
    ndarray (n, n)
    """
    n = A_c.shape[0]
    blk = np.zeros((2 * n, 2 * n))
    blk[:n, :n] = -A_c
    blk[:n, n:] = Q_c
    blk[n:, n:] = A_c.T
    E = scipy.linalg.expm(blk * dt)
    Ad = E[n:, n:].T
    Q = Ad @ E[:n, n:]
    return 0.5 * (Q + Q.T)


def as_force_model(force_model=None, force_increment_cov=None) -> ForceModel:
    """The :class:`ForceModel` of a call: the one given, or the random walk of ``force_increment_cov``.

    Parameters
    ----------
    force_model : ForceModel, str or None
        A model; a name (``"random_walk"`` only: a Matérn model needs its parameters); None: the
        random walk.
    force_increment_cov : float or array_like, optional
        ``S`` of the random walk (N^2 per step).

    Returns
    -------
    ForceModel

    Raises
    ------
    AKFInputError
        For an unknown model, a Matérn name without parameters, or ``force_increment_cov`` given
        with a Matérn model (it would be silently unused).

    Examples
    --------
    >>> as_force_model(None, 1e4).describe()
    'random walk, S = 1e+04 N^2 per step'
    """
    if force_model is None or (isinstance(force_model, str) and force_model == "random_walk"):
        return ForceModel("random_walk", increment_cov=force_increment_cov)
    if isinstance(force_model, str):
        if force_model not in FORCE_MODELS:
            raise AKFInputError(f"unknown force model {force_model!r}; the force models are {list(FORCE_MODELS)}")
        what = "band=(f_low, f_high)" if force_model == "butterworth" else "timescale=..."
        raise AKFInputError(f"the {force_model} force model needs its parameters: "
                            f"ForceModel({force_model!r}, std=..., {what})")
    if not isinstance(force_model, ForceModel):
        raise AKFInputError(f"force_model must be a ForceModel or a name, got {type(force_model).__name__}")
    if force_model.stationary and force_increment_cov is not None:
        raise AKFInputError(f"force_increment_cov is the random walk's S; the {force_model.kind} force model has "
                            "force_std and force_timescale instead: drop force_increment_cov")
    return force_model


@dataclass(frozen=True, eq=False)
class DummyMeasurements:
    """Zero-valued pseudo-measurements of chosen displacements or strains (Naets, Cuadrado &
    Desmet 2015).

    Each dummy channel says "this displacement (strain) is zero, give or take ``sqrt(variance)``".
    It anchors the quasi-static response that accelerations cannot see, so an accelerometer-only
    set under the random-walk force model does not drift; it costs no state.  It biases a load
    with a true static part towards zero: choose the variance of the response you expect.

    Parameters
    ----------
    sensors : sequence of str
        Displacement (``"disp:8:y"``) or strain (``"strain:13"``) sensor specs on the filter's model.
    variance : float
        The pseudo-measurement variance (m^2 for displacements, (m/m)^2 for strains).

    Examples
    --------
    >>> from core_akf.models import s17_truss
    >>> [s.label for s in DummyMeasurements(["disp:8:y"], 1e-8).layout(s17_truss(), [])]
    ['disp:8:y']
    """

    sensors: tuple
    variance: float

    def __post_init__(self):
        if not isinstance(self.sensors, (str, list, tuple)):
            raise AKFInputError(f"dummy sensors must be a list of labels (e.g. [\"disp:8:y\"]), got {self.sensors!r}")
        sensors = (self.sensors,) if isinstance(self.sensors, str) else tuple(self.sensors)
        object.__setattr__(self, "sensors", sensors)
        if not sensors:
            raise AKFInputError("dummy: name at least one displacement or strain (e.g. \"disp:8:y\")")
        try:
            var = float(self.variance)
        except (TypeError, ValueError):
            raise AKFInputError(f"dummy variance must be a positive number, got {self.variance!r}") from None
        if not np.isfinite(var) or var <= 0:
            raise AKFInputError(f"dummy variance must be positive and finite (m^2 or (m/m)^2), got {self.variance!r}")
        object.__setattr__(self, "variance", var)

    def layout(self, structure: Structure, real: Layout) -> list:
        """The dummy channels as sensors of ``structure``, checked.

        Parameters
        ----------
        structure : Structure
            The filter's model.
        real : sequence of Sensor
            The real layout (a dummy may not repeat one of its channels).

        Returns
        -------
        list of Sensor

        Raises
        ------
        AKFInputError
            For a dummy that is not a displacement or strain, not on the model, given twice, or
            the same as a real sensor.
        """
        from .sensors import as_layout, selection_matrices

        try:
            layout = as_layout(self.sensors)
            selection_matrices(structure, layout)
        except AKFInputError as exc:
            raise AKFInputError(f"dummy: {exc}") from None
        bad = [s.label for s in layout if s.kind not in ("disp", "strain")]
        if bad:
            raise AKFInputError(f"dummy: {bad} are not displacements or strains; a dummy measurement is a zero "
                                "displacement (\"disp:8:y\") or strain (\"strain:13\")")
        labels = [s.label for s in layout]
        both = sorted(set(labels) & {s.label for s in real})
        if both:
            raise AKFInputError(f"dummy: {both} are measured sensors of the layout; a dummy is a channel not measured")
        return list(layout)
