"""Cartesian impedance control of torque-controlled robot arms (Python bindings).

The package re-exports the extension module cartesian_impedance._core (built from python/*.cpp)
and adds data_dir(): the folder of the robot models and configurations shipped with it, and
rollouts: rollout functions evaluated over many (params, seed) pairs on a Dask cluster.
"""

import pathlib as _pathlib

from . import _core
from ._core import *  # noqa: F401,F403  (the bindings are this package's API)
# Pure Python on top (imports NumPy; Dask only when a cluster is used): always an attribute, so
# that the package's names do not depend on what was imported before.
from . import rollouts  # noqa: E402

__doc__ = _core.__doc__
__version__ = _core.__version__

# Installed (pip, cmake --install): a copy of the source tree's models/ and config/ beside this
# file. In the build tree: links to them. Not resolved: in the build tree this file may be a link.
_DATA_DIR = _pathlib.Path(__file__).absolute().parent / "data"


def data_dir() -> _pathlib.Path:
    """The folder of the shipped data: models/ (URDF and MJCF files of panda, iiwa14, ur5e,
    planar3 and the scenes) and config/ (a parameter file per robot, e.g. config/panda.yaml).

    Installed with the package, so it is found from any working directory, e.g.
    RobotModel.from_urdf_file(data_dir() / "models/panda/panda.urdf", "panda_link0",
    "panda_link8"). Raises LoadError naming the folder if the installation lacks it."""
    for part in ("models", "config"):
        if not (_DATA_DIR / part).is_dir():
            raise LoadError(  # noqa: F405
                "the shipped data folder '%s' has no %s/: the package is installed incompletely "
                "(reinstall it with pip or cmake --install)" % (_DATA_DIR, part))
    return _DATA_DIR
