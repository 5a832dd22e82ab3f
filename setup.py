"""Builds the Python package cartesian_impedance for pip (pyproject.toml) with scikit-build 0.16.

CMake builds only what the module needs: no tests, benchmarks, examples, demo or ROS nodes; the
simulation with MuJoCo, and DART if it is found. Then the CMake target install_python_package
installs the package folder (python/CMakeLists.txt): the module, __init__.py, the stubs, py.typed
and the shipped data (data/models, data/config), which scikit-build packs.

More CMake options: CMAKE_ARGS="-DCARTESIAN_IMPEDANCE_BUILD_DART=OFF" (they come last, so they
win). Parallel compile jobs: CMAKE_BUILD_PARALLEL_LEVEL (default: the CPUs this process may use).
"""

import os
import pathlib
import re
import sys

from skbuild import setup

ROOT = pathlib.Path(__file__).resolve().parent


def cmake_project_version():
    text = (ROOT / "CMakeLists.txt").read_text()
    match = re.search(r"project\(cartesian_impedance\s+VERSION\s+([0-9.]+)", text)
    if not match:
        sys.exit("setup.py: no 'project(cartesian_impedance VERSION x.y.z' in CMakeLists.txt")
    return match.group(1)


def cmake_arguments():
    arguments = [
        "-DCMAKE_BUILD_TYPE=Release",
        "-DCARTESIAN_IMPEDANCE_BUILD_PYTHON=ON",
        "-DCARTESIAN_IMPEDANCE_BUILD_TESTS=OFF",
        "-DCARTESIAN_IMPEDANCE_BUILD_BENCHMARKS=OFF",
        "-DCARTESIAN_IMPEDANCE_BUILD_EXAMPLES=OFF",
        "-DCARTESIAN_IMPEDANCE_BUILD_APPS=OFF",
        "-DCARTESIAN_IMPEDANCE_BUILD_ROS=OFF",
        "-DCARTESIAN_IMPEDANCE_BUILD_ROS2=OFF",
        "-DCARTESIAN_IMPEDANCE_BUILD_DART=AUTO",
        # Relative to scikit-build's install folder, which stands for python/ (cmake_install_dir).
        "-DCARTESIAN_IMPEDANCE_PYTHON_INSTALL_DIR=.",
        # The interpreter running pip (a venv's too) is the one the module is built for.
        "-DPython3_EXECUTABLE=" + sys.executable,
    ]
    try:  # the pybind11 that pyproject.toml requires, rather than whichever CMake finds first
        import pybind11
        arguments.append("-Dpybind11_DIR=" + pybind11.get_cmake_dir())
    except ImportError:
        pass
    return arguments


if hasattr(os, "sched_getaffinity"):
    os.environ.setdefault("CMAKE_BUILD_PARALLEL_LEVEL", str(len(os.sched_getaffinity(0))))

setup(
    version=cmake_project_version(),
    packages=["cartesian_impedance", "cartesian_impedance.envs"],
    package_dir={"": "python"},
    cmake_install_dir="python",
    cmake_install_target="install_python_package",
    cmake_args=cmake_arguments(),
    zip_safe=False,
)
