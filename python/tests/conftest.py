"""Shared fixtures. Run from the build tree with PYTHONPATH=<build>/python (ctest sets it, and
CARTESIAN_IMPEDANCE_SOURCE_DIR for the robot models)."""

import os
import pathlib

import numpy as np
import pytest

import cartesian_impedance as ci

SOURCE_DIR = pathlib.Path(
    os.environ.get("CARTESIAN_IMPEDANCE_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
PANDA_URDF = SOURCE_DIR / "models" / "panda" / "panda.urdf"
PANDA_XML = SOURCE_DIR / "models" / "panda" / "panda.xml"
PANDA_YAML = SOURCE_DIR / "config" / "panda.yaml"
# The MJCF keyframe "ready" [rad].
PANDA_READY = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])


@pytest.fixture(scope="session")
def panda():
    return ci.RobotModel.from_urdf_file(PANDA_URDF, "panda_link0", "panda_link8")


@pytest.fixture
def ready():
    return PANDA_READY.copy()


def has_sim():
    return hasattr(ci, "sim")


requires_sim = pytest.mark.skipif(not has_sim(), reason="built without the MuJoCo simulation")
