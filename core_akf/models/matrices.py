"""A linear model brought from files or an FE program: stiffness and mass matrices, the DOF map
(node id and direction of every matrix row), node coordinates (2-D or 3-D), the constrained DOFs
and the damping.

>>> import numpy as np
>>> K = np.array([[2.0, -1.0], [-1.0, 1.0]]) * 1e6          # two masses on springs, N/m
>>> M = np.eye(2) * 10.0                                   # kg
>>> s = from_matrices(K, M, dofs=[(1, "x"), (2, "x")], nodes={1: (1.0, 0.0), 2: (2.0, 0.0)},
...                   damping=0.02)
>>> np.round(s.frequencies(), 3)
array([31.105, 81.434])

Directions are ``x y z`` (translations, m) and ``rx ry rz`` (rotations, rad).  Node ids are the
user's own (any distinct integers).  Strain outputs are virtual extensometers between two nodes,
``eps = (u_b - u_a) . e / L`` with ``e`` the unit vector from ``a`` to ``b`` (the strain of a
bar between them), addressed like truss members: ``strain:1`` is the first extensometer.  A node
with coordinates but no DOF in the map is the ground (it does not move).
"""
from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..checks import (
    AKFInputError,
    ArrayLike,
    Damping,
    ModelError,
    check_memory,
    check_n_modes,
    describe_cell,
    first_repeat,
    found_columns,
)
from ..structure import Structure

if TYPE_CHECKING:
    import scipy.sparse
from .sparse import (
    DEFAULT_MODES,
    DENSE_LIMIT,
    RIGID_BODY_RTOL,
    as_sparse,
    check_symmetric,
    modal_parts,
    refuse_complex,
)

DIRECTIONS = ("x", "y", "z", "rx", "ry", "rz")
#: the first natural frequencies of a structural model in SI units lie in this band (Hz);
#: outside it, masses or stiffnesses are probably in other units (t, N/mm, kN/m, ...)
FREQUENCY_RANGE = (0.01, 50e3)
#: relative asymmetry of K or M above which a matrix is refused
SYMMETRY_RTOL = 1e-10


class ModelWarning(UserWarning):
    """A model that can be used but looks wrong (frequencies outside :data:`FREQUENCY_RANGE`)."""


def load_matrix(path: str | os.PathLike) -> np.ndarray | scipy.sparse.sparray:
    """A matrix from a file.

    Parameters
    ----------
    path : str
        Matrix Market (``.mtx``, ``.mtx.gz``; what ANSYS HBMAT conversions, Abaqus matrix output
        and OpenSees ``printA`` give), a scipy sparse ``.npz`` (``scipy.sparse.save_npz``), a
        NumPy ``.npz`` with one array, or ``.npy``.

    Returns
    -------
    ndarray or scipy.sparse matrix

    Examples
    --------
    >>> import os, tempfile
    >>> import scipy.io, scipy.sparse
    >>> path = os.path.join(tempfile.mkdtemp(), "K.mtx")
    >>> scipy.io.mmwrite(path, scipy.sparse.identity(3).tocsr())
    >>> load_matrix(path).shape
    (3, 3)
    """
    import scipy.io
    import scipy.sparse

    path = os.fspath(path)
    if not os.path.exists(path):
        raise AKFInputError(f"matrix file {path!r} not found")
    try:
        if path.endswith((".mtx", ".mtx.gz", ".mm")):
            _check_matrix_market_size(path)
            return scipy.io.mmread(path)
        if path.endswith(".npy"):
            return np.load(path, allow_pickle=False)
        if path.endswith(".npz"):
            try:
                return scipy.sparse.load_npz(path)
            except (ValueError, KeyError, OSError):
                with np.load(path, allow_pickle=False) as data:
                    if len(data.files) != 1:
                        raise AKFInputError(f"{path}: a .npz holds one matrix; found {len(data.files)} arrays") from None
                    return data[data.files[0]]
    except AKFInputError:
        raise
    except Exception as exc:  # noqa: BLE001 -- the readers raise many error types
        if "pickle" in str(exc).lower():
            raise AKFInputError(f"{path}: the file holds Python objects (pickled), which are never loaded (they can run "
                                "code): save the matrix as numbers (numpy.save of a float array)") from None
        raise AKFInputError(f"{path}: not a readable matrix file ({type(exc).__name__}: {' '.join(str(exc).split())})") from None
    raise AKFInputError(f"{path}: unknown matrix format; give .mtx (Matrix Market), .npz or .npy")


#: the fewest bytes an entry of a Matrix Market file takes: "i j v\n" (coordinate), "v\n" (array)
_MTX_ENTRY_BYTES = {"coordinate": 6, "array": 2}


def _check_matrix_market_size(path):
    """Refuse, from its header alone, a Matrix Market file whose size line cannot be true (more
    entries than the matrix has places, or than the file has bytes) or whose matrix would not fit
    in memory, before anything is allocated."""
    import scipy.io

    rows, cols, entries, layout, field, symmetry = scipy.io.mminfo(path)
    places = rows * cols if symmetry == "general" else rows * (rows + 1) // 2
    if layout == "coordinate" and entries > places:
        raise AKFInputError(f"{path}: the size line declares {entries} entries for a {rows} x {cols} matrix, which has "
                            f"{places} places: a wrong size line")
    if not path.endswith(".gz"):
        fits = os.path.getsize(path) // _MTX_ENTRY_BYTES.get(layout, 2)
        if (entries if layout == "coordinate" else places) > fits:
            raise AKFInputError(f"{path}: the size line declares a {rows} x {cols} matrix of "
                                f"{entries if layout == 'coordinate' else places} entries, but the file's "
                                f"{os.path.getsize(path)} bytes hold at most {fits}: the file is cut short or its size "
                                "line is wrong")
    values = rows + 1 + 3 * entries if layout == "coordinate" else rows * cols
    check_memory(values, 1, f"{path}: a {rows} x {cols} matrix", "reduce the model in the FE program (fewer DOFs, "
                 "or a modal or Guyan reduction) before exporting it", items="numbers")


def read_dof_map(path):
    """The DOF map from a CSV file.

    Parameters
    ----------
    path : str
        A CSV with columns ``node`` and ``direction``, one row per matrix row.

    Returns
    -------
    list of (int, str)
    """
    import pandas as pd

    table = _read_table(path, ["node", "direction"])
    nodes = pd.to_numeric(table["node"], errors="coerce")
    if nodes.isna().any() or (nodes != nodes.round()).any():
        r = int(np.flatnonzero(nodes.isna() | (nodes != nodes.round()))[0])
        raise AKFInputError(f"{path}: node in data row {r + 1} is {describe_cell(table['node'].iloc[r])}, not an "
                            "integer id")
    return list(zip(nodes.astype(int), table["direction"].astype(str).str.strip()))


def read_nodes(path):
    """Node coordinates from a CSV file.

    Parameters
    ----------
    path : str
        A CSV with columns ``node``, ``x``, ``y`` and optionally ``z`` (m).

    Returns
    -------
    dict
        Node id -> coordinates (m).
    """
    import pandas as pd

    table = _read_table(path, ["node", "x", "y"])
    cols = ["node", "x", "y"] + (["z"] if "z" in table.columns else [])
    values = table[cols].apply(pd.to_numeric, errors="coerce")
    bad = values.isna().to_numpy() | ~np.isfinite(values.to_numpy(dtype=float, na_value=np.nan))
    if bad.any():
        r, c = (int(i[0]) for i in np.nonzero(bad))
        raise AKFInputError(f"{path}: {cols[c]} in data row {r + 1} is {describe_cell(table[cols[c]].iloc[r])}, not a "
                            "finite number")
    ids = values["node"].to_numpy()
    if np.any(ids != np.round(ids)):
        r = int(np.flatnonzero(ids != np.round(ids))[0])
        raise AKFInputError(f"{path}: node in data row {r + 1} is {describe_cell(table['node'].iloc[r])}, not an "
                            "integer id")
    repeat = first_repeat(ids.tolist())
    if repeat:
        i, j, n = repeat
        raise AKFInputError(f"{path}: node {int(n)} is listed twice (data rows {i + 1} and {j + 1}); every node needs "
                            "one place")
    return {int(n): tuple(row) for n, row in zip(ids, values[cols[1:]].to_numpy(dtype=float))}


def read_extensometers(path):
    """Extensometers (or truss members) from a CSV file.

    Parameters
    ----------
    path : str
        A CSV with columns ``a`` and ``b`` (node ids), one strain output per row in order:
        ``strain:1`` is the first row.

    Returns
    -------
    list of (int, int)
    """
    import pandas as pd

    table = _read_table(path, ["a", "b"])
    ends = table[["a", "b"]].apply(pd.to_numeric, errors="coerce").to_numpy(dtype=float, na_value=np.nan)
    bad = ~np.isfinite(ends) | (ends != np.round(ends))
    if bad.any():
        r, c = (int(i[0]) for i in np.nonzero(bad))
        raise AKFInputError(f"{path}: node {'ab'[c]} in data row {r + 1} is {describe_cell(table[['a', 'b'][c]].iloc[r])}, "
                            "not an integer id")
    return [(int(a), int(b)) for a, b in ends]


def _read_table(path, columns):
    import pandas as pd

    if not os.path.exists(path):
        raise AKFInputError(f"file {path!r} not found")
    try:
        table = pd.read_csv(path, skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise AKFInputError(f"{path}: not a readable CSV file ({' '.join(str(exc).split())})") from None
    table.columns = [str(c).strip().lower().lstrip("\ufeff") for c in table.columns]
    filled = np.flatnonzero(table.notna().any(axis=1).to_numpy())
    table = table.iloc[:filled[-1] + 1 if filled.size else 0]     # trailing rows of empty cells (",,,") dropped
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise AKFInputError(f"{path}: missing column(s) {missing}; {found_columns(list(table.columns))}")
    return table


def _dense(A, name):
    import scipy.sparse

    refuse_complex(A, name)
    if scipy.sparse.issparse(A):
        A = A.toarray()
    A = np.asarray(A, dtype=float)
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise AKFInputError(f"{name} must be a square matrix, got shape {A.shape}")
    if not np.all(np.isfinite(A)):
        raise AKFInputError(f"{name} has NaN or infinite entries")
    return A


def _check_symmetric(A, name):
    scale = np.max(np.abs(A))
    if scale == 0:
        raise AKFInputError(f"{name} is all zeros")
    asym = np.abs(A - A.T)
    if asym.max() > SYMMETRY_RTOL * scale:
        i, j = np.unravel_index(np.argmax(asym), A.shape)
        raise AKFInputError(f"{name} is not symmetric: entries ({i + 1}, {j + 1}) and ({j + 1}, {i + 1}) differ by "
                            f"{asym[i, j]:.3g} ({asym[i, j] / scale:.2g} of its largest entry); a linear structural model "
                            "has symmetric matrices (was the file written as a triangle or with another DOF order?)")
    return 0.5 * (A + A.T)


def from_matrices(K: ArrayLike | scipy.sparse.sparray, M: ArrayLike | scipy.sparse.sparray,
                  dofs: Sequence[tuple[int, str]], nodes: Mapping[int, Sequence[float]],
                  fixed: Sequence | None = None, damping: Damping = None, C: ArrayLike | None = None,
                  extensometers: Sequence[tuple[int, int]] | None = None, strain_rows: ArrayLike | None = None,
                  name: str = "imported model", n_modes: int | None = None) -> Structure:
    """A :class:`~core_akf.structure.Structure` from stiffness and mass matrices.

    Checks, each a clear error: sizes, symmetry, finite entries, a DOF map that covers the matrix
    once, known directions and nodes, positive definite M, and no rigid-body mode left (a model
    without enough constraints).  The first frequencies outside :data:`FREQUENCY_RANGE` give a
    :class:`ModelWarning` (units that look wrong).

    Parameters
    ----------
    K, M : array_like (n, n) or scipy.sparse matrix
        Stiffness (N/m, N m/rad) and mass (kg, kg m^2), one row per DOF.
    dofs : sequence of (node id, direction)
        The DOF of every matrix row, directions in :data:`DIRECTIONS`.
    nodes : dict
        Node id -> (x, y) or (x, y, z) in m, for every node of ``dofs``.
    fixed : sequence, optional
        Constrained DOFs, removed from the model: (node, direction), ``"node:direction"`` or node
        ids (all of a node's DOFs).
    damping : float, sequence of float, tuple or None
        A modal ratio (one, or one per mode), ``("rayleigh", alpha, beta)``, or None (with ``C``).
    C : array_like (n, n) or scipy.sparse matrix, optional
        A damping matrix (N s/m) instead of ``damping``.
    extensometers : sequence of (node a, node b), optional
        Strain outputs ``strain:1``, ``strain:2``, ... between node pairs.
    strain_rows : array_like (k, n) or scipy.sparse matrix, optional
        Strain outputs of one's own (a strain operator from the FE program: strain = row . u over
        the matrix rows); they come first, ``strain:1`` .. ``strain:k``, then the extensometers.
    name : str
        The model's name.
    n_modes : int, optional
        Keep only the lowest ``n_modes`` modes, found by shift-invert Lanczos on the sparse
        matrices, with a static correction for the others (:mod:`core_akf.models.sparse`).
        Models above :data:`~core_akf.models.sparse.DENSE_LIMIT` DOFs are always reduced this way
        (default :data:`~core_akf.models.sparse.DEFAULT_MODES` modes); no dense n x n matrix is
        formed then.

    Returns
    -------
    Structure

    Examples
    --------
    A two-storey shear frame (1 N/m springs, 1 kg masses):

    >>> import numpy as np
    >>> s = from_matrices(np.array([[2.0, -1.0], [-1.0, 1.0]]), np.eye(2), [(1, "x"), (2, "x")],
    ...                   {1: (0.0, 1.0), 2: (0.0, 2.0)}, damping=0.02)
    >>> [round(float(f), 4) for f in s.frequencies()]
    [0.0984, 0.2575]
    """
    if n_modes is not None:
        n_modes = check_n_modes(n_modes)
    for A, label in ((K, "K"), (M, "M")):
        if len(np.shape(A)) != 2 or np.shape(A)[0] != np.shape(A)[1]:
            raise AKFInputError(f"{label} must be a square matrix, got shape {np.shape(A)}")
    if np.shape(K) != np.shape(M):
        raise AKFInputError(f"K is {np.shape(K)[0]}x{np.shape(K)[1]} but M is {np.shape(M)[0]}x{np.shape(M)[1]}")
    dofs, seen = _dof_map(dofs, np.shape(K)[0])          # before the matrices are converted: a size line is named
    K, M, large = _checked_matrices(K, M, n_modes)
    n = K.shape[0]
    coords = _coordinates(nodes, dofs)
    ids = np.array(sorted(coords))
    row_of = {int(k): i for i, k in enumerate(ids)}
    dof_names = tuple(d for d in DIRECTIONS if any(x[1] == d for x in dofs))
    keep = _free(fixed, dofs, seen)
    rows = np.flatnonzero(keep)
    diag_m = M.diagonal()
    massless = [f"{dofs[r][0]}:{dofs[r][1]}" for r in rows if diag_m[r] == 0]
    if massless:
        raise AKFInputError(f"{len(massless)} free DOF(s) have no mass ({', '.join(massless[:8])}"
                            f"{' ...' if len(massless) > 8 else ''}): give them a mass or rotary inertia, fix them, or "
                            "condense them out (static/Guyan condensation) before exporting K and M")
    if rows.size == 0:
        raise AKFInputError(f"every DOF of the model is fixed ({len(dofs)} of {len(dofs)}): nothing can move; fix only "
                            "the supports")
    free_dofs = np.array([row_of[dofs[r][0]] * len(dof_names) + dof_names.index(dofs[r][1]) for r in rows])
    blocks, members, ends = _strain_blocks(strain_rows, extensometers, n, large, rows, coords, dofs, seen, dof_names)
    _check_coordinate_units(coords, name, extensometers is not None and len(extensometers) > 0)
    strain = _stack(blocks)
    common = dict(nodes=np.array([coords[k] for k in ids]), dof_names=dof_names, free_dofs=free_dofs,
                  strain_matrix=strain, strain_kind="member", members=members, name=name, node_ids=ids)
    meta = {"dof_map": [dofs[r] for r in rows], "strain_ends": ends,
            "extensometers": 0 if extensometers is None else len(extensometers)}
    try:
        if large:
            Kf, Mf = K[rows][:, rows], M[rows][:, rows]
            Cf = None if C is None else check_symmetric(as_sparse(C, "C"), "C", SYMMETRY_RTOL)[rows][:, rows]
            Kr, basis, P, Cr, static = modal_parts(Kf, Mf, DEFAULT_MODES if n_modes is None else n_modes, Cf, name)
            meta["projection"] = P
            structure = Structure(M=np.eye(Kr.shape[0]), K=Kr, damping=damping if C is None else None, C=Cr,
                                  basis=basis, static=static, meta=meta, **common)
        else:
            Cf = None if C is None else _check_symmetric(_dense(C, "C"), "C")[np.ix_(rows, rows)]
            structure = Structure(M=M[np.ix_(rows, rows)], K=K[np.ix_(rows, rows)],
                                  damping=damping if C is None else None, C=Cf, meta=meta, **common)
    except ModelError as exc:
        raise AKFInputError(f"{name}: {exc}") from None
    _check_modes(structure)
    return structure


def _checked_matrices(K, M, n_modes):
    """K and M checked (sizes, symmetry, finite): sparse for a model to reduce, dense otherwise."""
    large = n_modes is not None or max(np.shape(K)[0], np.shape(M)[0]) > DENSE_LIMIT
    if large:
        K, M = as_sparse(K, "K"), as_sparse(M, "M")
    else:
        K, M = _dense(K, "K"), _dense(M, "M")
    if K.shape != M.shape:
        raise AKFInputError(f"K is {K.shape[0]}x{K.shape[1]} but M is {M.shape[0]}x{M.shape[1]}")
    if large:
        K, M = check_symmetric(K, "K", SYMMETRY_RTOL), check_symmetric(M, "M", SYMMETRY_RTOL)
    else:
        K, M = _check_symmetric(K, "K"), _check_symmetric(M, "M")
    if (K != M).sum() == 0:
        raise AKFInputError("K and M are the same matrix: give the stiffness matrix (N/m) as K and the mass matrix (kg) "
                            "as M")
    return K, M, large


def _dof_map(dofs, n):
    """The DOF map as ``(node, direction)`` per row, checked, and the row of each DOF."""
    dofs = [(_node_id(d[0]), str(d[1]).strip().lower()) for d in dofs]
    if len(dofs) != n:
        raise AKFInputError(f"the DOF map has {len(dofs)} rows for matrices of {n} rows: it must name the node and "
                            "direction of every row")
    bad = [d for d in dofs if d[1] not in DIRECTIONS]
    if bad:
        raise AKFInputError(f"unknown direction {bad[0][1]!r} (node {bad[0][0]}) in the DOF map; use {DIRECTIONS}")
    seen = {}
    for r, d in enumerate(dofs):
        if d in seen:
            raise AKFInputError(f"DOF {d[0]}:{d[1]} appears twice in the DOF map (rows {seen[d] + 1} and {r + 1})")
        seen[d] = r
    return dofs, seen


def _coordinates(nodes, dofs):
    """Node id -> coordinates (m), checked: one place per node, one dimension, every DOF's node."""
    pairs = list(nodes.items()) if isinstance(nodes, dict) else list(nodes)
    coords = {}
    for k, v in pairs:
        if _node_id(k) in coords:
            raise AKFInputError(f"node {_node_id(k)} is listed twice in the node coordinates; every node needs one place")
        coords[_node_id(k)] = np.asarray(v, dtype=float)
    dims = {c.size for c in coords.values()}
    if not coords or dims - {2, 3} or len(dims) != 1:
        raise AKFInputError(f"node coordinates must all be (x, y) or all (x, y, z); got sizes {sorted(dims)}")
    unknown = sorted({d[0] for d in dofs} - set(coords))
    if unknown:
        raise AKFInputError(f"the DOF map names node(s) {unknown[:10]} that have no coordinates")
    return coords


def _free(fixed, dofs, seen):
    """Which rows stay free (bool, one per DOF) after the constraints ``fixed``."""
    keep = np.ones(len(dofs), bool)
    if isinstance(fixed, (str, bytes)) or (fixed is not None and np.ndim(fixed) == 0):
        raise AKFInputError(f"fixed must be a list of DOFs (\"NODE:DIR\", e.g. [\"1:x\", \"1:y\"]) or node ids; got "
                            f"{fixed!r}")
    for f in fixed or ():
        if isinstance(f, str):
            f = tuple(f.split(":")) if ":" in f else f
        targets = [d for d in dofs if d[0] == _node_id(f)] if np.ndim(f) == 0 else [(_node_id(f[0]), str(f[1]).lower())]
        for t in targets:
            if t not in seen:
                raise AKFInputError(f"fixed DOF {t[0]}:{t[1]} is not in the DOF map")
            keep[seen[t]] = False
        if not targets:
            raise AKFInputError(f"fixed node {f} has no DOF in the DOF map")
    return keep


def _strain_blocks(strain_rows, extensometers, n, large, rows, coords, dofs, seen, dof_names):
    """The strain outputs' rows (one's own, then the extensometers'), the extensometers' members,
    and their ends by output number when rows of one's own come first."""
    blocks, members, ends = [], None, {}
    if strain_rows is not None:
        blocks.append(_rows(strain_rows, n, keep_sparse=large)[:, rows])
    if extensometers is not None and len(extensometers):
        bad = [k for k, e in enumerate(extensometers, start=1) if np.ndim(e) != 1 or len(e) != 2]
        if bad:
            raise AKFInputError(f"extensometer {bad[0]} is {list(extensometers)[bad[0] - 1]!r}: an extensometer is a pair "
                                "of node ids [a, b]")
        members = np.array([[_node_id(a), _node_id(b)] for a, b in extensometers], dtype=int)
        repeat = first_repeat([tuple(sorted(m)) for m in members.tolist()])
        if repeat:
            i, j, (a, b) = repeat
            raise AKFInputError(f"extensometers {i + 1} and {j + 1} both join nodes {a} and {b}: strain:{i + 1} and "
                                f"strain:{j + 1} would be one output twice (a member listed twice?); list each once")
        blocks.append(_extensometer_rows(members, coords, dofs, seen, rows, dof_names))
        if strain_rows is not None:           # extensometer k is strain:(k_own + k): its ends by output number
            first = blocks[0].shape[0] + 1
            ends = {first + k: (int(a), int(b)) for k, (a, b) in enumerate(members)}
            members = None
    return blocks, members, ends


def from_files(K: str, M: str, dofs: str, nodes: str, fixed: Sequence | None = None, damping: Damping = None,
               C: str | None = None, extensometers: str | Sequence[tuple[int, int]] | None = None,
               strains: str | None = None, name: str | None = None, n_modes: int | None = None) -> Structure:
    """:func:`from_matrices` with the matrices and tables given as files.

    Parameters
    ----------
    K, M : str
        Files as :func:`load_matrix` reads them (Matrix Market, ``.npz``, ``.npy``).
    dofs : str
        A CSV of columns node, direction (:func:`read_dof_map`).
    nodes : str
        A CSV of columns node, x, y[, z] (:func:`read_nodes`).
    fixed : sequence, optional
        As :func:`from_matrices`.
    damping : float, sequence or None
        As :func:`from_matrices`; also ``["rayleigh", alpha, beta]`` as a job file writes it.
    C : str, optional
        A damping matrix file (:func:`load_matrix`).
    extensometers : str or sequence of (node a, node b), optional
        Node pairs, or a CSV of columns a, b (:func:`read_extensometers`).
    strains : str, optional
        A strain operator (k x n) as :func:`load_matrix` reads it.
    name : str, optional
        The model's name (default the stiffness file's stem).
    n_modes : int, optional
        As :func:`from_matrices`.

    Returns
    -------
    Structure

    Examples
    --------
    A two-storey shear frame written as an FE program would export it:

    >>> import os, tempfile
    >>> import numpy as np, scipy.io, scipy.sparse
    >>> folder = tempfile.mkdtemp()
    >>> K = scipy.sparse.csr_matrix(np.array([[2.0, -1.0], [-1.0, 1.0]]) * 1e4)         # N/m
    >>> scipy.io.mmwrite(os.path.join(folder, "K.mtx"), K)
    >>> scipy.io.mmwrite(os.path.join(folder, "M.mtx"), scipy.sparse.identity(2).tocsr())  # kg
    >>> _ = open(os.path.join(folder, "dofs.csv"), "w").write("node,direction\\n1,x\\n2,x\\n")
    >>> _ = open(os.path.join(folder, "nodes.csv"), "w").write("node,x,y\\n1,0,1\\n2,0,2\\n")
    >>> frame = from_files(*(os.path.join(folder, f) for f in ("K.mtx", "M.mtx", "dofs.csv", "nodes.csv")),
    ...                    damping=0.02)
    >>> [round(float(f), 3) for f in frame.frequencies()]          # Hz
    [9.836, 25.752]
    """
    if isinstance(damping, list):
        damping = tuple(damping)
    if isinstance(extensometers, (str, os.PathLike)):
        extensometers = read_extensometers(extensometers)
    return from_matrices(load_matrix(K), load_matrix(M), read_dof_map(dofs), read_nodes(nodes), fixed=fixed,
                         damping=damping, C=None if C is None else load_matrix(C), extensometers=extensometers,
                         strain_rows=None if strains is None else load_matrix(strains),
                         name=name or os.path.splitext(os.path.basename(os.fspath(K)))[0], n_modes=n_modes)


def _rows(A, n, keep_sparse=False):
    """A (k, n) operator as a dense array (CSR if it is sparse and ``keep_sparse``), checked."""
    import scipy.sparse

    if scipy.sparse.issparse(A):
        A = scipy.sparse.csr_matrix(A, dtype=float) if keep_sparse else A.toarray()
    else:
        A = np.asarray(A, dtype=float)
    if A.ndim != 2 or A.shape[1] != n:
        raise AKFInputError(f"strain_rows must have one column per matrix row ({n}), got shape {A.shape}")
    if not np.all(np.isfinite(A.data if scipy.sparse.issparse(A) else A)):
        raise AKFInputError("strain_rows has NaN or infinite entries")
    return A


def _stack(blocks):
    """Strain rows stacked: sparse if any block is sparse, else dense; None without blocks."""
    import scipy.sparse

    if not blocks:
        return None
    if any(scipy.sparse.issparse(b) for b in blocks):
        return scipy.sparse.vstack([scipy.sparse.csr_matrix(b) for b in blocks]).tocsr()
    return np.vstack(blocks)


def _node_id(v):
    if isinstance(v, str):
        v = v.strip()
        if not v.lstrip("-").isdigit():
            raise AKFInputError(f"node ids are integers, got {v!r}")
        return int(v)
    try:
        i = int(v)
    except (TypeError, ValueError):
        raise AKFInputError(f"node ids are integers, got {v!r}") from None
    if i != v:
        raise AKFInputError(f"node ids are integers, got {v!r}")
    return i


def _extensometer_rows(members, coords, dofs, seen, rows, dof_names):
    """Strain rows (k, n_free): ``(u_b - u_a) . e / L`` on the translational DOFs."""
    col = {r: i for i, r in enumerate(rows)}
    out = np.zeros((members.shape[0], rows.size))
    trans = ("x", "y", "z")
    for k, (a, b) in enumerate(members):
        for node in (a, b):
            if node not in coords:
                raise AKFInputError(f"extensometer {k + 1}: node {node} has no coordinates")
        d = coords[b] - coords[a]
        L = float(np.linalg.norm(d))
        if L == 0:
            raise AKFInputError(f"extensometer {k + 1} joins node {a} to itself (or to a node at the same place)")
        e = d / L
        for sign, node in ((-1.0, a), (1.0, b)):
            for j, direction in enumerate(trans[:d.size]):
                if e[j] == 0:
                    continue
                r = seen.get((node, direction))
                if r is None and not any(d[0] == node for d in dofs):
                    continue                  # a node without DOFs in the model: the ground
                if r is None:
                    raise AKFInputError(f"extensometer {k + 1} ({a}-{b}) needs DOF {node}:{direction}, which the DOF "
                                        "map does not have")
                if r in col:                  # a constrained DOF does not move
                    out[k, col[r]] += sign * e[j] / L
    return out


#: median distance (m) from a node to its nearest neighbour above which coordinates look like mm
NODE_SPACING_LIMIT = 25.0
#: ... and above which they are mm for a model with extensometers (an error: their strains divide by it)
NODE_SPACING_MM = 100.0


def _check_coordinate_units(coords, name, extensometers=False):
    """A :class:`ModelWarning` when the nodes lie so far apart that the coordinates are probably in
    mm against SI matrices: every extensometer strain would be 1000 times too small, and forces
    estimated from strain gauges that much too large.  With extensometers and nodes more than
    :data:`NODE_SPACING_MM` apart it is an error: their strains would be wrong, not only the figures."""
    from scipy.spatial import cKDTree

    if len(coords) < 2:
        return
    xyz = np.array(list(coords.values()))
    d, _ = cKDTree(xyz).query(xyz, k=2)
    spacing = float(np.median(d[:, 1]))
    if extensometers and spacing > NODE_SPACING_MM:
        raise AKFInputError(f"{name}: neighbouring nodes lie {spacing:.4g} m apart (median): the coordinates look like "
                            "mm, while K and M are SI; an extensometer's strain divides by its length, so every one "
                            "would be 1000x too small and the forces from them wrong: give the nodes in m")
    if spacing > NODE_SPACING_LIMIT:
        warnings.warn(f"{name}: neighbouring nodes lie {spacing:.4g} m apart (median), the whole model spans "
                      f"{float(np.ptp(xyz, axis=0).max()):.4g} m: are the coordinates in mm? They must be in m (SI) like "
                      "K and M; in mm every extensometer strain is 1000x too small and forces estimated from strain "
                      "gauges 1000x too large", ModelWarning)


def _check_modes(structure):
    """No rigid-body mode; the first frequencies in :data:`FREQUENCY_RANGE`."""
    try:            # the modes are needed anyway (damping, the filter's modal coordinates): computed once
        omega = structure.eigen[0][:5]
    except ModelError:
        omega = np.zeros(1)
    w2 = omega ** 2
    top = float(np.max(np.abs(np.diag(structure.K)) / np.diag(structure.M)))
    if w2[0] <= RIGID_BODY_RTOL * top:
        raise AKFInputError(f"{structure.name}: the model has a rigid-body mode (lowest eigenvalue {w2[0]:.3g} against "
                            f"{top:.3g}): constrain it (fixed = [...]) so that it cannot move freely")
    f = np.sqrt(w2) / (2 * np.pi)
    lo, hi = FREQUENCY_RANGE
    if f[0] < lo or f[0] > hi:
        warnings.warn(f"{structure.name}: first natural frequencies {', '.join(f'{x:.4g}' for x in f)} Hz lie outside "
                      f"{lo:g} Hz .. {hi / 1e3:g} kHz: check the units of K and M (SI: N/m and kg; a mass in tonnes against "
                      "a stiffness in N/m, or N/mm against kg, gives absurd frequencies)", ModelWarning)
