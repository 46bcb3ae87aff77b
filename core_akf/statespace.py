"""State space of a structure with unknown inputs: continuous model, zero-order-hold
discretisation, heterogeneous observation matrices ``G``/``D``, augmentation with a
random-walk force model and the PBH detectability test (S17 §2 and eq. 14-30, IMP eq. 12-30), for
any force model of :mod:`core_akf.forcemodels`.

Everything that derives these matrices lives here; the filter, the simulator and the
optimisers call these functions instead of re-deriving them.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg

from .checks import Forces, Layout

if TYPE_CHECKING:
    from .structure import Structure
from . import rank
from .checks import UndetectableError, as_time_step
from .forcemodels import ForceModel
from .rank import is_supported
from .sensors import as_layout, parse_force_locations, selection_matrices


def _minv(structure):
    """Cholesky factor of M (M is SPD by construction of :class:`Structure`), computed once
    per structure: the matrices never change after construction."""
    return structure.memo("mass_cholesky", lambda: scipy.linalg.cho_factor(structure.M))


def modal_damping(structure, rtol=1e-10):
    """Modal damping coefficients when the damping is classical.

    Parameters
    ----------
    structure : Structure
    rtol : float
        Largest off-diagonal entry of ``Phi^T C Phi``, relative to its diagonal, for classical
        damping (modal or Rayleigh).

    Returns
    -------
    ndarray (n,) or None
        ``c_j = phi_j^T C phi_j`` (1/s), or None for non-classical damping.
    """
    phi = structure.eigen[1]
    Cm = phi.T @ structure.C @ phi
    c = np.diag(Cm).copy()
    if np.max(np.abs(Cm - np.diag(c)), initial=0.0) > rtol * max(np.max(np.abs(c), initial=0.0), 1e-300):
        return None
    return c


def force_selection(structure, forces):
    """``S_p``: unit loads at the force locations, in generalised coordinates.

    Parameters
    ----------
    structure : Structure
    forces : sequence of force specs
        n_p locations.

    Returns
    -------
    ndarray (n, n_p)
    """
    locs = parse_force_locations(structure, forces)
    return structure.dof_rows(locs).T


def state_matrix(structure):
    """Continuous-time ``A_c = [[0, I], [-M^-1 K, -M^-1 C]]`` for the state ``x = [u; u']``.

    Parameters
    ----------
    structure : Structure

    Returns
    -------
    ndarray (2n, 2n)
    """
    n = structure.n
    cf = _minv(structure)
    A_c = np.zeros((2 * n, 2 * n))
    A_c[:n, n:] = np.eye(n)
    A_c[n:, :n] = -scipy.linalg.cho_solve(cf, structure.K)
    A_c[n:, n:] = -scipy.linalg.cho_solve(cf, structure.C)
    return A_c


def continuous(structure, forces):
    """The continuous-time structural model ``x' = A_c x + B_c f``.

    Parameters
    ----------
    structure : Structure
    forces : sequence of force specs
        n_p locations.

    Returns
    -------
    A_c : ndarray (2n, 2n)
    B_c : ndarray (2n, n_p)
        ``[0; M^-1 S_p]``.
    """
    Sp = force_selection(structure, forces)
    MiSp = scipy.linalg.cho_solve(_minv(structure), Sp)
    return state_matrix(structure), np.vstack([np.zeros_like(MiSp), MiSp])


def zoh(A_c, B_c, dt):
    """Zero-order-hold discretisation from one block exponential.

    ``expm([[A_c, B_c], [0, 0]] dt) = [[A, B], [0, I]]``: no inverse of ``A_c`` needed.

    Parameters
    ----------
    A_c : ndarray (n_x, n_x)
    B_c : ndarray (n_x, n_u)
    dt : float
        Time step (s).

    Returns
    -------
    A : ndarray (n_x, n_x)
    B : ndarray (n_x, n_u)
    """
    dt = as_time_step(dt)
    nx, nu = B_c.shape
    blk = np.zeros((nx + nu, nx + nu))
    blk[:nx, :nx] = A_c
    blk[:nx, nx:] = B_c
    E = scipy.linalg.expm(blk * dt)
    return E[:nx, :nx], E[:nx, nx:]


def foh(A_c, B_c, dt):
    """First-order-hold discretisation (the input linear between samples) from one block
    exponential: ``x_k+1 = A x_k + B0 u_k + B1 u_k+1``.

    ``expm([[A_c, B_c, 0], [0, 0, I], [0, 0, 0]] dt)`` carries ``[x; u; v]`` with ``u(t) = u_k +
    v t / dt``: its blocks ``[[A, E_u, E_v], ...]`` give ``B0 = E_u - E_v`` and ``B1 = E_v``.

    Parameters
    ----------
    A_c : ndarray (n_x, n_x)
    B_c : ndarray (n_x, n_u)
    dt : float
        Time step (s).

    Returns
    -------
    A : ndarray (n_x, n_x)
    B0, B1 : ndarray (n_x, n_u)
    """
    dt = as_time_step(dt)
    nx, nu = B_c.shape
    blk = np.zeros((nx + 2 * nu, nx + 2 * nu))
    blk[:nx, :nx] = A_c
    blk[:nx, nx:nx + nu] = B_c
    blk[nx:nx + nu, nx + nu:] = np.eye(nu) / dt
    E = scipy.linalg.expm(blk * dt)
    return E[:nx, :nx], E[:nx, nx:nx + nu] - E[:nx, nx + nu:], E[:nx, nx + nu:]


def observation(structure, sensors, forces):
    """``G`` and ``D`` of ``y = G x + D f`` (S17 eq. 27-30, IMP eq. 26-30).

    ``G = [S_s + S_d - S_a M^-1 K, S_v - S_a M^-1 C]``, ``D = S_a M^-1 S_p`` (plus the static
    correction of a reduced structure on strain and displacement rows).

    Parameters
    ----------
    structure : Structure
    sensors : sequence of sensor specs
        m sensors.
    forces : sequence of force specs
        n_p locations.

    Returns
    -------
    G : ndarray (m, 2n)
    D : ndarray (m, n_p)
    """
    S = selection_matrices(structure, sensors)
    Sp = force_selection(structure, forces)
    cf = _minv(structure)
    Sa_Mi = scipy.linalg.cho_solve(cf, S["acc"].T).T  # S_a M^-1
    G = np.hstack([S["strain"] + S["disp"] - Sa_Mi @ structure.K, S["vel"] - Sa_Mi @ structure.C])
    D = Sa_Mi @ Sp
    if structure.static is not None:
        D = D + static_feedthrough(structure, sensors, forces)
    return G, D


def _residual(structure, forces):
    """Residual displacement (n_phys, n_p) of a reduced structure with a static correction."""
    locs = parse_force_locations(structure, forces)
    return structure.static.residual([structure.dof_index(node, d) for node, d in locs])


def static_feedthrough(structure, sensors, forces):
    """Feed-through of the modes a reduced structure leaves out, at the sensors.

    The quasi-static strain and displacement of its :class:`~core_akf.models.sparse.StaticCorrection`
    (zero rows for accelerometers and velocity sensors; all zero without a correction).

    Parameters
    ----------
    structure : Structure
    sensors : sequence of sensor specs
        m sensors.
    forces : sequence of force specs
        n_p locations.

    Returns
    -------
    ndarray (m, n_p)
        Sensor units per N.
    """
    layout = as_layout(sensors)
    locs = parse_force_locations(structure, forces)
    out = np.zeros((len(layout), len(locs)))
    if structure.static is None:
        return out
    U = _residual(structure, locs)
    for i, s in enumerate(layout):
        if s.kind == "strain":
            key = s.member if s.member is not None else (s.node, s.component)
            out[i] = structure.strain_matrix[[structure.strain_index(key)]] @ U
        elif s.kind == "disp":
            out[i] = U[structure.dof_index(s.node, s.direction)]
    return out


def strain_feedthrough(structure, forces):
    """Feed-through of the forces on every strain output: the static correction of a reduced structure.

    Parameters
    ----------
    structure : Structure
    forces : sequence of force specs
        n_p locations.

    Returns
    -------
    ndarray (n_strain, n_p) or None
        (m/m per N; :func:`static_feedthrough` for all strains), None without a correction.
    """
    if structure.static is None or structure.n_strain == 0:
        return None
    return np.asarray(structure.strain_matrix @ _residual(structure, forces))


def augment(A, B, G, D):
    """Augmented matrices for the random-walk force model (Lourens et al. 2012; S17 eq. 14-26).

    Parameters
    ----------
    A : ndarray (n_x, n_x)
    B : ndarray (n_x, n_p)
    G : ndarray (m, n_x)
    D : ndarray (m, n_p)

    Returns
    -------
    A_a : ndarray (n_x + n_p, n_x + n_p)
        ``[[A, B], [0, I]]``.
    G_a : ndarray (m, n_x + n_p)
        ``[G, D]``.
    """
    nx, nu = B.shape
    A_a = np.zeros((nx + nu, nx + nu))
    A_a[:nx, :nx] = A
    A_a[:nx, nx:] = B
    A_a[nx:, nx:] = np.eye(nu)
    return A_a, np.hstack([G, D])


def _modal_scale(omega):
    """Scale ``w`` of the modal displacement coordinate ``w q``: ``omega``, or 1 for rigid modes."""
    return np.where(omega > 1e-6 * max(omega.max(), 1.0), omega, 1.0)


def modal_state_transform(structure):
    """Energy-normalised modal state coordinates ``x = T z``.

    ``T = blockdiag(Phi diag(1/omega), Phi)`` (mass-normalised ``Phi``).  In ``z = [omega q; q']``
    every mode's displacement and velocity have the same size, so the transition matrix is close
    to orthogonal.  The filter and the Riccati solver work in these coordinates: in raw
    ``[u; u']`` the stiff high modes make the Riccati iteration lose accuracy (residual 1e-4
    instead of 1e-9 on the TH plate).

    Parameters
    ----------
    structure : Structure

    Returns
    -------
    T, T_inv : ndarray (2n, 2n)
    """
    omega, phi = structure.eigen
    w = _modal_scale(omega)
    phi_inv = phi.T @ structure.M  # Phi^T M Phi = I
    T = scipy.linalg.block_diag(phi / w[None, :], phi)
    T_inv = scipy.linalg.block_diag(w[:, None] * phi_inv, phi_inv)
    return T, T_inv


def modal_zoh(structure, forces, dt, rtol=1e-10, hold="zero"):
    """ZOH discretisation directly in the modal coordinates of :func:`modal_state_transform`
    (with ``hold = "linear"`` the first-order hold of :func:`foh`).

    Mode by mode, for a classically damped structure: each mode is a 2-state system
    ``d/dt [w q; q'] = [[0, w], [-omega^2 / w, -c]] [w q; q'] + [0; phi^T S_p] f`` (``w =
    omega``, or 1 for a rigid mode; ``c = phi^T C phi``), so the transition ``A_z`` consists of
    four diagonal blocks exactly and costs n small matrix exponentials instead of one of size 2n.

    Parameters
    ----------
    structure : Structure
    forces : sequence of force specs
        n_p locations.
    dt : float
        Time step (s).
    rtol : float
        Tolerance of the classical-damping test (:func:`modal_damping`).
    hold : str
        ``"zero"`` or ``"linear"``.

    Returns
    -------
    tuple or None
        ``(A_z (2n, 2n), B_z (2n, n_p))``; with ``hold = "linear"`` ``(A_z, B0_z, B1_z)``, the
        matrices of ``u_k`` and ``u_k+1``; None for non-classical damping.
    """
    parts = modal_blocks(structure, forces, dt, rtol, hold)
    if parts is None:
        return None
    blocks = parts[0]
    n = blocks.shape[0]
    A_z = np.zeros((2 * n, 2 * n))
    idx = np.arange(n)
    A_z[idx, idx] = blocks[:, 0, 0]
    A_z[idx, n + idx] = blocks[:, 0, 1]
    A_z[n + idx, idx] = blocks[:, 1, 0]
    A_z[n + idx, n + idx] = blocks[:, 1, 1]
    return (A_z,) + tuple(parts[1:])


def modal_blocks(structure, forces, dt, rtol=1e-10, hold="zero"):
    """The mode-by-mode ZOH of :func:`modal_zoh` as its 2 x 2 blocks, for work that runs on each
    mode separately (a simulation, the dropped modes of a reduced filter); with ``hold =
    "linear"`` the first-order hold of :func:`foh`.

    Parameters
    ----------
    structure : Structure
    forces : sequence of force specs
        n_p locations.
    dt : float
        Time step (s).
    rtol : float
        Tolerance of the classical-damping test (:func:`modal_damping`).

    hold : str
        ``"zero"`` or ``"linear"``.

    Returns
    -------
    tuple or None
        ``(blocks (n, 2, 2), B_z (2n, n_p))``: mode j's transition on ``[w q_j; q_j']`` and the
        input matrix (displacement rows first, as in :func:`modal_zoh`); with ``hold = "linear"``
        ``(blocks, B0_z, B1_z)``, the matrices of ``u_k`` and ``u_k+1``; None for non-classical
        damping.
    """
    c = modal_damping(structure, rtol)
    if c is None:
        return None
    dt = as_time_step(dt)
    omega, phi = structure.eigen
    n = structure.n
    w = _modal_scale(omega)
    p = phi.T @ force_selection(structure, forces)          # (n, n_p) modal force participation
    npf = p.shape[1]
    ramp = npf if hold == "linear" else 0
    blk = np.zeros((n, 2 + npf + ramp, 2 + npf + ramp))
    blk[:, 0, 1] = w
    blk[:, 1, 0] = -omega ** 2 / w
    blk[:, 1, 1] = -c
    blk[:, 1, 2:2 + npf] = p
    if ramp:
        blk[:, 2:2 + npf, 2 + npf:] = np.eye(npf) / dt
    E = scipy.linalg.expm(blk * dt)
    Bu = np.vstack([E[:, 0, 2:2 + npf], E[:, 1, 2:2 + npf]])
    if not ramp:
        return E[:, :2, :2].copy(), Bu
    Bv = np.vstack([E[:, 0, 2 + npf:], E[:, 1, 2 + npf:]])
    return E[:, :2, :2].copy(), Bu - Bv, Bv


# ---------------------------------------------------------------------------- detectability
@dataclass
class DetectabilityReport:
    """Result of the PBH test on the continuous augmented pair ``(A_ac, H_ac)``.

    Attributes
    ----------
    detectable : bool
    checked : list of complex
        The critical eigenvalues tested (Re s >= 0, including the force states' ``s = 0``).
    failures : list of dict
        For each eigenvalue where ``[[sI - A_ac], [H_ac]]`` loses column rank: the eigenvalue,
        the relative smallest singular value and the part of the state that cannot be seen.
    sensors : tuple of str
        The layout's labels.
    force_model : ForceModel or None
        The force model tested (None: the random walk).
    """

    detectable: bool
    checked: list = field(default_factory=list)
    failures: list = field(default_factory=list)
    sensors: tuple = ()
    force_model: object = None

    def __str__(self):
        head = "detectable" if self.detectable else "NOT detectable"
        lines = [f"PBH test ({len(self.sensors)} sensors: {', '.join(s.label for s in self.sensors)}): {head}"]
        for f in self.failures:
            lines.append(
                f"  s = {f['s']:.6g}: rank deficient (relative smallest singular value {f['sigma_rel']:.2e}); "
                f"unseen direction mostly in {f['unseen']}"
            )
        if self.detectable and self.checked:
            lines.append(f"  checked {len(self.checked)} critical eigenvalue(s): all full rank")
        elif self.detectable:
            lines.append(f"  the {self.force_model.kind} force model is stationary and the structure stable: "
                         "no critical eigenvalue (the forces are estimated as well as the sensors' band allows)")
        return "\n".join(lines)

    def __bool__(self):
        return self.detectable


def _critical_eigenvalues(structure, tol):
    """Distinct eigenvalues ``s`` of ``A_c`` with Re s >= 0 (one of each conjugate pair), plus 0
    for the force states.  Depends on the structure only, so it is computed once per structure."""

    def compute():
        omega = structure.eigen[0]
        c = modal_damping(structure)
        if c is not None:
            # classical damping: the roots of s^2 + c s + omega^2 = 0 mode by mode
            disc = np.sqrt((c ** 2 - 4 * omega ** 2).astype(complex))
            eig = np.concatenate([(-c + disc) / 2, (-c - disc) / 2])
        else:
            eig = np.linalg.eigvals(state_matrix(structure))
        distinct = [0.0]
        for s in eig:
            if s.real < -tol * max(1.0, abs(s)) or s.imag < 0:
                continue
            if not any(abs(s - d) <= 1e-8 * max(1, abs(s)) for d in distinct):
                distinct.append(complex(s))
        return distinct
    return structure.memo(("critical_eigenvalues", tol), compute)


def static_gain(structure, sensors, forces):
    """The static gain from forces to the strain and displacement sensors, ``(S_s + S_d) K^-1 S_p``.

    Velocity and acceleration rows are exactly zero in a static state.  Entries at rounding level
    (a zero-force member, a node at rest) are exactly zero; see :mod:`core_akf.rank`.

    Parameters
    ----------
    structure : Structure
    sensors : sequence of sensor specs
        m sensors.
    forces : sequence of force specs
        n_p locations.

    Returns
    -------
    StaticGain
        (m x n_p, with its rounding bound).
    """
    layout = as_layout(sensors)
    locs = parse_force_locations(structure, forces)
    S = selection_matrices(structure, layout)
    extra = static_feedthrough(structure, layout, locs) if structure.static is not None else None
    return rank.static_gain(structure, S["strain"] + S["disp"], force_selection(structure, locs), extra)


def static_test_suffices(structure):
    """Whether the PBH test reduces to the static gain.

    True when the structure is supported and damped, so the force states' ``s = 0`` is the only
    critical eigenvalue.

    Parameters
    ----------
    structure : Structure

    Returns
    -------
    bool
    """
    return len(_critical_eigenvalues(structure, rank.CRITICAL_RTOL)) == 1 and is_supported(structure)


def _describe_combination(locs, combo):
    terms = [f"{c:+.2f} x {node}:{d}" for (node, d), c in zip(locs, combo) if abs(c) > 1e-3]
    return " ".join(terms)


def detectability(structure: Structure, sensors: Layout, forces: Forces,
                   force_model: ForceModel | None = None) -> DetectabilityReport:
    """PBH detectability of the augmented system for a sensor layout (S17 §2.4).

    The pair ``(A_ac, H_ac)`` with ``A_ac = [[A_c, B_c H], [0, F]]`` and ``H_ac = [G, D H]`` (the
    force model's continuous ``F`` and output ``H``, :mod:`core_akf.forcemodels`) is detectable
    iff ``[[sI - A_ac], [H_ac]]`` has full column rank at every eigenvalue with Re s >= 0.  For the
    random walk (``F = 0``, ``H = I``) on a supported, damped structure only ``s = 0`` (the force
    states) is critical and the test reduces to the rank of the static gain from forces to
    sensors.  A stationary (Matérn) force model has its poles at ``-lambda``: it adds no critical
    eigenvalue, so only the structure's own ones are tested.  Every rank decision is taken in
    :mod:`core_akf.rank` against a rounding-error bound, so the verdict does not depend on the
    BLAS kernel.

    Parameters
    ----------
    structure : Structure
    sensors : sequence of sensor specs
    forces : sequence of force specs
    force_model : ForceModel, optional
        The forces' prior; default the random walk.

    Returns
    -------
    DetectabilityReport
        Its ``str`` names the failing eigenvalues.

    Examples
    --------
    >>> from core_akf.forcemodels import ForceModel
    >>> from core_akf.models import s17_truss
    >>> detectability(s17_truss(), ["acc:4:y", "acc:8:y"], ["8:y"]).detectable
    False
    >>> detectability(s17_truss(), ["strain:13", "acc:8:y"], ["8:y"]).detectable
    True
    >>> detectability(s17_truss(), ["acc:4:y", "acc:8:y"], ["8:y"],
    ...               ForceModel("matern32", std=500.0, timescale=0.01)).detectable
    True
    """
    layout = as_layout(sensors)
    locs = parse_force_locations(structure, forces)
    stationary = force_model is not None and force_model.stationary
    checked, failures = [], []
    if static_test_suffices(structure) and not stationary:
        rel, combo, seen = static_gain(structure, layout, locs).visibility()
        checked.append(0j)
        if not seen:
            acc_only = all(s.kind in ("acc", "vel") for s in layout)
            hint = ("; accelerations alone do not see the static response: a Matérn force model "
                    "(force_model = \"matern32\") or a dummy displacement makes this set detectable") if acc_only else \
                ("; a Matérn force model (force_model = \"matern32\") or a dummy displacement at the unseen "
                 "force makes this set detectable")
            failures.append(dict(s=0.0, sigma_rel=rel, unseen=(
                "displacements, forces: no strain/displacement sensor sees the static response to the "
                f"force combination {_describe_combination(locs, combo)}{hint}")))
        return DetectabilityReport(detectable=not failures, checked=checked, failures=failures, sensors=layout,
                                   force_model=force_model)
    A_c, B_c = continuous(structure, locs)
    G, D = observation(structure, layout, locs)
    fm = force_model or ForceModel("random_walk", increment_cov=0.0)     # the random walk: F = 0, H = I
    F, H_f = fm.continuous(len(locs))[0], fm.output(len(locs))
    n, ng = A_c.shape[0], F.shape[0]
    nu = structure.n
    A_ac = np.zeros((n + ng, n + ng))
    A_ac[:n, :n] = A_c
    A_ac[:n, n:] = B_c @ H_f
    A_ac[n:, n:] = F
    H = np.hstack([G, D @ H_f])
    critical = _critical_eigenvalues(structure, rank.CRITICAL_RTOL)
    if stationary:                                  # the force states' poles lie at -lambda: not critical
        critical = [s for s in critical if s != 0.0] + ([0.0] if not is_supported(structure) else [])
    for s in critical:
        rel, null, deficient = rank.column_rank_test(np.vstack([s * np.eye(n + ng) - A_ac, H]).astype(complex))
        checked.append(complex(s))
        if deficient:
            v = np.abs(null)  # in the scaled coordinates: comparable across blocks
            v = v / max(v.max(), 1e-300)
            parts = {"displacements": v[:nu].max(), "velocities": v[nu:2 * nu].max(), "forces": v[n:].max()}
            unseen = ", ".join(k for k, val in parts.items() if val > 1e-2)
            failures.append(dict(s=complex(s) if abs(complex(s).imag) > 0 else float(np.real(s)),
                                 sigma_rel=float(rel), unseen=unseen))
    return DetectabilityReport(detectable=not failures, checked=checked, failures=failures, sensors=layout,
                               force_model=force_model)


# ---------------------------------------------------------------------------- bundle
@dataclass
class StateSpace:
    """Discrete augmented model of one structure, sensor layout and set of force locations.

    Attributes
    ----------
    structure : Structure
    sensors : tuple of Sensor
    forces : list of (int, str)
    dt : float
        Time step (s).
    A, B : ndarray (2n, 2n), (2n, n_p)
        ZOH-discretised structural model.
    G, D : ndarray (m, 2n), (m, n_p)
        Observation ``y_k = G x_k + D f_k``.
    A_a, G_a : ndarray (n_a, n_a), (m, n_a)
        Augmented transition and observation, ``n_a = 2n + n_p``.
    """

    structure: object
    sensors: tuple
    forces: list
    dt: float
    A: np.ndarray
    B: np.ndarray
    G: np.ndarray
    D: np.ndarray
    A_a: np.ndarray
    G_a: np.ndarray

    @property
    def n_states(self):
        return self.A.shape[0]

    @property
    def n_forces(self):
        return self.B.shape[1]

    @property
    def n_aug(self):
        return self.A_a.shape[0]


class SubsetDetectability:
    """PBH detectability of many subsets of one list of candidate sensors, for one set of forces.

    What the optimisers ask thousands of times (placement layouts, role splits).  For a supported,
    damped structure (:func:`static_test_suffices`) the static gain of every candidate is computed
    once and a subset is detectable if its rows see every force combination
    (:meth:`core_akf.rank.StaticGain.sees_every_force`); otherwise each subset gets the full
    :func:`detectability` test.  Both are the same decision as :func:`detectability`.

    Parameters
    ----------
    structure : Structure
    sensors : sequence of sensor specs
        The candidates.
    forces : sequence of force specs
    force_model : ForceModel, optional
        The forces' prior (default the random walk).  Under a stationary (Matérn) model on a
        supported, damped structure every subset is detectable.
    """

    def __init__(self, structure, sensors, forces, force_model=None):
        self.structure, self.sensors = structure, list(sensors)
        self.forces = parse_force_locations(structure, forces)
        self.force_model = force_model
        stationary = force_model is not None and force_model.stationary
        self.always = stationary and static_test_suffices(structure)
        self.static = static_gain(structure, self.sensors, self.forces) \
            if static_test_suffices(structure) and not stationary else None

    def detectable(self, indices):
        """Whether a subset of the candidates is detectable.

        Parameters
        ----------
        indices : sequence of int
            0-based indices into the candidates.

        Returns
        -------
        bool
        """
        if self.always:
            return True
        if self.static is not None:
            return self.static.rows(indices).sees_every_force
        return detectability(self.structure, [self.sensors[i] for i in indices], self.forces,
                             self.force_model).detectable


def state_space(structure: Structure, sensors: Layout, forces: Forces, dt: float) -> StateSpace:
    """Build the discrete augmented :class:`StateSpace` (validates every id once).

    Parameters
    ----------
    structure : Structure
    sensors : sequence of sensor specs
    forces : sequence of force specs
    dt : float
        Time step (s).

    Returns
    -------
    StateSpace

    Examples
    --------
    >>> from core_akf.models import s17_truss
    >>> ss = state_space(s17_truss(), ["strain:13", "acc:8:y"], ["8:y"], 1e-3)
    >>> ss.A_a.shape, ss.G_a.shape             # 2 x 33 DOFs + 1 force
    ((67, 67), (2, 67))
    """
    layout = as_layout(sensors)
    locs = parse_force_locations(structure, forces)
    A_c, B_c = continuous(structure, locs)
    A, B = zoh(A_c, B_c, dt)
    G, D = observation(structure, layout, locs)
    A_a, G_a = augment(A, B, G, D)
    return StateSpace(structure, layout, locs, float(dt), A, B, G, D, A_a, G_a)


def check_detectable(structure, sensors, forces, allow_undetectable=False, force_model=None):
    """The PBH report of a layout, refusing an undetectable one unless allowed.

    Parameters
    ----------
    structure : Structure
    sensors : sequence of sensor specs
    forces : sequence of force specs
    allow_undetectable : bool
        Return the report of an undetectable set instead of raising.
    force_model : ForceModel, optional
        The forces' prior (default the random walk).

    Returns
    -------
    DetectabilityReport

    Raises
    ------
    UndetectableError
        For an undetectable set, unless ``allow_undetectable``.
    """
    report = detectability(structure, sensors, forces, force_model)
    if not report.detectable and not allow_undetectable:
        raise UndetectableError(report)
    return report
