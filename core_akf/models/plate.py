"""Mindlin (Reissner-Mindlin) plate: 4-node quadrilateral elements on a rectangular mesh.

Formulation after Ferreira, *MATLAB Codes for Finite Element Analysis* (2008), as used by
the thesis (TH 2.1): three DOFs per node ``(w, rx, ry)`` with in-plane displacements
``u = z rx``, ``v = z ry``; bending by 2 x 2 Gauss points, transverse shear by one point
(reduced integration against shear locking), shear correction factor 5/6, consistent
mass with translational ``rho t`` and rotary ``rho t^3 / 12`` inertia.

Surface strains (z = t/2): ``{e_x, e_y, g_xy} = z B_f u`` with the bending
strain-displacement matrix ``B_f``; nodal strains average the element-corner values over
the elements sharing the node.  Strain outputs are ordered all ``e_x``, then all ``e_y``,
then all ``g_xy`` (TH: dofs 1..121, 122..242, 243..363 on the 10 x 10 mesh).

Node numbering (TH, IMP): ``n = (iy - 1) (nx + 1) + ix`` with ``ix = 1..nx+1`` along x and
``iy = 1..ny+1`` along y; the origin is node 1.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..checks import Damping, FloatArray, ModelError, as_count, check_memory, check_n_modes, check_positive, is_real
from ..structure import Structure
from .sparse import DEFAULT_MODES, DENSE_LIMIT, modal_parts

_GAUSS2 = np.array([-1.0, 1.0]) / np.sqrt(3.0)
_CORNERS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
EDGES = ("x0", "x1", "y0", "y1")


def _shape(xi, eta):
    """Bilinear shape functions and their natural derivatives at (xi, eta)."""
    N = 0.25 * (1 + _CORNERS[:, 0] * xi) * (1 + _CORNERS[:, 1] * eta)
    dN_dxi = 0.25 * _CORNERS[:, 0] * (1 + _CORNERS[:, 1] * eta)
    dN_deta = 0.25 * _CORNERS[:, 1] * (1 + _CORNERS[:, 0] * xi)
    return N, dN_dxi, dN_deta


def _bending_B(dNx, dNy):
    """Curvature matrix B_f (3 x 12): rows d(rx)/dx, d(ry)/dy, d(rx)/dy + d(ry)/dx."""
    B = np.zeros((3, 12))
    B[0, 1::3] = dNx
    B[1, 2::3] = dNy
    B[2, 1::3] = dNy
    B[2, 2::3] = dNx
    return B


def rectangular_element(a, b, thickness, E, nu, rho, shear_factor=5.0 / 6.0):
    """Stiffness and mass of a rectangular Mindlin element.

    Parameters
    ----------
    a, b : float
        Element size along x and y (m).
    thickness : float
        m.
    E : float
        Young's modulus (Pa).
    nu : float
        Poisson's ratio.
    rho : float
        Density (kg/m^3).
    shear_factor : float
        Shear correction factor (5/6).

    Returns
    -------
    K, M : ndarray (12, 12)
        DOFs ``[w1, rx1, ry1, ..., w4, rx4, ry4]`` counter-clockwise from the lower-left corner
        (N/m, N, N m/rad; kg, kg m, kg m^2).
    """
    t = thickness
    Db = E * t ** 3 / (12 * (1 - nu ** 2)) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    Ds = shear_factor * E / (2 * (1 + nu)) * t * np.eye(2)
    detJ = a * b / 4.0
    inertia = rho * np.array([t, t ** 3 / 12, t ** 3 / 12])
    K = np.zeros((12, 12))
    M = np.zeros((12, 12))
    for xi in _GAUSS2:
        for eta in _GAUSS2:
            N, dxi, deta = _shape(xi, eta)
            Bb = _bending_B(dxi * 2 / a, deta * 2 / b)
            K += Bb.T @ Db @ Bb * detJ
            Nm = np.zeros((3, 12))
            for k in range(3):
                Nm[k, k::3] = N
            M += Nm.T @ (inertia[:, None] * Nm) * detJ
    N, dxi, deta = _shape(0.0, 0.0)
    Bs = np.zeros((2, 12))
    Bs[0, 0::3] = dxi * 2 / a
    Bs[0, 1::3] = N
    Bs[1, 0::3] = deta * 2 / b
    Bs[1, 2::3] = N
    K += Bs.T @ Ds @ Bs * detJ * 4.0  # one-point rule, weight 4
    return K, M


def _corner_strain_B(a, b, thickness):
    """Surface strain matrices ``(t/2) B_f`` at the four element corners, shape (4, 3, 12)."""
    out = np.zeros((4, 3, 12))
    for c, (xi, eta) in enumerate(_CORNERS):
        _, dxi, deta = _shape(xi, eta)
        out[c] = 0.5 * thickness * _bending_B(dxi * 2 / a, deta * 2 / b)
    return out


def _edge_nodes(edge, nx, ny):
    """0-based nodes on one edge: 'x0' (x = 0), 'x1' (x = lx), 'y0' (y = 0), 'y1' (y = ly)."""
    ix, iy = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1))
    ids = iy * (nx + 1) + ix
    sel = {"x0": ix == 0, "x1": ix == nx, "y0": iy == 0, "y1": iy == ny}
    if edge not in sel:
        raise ModelError(f"unknown edge {edge!r}; use one of {EDGES}")
    return np.sort(ids[sel[edge]])


def _as_edges(value, what):
    if value is None:
        return ()
    edges = (value,) if isinstance(value, str) else tuple(value)
    for e in edges:
        if e not in EDGES:
            raise ModelError(f"{what}: unknown edge {e!r}; use one of {EDGES}")
    return edges


def plate(nx: int, ny: int, lx: float, ly: float, thickness: float, E: float, nu: float, rho: float,
          clamped_edge: str | Sequence[str] | None = "y0", damping: Damping = 0.01,
          simply_supported_edges: str | Sequence[str] | None = None, name: str | None = None,
          n_modes: int | None = None) -> Structure:
    """Rectangular Mindlin plate on an ``nx`` x ``ny`` element mesh.

    Parameters
    ----------
    nx, ny : int
        Elements along x and y.
    lx, ly, thickness : float
        Plate size and thickness (m).
    E, nu, rho : float
        Young's modulus (Pa), Poisson's ratio, density (kg/m^3).
    clamped_edge : str or sequence of str or None
        Edge(s) with all DOFs fixed: ``"x0"`` (x = 0), ``"x1"`` (x = lx), ``"y0"`` (y = 0),
        ``"y1"`` (y = ly).
    damping : float, sequence, tuple or None
        As :class:`~core_akf.structure.Structure` (default 1 % modal, TH).
    simply_supported_edges : str or sequence of str, optional
        Hard simple supports: ``w`` and the rotation along the edge fixed.
    n_modes : int, optional
        Assemble sparse and keep the lowest ``n_modes`` modes with a static correction
        (:mod:`core_akf.models.sparse`).  A mesh of more than
        :data:`~core_akf.models.sparse.DENSE_LIMIT` DOFs is always built this way (default
        :data:`~core_akf.models.sparse.DEFAULT_MODES` modes).
    name : str, optional
        The model's name (default "plate NXxNY").

    Returns
    -------
    Structure
        Nodes numbered row by row from (0, 0), 1-based; strain outputs ``strain:NODE:ex``,
        ``ey`` and ``gxy`` (surface strains) at every node.

    Examples
    --------
    >>> s = plate(4, 2, 0.4, 0.2, 0.002, 200e9, 0.3, 7800.0)
    >>> s.n_nodes, s.n, s.n_strain
    (15, 30, 45)
    """
    if n_modes is not None:
        n_modes = check_n_modes(n_modes)
    nx, ny = as_count(nx, "nx (elements along x)", minimum=1), as_count(ny, "ny (elements along y)", minimum=1)
    check_memory(3 * (nx + 1) * (ny + 1), 300, f"a plate mesh of {nx:.6g} x {ny:.6g} elements", "use a coarser mesh",
                 items="DOFs")
    large = n_modes is not None or 3 * (nx + 1) * (ny + 1) > DENSE_LIMIT
    K, M, S, nodes, free = _assemble(nx, ny, lx, ly, thickness, E, nu, rho, clamped_edge, simply_supported_edges, large)
    nx, ny = int(nx), int(ny)
    meta = dict(nx=nx, ny=ny, lx=lx, ly=ly, thickness=thickness, E=E, nu=nu, rho=rho, clamped_edge=clamped_edge)
    if large:
        name = name or f"plate {nx}x{ny}"
        Kr, basis, P, _, static = modal_parts(K[free][:, free], M[free][:, free],
                                              DEFAULT_MODES if n_modes is None else n_modes, None, name)
        return Structure(M=np.eye(Kr.shape[0]), K=Kr, damping=damping, nodes=nodes, dof_names=("w", "rx", "ry"),
                         free_dofs=free, strain_matrix=S[:, free], strain_kind="node", basis=basis, static=static,
                         name=name, meta=dict(meta, projection=P))
    ix = np.ix_(free, free)
    return Structure(M=M[ix], K=K[ix], damping=damping, nodes=nodes, dof_names=("w", "rx", "ry"),
                     free_dofs=free, strain_matrix=S[:, free], strain_kind="node",
                     name=name or f"plate {nx}x{ny}",
                     meta=dict(meta, K_full=K, M_full=M))


def _assemble(nx, ny, lx, ly, thickness, E, nu, rho, clamped_edge, simply_supported_edges, large):
    """Checked inputs to K, M (all DOFs), the nodal strain operator, the node coordinates and
    the free DOFs; sparse (CSR) if ``large``."""
    for label, v in (("lx", lx), ("ly", ly), ("thickness", thickness), ("E", E), ("rho", rho)):
        check_positive(v, label)
    if not is_real(nu) or not -1 < nu < 0.5:
        raise ModelError(f"Poisson's ratio must be in (-1, 0.5), got {nu!r}")
    a, b = lx / nx, ly / ny
    Ke, Me = rectangular_element(a, b, thickness, E, nu, rho)
    Bc = _corner_strain_B(a, b, thickness)

    n_nodes = (nx + 1) * (ny + 1)
    X, Y = np.meshgrid(np.linspace(0, lx, nx + 1), np.linspace(0, ly, ny + 1))
    nodes = np.column_stack([X.ravel(), Y.ravel()])
    ex, ey = np.meshgrid(np.arange(nx), np.arange(ny))
    n1 = (ey * (nx + 1) + ex).ravel()
    conn = np.column_stack([n1, n1 + 1, n1 + nx + 2, n1 + nx + 1])  # (n_el, 4), counter-clockwise
    edofs = (3 * conn[:, :, None] + np.arange(3)).reshape(-1, 12)

    n_full = 3 * n_nodes
    rows = np.repeat(edofs, 12, axis=1)
    cols = np.tile(edofs, (1, 12))
    count = np.bincount(conn.ravel(), minlength=n_nodes).astype(float)
    if large:
        K, M, S = _sparse_assembly(rows, cols, Ke, Me, Bc, conn, edofs, count, n_full)
    else:
        K = np.zeros((n_full, n_full))
        M = np.zeros((n_full, n_full))
        np.add.at(K, (rows, cols), np.broadcast_to(Ke.ravel(), rows.shape))
        np.add.at(M, (rows, cols), np.broadcast_to(Me.ravel(), rows.shape))

        # nodal strains: average the corner values of all elements sharing a node
        S = np.zeros((3, n_nodes, n_full))
        for c in range(4):
            for comp in range(3):
                np.add.at(S[comp], (np.repeat(conn[:, c], 12), edofs.ravel()),
                          np.tile(Bc[c, comp], conn.shape[0]))
        S /= count[None, :, None]
        S = S.reshape(3 * n_nodes, n_full)

    fixed = set()
    for e in _as_edges(clamped_edge, "clamped_edge"):
        for nd in _edge_nodes(e, nx, ny):
            fixed.update(3 * nd + np.arange(3))
    for e in _as_edges(simply_supported_edges, "simply_supported_edges"):
        tangential = 2 if e.startswith("x") else 1  # along x = const the edge runs in y: fix ry
        for nd in _edge_nodes(e, nx, ny):
            fixed.update((3 * nd, 3 * nd + tangential))
    free = np.setdiff1d(np.arange(n_full), sorted(fixed))
    return K, M, S, nodes, free


def plate_matrices(nx: int, ny: int, lx: float, ly: float, thickness: float, E: float, nu: float, rho: float,
                   clamped_edge: str | Sequence[str] | None = "y0",
                   simply_supported_edges: str | Sequence[str] | None = None) -> dict:
    """The sparse matrices of :func:`plate` as an FE program would export them.

    For :func:`~core_akf.models.from_matrices`; node ids 1-based as in :func:`plate`.

    Parameters
    ----------
    nx, ny, lx, ly, thickness, E, nu, rho, clamped_edge, simply_supported_edges
        As :func:`plate`.

    Returns
    -------
    dict
        ``K``, ``M`` (N/m, kg; all DOFs, CSR), ``strains`` (3 n_nodes x n_dofs: all e_x, then
        e_y, then g_xy at the nodes), ``dofs`` (node id, direction per row: ``z`` for w, ``rx``,
        ``ry``), ``nodes`` (id -> (x, y), m) and ``fixed`` (the constrained DOFs).

    Examples
    --------
    >>> m = plate_matrices(2, 2, 0.2, 0.2, 0.002, 200e9, 0.3, 7800.0)
    >>> m["K"].shape, m["strains"].shape, len(m["fixed"])     # 9 nodes x 3 DOFs; y = 0 clamped
    ((27, 27), (27, 27), 9)
    """
    K, M, S, nodes, free = _assemble(nx, ny, lx, ly, thickness, E, nu, rho, clamped_edge, simply_supported_edges,
                                     True)
    n_nodes = nodes.shape[0]
    dofs = [(i + 1, d) for i in range(n_nodes) for d in ("z", "rx", "ry")]
    fixed = [dofs[r] for r in np.setdiff1d(np.arange(3 * n_nodes), free)]
    return dict(K=K, M=M, strains=S, dofs=dofs, nodes={i + 1: tuple(xy) for i, xy in enumerate(nodes)}, fixed=fixed)


def _sparse_assembly(rows, cols, Ke, Me, Bc, conn, edofs, count, n_full):
    """Sparse K, M (n_full x n_full) and nodal strain operator (3 n_nodes x n_full), CSR."""
    import scipy.sparse

    n_el, n_nodes = conn.shape[0], count.size
    K = scipy.sparse.coo_matrix((np.tile(Ke.ravel(), n_el), (rows.ravel(), cols.ravel())), shape=(n_full, n_full))
    M = scipy.sparse.coo_matrix((np.tile(Me.ravel(), n_el), (rows.ravel(), cols.ravel())), shape=(n_full, n_full))
    r, c, v = [], [], []
    for corner in range(4):
        for comp in range(3):
            node = np.repeat(conn[:, corner], 12)
            r.append(comp * n_nodes + node)
            c.append(edofs.ravel())
            v.append(np.tile(Bc[corner, comp], n_el) / count[node])
    S = scipy.sparse.coo_matrix((np.concatenate(v), (np.concatenate(r), np.concatenate(c))), shape=(3 * n_nodes, n_full))
    return K.tocsr(), M.tocsr(), S.tocsr()


def uniform_pressure_load(structure: Structure, q: float) -> FloatArray:
    """Consistent nodal forces of a uniform pressure on a plate.

    Parameters
    ----------
    structure : Structure
        A plate of :func:`plate`.
    q : float
        Pressure (Pa).

    Returns
    -------
    ndarray (n,)
        Forces (N) and moments (N m) in the free DOFs.

    Examples
    --------
    >>> f = uniform_pressure_load(imp_plate(), 1000.0)       # 1 kPa
    >>> f.shape
    (90,)
    """
    meta = structure.meta
    nx, ny = meta["nx"], meta["ny"]
    area = meta["lx"] / nx * meta["ly"] / ny
    wts = np.zeros((ny + 1, nx + 1))
    wts[:-1, :-1] += 1
    wts[:-1, 1:] += 1
    wts[1:, :-1] += 1
    wts[1:, 1:] += 1
    f_full = np.zeros(3 * structure.n_nodes)
    f_full[0::3] = q * area / 4.0 * wts.ravel()
    return f_full[structure.free_dofs]


# Thesis plate (TH 3): 40.64 cm x 30.48 cm x 0.3175 cm steel, clamped along the long edge y = 0.
TH_PLATE = dict(lx=0.4064, ly=0.3048, thickness=0.003175, E=200e9, nu=0.3, rho=7800.0)


def th_plate(nx: int = 10, ny: int = 10, rho: float = TH_PLATE["rho"], damping: Damping = 0.01) -> Structure:
    """The thesis plate: clamped long edge (nodes 1-11), 1 % modal damping.

    Parameters
    ----------
    nx, ny : int
        The mesh (10 x 10 in the thesis).
    rho : float
        Density (kg/m^3).
    damping : float
        Modal damping ratio.

    Returns
    -------
    Structure

    Examples
    --------
    >>> p = th_plate()
    >>> p.n_nodes, p.n, p.n_strain          # 11 x 11 nodes, the clamped edge removed
    (121, 330, 363)
    """
    p = dict(TH_PLATE, rho=rho)
    return plate(nx, ny, p["lx"], p["ly"], p["thickness"], p["E"], p["nu"], p["rho"],
                 clamped_edge="y0", damping=damping, name=f"TH plate {nx}x{ny}")


def imp_plate(damping: Damping = 0.01) -> Structure:
    """The IMP cantilever plate: 5 x 5 elements (36 nodes, 108 DOFs before supports).

    IMP gives no dimensions; we take the thesis plate's size, material and thickness with the
    short edge x = lx clamped (nodes 6, 12, ..., 36 as in IMP Fig. 18).

    Parameters
    ----------
    damping : float
        Modal damping ratio.

    Returns
    -------
    Structure

    Examples
    --------
    >>> imp_plate().n
    90
    """
    p = TH_PLATE
    return plate(5, 5, p["lx"], p["ly"], p["thickness"], p["E"], p["nu"], p["rho"],
                 clamped_edge="x1", damping=damping, name="IMP plate 5x5")
