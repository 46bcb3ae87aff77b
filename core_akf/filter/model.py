"""The filter built once: :class:`FilterModel`, the layout-free augmented model, and
:class:`Filter`, a model with sensor layout(s), covariances, prior and detectability report.

:class:`FilterModel` holds the augmented AKF matrices in energy-normalised modal coordinates
(:func:`~core_akf.statespace.modal_state_transform`), of the full structure or truncated to the
lowest modes *with a static correction*, and the output rows of the forces and of every strain.
The optimisers (sensor placement, impact localisation) build it once: each candidate only
selects observation rows (:meth:`FilterModel.observation`).

Static correction (mode-acceleration method): modes dropped by the truncation respond
quasi-statically to the forces, ``u_res = (K^-1 - Phi_r Omega_r^-2 Phi_r^T) S_p f``; their strain
and displacement enter every strain/displacement row as a feed-through on the force states.

:class:`Filter` is what every filter path runs (:mod:`core_akf.filter.kernels`): the estimate,
the batched estimate, the stream, the smoother, the likelihood and calibration.  Its inputs are
checked once, where it is built; :meth:`Filter.with_levels` and :meth:`Filter.with_structure`
give the filter of other covariance levels or another model without checking anything again.
"""
from __future__ import annotations

import copy
from collections.abc import Sequence
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg

from ..checks import (
    AKFInputError,
    ArrayLike,
    Covariance,
    FloatArray,
    Forces,
    Layout,
    Measurements,
    NoiseCovariance,
    as_finite_array,
    as_time_step,
)
from ..covariances import diag_levels, noise_covariance, state_covariance
from ..defaults import resolve_modes
from ..forcemodels import DummyMeasurements, ForceModel, as_force_model
from ..sensors import as_layout, parse_force_locations
from ..statespace import (
    DetectabilityReport,
    check_detectable,
    continuous,
    foh,
    modal_blocks,
    modal_state_transform,
    modal_zoh,
    observation,
    strain_feedthrough,
    zoh,
)
from .kernels import FilterRun, innovation_covariance
from .recursion import ModalBlockTransition
from .riccati import RiccatiError

if TYPE_CHECKING:
    from ..structure import Structure
    from .results import Estimate

#: mode pairs per row chunk of the dropped-mode covariance: bounds its (rows, n_d, 4, 4) arrays
_PAIR_ROWS = 64


class FilterModel:
    """Augmented AKF model of ``structure`` with forces at ``forces``, in modal coordinates: the
    one builder of the filter's transition matrix (used by :class:`Filter` for the full model and
    by the optimisers, reduced), and of the output rows of the forces and strains.

    Parameters
    ----------
    structure : Structure -- the filter's (full) model
    forces : force locations
    dt : float -- s
    n_modes : None (full model), an int, or ``"auto"`` (:func:`core_akf.defaults.auto_modes`, with
        accelerometers; resolve it with the sensors' kinds before if they are known)
    force_model : ForceModel, optional
        The forces' prior (:mod:`core_akf.forcemodels`); default the random walk, whose ``S`` is
        then given to :meth:`Q_a`.

    Attributes
    ----------
    A_a : (n_a, n_a) augmented transition ``[[A, B H], [0, F_d]]``;  Q_unit : (2n, 2n) state
    covariance for a unit ``model_error_cov`` level;  H : (n_p, n_g) the forces from the force
    states;  Q_f : (n_g, n_g) the force model's process covariance per step;  n_a = 2 n_modes + n_g
    (``n_g = n_p`` for the random walk)
    """

    def __init__(self, structure: Structure, forces: Forces, dt: float, n_modes: int | str | None = None,
                 force_model: ForceModel | None = None):
        self.full = structure
        self.load_hold = load_hold = "zero" if force_model is None else force_model.hold
        self.forces = parse_force_locations(structure, forces)
        self.dt = as_time_step(dt)
        self.n_modes = resolve_modes(n_modes, structure, dt, accelerations=True)
        # the one static-correction path: the reduced structure carries it (Structure.reduce), kept
        # with the structure so that every force location and candidate shares one factorisation
        k = self.n_modes
        self.structure = structure if k is None else structure.memo(
            ("reduced with static correction", k), lambda: structure.reduce(k, static_correction=True))
        self.T, self.T_inv = modal_state_transform(self.structure)
        AB = modal_zoh(self.structure, self.forces, self.dt, hold=load_hold)
        if AB is None:
            AB = (zoh if load_hold == "zero" else foh)(*continuous(self.structure, self.forces), self.dt)
            AB = (self.T_inv @ AB[0] @ self.T,) + tuple(self.T_inv @ B for B in AB[1:])
        self.A_z, self.B_z = AB[:2]
        # a linear hold, x_k+1 = A x_k + B0 f_k + B1 f_k+1, is an ordinary AKF in the states
        # xi_k = x_k - B1 f_k: xi_k+1 = A xi_k + (A B1 + B0) f_k, every output row of x gaining a
        # feed-through of the forces through B1 (E_z: x = xi + E_z f)
        self.E_z = None if load_hold == "zero" else AB[2]
        if self.E_z is not None:
            self.B_z = self.A_z @ self.E_z + AB[1]
        self.n_states = AB[0].shape[0]
        self._level_given = force_model is not None        # else the random walk's S comes with each Q_a call
        self.force_model = force_model = ForceModel("random_walk", increment_cov=0.0) if force_model is None \
            else force_model
        n_p = len(self.forces)
        self.H = force_model.output(n_p)
        F_d, self.Q_f = force_model.discrete(n_p, self.dt)
        nx, ng = self.n_states, F_d.shape[0]
        self.A_a = np.zeros((nx + ng, nx + ng))
        self.A_a[:nx, :nx] = self.A_z
        self.A_a[:nx, nx:] = self.B_z @ self.H
        self.A_a[nx:, nx:] = F_d

    def with_structure(self, structure: Structure) -> FilterModel:
        """The same filter model (forces, time step, force model, modes kept) of another structure.

        Parameters
        ----------
        structure : Structure
            Another (full) model of the same DOFs: scaled stiffness, other frequencies or damping.

        Returns
        -------
        FilterModel
        """
        return FilterModel(structure, self.forces, self.dt, self.n_modes, self.force_model if self._level_given else None)

    def output_rows(self) -> FloatArray:
        """Rows giving the forces, then every strain output, from the augmented state.

        Returns
        -------
        ndarray (n_p + n_strain, n_a)
        """
        return np.vstack([self.force_rows(), self.strain_rows()])

    @cached_property
    def Q_unit(self):
        """State covariance (2n x 2n, modal coordinates) for a unit ``model_error_cov`` level."""
        Qu = self.T_inv @ state_covariance(self.structure, 1.0) @ self.T_inv.T
        return 0.5 * (Qu + Qu.T)

    @property
    def n_a(self):
        return self.A_a.shape[0]

    def observation(self, sensors: Layout) -> FloatArray:
        """Augmented observation rows ``[G T, D]`` for a sensor layout.

        Strain and displacement rows carry the static correction of a reduced model.

        Parameters
        ----------
        sensors : sequence of sensor specs
            m sensors.

        Returns
        -------
        ndarray (m, n_a)
        """
        G, D = observation(self.structure, as_layout(sensors), self.forces)
        return self._held(np.hstack([G @ self.T, D @ self.H]))

    def _held(self, rows):
        """Output rows ``[C T, D H]`` of the physical state and forces, as rows of the filter's
        state: under a linear hold, the states' part also reads the forces through ``E_z``."""
        if self.E_z is not None:
            rows[:, self.n_states:] += rows[:, :self.n_states] @ self.E_z @ self.H
        return rows

    def strain_rows(self) -> FloatArray:
        """Rows giving every strain output from the augmented state (with the static correction).

        Returns
        -------
        ndarray (n_strain, n_a)
        """
        ops = self.structure.strain_operator            # (n_strain, n) in the model's coordinates
        out = np.zeros((ops.shape[0], self.n_a))
        out[:, :self.n_states] = np.hstack([ops, np.zeros_like(ops)]) @ self.T
        extra = strain_feedthrough(self.structure, self.forces)
        if extra is not None:
            out[:, self.n_states:] = extra @ self.H
        return self._held(out)

    def state_transform(self) -> tuple[FloatArray, FloatArray]:
        """``(Ta, Ta_inv)``: the physical augmented state ``[u; u'; g]`` from the filter's, ``x_a =
        Ta z_a``, and back (modal coordinates; under a linear hold the states also take
        ``E_z H g``).

        Returns
        -------
        Ta, Ta_inv : ndarray (n_a, n_a)
        """
        ng = self.H.shape[1]
        Ta = scipy.linalg.block_diag(self.T, np.eye(ng))
        Ta_inv = scipy.linalg.block_diag(self.T_inv, np.eye(ng))
        if self.E_z is not None:
            Ta[:self.n_states, self.n_states:] = self.T @ self.E_z @ self.H
            Ta_inv[:self.n_states, self.n_states:] = -self.E_z @ self.H
        return Ta, Ta_inv

    def force_rows(self) -> FloatArray:
        """Rows giving the forces from the augmented state, ``[0, H]``.

        Returns
        -------
        ndarray (n_p, n_a)
        """
        out = np.zeros((len(self.forces), self.n_a))
        out[:, self.n_states:] = self.H
        return out

    def residual_noise(self, sensors: Layout, model_error_cov: float) -> FloatArray:
        """Covariance of the dropped modes' response to the model-error noise, at the sensors.

        The full model's process noise (``model_error_cov`` per physical DOF,
        :func:`~core_akf.covariances.state_covariance`) also drives the modes a reduced model
        drops; a filter on the full model sees that response in its measurements.  Its stationary
        covariance ``Sigma_d = A_d Sigma_d A_d^T + q Q_dd`` is exact mode pair by mode pair (``A_d``
        is block diagonal in modal coordinates: one 4 x 4 solve per pair), and ``C_d Sigma_d
        C_d^T`` is what a reduced filter adds to its measurement noise ``R`` to behave like the full
        one.  Measured on a 147-DOF frame of one's own at 200 Hz (63 of 147 modes, ``q = 1e-14``):
        30 random 4-gauge layouts ranked like the full model with Spearman 0.985 (median error
        2 %) instead of 0.58 (30 %); the dropped modes' noise was 660x the sensor noise.  On the
        thesis plate with an accelerometer (``th-multi``, 101 of 330 modes, whole record): 3.2326
        µε against the full filter's 3.2363, where the reduced filter without it gave 2.1912.

        Parameters
        ----------
        sensors : sequence of sensor specs
            m sensors.
        model_error_cov : float
            The level ``q``.

        Returns
        -------
        ndarray (m, m)
            Zero for the full model, a model already reduced on import (its dropped modes are not
            known), or non-classical damping.
        """
        layout = as_layout(sensors)
        if self.n_modes is not None and "_dropped" not in self.__dict__:
            self._dropped = self._dropped_mode_covariance()
        sigma = None if self.n_modes is None else self._dropped
        if sigma is None:
            return np.zeros((len(layout), len(layout)))
        T, C_rows = sigma[1], sigma[2]
        G = observation(self.full, layout, self.forces)[0] @ T
        C = G[:, C_rows]
        out = float(model_error_cov) * (C @ sigma[0] @ C.T)
        return 0.5 * (out + out.T)

    def __getstate__(self):
        state = self.__dict__.copy()
        state.pop("_dropped", None)        # a cache of (2 n_d)^2 numbers, rebuilt where it is needed
        return state

    def _dropped_mode_covariance(self):
        """``(Sigma_d for q = 1, T of the full model, the dropped columns)``, or None."""
        full, k = self.full, self.n_modes
        if full.is_reduced:
            return None
        parts = modal_blocks(full, self.forces, self.dt)
        if parts is None:
            return None
        n = full.n
        T, T_inv = modal_state_transform(full)
        Qm = T_inv @ state_covariance(full, 1.0) @ T_inv.T
        d = np.arange(k, n)                                  # the dropped modes
        blocks = parts[0][d]                                 # (n_d, 2, 2)
        cols = np.r_[d, n + d]
        Q = 0.5 * (Qm[np.ix_(cols, cols)] + Qm[np.ix_(cols, cols)].T)
        nd = d.size
        # pair (i, j): X = A_i X A_j^T + Q_ij, i.e. (I - A_j kron A_i) vec(X) = vec(Q_ij) (column-major)
        Qp = Q.reshape(2, nd, 2, nd).transpose(1, 3, 0, 2)  # (i, j, 2, 2): Q_ij
        sigma = np.empty_like(Qp)
        eye = np.eye(4)
        for i0 in range(0, nd, _PAIR_ROWS):
            Ai = blocks[i0:i0 + _PAIR_ROWS]
            kron = np.einsum("jab,icd->ijacbd", blocks, Ai).reshape(Ai.shape[0], nd, 4, 4)
            rhs = np.swapaxes(Qp[i0:i0 + _PAIR_ROWS], -1, -2).reshape(Ai.shape[0], nd, 4, 1)
            x = np.linalg.solve(eye - kron, rhs)[..., 0]
            sigma[i0:i0 + _PAIR_ROWS] = np.swapaxes(x.reshape(Ai.shape[0], nd, 2, 2), -1, -2)
        Sigma = sigma.transpose(2, 0, 3, 1).reshape(2 * nd, 2 * nd)
        return 0.5 * (Sigma + Sigma.T), T, cols

    def Q_a(self, model_error_cov: float, force_increment_cov: Covariance | None = None) -> FloatArray:
        """The augmented process covariance ``blockdiag(q Q_unit, Q_f)`` in modal coordinates.

        Parameters
        ----------
        model_error_cov : float
            A scalar state level ``q`` (per physical DOF, as :func:`~core_akf.covariances.state_covariance`).
        force_increment_cov : float or array_like (n_p,), optional
            The random walk's ``S`` (N^2 per step), one for all forces or one per force; None:
            the force model's own ``Q_f`` (a Matérn model's, or the random walk's ``S``).

        Returns
        -------
        ndarray (n_a, n_a)
        """
        Q = np.zeros((self.n_a, self.n_a))
        Q[:self.n_states, :self.n_states] = float(model_error_cov) * self.Q_unit
        if force_increment_cov is None:
            if not self._level_given:
                raise AKFInputError("force_increment_cov (S) is needed: this filter model has the random walk without "
                                    "a level (give force_model=... to the model, or S here)")
            Q[self.n_states:, self.n_states:] = self.Q_f
        else:
            if self.force_model.stationary:
                raise AKFInputError(f"force_increment_cov is the random walk's S; this filter model has the "
                                    f"{self.force_model.kind} force model")
            S = np.broadcast_to(np.asarray(force_increment_cov, float), (len(self.forces),))
            Q[self.n_states:, self.n_states:] = np.diag(S)
        return Q


class Filter:
    """An AKF of one structure and force set for one or many sensor layouts, built and checked once.

    The matrices are in energy-normalised modal coordinates ``x = T z``
    (:func:`~core_akf.statespace.modal_state_transform`), discretised there mode by mode when the
    damping is classical; the kernels (:mod:`core_akf.filter.kernels`) run them, and
    :meth:`estimates` turns their states back into physical :class:`~core_akf.filter.Estimate`.

    Parameters
    ----------
    structure : Structure
        The filter's model.
    layouts : sequence of sensor layouts
        B layouts of m sensors each (``[layout]`` for one).
    forces : sequence of force specs
        The unknown force locations.
    dt : float
        Time step (s).
    model_error_cov, force_increment_cov, noise_cov
        Q, S and R as in :func:`core_akf.filter.estimate` (``noise_cov`` may give one entry per
        layout: a (B, m, m) array or a list of B dicts).
    steady : bool or None
        The steady-state filter (None: where every layout is detectable).
    allow_undetectable : bool
        Keep layouts that fail the PBH test (then only the time-varying filter runs).
    x0, P0 : optional
        Prior mean and covariance of the physical augmented state, as in
        :func:`core_akf.filter.estimate`.
    force_model : ForceModel, optional
        The forces' prior (default the random walk of ``force_increment_cov``).
    dummy : DummyMeasurements, optional
        Zero pseudo-measurements appended to every layout's channels (:meth:`extend`).

    Attributes
    ----------
    model : FilterModel
    layouts : list of tuple of Sensor
    reports : list of DetectabilityReport
        One per layout.
    steady : bool
    A_a : ndarray (n_a, n_a)
    G_a : ndarray (B, m_f, n_a)
        ``m_f = m`` plus the dummy channels.
    R : ndarray (B, m_f, m_f)
    Q_a : ndarray (n_a, n_a)
    z0, Pz0 : ndarray or None
        The prior in modal coordinates (None: zero / ``Q_a``).
    Ta, Ta_inv : ndarray (n_a, n_a)
        The transforms of the augmented state, ``x_a = Ta z_a``.
    H : ndarray (n_p, n_g)
        The forces from the force states.
    m : int
        The real channels per layout (the dummies follow them in ``G_a`` and ``R``).
    transition : ModalBlockTransition or None
        The cheap form of ``A_a`` for the time-varying covariance update.

    Examples
    --------
    >>> from core_akf.models import s17_truss
    >>> f = Filter(s17_truss(), [["strain:13", "acc:8:y"]], ["8:y"], 1e-3, model_error_cov=1e-16,
    ...            force_increment_cov=1e4, noise_cov={"strain": 1e-14, "acc": 1e-4})
    >>> f.steady, f.A_a.shape, f.G_a.shape
    (True, (67, 67), (1, 2, 67))
    """

    def __init__(self, structure: Structure, layouts: Sequence[Layout], forces: Forces, dt: float, *,
                 model_error_cov: Covariance, force_increment_cov: Covariance | None = None,
                 noise_cov: NoiseCovariance | Sequence[NoiseCovariance], steady: bool | None = None,
                 allow_undetectable: bool = False, x0: ArrayLike | None = None, P0: Covariance | None = None,
                 force_model: ForceModel | None = None, dummy: DummyMeasurements | None = None):
        dt = as_time_step(dt)
        if not isinstance(layouts, (list, tuple)):
            raise AKFInputError(f"layouts must be a list of sensor layouts (each a list of labels), got {layouts!r}")
        self.layouts = [as_layout(layout) for layout in layouts]
        if not self.layouts:
            raise AKFInputError("no sensor layouts given")
        self.m = len(self.layouts[0])
        if any(len(layout) != self.m for layout in self.layouts):
            raise AKFInputError("all layouts of a batch must have the same number of sensors")
        self.structure, self.dt = structure, float(dt)
        self.locs = parse_force_locations(structure, forces)
        self.force_model = as_force_model(force_model, force_increment_cov)
        self.dummy = dummy
        self.dummy_layout = [] if dummy is None else dummy.layout(structure, self.layouts[0])
        self.reports = self._reports(allow_undetectable)
        self.steady = all(r.detectable for r in self.reports) if steady is None else bool(steady)
        for layout, report in zip(self.layouts, self.reports):
            if self.steady and not report.detectable:
                raise AKFInputError("the steady-state AKF does not exist for an undetectable sensor set "
                                    f"({', '.join(s.label for s in layout)}); use steady=False to run the "
                                    "time-varying filter and watch it drift")
        self.model_error_cov, self.x0, self.P0 = model_error_cov, x0, P0
        self.R = self._noise(noise_cov)
        self._build(FilterModel(structure, self.locs, dt, force_model=self.force_model))

    def _reports(self, allow_undetectable):
        """The PBH report of every layout (one test per distinct layout)."""
        found = {}
        for layout in self.layouts:
            key = tuple(s.label for s in layout)
            if key not in found:
                found[key] = check_detectable(self.structure, list(layout) + self.dummy_layout, self.locs,
                                              allow_undetectable, self.force_model)
        return [found[tuple(s.label for s in layout)] for layout in self.layouts]

    def report_of(self, sensors: Layout) -> DetectabilityReport:
        """The PBH report of a subset of the sensors (with the filter's dummies): is the set of live
        channels detectable (:class:`core_akf.quality.LiveSets`)?

        Parameters
        ----------
        sensors : sequence of sensor specs

        Returns
        -------
        DetectabilityReport
        """
        return check_detectable(self.structure, list(as_layout(sensors)) + self.dummy_layout, self.locs, True,
                                self.force_model)

    def _noise(self, noise_cov):
        """R of every layout (with the dummies' variances), (B, m_f, m_f)."""
        per_layout = (isinstance(noise_cov, (list, tuple)) and len(noise_cov) > 0
                      and all(isinstance(c, dict) for c in noise_cov)) or (
            not isinstance(noise_cov, dict) and np.ndim(noise_cov) == 3)
        if per_layout and len(noise_cov) != len(self.layouts):
            raise AKFInputError(f"noise_cov has {len(noise_cov)} entries for {len(self.layouts)} layouts")
        R = np.stack([noise_covariance(layout, noise_cov[b] if per_layout else noise_cov)
                      for b, layout in enumerate(self.layouts)])
        if self.dummy_layout:
            extra = self.dummy.variance * np.eye(len(self.dummy_layout))
            R = np.stack([scipy.linalg.block_diag(r, extra) for r in R])
        return R

    def _build(self, model):
        """The modal matrices and prior of ``model`` (a FilterModel of this filter's forces)."""
        self.model = fm = model
        self.structure = fm.full
        self.A_a, self.H = fm.A_a, fm.H
        self.nx, ng = fm.n_states, fm.H.shape[1]
        self.Ta, self.Ta_inv = Ta, Ta_inv = fm.state_transform()
        self.G_a = np.stack([fm.observation(list(layout) + self.dummy_layout) for layout in self.layouts])
        Q_a = scipy.linalg.block_diag(state_covariance(fm.structure, self.model_error_cov), fm.Q_f)
        Tq = scipy.linalg.block_diag(fm.T_inv, np.eye(ng))       # the noises: a hold shifts states, not noise
        Q_a = Tq @ Q_a @ Tq.T
        self.Q_a = 0.5 * (Q_a + Q_a.T)
        self.z0 = None if self.x0 is None else Ta_inv @ as_finite_array(self.x0, "x0", ndim=1, shape=(self.nx + ng,))
        self.Pz0 = None if self.P0 is None else Ta_inv @ diag_levels(self.P0, self.nx + ng, "P0") @ Ta_inv.T
        if self.P0 is None and self.force_model.stationary:      # a stationary force starts from its own prior
            self.Pz0 = self.Q_a.copy()
            self.Pz0[self.nx:, self.nx:] = self.force_model.stationary_covariance(len(self.locs))
        self.transition = None if self.steady else ModalBlockTransition.detect(self.A_a, self.structure.n)

    # ------------------------------------------------------------------ other filters of it
    def with_structure(self, structure: Structure) -> Filter:
        """This filter (layouts, covariance levels, prior) on another model of the same DOFs.

        Nothing is checked again: the layouts and the detectability reports are this filter's.

        Parameters
        ----------
        structure : Structure
            A scaled, re-tuned or re-damped version of :attr:`structure`.

        Returns
        -------
        Filter
        """
        out = copy.copy(self)
        out._build(self.model.with_structure(structure))
        return out

    def with_levels(self, q: float = 1.0, s: float | ArrayLike = 1.0, r: ArrayLike | None = None,
                    timescale: ArrayLike | None = None) -> Filter:
        """This filter with its covariances scaled (Q, the force prior, R), as calibration searches them.

        Parameters
        ----------
        q : float
            Factor on the model-error covariance Q.
        s : float or array_like (n_p,)
            Factor on each force's prior variance (the random walk's S, or a Matérn model's
            variance ``std**2``).
        r : array_like (m,), optional
            Factor on each real channel's noise standard deviation (R by ``outer(r, r)``).
        timescale : array_like (n_p,), optional
            Factor on each force's time scale (a Matérn force model: its force block of ``A_a`` and
            ``Q_a`` anew; the coupling ``B H`` stays).

        Returns
        -------
        Filter
            A copy sharing every matrix that does not change.
        """
        out = copy.copy(self)
        nx, n_p = self.nx, len(self.locs)
        Q_a = self.Q_a.copy()
        Q_a[:nx, :nx] *= q
        if timescale is not None and np.any(np.asarray(timescale) != 1.0):
            F_d, Q_a[nx:, nx:] = self.force_model.scaled(1.0, np.asarray(timescale, float)).discrete(n_p, self.dt)
            out.A_a = self.A_a.copy()
            out.A_a[nx:, nx:] = F_d
            out.transition = None if self.steady else ModalBlockTransition.detect(out.A_a, self.structure.n)
        std = np.repeat(np.sqrt(np.broadcast_to(np.asarray(s, float), (n_p,))), self.force_model.states_per_force)
        Q_a[nx:, nx:] *= np.outer(std, std)
        out.Q_a = Q_a
        if r is not None:
            scale = np.r_[np.asarray(r, float), np.ones(len(self.dummy_layout))]
            out.R = self.R * np.outer(scale, scale)
        return out

    # ------------------------------------------------------------------ data in, estimates out
    def extend(self, Y: FloatArray) -> FloatArray:
        """The measurements with the dummy channels' zeros appended (the filter's channels).

        Parameters
        ----------
        Y : ndarray (..., N, m)

        Returns
        -------
        ndarray (..., N, m_f)
        """
        if not self.dummy_layout:
            return Y
        return np.concatenate([Y, np.zeros(Y.shape[:-1] + (len(self.dummy_layout),))], axis=-1)

    def riccati_error(self, exc: RiccatiError) -> RiccatiError:
        """A :class:`RiccatiError` naming the layouts whose gain failed.

        Parameters
        ----------
        exc : RiccatiError
            The error of the batched Riccati solve (its ``problems`` are batch indices).

        Returns
        -------
        RiccatiError
        """
        names = "; ".join(", ".join(s.label for s in self.layouts[b]) for b in exc.problems)
        return RiccatiError(f"steady-state gain failed for the layout(s) [{names}]: {exc}", exc.problems)

    def estimates(self, run: FilterRun, Y: FloatArray, t0: float = 0.0) -> list[Estimate]:
        """One :class:`~core_akf.filter.Estimate` per layout from a kernel's run (modal coordinates).

        States go back to physical ``[u; u'; f]`` and gains to the physical state.

        Parameters
        ----------
        run : FilterRun
            The kernel's output, one record per layout (B).
        Y : ndarray (B, N, m)
            The measurements (the real channels).
        t0 : float
            Time of the first step (s).

        Returns
        -------
        list of Estimate
        """
        from .results import Estimate

        nx, m = self.nx, self.m
        states = run.states @ self.Ta.T
        gains = (self.Ta @ run.gain)[..., :m]              # the real channels' (dummies are the filter's own)
        S_innov = innovation_covariance(self.G_a, run.P_prior, self.R)[:, :m, :m]
        innovations = run.innovations[..., :m]
        terms = None if run.loglik_terms is None else run.loglik_terms[..., :m]
        return [Estimate(self.structure, layout, self.locs, self.dt, states[b, :, :nx], states[b, :, nx:] @ self.H.T,
                         innovations[b], gains[b], self.reports[b], Y[b], S_innov[b],
                         (self.A_a, self.G_a[b], run.gain[b]), t0=t0, loglik_terms=None if terms is None else terms[b])
                for b, layout in enumerate(self.layouts)]

    def smooth(self, est: Estimate, b: int, Y: Measurements) -> Estimate:
        """The smoothed estimate of layout ``b`` (:func:`core_akf.filter.smoother.smooth` on the
        modal matrices): the filtered ``est`` with its states and forces ``x_k|N``, and
        :attr:`Estimate.force_std` and :attr:`Estimate.strain_std` their standard deviations; the
        innovations, the gain and the likelihood stay those of the filter.

        Parameters
        ----------
        est : Estimate
            The filtered estimate of layout ``b``.
        b : int
            The layout's index.
        Y : ndarray (N, m)
            Its measurements.

        Returns
        -------
        Estimate
            A new estimate.
        """
        from .smoother import smooth

        res = smooth(self.A_a, self.G_a[b], self.Q_a, self.R[b], self.extend(Y), x0=self.z0, P0=self.Pz0,
                     steady=self.steady, covariances=None, outputs=self.model.output_rows())
        return self.with_std(est, res.states, res.output_std)

    def with_std(self, est: Estimate, states: FloatArray, std: FloatArray) -> Estimate:
        """A smoothed estimate.

        Parameters
        ----------
        est : Estimate
            The filtered estimate of the same steps (its innovations and likelihood are kept).
        states : ndarray (N, n_a)
            The smoothed modal states.
        std : ndarray (N, n_p + n_strain)
            The standard deviations of :meth:`FilterModel.output_rows`.

        Returns
        -------
        Estimate
        """
        from dataclasses import replace

        states = states @ self.Ta.T
        n_p = self.H.shape[0]
        return replace(est, states=states[:, :self.nx], forces=states[:, self.nx:] @ self.H.T, force_std=std[:, :n_p],
                       strain_std=std[:, n_p:])
