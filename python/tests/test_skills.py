"""cartesian_impedance.skills: the insertion skill on PegInsertion-v0 (its spiral search finds a
hole whose observed position is off where a straight descent jams), and a short run of the CEM
example on a Dask LocalCluster of two workers."""

import json
import subprocess
import sys

import pytest

import cartesian_impedance as ci
from conftest import SOURCE_DIR, requires_sim

pytestmark = requires_sim

if hasattr(ci, "sim"):
    from cartesian_impedance.skills import InsertionSkill, insertion_rollout

EXAMPLE = SOURCE_DIR / "examples" / "python" / "peg_insertion_cem.py"
NOISY = {"goal_noise": 0.001}


def test_the_skill_is_a_vector_of_named_parameters():
    skill = InsertionSkill(radius=0.002)
    assert InsertionSkill.from_vector(skill.vector()) == skill
    with pytest.raises(ValueError, match="takes 8 values .*approach, speed.*got 3"):
        InsertionSkill.from_vector([1.0, 2.0, 3.0])
    # A Gaussian sample outside where a parameter means something is clipped, not refused.
    assert InsertionSkill.from_vector([-1.0] * 8).radius == 0.0


# The starting guess of the example (straight down, no search) and a hand-tuned spiral search
# (1.5 mm after 2 turns of 1 s, pressing 2 mm below the opening at 2000 N/m across and 575 N/m
# along the axis): 50 of 50 held-out seeds (2^31 + k) with goal_noise 1 mm.
STRAIGHT = [0.005, 0.3, 0.004, 0.0, 3.0, 1.0, 0.5, 0.5]
SPIRAL = [0.003, 0.3, 0.002, 0.0015, 2.0, 1.0, 1.0, -0.5]


def test_the_spiral_search_finds_the_hole_the_straight_descent_misses():
    # The observed hole is off by up to 1 mm in x and y (the clearance is 0.5 mm a side).
    straight = [insertion_rollout(STRAIGHT, seed, NOISY) for seed in range(5)]
    spiral = [insertion_rollout(SPIRAL, seed, NOISY) for seed in range(5)]
    assert sum(r["success"] for r in straight) <= 1  # measured: 0 of 5
    assert all(r["success"] == 1.0 for r in spiral)
    assert all(r["score"] > 5 for r in spiral) and all(r["score"] < 0 for r in straight
                                                       if not r["success"])
    # Several episodes per rollout: their mean, on the seeds the rollout's seed spawns.
    both = insertion_rollout(SPIRAL, 7, NOISY, episodes=2)
    assert both["success"] == 1.0 and both["steps"] < 100


@pytest.mark.parametrize("robot", ["iiwa14", "ur5e"])
def test_the_skill_inserts_on_the_other_shipped_arms(robot):
    # The same skill on arms of other kinematics, masses and friction (MuJoCo), with the hole
    # where it is observed: measured 10 of 10 seeds each (2^31 + k); the hand-tuned spiral with
    # the observation 1 mm off: 9 of 10 on each (DART: 6 of 10).
    results = [insertion_rollout(STRAIGHT, 2**31 + k, {"robot": robot}) for k in range(3)]
    assert all(r["success"] == 1.0 for r in results), results


def test_a_short_run_of_the_cem_example(tmp_path):
    pytest.importorskip("distributed", reason="the example's Pool needs dask.distributed "
                        "(Debian: python3-distributed)")
    pytest.importorskip("matplotlib", reason="the example plots with matplotlib")
    figures_path, plot_path = tmp_path / "figures.json", tmp_path / "curve.png"
    # 3 iterations of 8 samples, two episodes each, then 10 held-out seeds for the start and
    # the final mean: 68 episodes on a LocalCluster of 2 workers (10 s on the loaded 2-core VM).
    result = subprocess.run(
        [sys.executable, str(EXAMPLE), "--iterations", "3", "--population", "8",
         "--episodes", "2", "--evaluation-seeds", "10", "--json", str(figures_path),
         "--plot", str(plot_path)], capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode == 0, result.stderr
    assert "iteration 3: population success" in result.stdout
    figures = json.loads(figures_path.read_text())
    assert [row["iteration"] for row in figures["iterations"]] == [1, 2, 3]
    assert all(0.0 <= row["population_success"] <= 1.0 for row in figures["iterations"])
    assert sorted(figures["final_mean"]) == sorted(InsertionSkill.NAMES)
    # The run is deterministic (cem's seed, each rollout's seed): measured 0.60 at the start
    # and 0.70 after three iterations (one held-out seed more; the full run in python/README.md
    # goes from 0.48 to 0.94 on 100 seeds in 12 iterations of 32 samples).
    assert figures["final_success"] > figures["start_success"]
    assert plot_path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
