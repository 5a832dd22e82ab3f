"""The package around the extension (python/cartesian_impedance/__init__.py): its data folder, and
the names users see, which stay cartesian_impedance.X although the extension is
cartesian_impedance._core."""

import pathlib
import pickle

import pytest

import cartesian_impedance as ci
from conftest import SOURCE_DIR, has_sim


def test_data_dir_holds_the_shipped_models_and_configs():
    data = ci.data_dir()
    assert isinstance(data, pathlib.Path)
    assert data == pathlib.Path(ci.__file__).absolute().parent / "data"
    for name in ["models/panda/panda.urdf", "models/panda/panda.xml", "config/panda.yaml"]:
        assert (data / name).read_bytes() == (SOURCE_DIR / name).read_bytes(), name
    model = ci.RobotModel.from_urdf_file(data / "models/panda/panda.urdf", "panda_link0",
                                         "panda_link8")
    assert model.num_joints == 7


@pytest.mark.parametrize("lacking", ["models", "config"])
def test_data_dir_names_the_folder_an_incomplete_install_lacks(tmp_path, monkeypatch, lacking):
    for part in {"models", "config"} - {lacking}:
        (tmp_path / part).mkdir()
    monkeypatch.setattr(ci, "_DATA_DIR", tmp_path)
    with pytest.raises(ci.LoadError, match=f"'{tmp_path}' has no {lacking}/"):
        ci.data_dir()


def test_the_types_are_named_after_the_package():
    # pybind11 writes a type's module into each signature when the type is bound.
    assert ci.Pose.__module__ == "cartesian_impedance"
    assert ci.Error.__module__ == "cartesian_impedance"
    assert "self: cartesian_impedance.ControlLoop" in ci.ControlLoop.step.__doc__
    assert "_core" not in ci.ControlLoop.step.__doc__
    assert pickle.loads(pickle.dumps(ci.Frame.end_effector)) == ci.Frame.end_effector


def test_the_package_exports_the_extension():
    public = {name for name in vars(ci._core) if not name.startswith("_")}
    assert public <= set(vars(ci)), sorted(public - set(vars(ci)))
    assert ci.__version__ == ci._core.__version__
    assert ci.__doc__ == ci._core.__doc__


@pytest.mark.skipif(not has_sim(), reason="built without the MuJoCo simulation")
def test_sim_is_a_submodule():
    import cartesian_impedance.sim as sim

    assert sim is ci.sim
    assert sim.__name__ == "cartesian_impedance.sim"
    assert sim.Simulation.__module__ == "cartesian_impedance.sim"


def test_runtime_is_a_submodule():
    import cartesian_impedance.runtime as runtime

    assert runtime is ci.runtime
    assert runtime.__name__ == "cartesian_impedance.runtime"
    assert runtime.ControlThread.__module__ == "cartesian_impedance.runtime"
    assert "loop: cartesian_impedance.ControlLoop" in runtime.ControlThread.start.__doc__
