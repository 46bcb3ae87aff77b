"""Bad input gets a clear exception naming the problem."""
import numpy as np
import pandas as pd
import pytest
from helpers import read_record

from core_akf import AKFInputError, ModelError, Structure, UndetectableError
from core_akf.filter import estimate, run
from core_akf.models import plate, s17_truss, th_plate
from core_akf.sensors import Sensor, as_layout
from core_akf.simulate import simulate

KW = dict(model_error_cov=1e-16, force_increment_cov=1e4, noise_cov={"strain": 1e-14, "acc": 1e-2})


@pytest.fixture(scope="module")
def truss():
    return s17_truss()


def test_an_infinite_measurement_is_named_and_nan_is_a_missing_sample(truss):
    Y = np.zeros((50, 2))
    Y[17, 1] = np.inf
    with pytest.raises(AKFInputError, match=r"measurements contains 1 infinite value.*\(17, 1\)"):
        estimate(truss, ["strain:13", "acc:8:y"], ["8:y"], Y, 1e-3, **KW)
    Y[17, 1] = np.nan
    est = estimate(truss, ["strain:13", "acc:8:y"], ["8:y"], Y, 1e-3, **KW)
    assert np.isfinite(est.forces).all() and np.isnan(est.innovations[17, 1])


def test_wrong_measurement_shape(truss):
    with pytest.raises(AKFInputError, match="3 columns for 2 sensors"):
        estimate(truss, ["strain:13", "acc:8:y"], ["8:y"], np.zeros((50, 3)), 1e-3, **KW)
    with pytest.raises(AKFInputError, match="channels"):
        run(np.eye(3), np.ones((2, 3)), np.eye(3), np.eye(2), np.zeros((10, 3)))


def test_unknown_joint_member_and_node(truss):
    with pytest.raises(AKFInputError, match="unknown node/joint 19"):
        estimate(truss, ["acc:19:y", "strain:13"], ["8:y"], np.zeros((5, 2)), 1e-3, **KW)
    with pytest.raises(AKFInputError, match="unknown member 35"):
        estimate(truss, ["strain:35"], ["8:y"], np.zeros((5, 1)), 1e-3, **KW)
    with pytest.raises(AKFInputError, match="unknown direction 'z'"):
        truss.dof_index(4, "z")
    with pytest.raises(AKFInputError, match="constrained"):
        truss.dof_index(1, "y")  # the pin
    p = th_plate()
    with pytest.raises(AKFInputError, match="unknown node/joint 122"):
        p.strain_index((122, "ex"))
    with pytest.raises(AKFInputError, match="unknown strain component 'ez'"):
        p.strain_index((5, "ez"))
    with pytest.raises(AKFInputError, match="needs component in"):
        Sensor("strain", node=5, component="ez")


def test_duplicate_sensor_and_force(truss):
    with pytest.raises(AKFInputError, match="duplicate sensor strain:13"):
        estimate(truss, ["strain:13", "acc:8:y", "strain:13"], ["8:y"], np.zeros((5, 3)), 1e-3, **KW)
    with pytest.raises(AKFInputError, match="duplicate force location 8:y"):
        estimate(truss, ["strain:13"], ["8:y", "8:y"], np.zeros((5, 1)), 1e-3, **KW)


def test_bad_sensor_strings():
    with pytest.raises(AKFInputError, match="unknown sensor kind"):
        Sensor.parse("gyro:4:y")
    with pytest.raises(AKFInputError, match="cannot read sensor"):
        Sensor.parse("acc:4")
    with pytest.raises(AKFInputError, match="empty"):
        as_layout([])


def test_truss_strain_addressing_on_plate():
    with pytest.raises(AKFInputError, match="addressed by node= and component="):
        simulate(th_plate(), ["strain:5"], ["121:w"], np.zeros((3, 1)), 1e-3)


def test_singular_mass_matrix():
    M = np.diag([1.0, 0.0])
    with pytest.raises(ModelError, match="mass matrix M is singular or not positive definite"):
        Structure(M=M, K=np.eye(2), nodes=np.zeros((1, 2)), dof_names=("x", "y"), free_dofs=[0, 1])


def test_non_symmetric_mass_matrix():
    M = np.array([[1.0, 0.2], [0.0, 1.0]])
    with pytest.raises(ModelError, match="mass matrix M is not symmetric"):
        Structure(M=M, K=np.eye(2), nodes=np.zeros((1, 2)), dof_names=("x", "y"), free_dofs=[0, 1])


def test_nan_in_stiffness():
    K = np.eye(2)
    K[0, 1] = np.nan
    with pytest.raises(AKFInputError, match="stiffness matrix K contains"):
        Structure(M=np.eye(2), K=K, nodes=np.zeros((1, 2)), dof_names=("x", "y"), free_dofs=[0, 1])


def test_undetectable_set_refused_unless_forced(truss):
    sensors = ["acc:4:y", "acc:8:y"]
    Y = simulate(truss, sensors, ["8:y"], np.ones((200, 1)) * 100.0, 1e-3, relative_noise=0.01, seed=0).measurements
    with pytest.raises(UndetectableError, match="s = 0"):
        estimate(truss, sensors, ["8:y"], Y, 1e-3, **KW)
    with pytest.raises(AKFInputError, match="steady-state AKF does not exist"):
        estimate(truss, sensors, ["8:y"], Y, 1e-3, steady=True, allow_undetectable=True, **KW)
    est = estimate(truss, sensors, ["8:y"], Y, 1e-3, allow_undetectable=True, **KW)
    assert est.forces.shape == (200, 1)


def test_bad_covariances(truss):
    Y = np.zeros((10, 1))
    with pytest.raises(AKFInputError, match="noise_cov has no variance for sensor kind"):
        estimate(truss, ["strain:13"], ["8:y"], Y, 1e-3, model_error_cov=1e-16, force_increment_cov=1.0,
                 noise_cov={"acc": 1.0})
    with pytest.raises(AKFInputError, match="force_increment_cov has 2 variances; expected 1"):
        estimate(truss, ["strain:13"], ["8:y"], Y, 1e-3, model_error_cov=1e-16, force_increment_cov=[1.0, 2.0],
                 noise_cov=1e-14)
    with pytest.raises(AKFInputError, match="noise_cov must be positive definite"):
        estimate(truss, ["strain:13"], ["8:y"], Y, 1e-3, model_error_cov=1e-16, force_increment_cov=1.0,
                 noise_cov=0.0)


def test_bad_dt_and_plate_arguments(truss):
    with pytest.raises(AKFInputError, match="dt"):
        estimate(truss, ["strain:13"], ["8:y"], np.zeros((5, 1)), -1.0, **KW)
    with pytest.raises(ModelError, match="Poisson"):
        plate(2, 2, 1, 1, 0.01, 200e9, 0.6, 7800)
    with pytest.raises(ModelError, match="unknown edge"):
        plate(2, 2, 1, 1, 0.01, 200e9, 0.3, 7800, clamped_edge="north")


def test_measurement_file_checks(tmp_path):
    sensors = ["strain:13", "acc:8:y"]
    t = np.arange(10) * 0.001
    rng = np.random.default_rng(0)
    df = pd.DataFrame({"time": t, "strain:13": 1e-6 * rng.normal(size=10), "acc:8:y": rng.normal(size=10)})
    ok = tmp_path / "ok.csv"
    df.to_csv(ok, index=False)
    assert read_record(ok, sensors, 0.001).shape == (10, 2)
    with pytest.raises(AKFInputError, match="does not match the job's dt"):
        read_record(ok, sensors, 0.002)
    df.drop(columns=["acc:8:y"]).to_csv(tmp_path / "missing.csv", index=False)
    with pytest.raises(AKFInputError, match=r"no channel\(s\) \['acc:8:y'\]"):
        read_record(tmp_path / "missing.csv", sensors, 0.001)
    df.loc[4, "strain:13"] = np.nan                     # an empty cell: a missing sample
    df.to_csv(tmp_path / "nan.csv", index=False)
    Y = read_record(tmp_path / "nan.csv", sensors, 0.001)
    assert np.isnan(Y[4, 0]) and np.isnan(Y).sum() == 1
    df["strain:13"] = df["strain:13"].astype(object)
    df.loc[4, "strain:13"] = "1.2 ue"
    df.to_csv(tmp_path / "text.csv", index=False)
    with pytest.raises(AKFInputError, match="'strain:13' has 1 non-numeric sample.*in data row 5, is a number "
                       "followed by text") as info:
        read_record(tmp_path / "text.csv", sensors, 0.001)
    assert "1.2" not in str(info.value)                 # a message names the problem, never the file's content
