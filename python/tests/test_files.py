"""Files given by name to the module's loaders: a FIFO, /dev/zero or a file beyond the cap of
16 MiB is refused before it is read, with cartesian_impedance.LoadError naming the file and what
it is (core/files.hpp). A FIFO used to hang the interpreter for good, /dev/zero read 2 GB first."""

import os
import subprocess
import sys

import pytest

import cartesian_impedance as ci
from conftest import PANDA_URDF


# Opens the FIFO read-write every 5 s (never blocking, and the writer a blocked reader waits for).
UNBLOCKER = """
import os, sys, time
while True:
    time.sleep(5)
    os.close(os.open(sys.argv[1], os.O_RDWR | os.O_NONBLOCK))
"""


@pytest.fixture
def fifo(tmp_path):
    """A FIFO. Should a loader open it to read, it would wait for a writer forever (holding the
    GIL, so no thread of this interpreter could help): a child process opens it now and then, so
    that such a loader reads an empty file and fails the test instead of hanging."""
    path = tmp_path / "pipe"
    os.mkfifo(path)
    unblocker = subprocess.Popen([sys.executable, "-c", UNBLOCKER, str(path)])
    yield path
    unblocker.kill()
    unblocker.wait()


LOADERS = {
    "Parameters.load": lambda path: ci.Parameters.load(path),
    "load_parameters": lambda path: ci.load_parameters(path),
    "RobotModel.from_urdf_file": lambda path: ci.RobotModel.from_urdf_file(path, "a", "b"),
}
WHAT = {"Parameters.load": "parameter file", "load_parameters": "parameter file",
        "RobotModel.from_urdf_file": "URDF file"}


@pytest.mark.parametrize("loader", sorted(LOADERS))
def test_a_fifo_is_refused_without_waiting(loader, fifo):
    with pytest.raises(ci.LoadError, match=f"^{WHAT[loader]} '{fifo}' is a FIFO "
                                           r"\(named pipe\), not a regular file$"):
        LOADERS[loader](fifo)


@pytest.mark.parametrize("loader", sorted(LOADERS))
def test_dev_zero_is_refused_without_reading(loader):
    with pytest.raises(ci.LoadError, match=f"^{WHAT[loader]} '/dev/zero' is a character device"):
        LOADERS[loader]("/dev/zero")


@pytest.mark.parametrize("loader", sorted(LOADERS))
def test_a_file_beyond_the_cap_is_refused_by_its_size(loader, tmp_path):
    path = tmp_path / "large"
    with open(path, "wb") as handle:
        handle.truncate(16 * 1024 * 1024 + 1)  # sparse
    with pytest.raises(ci.LoadError, match=r"has 16777217 bytes; files of at most 16777216 bytes "
                                           r"\(16 MiB\) are read$"):
        LOADERS[loader](path)


def test_regular_files_still_load():
    assert ci.RobotModel.from_urdf_file(PANDA_URDF, "panda_link0", "panda_link8").num_joints == 7
