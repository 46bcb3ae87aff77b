"""Shared pieces of the studies: results container, output folder, spectra, figures."""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from core_akf.figures import save_figure


@dataclass
class StudyResult:
    """A study's outcome: the tidy table (one row per case/channel), extra tables, files written."""

    name: str
    table: object                      # pandas DataFrame
    summary: object = None             # pandas DataFrame: one row per case
    files: dict = field(default_factory=dict)
    data: dict = field(default_factory=dict)  # per-case EstimateResult objects (for tests and plots)


def output_dir(name, out=None):
    path = out or os.path.join("akf-out", "studies", name)
    os.makedirs(path, exist_ok=True)
    return path


def psd(signal, dt, nperseg=None):
    """One-sided power spectral density (Welch, Hann window): ``(f (Hz), P (unit^2/Hz))``."""
    from scipy.signal import welch

    signal = np.asarray(signal, float)
    n = signal.shape[0]
    return welch(signal, fs=1.0 / dt, nperseg=min(n, nperseg or 2048), axis=0)


def save(fig, path, files, key):
    """Write ``fig`` to ``path`` and record it as ``files[key]``."""
    files[key] = save_figure(fig, path)


def drift_ratio(error):
    """RMS of an error signal over its last quarter divided by that over its first quarter
    (after the first 5 % as a start-up transient): >> 1 means the estimate drifts/diverges."""
    error = np.asarray(error, float)
    n = error.shape[0]
    start = n // 20
    q = max((n - start) // 4, 1)
    first = np.sqrt(np.mean(error[start:start + q] ** 2, axis=0))
    last = np.sqrt(np.mean(error[-q:] ** 2, axis=0))
    return last / np.maximum(first, 1e-300)


class Progress:
    """One line per step of a long study, logged at INFO on the ``akf`` logger
    (``[th_placement 3/17] case 6: 4 gauges, 41 s so far``), so a run of minutes is never silent
    on the command line; ``quiet`` switches it off."""

    def __init__(self, name, total, quiet=False):
        import time

        self.name, self.total, self.quiet = name, int(total), quiet
        self.done, self.t0 = 0, time.perf_counter()

    def step(self, label):
        import logging
        import time

        self.done += 1
        if not self.quiet:
            logging.getLogger("akf").info(f"[{self.name} {self.done}/{self.total}] {label} "
                                          f"({time.perf_counter() - self.t0:.0f} s so far)")
