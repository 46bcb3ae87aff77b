"""Load generators (N) on a uniform time grid ``t = k dt``; all random ones take a ``seed``
(int or :class:`numpy.random.Generator`) so a run can be repeated exactly."""
from __future__ import annotations

import numpy as np

from .checks import AKFInputError, Seed, Signal, Time


def time_grid(n_steps: int, dt: float) -> Time:
    """The time of each step, ``t_k = k dt`` for ``k = 0..n_steps-1``.

    Parameters
    ----------
    n_steps : int
    dt : float
        Time step (s).

    Returns
    -------
    ndarray (n_steps,)
        Time (s).

    Examples
    --------
    >>> time_grid(4, 0.5).tolist()
    [0.0, 0.5, 1.0, 1.5]
    """
    n_steps = int(n_steps)
    if n_steps < 1:
        raise AKFInputError(f"n_steps must be >= 1, got {n_steps}")
    if not np.isfinite(dt) or dt <= 0:
        raise AKFInputError(f"dt must be a positive number of seconds, got {dt!r}")
    return np.arange(n_steps) * float(dt)


def _rng(seed):
    return seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)


def half_sine_pulse(t: Time, start: float, duration: float, peak: float) -> Signal:
    """An impact: one half sine.

    Parameters
    ----------
    t : ndarray (N,)
        Time (s).
    start : float
        Start of the pulse (s).
    duration : float
        Length of the pulse (s).
    peak : float
        Amplitude (N).

    Returns
    -------
    ndarray (N,)
        Force (N).

    Examples
    --------
    >>> t = time_grid(10, 1e-3)
    >>> half_sine_pulse(t, 0.002, 0.004, 100.0).round(1).tolist()
    [0.0, 0.0, 0.0, 70.7, 100.0, 70.7, 0.0, 0.0, 0.0, 0.0]
    """
    if duration <= 0:
        raise AKFInputError(f"pulse duration must be positive, got {duration!r}")
    t = np.asarray(t, float)
    tau = (t - start) / duration
    return np.where((tau >= 0) & (tau <= 1), peak * np.sin(np.pi * np.clip(tau, 0, 1)), 0.0)


def ramp(t: Time, start: float, end: float, peak: float) -> Signal:
    """Zero until ``start``, linear to ``peak`` at ``end``, then held.

    Parameters
    ----------
    t : ndarray (N,)
        Time (s).
    start, end : float
        Start and end of the rise (s).
    peak : float
        Final value (N).

    Returns
    -------
    ndarray (N,)
        Force (N).

    Examples
    --------
    >>> ramp(time_grid(5, 1.0), 1.0, 3.0, 10.0).tolist()
    [0.0, 0.0, 5.0, 10.0, 10.0]
    """
    if end <= start:
        raise AKFInputError(f"ramp end ({end}) must be after its start ({start})")
    t = np.asarray(t, float)
    return peak * np.clip((t - start) / (end - start), 0.0, 1.0)


def half_sine(t: Time, start: float, end: float, peak: float) -> Signal:
    """A slow half sine: zero, rising to ``peak`` mid-way between ``start`` and ``end``, back to zero.

    Parameters
    ----------
    t : ndarray (N,)
        Time (s).
    start, end : float
        Start and end of the half sine (s).
    peak : float
        Amplitude (N).

    Returns
    -------
    ndarray (N,)
        Force (N).

    Examples
    --------
    >>> half_sine(time_grid(5, 1.0), 0.0, 4.0, 10.0).round(2).tolist()
    [0.0, 7.07, 10.0, 7.07, 0.0]
    """
    if end <= start:
        raise AKFInputError(f"half-sine end ({end}) must be after its start ({start})")
    return half_sine_pulse(t, start, end - start, peak)


def sine(t: Time, frequency: float, amplitude: float, phase: float = 0.0) -> Signal:
    """``amplitude sin(2 pi frequency t + phase)``.

    Parameters
    ----------
    t : ndarray (N,)
        Time (s).
    frequency : float
        Hz.
    amplitude : float
        N.
    phase : float
        rad.

    Returns
    -------
    ndarray (N,)
        Force (N).

    Examples
    --------
    >>> sine(time_grid(4, 0.25), 1.0, 2.0).round(6).tolist()
    [0.0, 2.0, 0.0, -2.0]
    """
    return amplitude * np.sin(2 * np.pi * frequency * np.asarray(t, float) + phase)


def white_noise(n_steps: int, std: float, seed: Seed = None) -> Signal:
    """Gaussian white noise.

    Parameters
    ----------
    n_steps : int
    std : float
        Standard deviation (N).
    seed : int or numpy.random.Generator, optional
        The random stream (None: fresh entropy, not repeatable).

    Returns
    -------
    ndarray (n_steps,)
        Force (N).

    Examples
    --------
    >>> f = white_noise(100000, 50.0, seed=0)
    >>> round(float(f.std()), 0)
    50.0
    """
    return _rng(seed).normal(0.0, std, int(n_steps))


def band_limited_white_noise(n_steps: int, dt: float, rms: float, f_low: float = 0.0, f_high: float | None = None,
                             seed: Seed = None) -> Signal:
    """Gaussian noise with a flat spectrum in a band, scaled to an RMS value.

    Built in the frequency domain (zero outside the band), so the band edges are sharp.

    Parameters
    ----------
    n_steps : int
    dt : float
        Time step (s).
    rms : float
        RMS of the result (N).
    f_low : float
        Lower band edge (Hz).
    f_high : float, optional
        Upper band edge (Hz; default the Nyquist frequency).
    seed : int or numpy.random.Generator, optional
        The random stream (None: fresh entropy, not repeatable).

    Returns
    -------
    ndarray (n_steps,)
        Force (N).

    Examples
    --------
    >>> f = band_limited_white_noise(4096, 1e-3, 50.0, 0.0, 100.0, seed=1)
    >>> round(float(np.sqrt(np.mean(f ** 2))), 6)
    50.0
    """
    n_steps = int(n_steps)
    nyq = 0.5 / dt
    f_high = nyq if f_high is None else f_high
    if not 0 <= f_low < f_high <= nyq + 1e-12:
        raise AKFInputError(f"need 0 <= f_low < f_high <= Nyquist ({nyq:g} Hz); got {f_low}, {f_high}")
    f = np.fft.rfftfreq(n_steps, dt)
    if not np.any((f > 0) & (f >= f_low) & (f <= f_high)):
        raise AKFInputError(f"the band {f_low:g}-{f_high:g} Hz holds no frequency of a record of {n_steps} steps: its "
                            f"frequencies are {1 / (n_steps * dt):.4g} Hz apart (1 / its length); widen the band or "
                            "lengthen the record")
    rng = _rng(seed)
    spec = rng.normal(size=n_steps // 2 + 1) + 1j * rng.normal(size=n_steps // 2 + 1)
    spec[(f < f_low) | (f > f_high)] = 0.0
    x = np.fft.irfft(spec, n_steps)
    s = np.sqrt(np.mean(x ** 2))
    return x * (rms / s) if s > 0 else x
