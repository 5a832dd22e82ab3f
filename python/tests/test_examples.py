"""The Python examples run, and print the same table as their C++ twins."""

import os
import subprocess
import sys

import pytest

from conftest import SOURCE_DIR

EXAMPLES = SOURCE_DIR / "examples" / "python"


def run(command):
    result = subprocess.run(command, capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_scripted_motion_prints_the_table():
    output = run([sys.executable, str(EXAMPLES / "scripted_motion.py"), "--quiet"])
    assert "scenario" in output and "10 N push at 500 N/m" in output
    assert "20.00 mm                     20.00 mm" in output


def test_scripted_motion_matches_its_cpp_twin():
    cpp = os.environ.get("CARTESIAN_IMPEDANCE_SCRIPTED_MOTION")
    if not cpp:
        pytest.skip("CARTESIAN_IMPEDANCE_SCRIPTED_MOTION (the C++ example) not given")
    python = run([sys.executable, str(EXAMPLES / "scripted_motion.py")])
    assert python == run([cpp])
