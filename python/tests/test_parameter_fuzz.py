"""The Python converter of parameter values (python/parameters.cpp) on containers no user means
to give: cyclic, deep, wide, and seeded random nestings of lists, tuples, dicts, numbers, strings,
bools, None and arrays. Every outcome is a value or an error the module documents:
cartesian_impedance.Error (a ValueError) for what is no parameter set, TypeError for a value of
the wrong type. Never a crash: a list that contains itself used to end the interpreter with
SIGSEGV, so those cases run in a child interpreter whose death is a test failure, not the end of
the test run."""

import os
import random
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import cartesian_impedance as ci
from conftest import PANDA_URDF


def run_isolated(code):
    """Runs `code` in a child interpreter with this one's module path; its stdout."""
    result = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                            text=True, timeout=120, env=dict(os.environ))
    assert result.returncode == 0, (
        f"the interpreter ended with {result.returncode} (negative: killed by that signal)\n"
        f"{result.stdout}\n{result.stderr}")
    return result.stdout


def test_cyclic_and_deep_containers_are_errors_naming_the_path():
    output = run_isolated(f"""
        import cartesian_impedance as ci
        def message(make):
            try:
                make()
            except ci.Error as error:
                return str(error)
            return "no error"
        a = []
        a.append(a)
        print(message(lambda: ci.Parameters({{"stiffness": {{"translation": a}}}})))
        d = {{}}
        d["stiffness"] = d
        print(message(lambda: ci.Parameters(d)))
        deep = 0
        for _ in range(20000):
            deep = [deep]
        print(message(lambda: ci.Parameters({{"stiffness.translation": deep}})))
        loop = ci.ControlLoop(ci.RobotModel.from_urdf_file({str(PANDA_URDF)!r}, "panda_link0",
                                                            "panda_link8"))
        print(message(lambda: loop.set_parameters(d)))
        """)
    lines = output.splitlines()
    assert lines[0] == ("'stiffness.translation[0]' is 'stiffness.translation' again: a list or "
                        "map that contains itself has no end; a parameter value is a tree")
    assert lines[1] == ("'stiffness' is the top level again: a list or map that contains itself "
                        "has no end; a parameter value is a tree")
    assert lines[2].startswith("'stiffness.translation[0][0][0]")
    assert "is nested too deeply: more than 32 levels of lists and maps" in lines[2]
    assert lines[3] == lines[1]


def test_a_list_too_long_for_any_parameter_set_is_refused_by_count():
    # The dict, its key, the inner dict, its key and the list are the first five values.
    with pytest.raises(ci.Error, match=r"more than 100000 values \(the next at "
                                       r"'stiffness\.translation\[99995\]'\)"):
        ci.Parameters({"stiffness": {"translation": [0.0] * 10**6}})
    # The same object twice beside itself is no cycle: it is read twice.
    shared = [50.0, 60.0, 70.0]
    p = ci.Parameters({"stiffness": {"translation": shared, "rotation": shared}})
    assert list(p["stiffness.translation"]) == shared == list(p["stiffness.rotation"])


# ---- seeded random containers ----------------------------------------------------------------

NAMES = ["stiffness", "translation", "rotation", "limits", "joint_torque", "damping_ratio",
         "nullspace", "filter", "x", "dynamics", "armature", "stiffness.translation",
         "limits.joint_torque", "nullspace.stiffness"]
LEAVES = [0, 1, -5, 0.5, 500.0, 10**400, float("nan"), float("inf"), True,
          False, None, "base", "end_effector", "", "5", "tool"]


def random_value(rng, depth, pool):
    """A random value; `pool` collects the containers made so far, so that some contain one of
    their ancestors (a cycle) or a sibling (shared, no cycle)."""
    roll = rng.random()
    if depth > 0 and roll < 0.1 and pool:
        return rng.choice(pool)  # an ancestor or a shared container
    if depth > 0 and roll < 0.35:
        items = []
        pool.append(items)
        items.extend(random_value(rng, depth - 1, pool) for _ in range(rng.randrange(0, 5)))
        return tuple(items) if rng.random() < 0.2 else items
    if depth > 0 and roll < 0.6:
        members = {}
        pool.append(members)
        for _ in range(rng.randrange(0, 4)):
            members[rng.choice(NAMES)] = random_value(rng, depth - 1, pool)
        return members
    if roll < 0.65:
        return np.array([rng.random() for _ in range(rng.randrange(1, 8))])
    return rng.choice(LEAVES)


def test_seeded_random_containers_give_a_value_or_a_documented_error():
    rng = random.Random(20240611)
    outcomes = {"value": 0, "Error": 0, "TypeError": 0}
    for case in range(3000):
        pool = []
        tree = {rng.choice(NAMES): random_value(rng, rng.randrange(1, 8), pool)
                for _ in range(rng.randrange(1, 4))}
        # Now and then a member that holds the whole tree, or a chain deeper than any bound.
        if case % 10 == 0:
            tree[rng.choice(NAMES)] = tree
        if case % 97 == 0:
            deep = rng.choice(LEAVES)
            for _ in range(rng.randrange(30, 3000)):
                deep = [deep] if rng.random() < 0.5 else {rng.choice(NAMES): deep}
            tree[rng.choice(NAMES)] = deep
        try:
            parameters = ci.Parameters(tree)
        except ci.Error:
            outcomes["Error"] += 1
            continue
        except TypeError:
            outcomes["TypeError"] += 1
            continue
        outcomes["value"] += 1
        # What is accepted is a valid set that reads back to itself.
        parameters.validate()
        assert ci.Parameters(parameters.to_dict()) == parameters
    # Every kind of outcome happened (the cases reach past the converter into the decoder).
    assert all(count > 0 for count in outcomes.values()), outcomes
