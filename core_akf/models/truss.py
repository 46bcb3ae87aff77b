"""Planar truss finite elements (2-node bars) and the S17 truss.

The S17 truss (Khodabandeloo, Melvin, Jo, Sensors 2017, Fig. 4 and Table 1): a simply
supported 9-bay planar truss with 18 joints and 34 members.  What the paper fixes is
kept: joint numbering (bottom chord 1, 2, 4, ..., 16, 18; top chord 3, 5, ..., 17 above
2, 4, ..., 16), supports (pin at joint 1, roller at joint 18), the three area groups,
E = 200 GPa, rho = 7800 kg/m^3, 0.7 % modal damping.

What the paper does not give is chosen here and documented:

* panel length 1.0 m and height 1.0 m (a 9 m span);
* the web: end diagonals 1-3 and 17-18, an X-braced middle panel (8-11 and 9-10) and
  one diagonal in each other panel: 2-5, 5-6, 7-8 on the left, 10-13, 12-15, 14-17 on the
  right -- 9 + 7 + 8 + 2 + 6 + 2 = 34 members (one redundant).  The orientations were
  chosen (out of the 64 possible) so that the paper's case-4 strain gauges (members 5, 9,
  13, 26) see the four static load patterns at joints 4, 6, 8, 12 independently, i.e. the
  case-4 sensor set is PBH-detectable as the paper's results imply; with a plain Pratt or
  Howe web, verticals 5 and 9 carry the same (or zero) static force and it is not;
* member numbers sweep left to right panel by panel so that the paper's area groups
  land on the bottom chord (1, 6, 10, 14, 18, 23, 27, 31, 34) and the verticals
  (5, 9, 13, 17, 19, 22, 26, 30); all others are top chord and diagonals.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..checks import ArrayLike, Damping, ModelError, check_positive
from ..structure import Structure

#: S17 member connectivity, 1-based joints, in member order 1..34
S17_MEMBERS = (
    (1, 2), (1, 3), (3, 5), (2, 5), (2, 3),          # 1-5
    (2, 4), (5, 7), (5, 6), (4, 5),                  # 6-9
    (4, 6), (7, 9), (7, 8), (6, 7),                  # 10-13
    (6, 8), (9, 11), (9, 10), (8, 9),                # 14-17
    (8, 10), (10, 11), (8, 11), (11, 13),            # 18-21
    (12, 13), (10, 12), (10, 13), (13, 15),          # 22-25
    (14, 15), (12, 14), (12, 15), (15, 17),          # 26-29
    (16, 17), (14, 16), (14, 17), (17, 18), (16, 18),  # 30-34
)
S17_AREA_BOTTOM = 15e-4     # m^2, bottom chord
S17_AREA_VERTICAL = 4.75e-4  # m^2, verticals
S17_AREA_OTHER = 9.75e-4     # m^2, top chord and diagonals
S17_BOTTOM = (1, 6, 10, 14, 18, 23, 27, 31, 34)
S17_VERTICAL = (5, 9, 13, 17, 19, 22, 26, 30)


def s17_joint_coordinates(panel=1.0, height=1.0):
    """Joint coordinates of the S17 truss: joint 1 at (0, 0), joint 18 at (9 panel, 0).

    Parameters
    ----------
    panel : float
        Panel length (m).
    height : float
        Truss height (m).

    Returns
    -------
    ndarray (18, 2)
        Coordinates (m); joint ``i`` is row ``i - 1``.
    """
    xy = np.zeros((18, 2))
    xy[0] = (0.0, 0.0)
    xy[17] = (9 * panel, 0.0)
    for p in range(1, 9):
        xy[2 * p - 1] = (p * panel, 0.0)        # bottom joint 2p
        xy[2 * p] = (p * panel, height)          # top joint 2p + 1
    return xy


def bar_matrices(xy_i, xy_j, E, A, rho, lumped=False):
    """Stiffness, mass and strain row of a 2-node planar bar.

    DOFs ``[u_i, v_i, u_j, v_j]``; the strain row gives ``eps = [-c, -s, c, s] / L . d``
    (S17 eq. 35-36).

    Parameters
    ----------
    xy_i, xy_j : array_like (2,)
        End coordinates (m).
    E : float
        Young's modulus (Pa).
    A : float
        Cross-section area (m^2).
    rho : float
        Density (kg/m^3).
    lumped : bool
        Lumped instead of consistent mass.

    Returns
    -------
    K : ndarray (4, 4)
        N/m.
    M : ndarray (4, 4)
        kg.
    strain_row : ndarray (4,)
        1/m.
    """
    d = np.asarray(xy_j, float) - np.asarray(xy_i, float)
    L = float(np.hypot(*d))
    if L <= 0:
        raise ModelError("a bar member has zero length")
    c, s = d / L
    t = np.array([-c, -s, c, s])
    K = E * A / L * np.outer(t, t)
    m = rho * A * L
    if lumped:
        M = m / 2.0 * np.eye(4)
    else:
        M = m / 6.0 * np.array([[2, 0, 1, 0], [0, 2, 0, 1], [1, 0, 2, 0], [0, 1, 0, 2]], float)
    return K, M, t / L


def planar_truss(nodes: ArrayLike, members: Sequence[tuple[int, int]], areas: float | ArrayLike, E: float, rho: float,
                 supports: Mapping[int, str], damping: Damping = None, lumped: bool = False,
                 name: str = "truss") -> Structure:
    """Assemble a planar truss.

    Parameters
    ----------
    nodes : array (n_nodes, 2)
        Joint coordinates in m; joint ``i`` (1-based) is row ``i - 1``.
    members : sequence of (i, j)
        1-based end joints of each member; member ``k`` (1-based) is entry ``k - 1``.
    areas : float or array (n_members,)
        Cross-section areas in m^2.
    E, rho : float
        Young's modulus (Pa) and density (kg/m^3).
    supports : dict {joint: directions}
        Constrained DOFs, e.g. ``{1: "xy", 18: "y"}``.
    damping : float, sequence, tuple or None
        As :class:`~core_akf.structure.Structure`.
    lumped : bool
        Lumped instead of consistent mass.
    name : str
        The model's name.

    Returns
    -------
    Structure
        Strain outputs ``strain:1`` .. ``strain:K``: the members in order.

    Examples
    --------
    A three-bar triangle, pinned at joint 1 and on a roller at joint 2:

    >>> t = planar_truss([[0, 0], [1, 0], [0.5, 0.5]], [(1, 2), (2, 3), (1, 3)], 1e-4, 200e9, 7800.0,
    ...                  {1: "xy", 2: "y"})
    >>> t.n, t.strain_labels
    (3, ['strain:1', 'strain:2', 'strain:3'])
    """
    check_positive(E, "E"), check_positive(rho, "rho")
    nodes = np.asarray(nodes, float)
    n_nodes = nodes.shape[0]
    members0 = np.asarray(members, int) - 1
    if members0.ndim != 2 or members0.shape[1] != 2:
        raise ModelError("members must be a sequence of (i, j) joint pairs")
    if members0.min() < 0 or members0.max() >= n_nodes:
        raise ModelError(f"a member refers to a joint outside 1..{n_nodes}")
    areas = np.broadcast_to(np.asarray(areas, float), (members0.shape[0],))
    if np.any(areas <= 0) or E <= 0 or rho <= 0:
        raise ModelError("areas, E and rho must be positive")
    n_full = 2 * n_nodes
    K = np.zeros((n_full, n_full))
    M = np.zeros((n_full, n_full))
    S = np.zeros((members0.shape[0], n_full))
    for k, (i, j) in enumerate(members0):
        Ke, Me, se = bar_matrices(nodes[i], nodes[j], E, areas[k], rho, lumped)
        dofs = np.array([2 * i, 2 * i + 1, 2 * j, 2 * j + 1])
        K[np.ix_(dofs, dofs)] += Ke
        M[np.ix_(dofs, dofs)] += Me
        S[k, dofs] = se
    fixed = []
    for joint, dirs in supports.items():
        for d in dirs:
            if d not in "xy":
                raise ModelError(f"support direction must be 'x' or 'y', got {d!r}")
            fixed.append(2 * (int(joint) - 1) + "xy".index(d))
    free = np.setdiff1d(np.arange(n_full), fixed)
    ix = np.ix_(free, free)
    return Structure(M=M[ix], K=K[ix], damping=damping, nodes=nodes, dof_names=("x", "y"),
                     free_dofs=free, strain_matrix=S[:, free], strain_kind="member",
                     members=members0 + 1, name=name,
                     meta=dict(K_full=K, M_full=M, areas=areas, E=E, rho=rho, supports=dict(supports)))


def s17_areas():
    """Member areas of the S17 truss, by the paper's area groups.

    Returns
    -------
    ndarray (34,)
        m^2.
    """
    a = np.full(34, S17_AREA_OTHER)
    a[np.asarray(S17_BOTTOM) - 1] = S17_AREA_BOTTOM
    a[np.asarray(S17_VERTICAL) - 1] = S17_AREA_VERTICAL
    return a


def s17_truss(E: float = 200e9, rho: float = 7800.0, damping: Damping = 0.007, panel: float = 1.0, height: float = 1.0,
              lumped: bool = False) -> Structure:
    """The S17 / IMP planar truss: 18 joints, 34 members, pin at joint 1, roller at joint 18.

    Parameters
    ----------
    E : float
        Young's modulus (Pa).
    rho : float
        Density (kg/m^3).
    damping : float
        Modal damping ratio.
    panel, height : float
        Panel length and truss height (m).
    lumped : bool
        Lumped instead of consistent mass.

    Returns
    -------
    Structure
        Strain outputs ``strain:1`` .. ``strain:34`` (the members).

    Examples
    --------
    >>> s = s17_truss()
    >>> s.n, s.n_strain, round(float(s.frequencies(1)[0]), 2)
    (33, 34, 30.37)
    """
    check_positive(panel, "panel"), check_positive(height, "height")
    return planar_truss(s17_joint_coordinates(panel, height), S17_MEMBERS, s17_areas(), E, rho,
                 supports={1: "xy", 18: "y"}, damping=damping, lumped=lumped, name="S17 truss")


def member_strain_exact(structure, u_free):
    """Exact geometric member strains ``(|x_j + d_j - x_i - d_i| - L) / L`` (S17).

    For small displacements this equals ``structure.strain_matrix @ u_free`` (S17 eq. 35-36).

    Parameters
    ----------
    structure : Structure
        A truss of :func:`planar_truss`.
    u_free : ndarray (..., n_phys)
        Free physical displacements (m).

    Returns
    -------
    ndarray (..., n_members)
        Strains (m/m).
    """
    u_free = np.asarray(u_free, float)
    d = np.zeros(u_free.shape[:-1] + (2 * structure.n_nodes,))
    d[..., structure.free_dofs] = u_free
    d = d.reshape(u_free.shape[:-1] + (structure.n_nodes, 2))
    i, j = structure.members[:, 0] - 1, structure.members[:, 1] - 1
    x = structure.nodes
    L0 = np.linalg.norm(x[j] - x[i], axis=1)
    L = np.linalg.norm(x[j] + d[..., j, :] - x[i] - d[..., i, :], axis=-1)
    return (L - L0) / L0
