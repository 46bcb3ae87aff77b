"""A live OpenSeesPy model as a :class:`~core_akf.structure.Structure`: the nodes, the supports
and the equation numbering, K and M (and C, if the model has Rayleigh damping) taken from OpenSees
itself, and every two-node element (truss, beam-column) turned into a strain output -- the
axial strain between its end nodes, ``strain:k`` for the k-th element in OpenSees' tag order.

Needs the optional ``openseespy`` package (the ``opensees`` extra; on Linux it
loads the system's BLAS and LAPACK, e.g. Debian's ``libblas3`` and ``liblapack3``).

Build the model with ``openseespy.opensees`` as usual (``model``, ``node``, ``fix``, ``element``
with mass, optionally ``rayleigh``), then call :func:`from_opensees`.  The matrices come from
``printA`` after one transient step with the ``GimmeMCK`` integrator (``FullGeneral`` system,
``Plain`` numberer and constraints), so the analysis settings of the OpenSees domain are replaced.
Masses must make M positive definite: give truss elements ``-rho`` (``-cMass`` for the consistent
mass), and beams a rotational mass, or condense the massless DOFs first.
"""
from __future__ import annotations

import numpy as np

from ..checks import AKFInputError, install_hint
from .sparse import DENSE_LIMIT

#: OpenSees' DOF order per (ndm, ndf)
DOF_NAMES = {(1, 1): ("x",), (2, 2): ("x", "y"), (2, 3): ("x", "y", "rz"), (3, 3): ("x", "y", "z"),
             (3, 6): ("x", "y", "z", "rx", "ry", "rz")}
#: models above this many equations are refused (printA gives a dense matrix): the dense-size limit
OPENSEES_LIMIT = DENSE_LIMIT


def _ops():
    try:
        import openseespy.opensees as ops
    except (ImportError, OSError, RuntimeError) as exc:
        # openseespy wraps a native library that fails to load in RuntimeError("Failed to import openseespy ...")
        cause = exc.__cause__ or exc.__context__
        native = isinstance(exc, (OSError, RuntimeError)) or any(t in str(exc) for t in (".so", "DLL", ".dylib"))
        if native:                                       # installed, but a system library is missing
            why = f"{exc}: {cause}" if cause is not None else str(exc)
            raise AKFInputError(f"openseespy is installed but cannot load ({why}): it needs the system's BLAS and LAPACK "
                                "(on Debian/Ubuntu `apt-get install libblas3 liblapack3`, on Fedora/RHEL `dnf install "
                                "blas lapack`)") from None
        raise AKFInputError(f"reading an OpenSees model needs the package 'openseespy': {install_hint('opensees')} "
                            f"({exc})") from None
    return ops


def _system_matrix(ops, m, c, k, n):
    """``m M + c C + k K`` (n x n) from OpenSees' own assembly."""
    ops.wipeAnalysis()
    ops.system("FullGeneral")
    ops.numberer("Plain")
    ops.constraints("Plain")
    ops.algorithm("Linear")
    ops.integrator("GimmeMCK", float(m), float(c), float(k))
    ops.analysis("Transient")
    ops.analyze(1, 0.0)
    A = np.array(ops.printA("-ret"), dtype=float)
    if A.size != n * n:
        raise AKFInputError(f"OpenSees returned a system of {A.size} entries for {n} equations")
    return A.reshape(n, n)


def from_opensees(damping=None, strains="elements", name="OpenSees model", n_modes=None):
    """The OpenSeesPy model in memory as a :class:`~core_akf.structure.Structure`.

    Node ids are OpenSees' node tags; directions follow ``ndm``/``ndf`` (:data:`DOF_NAMES`).

    Parameters
    ----------
    damping : float, sequence, tuple or None
        Modal ratio(s) or ``("rayleigh", alpha, beta)``; None: OpenSees' own Rayleigh damping
        (``rayleigh`` command) if the model has one, else none.
    strains : str or None
        ``"elements"``: every two-node element an extensometer, in element-tag order.
    name : str
        The model's name.
    n_modes : int, optional
        Keep only the lowest modes, with a static correction
        (:func:`~core_akf.models.from_matrices`).

    Returns
    -------
    Structure
    """
    from .matrices import from_matrices

    ops = _ops()
    tags = [int(t) for t in ops.getNodeTags()]
    if not tags:
        raise AKFInputError("the OpenSees domain has no nodes: build the model first (ops.model, ops.node, ...)")
    coords = {t: tuple(float(v) for v in ops.nodeCoord(t)) for t in tags}
    ndm = {len(c) for c in coords.values()}
    ops.wipeAnalysis()
    ops.numberer("Plain")
    ops.constraints("Plain")
    ops.system("FullGeneral")
    ops.algorithm("Linear")
    ops.integrator("GimmeMCK", 0.0, 0.0, 1.0)
    ops.analysis("Transient")
    ops.analyze(1, 0.0)
    equations, constrained = {}, []
    for t in tags:
        ndf = len(ops.nodeDOFs(t))
        key = (len(coords[t]), ndf)
        if key not in DOF_NAMES:
            raise AKFInputError(f"node {t}: ndm {key[0]} with ndf {key[1]} is not supported; use one of "
                                f"{sorted(DOF_NAMES)}")
        for d, eq in zip(DOF_NAMES[key], ops.nodeDOFs(t)):
            if eq >= 0:
                equations[int(eq)] = (t, d)
            else:
                constrained.append((t, d))
    n = len(equations)
    if n == 0:
        raise AKFInputError("the OpenSees model has no free DOF")
    if n > OPENSEES_LIMIT:
        raise AKFInputError(f"the OpenSees model has {n} equations; above {OPENSEES_LIMIT} export K and M "
                            "(e.g. as Matrix Market files) and use from_files")
    if sorted(equations) != list(range(n)):
        raise AKFInputError("OpenSees' equation numbers are not 0..n-1; use the Plain numberer")
    dofs = [equations[i] for i in range(n)] + constrained      # constrained DOFs: zero rows, then removed
    K, M, C = (np.pad(_system_matrix(ops, *w, n), (0, len(constrained)))
               for w in ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)))
    use_C = damping is None and np.any(C)
    members = None
    if strains == "elements":
        pairs = [tuple(int(v) for v in ops.eleNodes(e)) for e in ops.getEleTags()]
        members = [p for p in pairs if len(p) == 2]
        if not members:
            members = None
    elif strains is not None:
        raise AKFInputError(f"strains must be 'elements' or None, got {strains!r}")
    if len(ndm) != 1 or next(iter(ndm)) not in (2, 3):
        raise AKFInputError(f"node coordinates must all be 2-D or all 3-D, got dimensions {sorted(ndm)}")
    return from_matrices(K, M, dofs, coords, fixed=constrained, damping=None if use_C else damping,
                         C=C if use_C else None, extensometers=members, name=name, n_modes=n_modes)
