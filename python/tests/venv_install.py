#!/usr/bin/python3
"""pip installs the package cartesian_impedance into a fresh venv and uses it from elsewhere.

What a user does (python/README.md), without a package index: a venv with Debian's NumPy
(--system-site-packages), `pip install --no-build-isolation --no-index SOURCE` (setup.py: CMake
builds only the module, with scikit-build), then from a folder outside the tree: import the module,
load the Panda shipped with it (ci.data_dir()), step the simulation 500 cycles from Python after a
5 cm reference step, and check that the arm moved toward the reference. Also that the module, its
data, its stubs and py.typed come from the venv, not from the source or build tree.

It builds from a copy of the source distribution's files (MANIFEST.in) in WORK/source, so the
build folder (scikit-build's _skbuild/) is outside the source tree; the copy keeps the files'
times, so a second run recompiles only what changed. The venv is new each run.

With --from-build BUILD_DIR the package is not compiled again: the build's own install
component `python` (the module, its files and data, as setup.py packs them) is staged, wrapped in
a setuptools project and pip-installed, so the venv install and everything after it is checked
in seconds (ctest python_package_install). Without it, pip builds from the source as a user does
(ctest python_package_install_from_source, label long: scripts/test --long, and CI).

Usage: venv_install.py SOURCE_DIR WORK_DIR [--from-build BUILD_DIR]
Prints how long pip took. Exit status 0 if every check passed.
"""

import os
import pathlib
import shutil
import subprocess
import sys
import time

# Run by the venv's interpreter in a folder outside the tree; exit status 0 if the arm moved.
EXAMPLE = r'''
import pathlib
import sys

import numpy as np

import cartesian_impedance as ci

venv = pathlib.Path(sys.prefix).resolve()
package = pathlib.Path(ci.__file__).resolve().parent
data = ci.data_dir().resolve()
for what, path in [("the module", package), ("its data", data)]:
    assert venv in path.parents, f"{what} is not from the venv {venv}: {path}"
for name in ["__init__.pyi", "sim.pyi", "runtime.pyi", "py.typed", "data/models/panda/panda.xml",
             "data/config/panda.yaml", "envs/__init__.py"]:
    assert (package / name).is_file(), f"the installed package lacks {name}"

import cartesian_impedance.envs as envs  # the environments (pure Python) came along
env = envs.make("CartesianImpedance/Reach-v0")
observation, _ = env.reset(seed=0)
assert env.observation_space.contains(env.step(env.action_space.sample())[0])

model = ci.RobotModel.from_urdf_file(data / "models/panda/panda.urdf", "panda_link0",
                                     "panda_link8")
parameters = ci.Parameters.load(data / "config/panda.yaml")
sim = ci.sim.Simulation.from_mjcf_file(data / "models/panda/panda.xml")
loop = ci.ControlLoop(model, parameters)
loop.start(sim.q, sim.dq)
start = loop.state.controller.pose
step = np.array([0.0, 0.05, 0.0])  # [m], base frame
reference = start.position + step
loop.set_reference_pose((reference, start.orientation))
for _ in range(500):  # 0.5 s at 1 kHz
    sim.set_torque(loop.step(sim.q, sim.dq, sim.timestep))
    sim.step()
position = loop.state.controller.pose.position
remaining = np.linalg.norm(reference - position)
# The pose filter (0.95 of a step in 0.2 s: time constant 0.067 s) has passed the whole step on
# after about 0.07 s; a critically damped 500 N/m spring on the Panda's task-space inertia (under
# 10 kg here, so omega >= 7 rad/s) then leaves (1 + omega t) exp(-omega t) <= 20 % of it at
# 0.43 s. Half the step is the bound: a dead, reversed or unstable law cannot get there.
print(f"moved {np.dot(position - start.position, step) / 0.05 * 1000:.1f} mm of 50 mm toward the "
      f"reference; {remaining * 1000:.1f} mm left after 500 cycles")
assert remaining < 0.5 * np.linalg.norm(step), f"{remaining * 1000:.1f} mm left of 50 mm"
assert np.dot(position - start.position, step) > 0, "the arm moved away from the reference"
print("installed package ok:", package)
'''


def manifest_paths(source):
    """The files and folders MANIFEST.in puts into the source distribution."""
    paths = []
    for line in (source / "MANIFEST.in").read_text().splitlines():
        words = line.split("#", 1)[0].split()
        if words and words[0] in ("include", "graft"):
            paths += words[1:]
    return paths


def copy_sources(source, destination):
    """Copies the source distribution's files into destination, keeping times; leaves _skbuild/
    (the previous build) and removes everything else that is there."""
    destination.mkdir(parents=True, exist_ok=True)
    for entry in destination.iterdir():
        if entry.name != "_skbuild":
            shutil.rmtree(entry) if entry.is_dir() and not entry.is_symlink() else entry.unlink()
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info")
    for name in manifest_paths(source):
        if (source / name).is_dir():
            shutil.copytree(source / name, destination / name, ignore=ignore)
        else:
            shutil.copy2(source / name, destination / name)


# The staged package as a setuptools project: what pip installs is the build's module and files.
PREBUILT_SETUP = """
from setuptools import setup
setup(name="cartesian_impedance", version="{version}",
      packages=["cartesian_impedance", "cartesian_impedance.envs"],
      package_data={{"cartesian_impedance": ["*.so", "*.pyi", "py.typed", "data/**/*"]}},
      zip_safe=False)
"""


def cmake_project_version(source):
    import re
    match = re.search(r"project\(cartesian_impedance\s+VERSION\s+([0-9.]+)",
                      (source / "CMakeLists.txt").read_text())
    return match.group(1)


def stage_prebuilt(source, build, work, environment):
    """The build's install component `python` as a setuptools project in work/prebuilt."""
    stage = work / "stage"
    shutil.rmtree(stage, ignore_errors=True)
    run(["cmake", "--install", build, "--component", "python", "--prefix", stage], work,
        environment)
    packages = list(stage.glob("**/cartesian_impedance/__init__.py"))
    if len(packages) != 1:
        sys.exit(f"the install component python of {build} has no single package: {packages}")
    project = work / "prebuilt"
    shutil.rmtree(project, ignore_errors=True)
    project.mkdir(parents=True)
    shutil.copytree(packages[0].parent, project / "cartesian_impedance")
    (project / "setup.py").write_text(PREBUILT_SETUP.format(version=cmake_project_version(source)))
    return project


def run(command, cwd, environment):
    shown = ["<EXAMPLE>" if "\n" in str(part) else str(part) for part in command]
    print("+", " ".join(shown), f"(in {cwd})", flush=True)
    subprocess.run([str(part) for part in command], cwd=cwd, env=environment, check=True)


def main():
    arguments = sys.argv[1:]
    build = None
    if len(arguments) == 4 and arguments[2] == "--from-build":
        build = pathlib.Path(arguments[3]).resolve()
        arguments = arguments[:2]
    if len(arguments) != 2:
        sys.exit(__doc__)
    source, work = (pathlib.Path(argument).resolve() for argument in arguments)
    # Nothing of the build tree's or the test's Python path may reach the venv: the module must
    # come from the install.
    environment = {key: value for key, value in os.environ.items()
                   if key not in ("PYTHONPATH", "PYTHONHOME", "CARTESIAN_IMPEDANCE_SOURCE_DIR")}
    environment.update(PYTHONNOUSERSITE="1", PIP_DISABLE_PIP_VERSION_CHECK="1", PIP_NO_INPUT="1")
    # scikit-build's `cmake --build` runs one compiler at a time unless told otherwise; ctest
    # gives this test two processors (PROCESSORS 2), as many as CI's machine has.
    environment.setdefault("CMAKE_BUILD_PARALLEL_LEVEL", "2")

    if build is None:
        copy_sources(source, work / "source")
        installed = work / "source"
    else:
        work.mkdir(parents=True, exist_ok=True)
        installed = stage_prebuilt(source, build, work, environment)
    venv = work / "venv"
    shutil.rmtree(venv, ignore_errors=True)
    run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", venv], work, environment)
    python = venv / "bin" / "python"

    began = time.monotonic()
    run([python, "-m", "pip", "install", "--no-build-isolation", "--no-index", installed], work,
        environment)
    seconds = time.monotonic() - began
    print(f"pip install took {seconds:.0f} s", flush=True)

    elsewhere = work / "elsewhere"
    shutil.rmtree(elsewhere, ignore_errors=True)
    elsewhere.mkdir()
    run([python, "-c", EXAMPLE], elsewhere, environment)
    return 0


if __name__ == "__main__":
    sys.exit(main())
