"""The plausibility of a model of one's own: units, repeated nodes, complex or overflowing values."""
import os

import numpy as np
import pytest
import scipy.io
import scipy.sparse
from helpers import ROOT, two_dof

from akf.cli import main


def test_node_coordinates_in_mm_against_si_matrices():
    """With extensometers the strains divide by the lengths: mm coordinates are refused (the run
    ended with exit 0 and forces 16x off after a warning); without, the figures alone are off: a
    warning; between 25 and 100 m apart it may be a coarse model: a warning."""
    from core_akf.checks import AKFInputError
    from core_akf.models.matrices import ModelWarning

    with pytest.raises(AKFInputError, match="nodes lie 1000 m apart .* coordinates look like mm"):
        two_dof(nodes={1: (1000.0, 0.0), 2: (2000.0, 0.0)}, extensometers=[(1, 2)])
    with pytest.warns(ModelWarning, match="are the coordinates in mm"):
        two_dof(nodes={1: (1000.0, 0.0), 2: (2000.0, 0.0)})
    with pytest.warns(ModelWarning, match="are the coordinates in mm"):
        two_dof(nodes={1: (40.0, 0.0), 2: (80.0, 0.0)}, extensometers=[(1, 2)])


def test_node_coordinates_in_m_give_no_unit_warning(recwarn):
    two_dof(nodes={1: (1.0, 0.0), 2: (3.5, 0.0)})
    assert not [w for w in recwarn if "in mm" in str(w.message)]


def test_a_node_listed_twice(tmp_path):
    from core_akf.models.matrices import read_nodes

    with pytest.raises(ValueError, match="node 1 is listed twice"):
        two_dof(nodes=[(1, (1.0, 0.0)), (2, (2.0, 0.0)), (1, (3.0, 0.0))])
    (tmp_path / "nodes.csv").write_text("node,x,y\n1,0,0\n2,1,0\n1,2,0\n")
    with pytest.raises(ValueError, match="node 1 is listed twice \\(data rows 1 and 3\\)"):
        read_nodes(tmp_path / "nodes.csv")


@pytest.mark.parametrize("sparse", [False, True])
def test_a_complex_stiffness_matrix(sparse):
    K = np.array([[2.0, -1.0], [-1.0, 1.0]]) * 1e6 * (1 + 0.04j)
    with pytest.raises(ValueError, match="K is complex"):
        two_dof(K=scipy.sparse.csr_matrix(K) if sparse else K)


def test_damping_typed_as_a_percentage():
    from core_akf.structure import DampingWarning

    with pytest.raises(ValueError, match="damping is a ratio, not a percentage"):
        two_dof(damping=2.0)
    with pytest.warns(DampingWarning, match="is it a percentage"):
        two_dof(damping=0.5)


@pytest.mark.parametrize("n_modes", [2.5, "all", True, 0])
def test_n_modes_that_is_not_a_number_of_modes(n_modes):
    with pytest.raises(ValueError, match="n_modes must be a whole number of modes >= 1"):
        two_dof(n_modes=n_modes)


@pytest.mark.parametrize("factor", ["1e308", "1e12", "1e-12", "0.005"])
def test_a_stiffness_factor_that_makes_another_structure_is_named(tmp_path, capsys, factor):
    """1e308 overflowed the stiffness matrix; 1e-12 ended in "the innovation covariance is not
    positive definite (check the noise covariance R)", 1e12 in a failed steady-state gain."""
    job = tmp_path / "j.toml"
    text = open(os.path.join(ROOT, "akf", "examples", "jobs", "s17-case4.toml")).read()
    job.write_text(text.replace("stiffness_factor = 1.05", f"stiffness_factor = {factor}"))
    assert factor in job.read_text()
    assert main(["estimate", str(job), "--no-plot", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"[filter] stiffness_factor = {float(factor):.4g} multiplies the model's stiffness" in err
    assert "give a factor between 0.01 and 100" in err


def test_a_frequency_factor_that_makes_another_structure_is_named(tmp_path, capsys):
    job = tmp_path / "j.toml"
    text = open(os.path.join(ROOT, "akf", "examples", "jobs", "s17-case4.toml")).read()
    job.write_text(text.replace("stiffness_factor = 1.05", "stiffness_factor = 1.05\nfrequency_factors = [1.0, 20.0]"))
    assert main(["estimate", str(job), "--no-plot", "--out", str(tmp_path / "o")]) == 2
    assert "[filter] frequency_factors[1] = 20 multiplies mode 2's frequency" in capsys.readouterr().err


@pytest.mark.parametrize("line, message", [
    ('stiffness_factor = ""', "stiffness_factor must be a number and frequency_factors a list of numbers, got ''"),
    ("stiffness_factor = 1e-12", "stiffness_factor = 1e-12 multiplies the model's stiffness"),
    ("frequency_factors = 1.1", "frequency_factors a list of numbers, got 1.05 and 1.1")])
def test_show_names_a_filter_model_it_cannot_build(tmp_path, capsys, line, message):
    """``akf show JOB`` reads any command's job loosely: a text stiffness factor ended in an
    internal error ("could not convert string to float")."""
    job = tmp_path / "j.toml"
    job.write_text(f'name = "j"\n[structure]\nmodel = "s17_truss"\n[filter]\nstiffness_factor = 1.05\n{line}\n'
                   .replace("stiffness_factor = 1.05\nstiffness_factor", "stiffness_factor"))
    assert main(["show", str(job), "--out", str(tmp_path / "o"), "--no-plot"]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("line, message", [
    ('sensors = "inf"', "sensors must be a list of texts such as"),
    ('sensors = ["strain:999"]', "999"),
    ('forces = ["99:y"]', "99")])
def test_show_names_sensors_and_forces_it_cannot_draw(tmp_path, capsys, line, message):
    """``sensors = "inf"`` was drawn as the sensors 'i', 'n' and 'f', with exit 0."""
    job = tmp_path / "j.toml"
    job.write_text(f'name = "j"\n{line}\n[structure]\nmodel = "s17_truss"\n')
    assert main(["show", str(job), "--out", str(tmp_path / "o")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o" / "j.png").exists()
