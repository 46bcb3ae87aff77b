"""A 3-D truss footbridge: a worked example that is not from the papers, built as a user would
bring a model of their own -- sparse K and M, a DOF map, 3-D coordinates and the members as
extensometers -- and read through :func:`~core_akf.models.from_matrices`.

The bridge is a box truss of ``n_panels`` panels: two side trusses (bottom and top chords,
verticals, diagonals alternating in direction), cross beams and plan bracing in the deck
(bottom) and top planes, and a sway brace in every cross frame.  Steel tubes; the deck's own
mass (kg per m^2 of deck) is lumped at the bottom nodes.  Pinned at x = 0 (both bottom nodes
fixed in x, y, z), on rollers at x = L (one fixed in y and z, one in z).

Node numbering (1-based): station ``s = 0..n_panels`` at ``x = s * panel`` has nodes
``4 s + 1`` (bottom, y = -w/2), ``4 s + 2`` (bottom, y = +w/2), ``4 s + 3`` (top, y = -w/2),
``4 s + 4`` (top, y = +w/2); z is up.  Member ``k`` is strain output ``strain:k``.

>>> b = footbridge()
>>> b.free_dofs.size, len(b.members)
(1011, 1097)
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..checks import Damping, ModelError

if TYPE_CHECKING:
    from ..structure import Structure

#: the default bridge: 42 m span, 84 panels of 0.5 m, 2.0 m wide, 1.5 m deep
FOOTBRIDGE = dict(n_panels=84, panel=0.5, width=2.0, height=1.5, E=210e9, rho=7850.0,
                  area_chord=3.0e-3, area_web=1.2e-3, area_bracing=0.6e-3, deck_mass=250.0)


def footbridge_geometry(n_panels, panel, width, height):
    """The bridge's nodes and members.

    Parameters
    ----------
    n_panels : int
        Panels along the span (at least 2).
    panel : float
        Panel length (m).
    width : float
        Deck width (m).
    height : float
        Truss height (m).

    Returns
    -------
    nodes : ndarray (n_nodes, 3)
        Coordinates (m).
    members : ndarray (n_members, 2)
        End nodes, 1-based.
    groups : ndarray of str
        Each member's group: "chord", "web" or "bracing".
    """
    if int(n_panels) < 2:
        raise ModelError(f"the bridge needs at least 2 panels, got {n_panels}")
    for label, v in (("panel", panel), ("width", width), ("height", height)):
        if not np.isfinite(v) or v <= 0:
            raise ModelError(f"{label} must be a positive length in m, got {v!r}")
    n = int(n_panels)
    st = np.arange(n + 1)
    nodes = np.zeros((4 * (n + 1), 3))
    for k, (y, z) in enumerate(((-width / 2, 0.0), (width / 2, 0.0), (-width / 2, height), (width / 2, height))):
        nodes[k::4] = np.column_stack([st * panel, np.full(n + 1, y), np.full(n + 1, z)])

    def node(s, k):
        return 4 * s + k + 1

    members, groups = [], []

    def add(a, b, group):
        members.append((a, b))
        groups.append(group)

    for s in range(n):
        for k in range(4):                                    # chords
            add(node(s, k), node(s + 1, k), "chord")
        for bottom, top in ((0, 2), (1, 3)):                  # side diagonals, alternating
            if s % 2 == 0:
                add(node(s, bottom), node(s + 1, top), "web")
            else:
                add(node(s, top), node(s + 1, bottom), "web")
        add(node(s, 0), node(s + 1, 1), "bracing")            # deck plan bracing
        add(node(s, 2), node(s + 1, 3), "bracing")            # top plan bracing
    for s in range(n + 1):
        add(node(s, 0), node(s, 2), "web")                    # verticals
        add(node(s, 1), node(s, 3), "web")
        add(node(s, 0), node(s, 1), "bracing")                # deck cross beam
        add(node(s, 2), node(s, 3), "bracing")                # top cross beam
        add(node(s, 0) if s % 2 == 0 else node(s, 1), node(s, 3) if s % 2 == 0 else node(s, 2), "bracing")  # sway
    return nodes, np.array(members, dtype=int), np.array(groups)


def footbridge_matrices(**overrides: float) -> dict:
    """The bridge as an FE program would export it.

    Parameters
    ----------
    **overrides
        Keys of :data:`FOOTBRIDGE` to change (``n_panels``, ``panel``, ``width``, ``height`` in m,
        ``E`` in Pa, ``rho`` in kg/m^3, the areas ``area_chord``, ``area_web``, ``area_bracing``
        in m^2, ``deck_mass`` in kg per m^2 of deck).

    Returns
    -------
    dict
        ``K``, ``M`` (sparse CSR over all 3 DOFs of every node, N/m and kg), ``dofs`` (node,
        direction per row), ``nodes`` (id -> (x, y, z)), ``fixed`` (the supports), ``members``
        (n_members x 2, 1-based) and ``groups``.

    Examples
    --------
    >>> m = footbridge_matrices(n_panels=4)
    >>> m["K"].shape, len(m["members"])         # 20 nodes x 3 DOFs
    ((60, 60), 57)
    """
    import scipy.sparse

    p = dict(FOOTBRIDGE)
    unknown = sorted(set(overrides) - set(p))
    if unknown:
        raise ModelError(f"unknown footbridge parameter(s) {unknown}; use {sorted(p)}")
    p.update(overrides)
    nodes, members, groups = footbridge_geometry(p["n_panels"], p["panel"], p["width"], p["height"])
    area = np.array([p[f"area_{g}"] for g in groups], float)
    if np.any(area <= 0) or p["E"] <= 0 or p["rho"] <= 0 or p["deck_mass"] < 0:
        raise ModelError("areas, E and rho must be positive and deck_mass >= 0")
    a, b = members[:, 0] - 1, members[:, 1] - 1
    d = nodes[b] - nodes[a]
    L = np.linalg.norm(d, axis=1)
    e = d / L[:, None]
    t = np.hstack([-e, e])                                    # (n_m, 6): axial extension per unit DOF
    dofs = np.hstack([3 * a[:, None] + np.arange(3), 3 * b[:, None] + np.arange(3)])
    ke = (p["E"] * area / L)[:, None, None] * t[:, :, None] * t[:, None, :]
    m = p["rho"] * area * L                                   # consistent bar mass, isotropic
    me = (m / 6.0)[:, None, None] * np.kron(np.array([[2.0, 1.0], [1.0, 2.0]]), np.eye(3))[None]
    rows = np.repeat(dofs, 6, axis=1).ravel()
    cols = np.tile(dofs, (1, 6)).ravel()
    n_full = 3 * nodes.shape[0]
    K = scipy.sparse.coo_matrix((ke.ravel(), (rows, cols)), shape=(n_full, n_full)).tocsr()
    deck = np.zeros(n_full)
    bottom = np.flatnonzero(nodes[:, 2] == 0.0)
    tributary = np.where((nodes[bottom, 0] == 0) | (nodes[bottom, 0] == nodes[:, 0].max()), 0.5, 1.0) * p["panel"]
    for k in range(3):
        deck[3 * bottom + k] = p["deck_mass"] * tributary * p["width"] / 2
    M = (scipy.sparse.coo_matrix((me.ravel(), (rows, cols)), shape=(n_full, n_full)) + scipy.sparse.diags(deck)).tocsr()
    last = 4 * int(p["n_panels"])
    fixed = [(1, "x"), (1, "y"), (1, "z"), (2, "x"), (2, "y"), (2, "z"), (last + 1, "y"), (last + 1, "z"), (last + 2, "z")]
    ids = np.arange(1, nodes.shape[0] + 1)
    return dict(K=K, M=M, dofs=[(int(i), dd) for i in ids for dd in "xyz"],
                nodes={int(i): tuple(float(v) for v in xyz) for i, xyz in zip(ids, nodes)}, fixed=fixed,
                members=members, groups=groups)


def footbridge(damping: Damping = 0.005, n_modes: int | None = None, **overrides: float) -> Structure:
    """The 3-D truss footbridge, read through :func:`~core_akf.models.from_matrices`.

    340 nodes, 1011 free DOFs, 1097 members as strain outputs ``strain:1..1097``; ``meta["E"]``
    is the members' Young's modulus (for their stresses, :mod:`core_akf.fatigue`).

    Parameters
    ----------
    damping : float
        Modal damping ratio (default 0.5 %).
    n_modes : int, optional
        Keep the lowest modes with a static correction.
    **overrides
        Keys of :data:`FOOTBRIDGE` to change (see :func:`footbridge_matrices`).

    Returns
    -------
    Structure

    Examples
    --------
    >>> bridge = footbridge()
    >>> bridge.n, bridge.n_strain
    (1011, 1097)
    """
    from .matrices import from_matrices

    parts = footbridge_matrices(**overrides)
    bridge = from_matrices(parts["K"], parts["M"], parts["dofs"], parts["nodes"], fixed=parts["fixed"], damping=damping,
                           extensometers=parts["members"], name="footbridge", n_modes=n_modes)
    bridge.meta["E"] = float(dict(FOOTBRIDGE, **overrides)["E"])       # the members' steel: their stress is E strain
    return bridge
