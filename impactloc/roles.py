"""Role splits: which installed sensors feed the AKF (SE, state estimation) and which are held
back for validation (AD, additional) -- IMP §3."""
from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from core_akf.checks import AKFInputError, Layout
from core_akf.sensors import KINDS, Sensor, as_layout


@dataclass(frozen=True)
class RoleSplit:
    """The SE and AD sensors of one role split.

    Attributes
    ----------
    se : tuple of int
        Indices (0-based, into the installed layout) of the sensors the filter is fed.
    ad : tuple of int
        Indices of the held-back sensors the estimate is checked against.
    """

    se: tuple
    ad: tuple

    def labels(self, layout: Sequence[Sensor]) -> tuple[list[str], list[str]]:
        """The split's sensors by label.

        Parameters
        ----------
        layout : sequence of Sensor
            The installed layout.

        Returns
        -------
        se, ad : list of str
        """
        return [layout[i].label for i in self.se], [layout[i].label for i in self.ad]


def role_splits(sensors: Layout, n_ad: int, ad_kinds: Sequence[str] = ("strain",), max_splits: int | None = None,
                seed: int = 0) -> list[RoleSplit]:
    """All splits of the installed sensors into SE and AD roles.

    The AD sensors are ``n_ad`` of the sensors whose kind is in ``ad_kinds``; every other
    sensor is SE.  IMP case 1: 4 of 7 strain gauges AD (35 splits); case 2: 4 of 7
    accelerometers AD.

    Parameters
    ----------
    sensors : sensor layout (the installed sensors)
    n_ad : int
        Number of AD sensors per split.
    ad_kinds : sequence of str
        Sensor kinds that may take the AD role ("strain", "acc", "vel", "disp").
    max_splits : int, optional
        Cap: a seeded random sample of this many splits when there are more (large sensor sets).
    seed : int
        For that sample.

    Returns
    -------
    list of :class:`RoleSplit`, in ``itertools.combinations`` order.

    Examples
    --------
    Every way to hold one strain gauge back from three:

    >>> [s.ad for s in role_splits(["strain:5", "strain:9", "strain:13", "acc:8:y"], 1)]
    [(0,), (1,), (2,)]
    """
    layout = as_layout(sensors)
    ad_kinds = (ad_kinds,) if isinstance(ad_kinds, str) else tuple(ad_kinds)
    unknown = [k for k in ad_kinds if k not in KINDS]
    if unknown:
        raise AKFInputError(f"unknown AD sensor kind(s) {unknown}; use {list(KINDS)}")
    pool = [i for i, s in enumerate(layout) if s.kind in ad_kinds]
    if not isinstance(n_ad, (int, np.integer)) or n_ad < 1:
        raise AKFInputError(f"n_ad must be a positive integer, got {n_ad!r}")
    if n_ad > len(pool):
        raise AKFInputError(f"{n_ad} AD sensors requested but only {len(pool)} installed sensor(s) of kind "
                            f"{'/'.join(ad_kinds)}")
    if n_ad == len(layout):
        raise AKFInputError("every sensor would be AD: at least one sensor must feed the filter (SE)")
    total = math.comb(len(pool), n_ad)
    if max_splits is not None and max_splits < 1:
        raise AKFInputError(f"max_splits must be >= 1, got {max_splits}")
    if max_splits is not None and total > max_splits:
        rng = np.random.default_rng(seed)
        chosen = set()
        while len(chosen) < max_splits:  # sample combinations without enumerating them all
            chosen.add(tuple(sorted(rng.choice(pool, size=n_ad, replace=False).tolist())))
        combos = sorted(chosen)
    else:
        combos = itertools.combinations(pool, n_ad)
    splits = []
    for ad in combos:
        ad_set = set(ad)
        splits.append(RoleSplit(se=tuple(i for i in range(len(layout)) if i not in ad_set), ad=tuple(ad)))
    return splits
