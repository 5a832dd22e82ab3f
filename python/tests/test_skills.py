"""cartesian_impedance.skills: the insertion skill on PegInsertion-v0 (its spiral search finds a
hole whose observed position is off where a straight descent jams), and a short run of the CEM
example on a Dask LocalCluster of two workers."""

import json
import subprocess
import sys

import numpy as np
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
