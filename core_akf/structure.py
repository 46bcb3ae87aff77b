"""The :class:`Structure`: mass, stiffness and damping matrices with the map from
user ids (1-based node/joint numbers and directions, member numbers, strain
components) to matrix rows and columns.

A structure is either *full* (generalised coordinates are the free physical DOFs)
or *modally reduced* (generalised coordinates are modal amplitudes ``q`` with
``u = basis @ q``).  Sensors, strains and force locations are always given by user
id; :meth:`Structure.dof_rows` and :meth:`Structure.strain_rows` return the rows in
generalised coordinates, so the rest of the toolkit never needs to know which kind
of structure it holds.
"""
from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
import scipy.linalg
import scipy.sparse
from numpy.typing import ArrayLike, NDArray

from .checks import (
    AKFInputError,
    Damping,
    FloatArray,
    ForceLocation,
    ModelError,
    as_finite_array,
    check_positive_definite,
    check_square_symmetric,
)

STRAIN_COMPONENTS = ("ex", "ey", "gxy")


#: a modal damping ratio above this is warned about (a percentage typed for a ratio?)
DAMPING_WARN = 0.3


class DampingWarning(UserWarning):
    """A damping ratio that a structure hardly has (above :data:`DAMPING_WARN`)."""


def _damping_matrix(M, K, damping, modes):
    """Damping matrix from a damping spec (see :class:`Structure`); ``modes()`` gives
    ``(omega, Phi)`` and is only called for modal damping."""
    if damping is None:
        return np.zeros_like(M)
    if isinstance(damping, (tuple, list)) and len(damping) == 3 and str(damping[0]).lower() == "rayleigh":
        alpha, beta = float(damping[1]), float(damping[2])
        return alpha * M + beta * K
    try:
        zeta = np.asarray(damping, dtype=float)
    except (TypeError, ValueError):
        raise AKFInputError(f"damping must be a modal damping ratio or ('rayleigh', alpha, beta); got {damping!r}") from None
    omega, phi = modes()
    if zeta.ndim > 1 or (zeta.ndim == 1 and zeta.size != omega.size):
        raise AKFInputError(
            f"damping must be a modal damping ratio (scalar or one per mode, {omega.size}) "
            f"or ('rayleigh', alpha, beta); got {damping!r}"
        )
    if np.any(zeta < 0) or np.any(~np.isfinite(zeta)):
        raise AKFInputError(f"damping ratios must be finite and >= 0, got {damping!r}")
    if np.any(zeta >= 1.0):
        raise AKFInputError(f"damping ratio {float(np.max(zeta)):g} is critical or overdamped: damping is a ratio, not a "
                            "percentage (2 % is 0.02)")
    if np.any(zeta > DAMPING_WARN):
        import warnings

        warnings.warn(f"damping ratio {float(np.max(zeta)):g} is above {DAMPING_WARN:g}: structures damp a few percent "
                      "(a ratio of 0.02 is 2 %); is it a percentage?", DampingWarning)
    # C = M Phi diag(2 zeta omega) Phi^T M with mass-normalised Phi
    mphi = M @ phi
    C = (mphi * (2.0 * zeta * omega)) @ mphi.T
    return 0.5 * (C + C.T)


@dataclass(eq=False)
class Structure:
    """A linear structural model ``M u'' + C u' + K u = S_p f`` (SI units).

    Parameters
    ----------
    M, K : ndarray, shape (n, n)
        Mass (kg, kg m^2) and stiffness (N/m, N m/rad) in generalised coordinates.
    damping : float, array, ('rayleigh', alpha, beta) or None
        Modal damping ratio (one for all modes or one per mode), Rayleigh
        coefficients, or no damping.  Ignored if ``C`` is given.
    nodes : ndarray, shape (n_nodes, 2)
        Node (joint) coordinates in m; user node id ``i`` is row ``i - 1``.
    dof_names : tuple of str
        Names of the DOFs per node, e.g. ``("x", "y")`` (truss) or ``("w", "rx", "ry")`` (plate).
    free_dofs : ndarray of int
        Full physical DOF indices ``(node-1)*ndof + d`` that are not constrained, in the
        order of the physical free coordinates.
    strain_matrix : ndarray, shape (n_strain, n_phys)
        Maps free physical displacements to strains (truss: member strains; plate:
        surface strains at nodes, all e_x, then all e_y, then all g_xy).
    strain_kind : {"member", "node"}
        How strains are addressed: by member number, or by (node, component).
    members : ndarray, shape (n_members, 2), optional
        End nodes of the bar members as user node ids (1-based, as every id a user sees; truss
        only): member ``m`` joins nodes ``members[m - 1]``.
    basis : ndarray, shape (n_phys, n), optional
        ``u_phys = basis @ q`` for a modally reduced structure; ``None`` for a full one.
    node_ids : ndarray of int, shape (n_nodes,), optional
        The user's node ids, row by row, for a model whose nodes are not numbered 1..n_nodes
        (one imported from an FE program, :func:`core_akf.models.from_matrices`); default
        ``1..n_nodes``.
    static : :class:`~core_akf.models.sparse.StaticCorrection`, optional
        For a reduced structure: the residual flexibility of the modes it leaves out, added to
        every strain and displacement output as a feed-through of the forces (a large model
        reduced by :func:`core_akf.models.from_matrices` has one).  ``strain_matrix`` may then be
        a ``scipy.sparse`` matrix.
    C : ndarray, shape (n, n), optional
        A damping matrix (N s/m) instead of ``damping``.
    name : str
        The model's name.
    meta : dict
        What the model generator keeps beside the matrices (the unconstrained ``K_full`` and
        ``M_full``, member areas, the projection of a reduced model).

    Examples
    --------
    A two-storey shear frame with 2 % modal damping:

    >>> import numpy as np
    >>> s = Structure(M=np.eye(2), K=np.array([[2.0, -1.0], [-1.0, 1.0]]), damping=0.02,
    ...               nodes=np.array([[0.0, 1.0], [0.0, 2.0]]), dof_names=("x",), free_dofs=np.arange(2))
    >>> [round(float(f), 4) for f in s.frequencies()]
    [0.0984, 0.2575]
    """

    M: np.ndarray
    K: np.ndarray
    damping: object = None
    nodes: np.ndarray = None
    dof_names: tuple = ()
    free_dofs: np.ndarray = None
    strain_matrix: np.ndarray = None
    strain_kind: str = "member"
    members: np.ndarray = None
    basis: np.ndarray = None
    C: np.ndarray = None
    name: str = ""
    meta: dict = field(default_factory=dict)
    node_ids: np.ndarray = None
    static: object = None
    _memo: dict = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self):
        self.M = as_finite_array(self.M, "mass matrix M", ndim=2)
        self.K = as_finite_array(self.K, "stiffness matrix K", ndim=2)
        check_positive_definite(self.M, "mass matrix M")
        check_square_symmetric(self.K, "stiffness matrix K")
        if self.K.shape != self.M.shape:
            raise ModelError(f"K has shape {self.K.shape} but M has shape {self.M.shape}")
        self.nodes = np.asarray(self.nodes, dtype=float)
        if self.node_ids is not None:
            self.node_ids = np.asarray(self.node_ids, dtype=int)
            if self.node_ids.shape != (self.nodes.shape[0],) or np.unique(self.node_ids).size != self.node_ids.size:
                raise ModelError(f"node_ids must be {self.nodes.shape[0]} distinct integers, one per node")
            self._row_of_id = {int(k): i for i, k in enumerate(self.node_ids)}
        self.dof_names = tuple(self.dof_names)
        self.free_dofs = np.asarray(self.free_dofs, dtype=int)
        n_full = self.nodes.shape[0] * len(self.dof_names)
        self._free_index = np.full(n_full, -1, dtype=int)
        self._free_index[self.free_dofs] = np.arange(self.free_dofs.size)
        n_phys = self.free_dofs.size
        if self.basis is None and n_phys != self.n:
            raise ModelError(f"{n_phys} free DOFs but matrices of size {self.n}")
        if self.basis is not None and self.basis.shape != (n_phys, self.n):
            raise ModelError(f"basis must have shape ({n_phys}, {self.n}), got {self.basis.shape}")
        if self.strain_matrix is not None and self.strain_matrix.shape[1] != n_phys:
            raise ModelError("strain_matrix must have one column per free physical DOF")
        if self.C is None:
            self.C = _damping_matrix(self.M, self.K, self.damping, lambda: self.eigen)
        else:
            self.C = as_finite_array(self.C, "damping matrix C", ndim=2)
            check_square_symmetric(self.C, "damping matrix C")

    # ------------------------------------------------------------------ sizes
    @property
    def n(self):
        """Number of generalised coordinates."""
        return self.M.shape[0]

    @property
    def n_nodes(self):
        return self.nodes.shape[0]

    @property
    def n_strain(self):
        """Number of strain outputs (members, or 3 components x nodes)."""
        return 0 if self.strain_matrix is None else self.strain_matrix.shape[0]

    @property
    def is_reduced(self):
        return self.basis is not None

    # ------------------------------------------------------------------ modes
    @cached_property
    def eigen(self):
        """The undamped modes, computed once: ``(omega, Phi)`` with ``omega`` (n,) in rad/s,
        ascending, and ``Phi`` (n, n) mass-normalised, in generalised coordinates."""
        w2, phi = scipy.linalg.eigh(self.K, self.M)
        if w2[0] < -1e-8 * max(abs(w2[-1]), 1.0):
            raise ModelError(f"K is not positive semi-definite (eigenvalue {w2[0]:.3g})")
        return np.sqrt(np.clip(w2, 0.0, None)), phi

    def frequencies(self, k: int | None = None) -> FloatArray:
        """The lowest undamped natural frequencies.

        Parameters
        ----------
        k : int, optional
            How many (all if None).

        Returns
        -------
        ndarray (k,)
            Hz, ascending.
        """
        omega = self.eigen[0]
        if k is not None:
            if not 1 <= int(k) <= omega.size:
                raise AKFInputError(f"k must be between 1 and {omega.size}, got {k}")
            omega = omega[: int(k)]
        return omega / (2.0 * np.pi)

    def modes(self, k: int | None = None) -> FloatArray:
        """The lowest mass-normalised mode shapes, in physical free DOFs.

        Parameters
        ----------
        k : int, optional
            How many (all if None).

        Returns
        -------
        ndarray (n_phys, k)
        """
        phi = self.eigen[1][:, :k]
        return phi if self.basis is None else self.basis @ phi

    def memo(self, key: Hashable, compute: Callable[[], Any]) -> Any:
        """A result of an analysis of this structure, computed once.

        The structure's matrices never change after construction (a changed model is a new
        :class:`Structure`), so a result that depends only on them is kept.

        Parameters
        ----------
        key : hashable
            What the result is (a factorisation, the critical eigenvalues, ...).
        compute : callable
            ``compute()`` gives the result the first time.

        Returns
        -------
        object
        """
        if key not in self._memo:
            self._memo[key] = compute()
        return self._memo[key]

    # ------------------------------------------------------------------ id maps
    def _node_index(self, node):
        try:
            node_int = int(node)
        except (TypeError, ValueError):
            raise AKFInputError(f"node id must be an integer, got {node!r}") from None
        if self.node_ids is not None:
            if node_int != node or node_int not in self._row_of_id:
                raise AKFInputError(f"unknown node {node!r}: this structure's node ids run from {self.node_ids.min()} to "
                                    f"{self.node_ids.max()} ({self.n_nodes} nodes)")
            return self._row_of_id[node_int]
        if node_int != node or not 1 <= node_int <= self.n_nodes:
            raise AKFInputError(f"unknown node/joint {node!r}: this structure has nodes 1..{self.n_nodes}")
        return node_int - 1

    def node_rows(self, nodes: Sequence[int]) -> NDArray[np.intp]:
        """Rows of :attr:`nodes` (0-based) of user node ids.

        Parameters
        ----------
        nodes : sequence of int
            User node ids.

        Returns
        -------
        ndarray of int

        Raises
        ------
        AKFInputError
            Naming an unknown node.
        """
        return np.array([self._node_index(n) for n in np.atleast_1d(nodes)], dtype=int)

    @property
    def user_node_ids(self):
        """The user's node ids, row by row (``1..n_nodes`` unless the model has ids of its own)."""
        return np.arange(1, self.n_nodes + 1) if self.node_ids is None else self.node_ids

    def dof_index(self, node: int, direction: str) -> int:
        """Index of a free physical DOF.

        Parameters
        ----------
        node : int
            User node id (1-based).
        direction : str
            A DOF name (:attr:`dof_names`).

        Returns
        -------
        int
            0-based index among the physical free DOFs.
        """
        i = self._node_index(node)
        if direction not in self.dof_names:
            raise AKFInputError(
                f"unknown direction {direction!r} at node {node}; this structure has {self.dof_names}"
            )
        full = i * len(self.dof_names) + self.dof_names.index(direction)
        idx = self._free_index[full]
        if idx < 0:
            raise AKFInputError(f"DOF {direction!r} of node {node} is constrained (a support): no response there")
        return int(idx)

    def dof_rows(self, locations: Sequence[ForceLocation]) -> FloatArray:
        """Selection rows mapping generalised coordinates to physical DOFs.

        Parameters
        ----------
        locations : sequence of (int, str)
            ``(node, direction)`` pairs.

        Returns
        -------
        ndarray (len(locations), n)
        """
        idx = [self.dof_index(node, d) for node, d in locations]
        if self.basis is None:
            rows = np.zeros((len(idx), self.n))
            rows[np.arange(len(idx)), idx] = 1.0
            return rows
        return self.basis[idx].copy()

    def strain_index(self, key: int | tuple[int, str]) -> int:
        """Row of a strain output.

        Parameters
        ----------
        key : int or (int, str)
            A member number (truss, extensometer, strain row) or ``(node, component)`` with component
            in ``("ex", "ey", "gxy")`` (plate), 1-based.

        Returns
        -------
        int
            0-based row of :attr:`strain_matrix`.
        """
        if self.strain_matrix is None:
            raise AKFInputError("this structure has no strain operator")
        if self.strain_kind == "member":
            try:
                m = int(key)
            except (TypeError, ValueError):
                raise AKFInputError(f"truss strains are addressed by member number, got {key!r}") from None
            if m != key or not 1 <= m <= self.n_strain:
                raise AKFInputError(f"unknown member {key!r}: this truss has members 1..{self.n_strain}")
            return m - 1
        try:
            node, comp = key
        except (TypeError, ValueError):
            raise AKFInputError(f"plate strains are addressed as (node, component), got {key!r}") from None
        if comp not in STRAIN_COMPONENTS:
            raise AKFInputError(f"unknown strain component {comp!r}; use one of {STRAIN_COMPONENTS}")
        return STRAIN_COMPONENTS.index(comp) * self.n_nodes + self._node_index(node)

    def strain_rows(self, keys: Sequence[int | tuple[int, str]]) -> FloatArray:
        """Strain rows in generalised coordinates.

        Parameters
        ----------
        keys : sequence
            Keys as :meth:`strain_index` takes them.

        Returns
        -------
        ndarray (len(keys), n)
        """
        idx = [self.strain_index(k) for k in keys]
        if self.basis is not None and scipy.sparse.issparse(self.strain_matrix) and "strain_operator" not in self.__dict__:
            return np.asarray(self.strain_matrix[idx] @ self.basis)     # a large model: only the rows asked for
        return self.strain_operator[idx]

    @cached_property
    def strain_operator(self):
        """All strains from generalised coordinates, shape (n_strain, n)."""
        if self.strain_matrix is None:
            return np.zeros((0, self.n))
        return self.strain_matrix if self.basis is None else self.strain_matrix @ self.basis

    @property
    def strain_labels(self):
        """Labels of all strain outputs in the sensor grammar: ``strain:1, strain:2, ...`` (truss
        members) or ``strain:1:ex, ..., strain:1:ey, ..., strain:1:gxy, ...`` (plate nodes), so that
        a strain output and a strain gauge at the same place have the same name."""
        if self.strain_kind == "member":
            return [f"strain:{i + 1}" for i in range(self.n_strain)]
        return [f"strain:{i + 1}:{c}" for c in STRAIN_COMPONENTS for i in range(self.n_nodes)]

    def strain_label_index(self, labels: Sequence[str]) -> list[int]:
        """Rows of the strain outputs named by their labels.

        Parameters
        ----------
        labels : sequence of str
            Labels as :attr:`strain_labels` ("strain:13", "strain:70:ex").

        Returns
        -------
        list of int

        Raises
        ------
        AKFInputError
            For an unknown label, naming the closest known one.
        """
        import difflib

        known = {lab: i for i, lab in enumerate(self.strain_labels)}
        rows = []
        for lab in labels:
            if lab not in known:
                hint = difflib.get_close_matches(str(lab), list(known), n=1)
                raise AKFInputError(f"unknown strain output {lab!r}; outputs are named like sensors "
                                    f"({self.strain_labels[0]!r} ... {self.strain_labels[-1]!r})"
                                    + (f"; did you mean {hint[0]!r}?" if hint else ""))
            rows.append(known[lab])
        return rows

    # ------------------------------------------------------------------ derived structures
    def _replace(self, **changes):
        fields = dict(M=self.M, K=self.K, damping=self.damping, nodes=self.nodes, dof_names=self.dof_names,
                      free_dofs=self.free_dofs, strain_matrix=self.strain_matrix, strain_kind=self.strain_kind,
                      members=self.members, basis=self.basis, C=None, name=self.name, meta=dict(self.meta),
                      node_ids=self.node_ids, static=self.static)
        fields.update(changes)
        return Structure(**fields)

    def with_damping(self, damping: Damping) -> Structure:
        """A copy with another damping spec, its damping matrix built from it.

        Parameters
        ----------
        damping : float, array, ('rayleigh', alpha, beta) or None
            As the ``damping`` of :class:`Structure` (a modal ratio, one per mode, Rayleigh
            coefficients, or none).

        Returns
        -------
        Structure

        Examples
        --------
        >>> from core_akf.models import s17_truss
        >>> s17_truss().with_damping(0.02).damping
        0.02
        """
        return self._replace(damping=damping)

    def scaled(self, stiffness_factor: float = 1.0, mass_factor: float = 1.0) -> Structure:
        """A copy with K (and M) multiplied by a factor; damping is rebuilt from the spec (a damping
        matrix ``C`` given instead of a spec is kept as given).

        ``stiffness_factor=1.05`` is the papers' "5 % stiffer" model error (equivalent to a 5 %
        larger Young's modulus).

        Parameters
        ----------
        stiffness_factor : float
        mass_factor : float

        Returns
        -------
        Structure
        """
        for name, v in (("stiffness_factor", stiffness_factor), ("mass_factor", mass_factor)):
            if not np.isfinite(v) or v <= 0:
                raise AKFInputError(f"{name} must be a positive number, got {v!r}")
        with np.errstate(over="ignore"):
            changes = dict(K=self.K * stiffness_factor, M=self.M * mass_factor)
        for name, v, A in (("stiffness_factor", stiffness_factor, changes["K"]), ("mass_factor", mass_factor, changes["M"])):
            with np.errstate(over="ignore"):
                big = float(np.max(np.abs(A)))
            if not np.isfinite(big) or big == 0.0:
                raise AKFInputError(f"{name} {v!r} makes the {'stiffness' if name[0] == 's' else 'mass'} matrix "
                                    f"{'overflow' if not np.isfinite(big) else 'vanish'} in float64; a factor near 1 "
                                    "(1.05: 5 % stiffer) is what it is for")
        if self.static is not None:
            changes["static"] = self.static.scaled(stiffness_factor, mass_factor)
        if self.damping is None and np.any(self.C):
            changes["C"] = self.C                   # a damping matrix of one's own is kept as given
        return self._replace(**changes)

    def with_frequency_factors(self, factors: ArrayLike) -> Structure:
        """A copy whose lowest natural frequencies are multiplied by ``factors``, mode shapes kept.

        ``K' = K + M Phi diag((f^2 - 1) omega^2) Phi^T M`` over the modes changed (mass-normalised
        ``Phi``): a change of one mode's stiffness that leaves the others and every mode shape as
        they were.  A static correction (:attr:`static`) follows, so that the full model's
        static response is that of ``K'``.  The damping is rebuilt from its spec (a modal ratio
        stays the ratio of each mode); a damping matrix ``C`` given instead is kept as given.

        Parameters
        ----------
        factors : array_like (k,)
            Positive factors on the frequencies of modes 1..k (k <= n); the other modes keep theirs.

        Returns
        -------
        Structure

        Examples
        --------
        >>> from core_akf.models import s17_truss
        >>> s = s17_truss()
        >>> (s.with_frequency_factors([1.0, 0.9]).frequencies(3) / s.frequencies(3)).round(6).tolist()
        [1.0, 0.9, 1.0]
        """
        f = np.atleast_1d(np.asarray(factors, dtype=float))
        if f.ndim != 1 or not 1 <= f.size <= self.n:
            raise AKFInputError(f"frequency factors: give one per mode for modes 1..k (k <= {self.n}), got shape {f.shape}")
        if not np.all(np.isfinite(f)) or np.any(f <= 0):
            raise AKFInputError(f"frequency factors must be positive numbers, got {f.tolist()}")
        omega, phi = self.eigen
        k = f.size
        change = (f ** 2 - 1.0) * omega[:k] ** 2                  # rad^2/s^2 added to each mode's eigenvalue
        mphi = self.M @ phi[:, :k]
        K = self.K + (mphi * change) @ mphi.T
        changes = dict(K=0.5 * (K + K.T))
        if self.static is not None:
            # K'^-1 = K^-1 + Phi_k diag(1/omega'^2 - 1/omega^2) Phi_k^T: the residual of the kept modes is unchanged
            st, modes = self.static, self.modes(k)
            flex = (1.0 / (f * omega[:k]) ** 2 - 1.0 / omega[:k] ** 2) / st.flexibility_scale

            def solve(B, s=st.solve):
                return s(B) + (modes * flex) @ (modes.T @ B)
            kept = st.omega.copy()
            matched = np.argmin(np.abs(kept[:, None] - omega[None, :k]), axis=0)    # the kept modes changed
            kept[matched] = kept[matched] * f
            from .models.sparse import StaticCorrection

            changes["static"] = StaticCorrection(solve, st.phi, kept, st.flexibility_scale)
        if self.damping is None and np.any(self.C):
            changes["C"] = self.C                   # a damping matrix of one's own is kept as given
        return self._replace(**changes)

    def reduce(self, n_modes: int, static_correction: bool = False) -> Structure:
        """Modal reduction to the lowest modes, with the same sensor and strain interface.

        The reduced model has ``M = I``, ``K = diag(omega^2)`` and ``C = Phi^T C Phi`` (diagonal for
        modal damping).  A structure that is itself reduced with a static correction (:attr:`static`)
        keeps it, the modes dropped now joining the residual.

        Parameters
        ----------
        n_modes : int
            Modes kept.
        static_correction : bool
            Give a full structure's reduction a static correction
            (:class:`~core_akf.models.sparse.StaticCorrection` from a Cholesky factor of K): every strain
            and displacement output then has the full model's static response.

        Returns
        -------
        Structure
        """
        from .checks import check_n_modes

        n_modes = check_n_modes(n_modes)
        if not 1 <= n_modes <= self.n:
            raise AKFInputError(f"n_modes must be between 1 and {self.n}, got {n_modes}")
        omega, phi = self.eigen
        phi = phi[:, :n_modes]
        Cr = phi.T @ self.C @ phi
        basis = phi if self.basis is None else self.basis @ phi
        zeta = self.damping
        if zeta is not None and not isinstance(zeta, (tuple, list)) and np.ndim(zeta) == 1:
            zeta = np.asarray(zeta)[:n_modes]
        # q = P u_phys with P = Phi^T M_phys (mass-orthogonal projection), kept for mapping
        # physical quantities (e.g. model-error covariances) to the reduced coordinates
        P_prev = self.meta.get("projection")
        P = phi.T @ self.M if P_prev is None else phi.T @ self.M @ P_prev
        meta = dict(self.meta, projection=P)
        if self.static is not None:
            static = self.static.keeping(basis, omega[:n_modes])
        elif static_correction and self.basis is None:
            from .models.sparse import StaticCorrection

            factor = scipy.linalg.cho_factor(self.K)
            static = StaticCorrection(lambda B: scipy.linalg.cho_solve(factor, B), basis, omega[:n_modes])
        else:
            static = None
        return self._replace(M=np.eye(n_modes), K=np.diag(omega[:n_modes] ** 2), basis=basis, static=static,
                             damping=zeta, C=0.5 * (Cr + Cr.T), name=f"{self.name} ({n_modes} modes)", meta=meta)

    @property
    def projection(self):
        """``P`` (n x n_phys) with ``q = P u_phys``: identity for a full structure, ``Phi^T M`` for a
        modally reduced one (``P @ basis = I``)."""
        P = self.meta.get("projection")
        return np.eye(self.n) if P is None else P

    def total_mass(self, direction: str) -> float:
        """Total translational mass of the full, unconstrained model.

        Parameters
        ----------
        direction : str
            A DOF name ("x", "y", "z").

        Returns
        -------
        float
            kg (from ``meta['M_full']``, when the model generator stored it).
        """
        M_full = self.meta.get("M_full")
        if M_full is None:
            raise AKFInputError("total_mass needs the unconstrained mass matrix (meta['M_full'])")
        ndof = len(self.dof_names)
        r = np.zeros(M_full.shape[0])
        r[self.dof_names.index(direction)::ndof] = 1.0
        return float(r @ M_full @ r)

    def __repr__(self):
        kind = f"reduced to {self.n} modes" if self.is_reduced else f"{self.n} DOFs"
        return f"<Structure {self.name!r}: {self.n_nodes} nodes, {kind}, {self.n_strain} strain outputs>"


def check_structure(structure) -> Structure:
    """``structure`` checked to be a :class:`Structure`: a path, a job or a dict is named.

    Parameters
    ----------
    structure : object

    Returns
    -------
    Structure
        ``structure`` itself.

    Raises
    ------
    AKFInputError
        For anything else.
    """
    if not isinstance(structure, Structure):
        raise AKFInputError(f"structure must be a Structure (core_akf.models.s17_truss(), from_files(...), ...), got "
                            f"{type(structure).__name__}")
    return structure
