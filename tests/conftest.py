"""Fixtures several test modules share."""
import numpy as np
import pytest
import scipy.io
import scipy.sparse
from helpers import OFFSET

from core_akf.models import s17_truss


@pytest.fixture(scope="module")
def frame3d(tmp_path_factory):
    """The S17 truss exported as a model of one's own in 3-D coordinates (z = 0): K.mtx, M.mtx,
    dofs.csv, nodes.csv, a strain operator S.mtx (the 34 member strains) and the start of a job."""
    s = s17_truss()
    d = tmp_path_factory.mktemp("frame3d")
    ids = np.arange(1, s.n_nodes + 1) + OFFSET
    dofs = [(int(i), c) for i in ids for c in "xy"]
    (d / "dofs.csv").write_text("node,direction\n" + "".join(f"{n},{c}\n" for n, c in dofs))
    (d / "nodes.csv").write_text("node,x,y,z\n" + "".join(
        f"{i},{float(s.nodes[i - OFFSET - 1][0])!r},{float(s.nodes[i - OFFSET - 1][1])!r},0.0\n" for i in ids))
    scipy.io.mmwrite(d / "K.mtx", scipy.sparse.coo_matrix(s.meta["K_full"]), symmetry="symmetric")
    scipy.io.mmwrite(d / "M.mtx", scipy.sparse.coo_matrix(s.meta["M_full"]), symmetry="symmetric")
    S = np.zeros((s.n_strain, len(dofs)))
    S[:, s.free_dofs] = s.strain_matrix
    scipy.io.mmwrite(d / "S.mtx", scipy.sparse.coo_matrix(S))
    fixed = ", ".join(f'"{j + OFFSET}:{c}"' for j, cs in s.meta["supports"].items() for c in cs)
    structure = f"""dt = 0.001953125
forces = ["108:y"]
[structure]
model = "matrices"
K = "K.mtx"
M = "M.mtx"
dofs = "dofs.csv"
nodes = "nodes.csv"
fixed = [{fixed}]
damping = 0.007
"""
    return d, structure
