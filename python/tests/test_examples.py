"""The Python examples run, and print the same table as their C++ twins."""

import json
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


def test_a_short_run_of_the_ppo_example(tmp_path):
    pytest.importorskip("torch", reason="the example's policy is a PyTorch MLP (Debian: "
                        "python3-torch)")
    pytest.importorskip("matplotlib", reason="the example plots with matplotlib")
    figures_path, plot_path = tmp_path / "figures.json", tmp_path / "curve.png"
    # 25 iterations of 4 x 128 steps (12,800 environment steps, about 10 s): too short to reach
    # the goals (the full run in python/README.md: 5 % -> 100 % success in 154k steps), long
    # enough that the policy's first move on held-out seeds turns toward the goal. Deterministic
    # for the seed: measured cosine -0.29 before, 0.37 after. A controller that did not move the
    # arm gives the policy nothing to learn from; a reward of the wrong sign turns it away.
    output = run([sys.executable, str(EXAMPLES / "reach_ppo.py"), "--iterations", "25",
                  "--envs", "4", "--held-out", "10", "--json", str(figures_path),
                  "--plot", str(plot_path)])
    assert "iteration  25:  12800 env steps" in output
    figures = json.loads(figures_path.read_text())
    assert [row["iteration"] for row in figures["curve"]] == list(range(1, 26))
    before, after = figures["before"]["direction_cosine"], figures["after"]["direction_cosine"]
    assert after > 0.2 and after > before + 0.3, (before, after)
    assert plot_path.stat().st_size > 10000
