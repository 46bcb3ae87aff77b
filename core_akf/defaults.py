"""One home for the toolkit's default settings and the one ``"auto"`` rule for filter models.

Every default the API, the job files and the command line fall back on is read from
:data:`DEFAULTS` through :func:`default`, so a value is stated once.  SI units throughout.
"""
from __future__ import annotations

import numpy as np

#: name -> (value, unit, what it is)
DEFAULTS = {
    "stiffness_factor": (1.0, "-", "the filter's stiffness relative to the given (true) structure: an estimate on "
                                   "measured data uses the model as given"),
    "placement_stiffness_factor": (1.05, "-", "model error simulated when placing sensors and in the papers' "
                                              "cases: the filter's model 5 % stiffer than the true structure"),
    "relative_noise": (0.02, "-", "simulated sensor noise: 2 % of each channel's RMS"),
    "model_error_cov": (1e-16, "state units^2", "Q: model-error variance per step, per state"),
    "force_increment_cov": (1.0, "N^2", "S: force-increment variance per step (random-walk force model)"),
    "noise_floor": (1e-30, "SI", "smallest noise standard deviation turned into a variance (a noise-free "
                                 "simulated channel would make R singular)"),
    "steady": (True, "-", "the steady-state (constant-gain) filter; False: the time-varying filter"),
    "window": (0.1, "s", "simulated record per placement fitness evaluation (TH)"),
    "penalty": (100.0, "objective units", "fitness of an infeasible layout (undetectable, failing filter, NaN); "
                                          "the strain-error objective is in microstrain"),
    "impact_force_increment_cov": (1e6, "N^2", "S assumed for an impact before tuning"),
    "impact_relative_noise": (0.05, "-", "noise level assumed for impact data before tuning: 5 % of each "
                                         "channel's RMS"),
    "auto_modes_factor_strain": (6.0, "-", "auto rule: keep the modes below this multiple of the sampling rate "
                                           "when no accelerometer is used (strain and displacement get a static "
                                           "correction for the rest)"),
    "auto_modes_factor_acc": (10.0, "-", "auto rule: the same with accelerometers, which see higher modes"),
    "auto_modes_minimum": (4, "-", "auto rule: at least this many modes"),
    "band_modes_factor": (3.0, "-", "inner-loop rule (placement fitness): keep the modes below this multiple of the "
                                    "Nyquist frequency 1 / (2 dt) when no accelerometer is used (static correction "
                                    "for the rest)"),
    "calibration_stiffness_range": ((0.7, 1.4), "-", "calibration: the stiffness factor is searched in this range "
                                                     "of the starting model's (a grid scan, then a local fit)"),
    "calibration_damping_range": ((0.1, 10.0), "-", "calibration: the modal damping ratio is searched in this range "
                                                    "of the starting model's"),
    "calibration_frequency_range": ((0.85, 1.15), "-", "calibration: the factor on each mode's frequency is "
                                                      "searched in this range (a scan per mode, then a joint fit)"),
    "calibration_modes": (4, "-", "calibration of frequencies: the lowest this many modes below a quarter of the "
                                  "sampling rate, unless the modes are given"),
    "smooth_lag_tolerance": (1e-3, "-", "fixed-lag smoothing, lag \"auto\": the shortest lag after which an "
                                        "innovation weighs less than this fraction of the next step's"),
    "smooth_lag_longest": (65536, "steps", "fixed-lag smoothing: the longest automatic lag"),
    "calibration_decades": (3.0, "decades", "calibration: a covariance is searched this many decades either side "
                                            "of its starting level"),
}


def default(name, value=None):
    """A value, or its registered default.

    Parameters
    ----------
    name : str
        A key of :data:`DEFAULTS`.
    value : object, optional
        The value given by the user; None takes the default.

    Returns
    -------
    object
        ``value`` if it is not None, else ``DEFAULTS[name][0]``.

    Examples
    --------
    >>> default("stiffness_factor"), default("stiffness_factor", 1.05)
    (1.0, 1.05)
    """
    if value is not None:
        return value
    return DEFAULTS[name][0]


def auto_modes(structure, dt, accelerations=True):
    """The ``"auto"`` number of filter modes (with static correction).

    The modes whose frequency lies below ``factor / dt`` Hz, with ``factor`` 10 when
    accelerometers are used and 6 otherwise (:data:`DEFAULTS`), and at least 4.  Measured on the
    thesis plate at 2 kHz: 80 modes for strain gauges only (fitness within 0.1 % of the full
    model's, same layout ranking, Spearman 0.997) and 101 with accelerometers; the S17 truss and
    the IMP plate at 1 kHz keep 33 and 30 modes.

    Parameters
    ----------
    structure : Structure
    dt : float
        Time step (s).
    accelerations : bool
        Whether any acceleration sensor is (or may be) used.

    Returns
    -------
    int
    """
    factor = default("auto_modes_factor_acc" if accelerations else "auto_modes_factor_strain")
    f = structure.frequencies()
    return int(max(min(default("auto_modes_minimum"), structure.n), np.sum(f < factor / float(dt))))


def band_modes(structure, dt, accelerations=False):
    """The number of filter modes for an optimiser's inner loop (the placement fitness).

    The sensors see the band up to the Nyquist frequency ``f_N = 1 / (2 dt)``, and the loads
    (sampled with the same step) lie in it.  A mode at ``f_j`` far above that band responds
    quasi-statically, which the static correction represents exactly; what it misses is the
    dynamic amplification ``1 / (1 - r^2) - 1 = r^2 / (1 - r^2)`` of that mode's share, ``r = f /
    f_j`` for excitation at ``f``.  Keeping the modes below ``band_modes_factor x f_N`` (3, from
    :data:`DEFAULTS`) bounds it by ``1/8`` of the (small) share of the dropped modes, at the
    band's edge, and by ``(f_load / (3 f_N))^2`` for loads band-limited to ``f_load``.

    The same bound holds for accelerometers: a dropped mode's acceleration under a load at ``f``
    is its quasi-static share times ``r^2 / (1 - r^2)`` (the reduced model's accelerometer
    feed-through holds the kept modes only, so nothing quasi-static is double counted).  What the
    dropped modes add at any sensor is their response to the model-error noise, which the
    reduced filter carries in its measurement noise
    (:meth:`~core_akf.filter.model.FilterModel.residual_noise`); without it the model error
    that a full filter spreads over every mode is simply lost.  The rule is never more than
    :func:`auto_modes` and at least ``auto_modes_minimum`` modes.

    Measured, strain gauges only: on the thesis plate at 2 kHz (3 gauges, 0.1 s window) 32 modes
    instead of 80, the GA 4.4x faster per evaluation; ``akf place --example th-case5 --seed 7``
    finds a layout of 1.7857 µε over the whole record (the full 330-DOF filter: 1.7858) where the
    80-mode fitness found one of 1.8077 µε.  On a 3-D frame of one's own (147 DOFs, 200 Hz): 63
    modes, 30 random layouts ranked like the full model (Spearman 0.985, median difference 2 %).

    Measured with accelerometers (before, every mode below 10 / dt was kept): on the thesis plate
    (2 gauges + 1 accelerometer, 0.5 s window) 32 modes against the full 330, 30 random layouts
    ranked with Spearman 0.999 (median difference 1.7 %), and ``th-multi``'s GA finds the layout
    of the 101-mode fitness in 16.8 s instead of 100.7 s.  On a 147-DOF 3-D truss at 512 Hz
    (``footbridge(n_panels=12)``, 4 gauges + 2 accelerometers, 2 s window): 118 of 147 modes, 30
    random layouts with Spearman 0.96 (median 4.6 %); a 30 x 30 GA takes 32.5 s against 869 s on
    the full model, and its layout is 4.5 % above the full-model GA's on the full model.  Fewer
    modes rank worse there (60 modes: Spearman 0.948, median 12 %): the rule is not cut further.

    Parameters
    ----------
    structure : Structure
    dt : float
        Time step (s).
    accelerations : bool
        Whether any acceleration sensor is (or may be) used (it bounds the result by
        :func:`auto_modes` of that case; the band itself is the same).

    Returns
    -------
    int

    Examples
    --------
    >>> from core_akf.models import th_plate
    >>> band_modes(th_plate(), 0.0005), band_modes(th_plate(), 0.0005, accelerations=True)
    (32, 32)
    """
    full = auto_modes(structure, dt, accelerations)
    f = structure.frequencies()
    keep = int(np.sum(f < default("band_modes_factor") * 0.5 / float(dt)))
    return int(min(full, max(min(default("auto_modes_minimum"), structure.n), keep)))


def resolve_modes(n_modes, structure, dt, accelerations, rule="auto"):
    """The modes a filter model keeps, decided once for every caller (the filter model, the
    placement fitness, the location scan, the reconstruction).

    Parameters
    ----------
    n_modes : None, "full", "auto" or int
        None or ``"full"``: the full model; ``"auto"``: the rule; a number: checked against the model.
    structure : Structure
        The model.
    dt : float
        Time step (s).
    accelerations : bool
        Whether any acceleration sensor is (or may be) used (:func:`core_akf.sensors.sees_accelerations`).
    rule : "auto" or "band"
        :func:`auto_modes` (reported errors, estimates) or :func:`band_modes` (the placement fitness).

    Returns
    -------
    int or None
        None for the full model (also when the count is every mode).

    Examples
    --------
    >>> from core_akf.models import th_plate
    >>> resolve_modes("auto", th_plate(), 0.0005, False) == auto_modes(th_plate(), 0.0005, False)
    True
    """
    from .checks import AKFInputError, check_n_modes

    if n_modes is None or (isinstance(n_modes, str) and n_modes == "full"):
        return None
    if isinstance(n_modes, str):
        if n_modes != "auto":
            raise AKFInputError(f"n_modes must be a number of modes, \"auto\" or \"full\", got {n_modes!r}")
        n_modes = (band_modes if rule == "band" else auto_modes)(structure, dt, accelerations)
    n_modes = check_n_modes(n_modes)
    if n_modes > structure.n:
        raise AKFInputError(f"n_modes must be between 1 and {structure.n}, got {n_modes}")
    return None if n_modes == structure.n else n_modes
