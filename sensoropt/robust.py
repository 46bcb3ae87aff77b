"""Design under uncertainty: the models a layout is scored on, and how their errors are combined.

A layout is placed for a filter model that is never the structure.  :class:`Uncertainty` draws
the *true* structures a layout may meet -- the filter's stiffness against the truth over a range
(Latin hypercube, seeded), optionally per-mode frequency factors of a calibration -- and the noise
draws per model; :func:`combine` turns a layout's errors over them into one fitness (``mean``,
``p90``, ``worst``, ``cvar90``).  The filter itself stays one model: every truth is read by the
same steady-state filter, so a layout costs one Riccati solve whatever the number of models
(:class:`~sensoropt.objective.StrainErrorObjective`).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from core_akf.checks import AKFInputError

if TYPE_CHECKING:
    from core_akf.structure import Structure

#: how the errors of one layout over the models (and seeds, and sensor losses) become one number
MEASURES = ("mean", "p90", "worst", "cvar90")


def combine(errors: np.ndarray, measure: str) -> np.ndarray:
    """One number per row of ``errors``: its mean, 90 % quantile (linear interpolation), maximum
    or CVaR at 90 % (the mean of the worst ``max(1, ceil(0.1 n))`` values).

    Parameters
    ----------
    errors : ndarray (..., n)
        Errors of a layout over n scenarios; ``inf`` for a scenario the layout fails.
    measure : {"mean", "p90", "worst", "cvar90"}

    Returns
    -------
    ndarray (...)
        ``inf`` where a scenario is ``inf``.

    Examples
    --------
    >>> combine(np.array([[1.0, 2.0, 3.0, 4.0], [1.0, 1.0, 1.0, np.inf]]), "worst").tolist()
    [4.0, inf]
    >>> float(combine(np.arange(1.0, 11.0), "p90")), float(combine(np.arange(1.0, 11.0), "cvar90"))
    (9.1, 10.0)
    """
    errors = np.asarray(errors, float)
    if measure not in MEASURES:
        raise AKFInputError(f"measure must be one of {', '.join(MEASURES)}, got {measure!r}")
    bad = ~np.all(np.isfinite(errors), axis=-1)
    safe = np.where(np.isfinite(errors), errors, 0.0)
    if measure == "mean":
        out = safe.mean(axis=-1)
    elif measure == "p90":
        out = np.quantile(safe, 0.9, axis=-1)
    elif measure == "worst":
        out = safe.max(axis=-1)
    else:
        k = max(1, math.ceil(0.1 * errors.shape[-1]))
        out = np.sort(safe, axis=-1)[..., -k:].mean(axis=-1)
    return np.where(bad, np.inf, out)


def latin_hypercube(n: int, dims: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points of a Latin hypercube in ``[0, 1)^dims``: each dimension has one point in each
    of its ``n`` equal strata, in a random order.

    Parameters
    ----------
    n, dims : int
    rng : numpy.random.Generator

    Returns
    -------
    ndarray (n, dims)
    """
    u = (np.arange(n)[:, None] + rng.random((n, dims))) / n
    for d in range(dims):
        u[:, d] = u[rng.permutation(n), d]
    return u


@dataclass(frozen=True)
class Uncertainty:
    """The true structures a layout is scored on, and how its errors over them are combined.

    Model ``i``'s truth is the filter's model with its stiffness divided by
    ``stiffness_factors[i]`` (the filter is that factor times as stiff as the truth, the
    convention of ``[filter] stiffness_factor``) and, with ``frequency_factors``, the
    frequencies of its lowest modes multiplied by row ``i`` (a calibration's convention: the
    filter's model times the factors is the truth).  The filter is the same for every model:
    what varies is the structure it meets.

    Parameters
    ----------
    stiffness_factors : sequence of float (M,)
        The filter's stiffness against the truth, per model.
    frequency_factors : ndarray (M, k), optional
        Per-mode frequency factors of the truth against the filter, per model.
    seeds : int
        Noise draws per model.
    measure : {"mean", "p90", "worst", "cvar90"}
        What :func:`combine` makes of a layout's errors over the models and seeds.

    Examples
    --------
    >>> u = Uncertainty.sample((0.95, 1.10), samples=4, seeds=2, seed=0)
    >>> len(u.stiffness_factors), u.n_scenarios, all(0.95 <= f <= 1.10 for f in u.stiffness_factors)
    (4, 8, True)
    """

    stiffness_factors: tuple
    frequency_factors: np.ndarray | None = None
    seeds: int = 1
    measure: str = "p90"

    def __post_init__(self):
        f = np.asarray(self.stiffness_factors, float)
        if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)) or np.any(f <= 0):
            raise AKFInputError(f"stiffness factors must be positive numbers, got {list(np.ravel(f))}")
        if int(self.seeds) < 1:
            raise AKFInputError(f"seeds (noise draws per model) must be >= 1, got {self.seeds}")
        if self.measure not in MEASURES:
            raise AKFInputError(f"measure must be one of {', '.join(MEASURES)}, got {self.measure!r}")
        if self.frequency_factors is not None:
            c = np.asarray(self.frequency_factors, float)
            if c.ndim != 2 or c.shape[0] != f.size or not np.all(np.isfinite(c)) or np.any(c <= 0):
                raise AKFInputError(f"frequency factors must be positive, one row of per-mode factors per model "
                                    f"({f.size}), got shape {c.shape}")

    @property
    def n_models(self) -> int:
        """Models drawn (M)."""
        return len(self.stiffness_factors)

    @property
    def n_scenarios(self) -> int:
        """Models times noise draws."""
        return self.n_models * int(self.seeds)

    @classmethod
    def sample(cls, stiffness_factor: float | Sequence[float] = 1.0, *, frequency: tuple | None = None,
               samples: int = 8, seeds: int = 3, measure: str = "p90", seed: int = 0) -> Uncertainty:
        """Models drawn by a seeded Latin hypercube.

        Parameters
        ----------
        stiffness_factor : float, (lo, hi) or list
            A fixed factor, a range ``[lo, hi]`` (uniform; a two-element list is a range) or a
            list of three or more factors (used as they are; ``samples`` is then their number).
        frequency : (factors, std_errors), optional
            Per-mode frequency factors and the standard errors of their logarithms (a
            calibration's fit): each model draws ``factor * exp(std_error * z)``, ``z`` standard
            normal (stratified).
        samples : int
            Models drawn.
        seeds : int
            Noise draws per model.
        measure : {"mean", "p90", "worst", "cvar90"}
        seed : int
            Seeds the draw.

        Returns
        -------
        Uncertainty
        """
        from scipy.stats import norm

        if int(samples) < 1:
            raise AKFInputError(f"samples (models drawn) must be >= 1, got {samples}")
        rng = np.random.default_rng(seed)
        given = np.atleast_1d(np.asarray(stiffness_factor, float))
        if not np.all(np.isfinite(given)) or np.any(given <= 0):
            raise AKFInputError(f"stiffness_factor must be positive (the filter's stiffness against the truth), got "
                                f"{np.ravel(given).tolist()}")
        if given.size == 2:
            lo, hi = given
            if not lo < hi:
                raise AKFInputError(f"stiffness_factor = [{lo:g}, {hi:g}] is a range: give it as [low, high] with "
                                    "low < high (a list of three or more factors is used as it is)")
            factors = lo + (hi - lo) * latin_hypercube(int(samples), 1, rng)[:, 0]
        elif given.size == 1:
            factors = np.full(int(samples), given[0])
        else:
            factors = given
        freq = None
        if frequency is not None:
            mean, std = (np.asarray(v, float) for v in frequency)
            if mean.shape != std.shape or mean.ndim != 1 or not np.all(np.isfinite(std)) or np.any(std < 0):
                raise AKFInputError("the frequency factors need one finite standard error >= 0 per factor")
            z = norm.ppf(latin_hypercube(factors.size, mean.size, rng))
            freq = mean[None] * np.exp(std[None] * z)
        return cls(tuple(float(f) for f in factors), freq, int(seeds), measure)

    def truths(self, structure: Structure, filter_factor: float = 1.0) -> list:
        """The true structure of each model.

        Parameters
        ----------
        structure : Structure
            The structure whose ``structure.scaled(filter_factor)`` is the filter's model.
        filter_factor : float
            The filter's stiffness factor on ``structure``: a model whose factor equals it has
            ``structure`` itself as its truth.

        Returns
        -------
        list of Structure (M,)
        """
        out = []
        for i, f in enumerate(self.stiffness_factors):
            truth = structure if f == filter_factor else structure.scaled(filter_factor / f)
            if self.frequency_factors is not None:
                truth = truth.with_frequency_factors(self.frequency_factors[i])
            out.append(truth)
        return out

    def table(self) -> list[dict]:
        """One record per model: its index (1-based), stiffness factor and frequency factors.

        Returns
        -------
        list of dict
        """
        rows = []
        for i, f in enumerate(self.stiffness_factors):
            row = {"model": i + 1, "stiffness_factor": f}
            if self.frequency_factors is not None:
                row |= {f"frequency_factor_{k + 1}": float(c) for k, c in enumerate(self.frequency_factors[i])}
            rows.append(row)
        return rows
