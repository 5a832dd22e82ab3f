"""Parameters: every row of the parameter table reachable by its dotted name, dicts (dotted or
nested) and YAML in and out, round trips, and the repr."""

import copy
import math
import pickle

import numpy as np
import pytest

import cartesian_impedance as ci
from conftest import PANDA_YAML


# Rows that bound another row from above (safety.energy_tank.initial <= .capacity; a declared
# payload's weight and moment <= safety.max_force.force and .torque, where those caps are on): a
# value just above their default would be below the other's value, so theirs lies halfway to the
# top of the range.
UPPER_BOUNDS = {"safety.energy_tank.capacity", "safety.max_force.force", "safety.max_force.torque"}


def other_value(row):
    """A valid value different from the row's default, whatever kind the row is, also with every
    other row at its default."""
    default = row["default"]
    if row["kind"] == "frame":
        return "end_effector" if default == "base" else "base"
    if row["kind"] == "switch":
        return not default
    if row["kind"] == "choice":
        return next(name for name in row["range"].split(", ") if name != default)
    if row["name"] in UPPER_BOUNDS:
        return (default + row["max"]) / 2

    low, high = max(row["min"], 0.0), row["max"]

    def number(d, i=0):
        # Halfway from the default to the bottom of the range (or, for a default at the bottom,
        # a little above it): different from the default and valid.
        return (d + low) / 2 if d > low else min(low + 0.25 * (i + 1) * max(low, 1e-3), high)

    if row["kind"] == "number":
        return number(default)
    if row["kind"] == "xyz":
        return [number(d, i) for i, d in enumerate(default)]
    # per joint, 7 joints (an empty default, limits.joint_torque's "the URDF's", as 100 Nm)
    first = default[0] if len(default) else 100.0
    return [number(first, i) for i in range(7)]


def same(a, b):
    return np.array_equal(np.asarray(a), np.asarray(b))


def test_the_table_lists_every_parameter_with_its_default():
    table = ci.parameter_table()
    defaults = ci.Parameters()
    assert [row["name"] for row in table] == defaults.keys() == list(defaults)
    assert len(defaults) == len(table)
    for row in table:
        assert row["name"] in defaults
        assert same(defaults[row["name"]], row["default"]), row["name"]
        assert row["kind"] in ("number", "xyz", "per_joint", "frame", "choice", "switch")
        assert row["description"]
        assert row["name"] in ci.parameter_table_markdown()
    assert ci.Parameters.table() == table
    assert "stiffness.translation" in defaults and "stiffness.tranlation" not in defaults


def test_every_row_can_be_set_read_and_round_tripped():
    table = ci.parameter_table()
    changed = ci.Parameters()
    for row in table:
        value = other_value(row)
        single = ci.Parameters()
        single[row["name"]] = value  # each row on its own, through __setitem__
        assert same(single[row["name"]], value), row["name"]
        assert single != ci.Parameters()
        assert repr(single) == "Parameters({%r: %r})" % (row["name"], single.to_dict()[row["name"]])
        changed[row["name"]] = value
    flat = changed.to_dict()
    for row in table:
        assert same(flat[row["name"]], other_value(row)), row["name"]
    assert ci.Parameters.from_dict(flat) == changed
    assert ci.Parameters(changed.to_dict(nested=True)) == changed
    assert ci.Parameters.from_yaml(changed.to_yaml()) == changed
    assert pickle.loads(pickle.dumps(changed)) == changed
    assert copy.deepcopy(changed) == changed and changed.copy() == changed
    assert eval(repr(changed), {"Parameters": ci.Parameters}) == changed


def test_dotted_nested_and_mixed_dicts_are_the_same():
    dotted = ci.Parameters({"stiffness.translation": [800, 800, 600],
                            "filter.pose.time": 0.1, "wrench.frame": "end_effector"})
    nested = ci.Parameters({"stiffness": {"translation": [800, 800, 600]},
                            "filter": {"pose": {"time": 0.1}}, "wrench": {"frame": "end_effector"}})
    mixed = ci.Parameters({"stiffness": {"translation": [800, 800, 600]},
                           "filter": {"pose.time": 0.1}, "wrench.frame": ci.Frame.end_effector})
    assert dotted == nested == mixed
    assert dotted != ci.Parameters()
    nested_out = dotted.to_dict(nested=True)
    assert nested_out["filter"]["pose"]["time"] == 0.1
    assert nested_out["stiffness"]["translation"] == [800.0, 800.0, 600.0]


def test_values_come_out_as_numpy_arrays_floats_str_and_bool():
    p = ci.Parameters()
    assert isinstance(p["stiffness.translation"], np.ndarray)
    assert p["stiffness.translation"].shape == (3,)
    assert isinstance(p["filter.pose.time"], float)
    assert p["stiffness.frame"] == "base"
    assert p["dynamics.gravity_compensation"] is False
    # One number sets every axis, and per-joint fields keep one value or one per joint.
    p["stiffness.rotation"] = 30
    assert list(p["stiffness.rotation"]) == [30, 30, 30]
    p["nullspace.stiffness"] = np.arange(1, 8)
    assert list(p["nullspace.stiffness"]) == [1, 2, 3, 4, 5, 6, 7]
    p["nullspace.stiffness"] = np.float32(4)
    assert list(p["nullspace.stiffness"]) == [4]


def test_yaml_files_load_and_save(tmp_path):
    panda = ci.Parameters.load(PANDA_YAML)
    assert list(panda["limits.joint_torque"]) == [87, 87, 87, 87, 12, 12, 12]
    assert ci.load_parameters(str(PANDA_YAML)) == panda
    path = tmp_path / "saved.yaml"
    panda.save(path)
    assert ci.Parameters.load(path) == panda
    assert ci.Parameters.from_yaml(path.read_text()) == panda
    assert ci.Parameters.from_yaml("") == ci.Parameters()


def test_repr_shows_only_what_differs_from_the_defaults():
    assert repr(ci.Parameters()) == "Parameters()"
    p = ci.Parameters({"stiffness.translation": 800, "dynamics.gravity_compensation": True})
    assert repr(p) == ("Parameters({'stiffness.translation': [800.0, 800.0, 800.0], "
                       "'dynamics.gravity_compensation': True})")


def test_update_applies_all_or_nothing():
    p = ci.Parameters()
    p.update({"filter": {"pose": {"time": 0.5}}})
    assert p["filter.pose.time"] == 0.5
    with pytest.raises(ci.Error, match=r"stiffness.rotation.y = -1 Nm/rad is outside \[0, 10000\]"):
        p.update({"filter.pose.time": 0.7, "stiffness.rotation": [1, -1, 1]})
    assert p["filter.pose.time"] == 0.5


def test_controller_and_loop_take_parameters_or_dicts(panda):
    controller = ci.CartesianImpedanceController(7, {"stiffness.translation": 700})
    assert list(controller.parameters["stiffness.translation"]) == [700] * 3
    controller.set_parameters(ci.Parameters({"stiffness": {"rotation": 20}}))
    assert list(controller.parameters["stiffness.rotation"]) == [20] * 3
    loop = ci.ControlLoop(panda, {"limits.joint_torque": [87, 87, 87, 87, 12, 12, 12]})
    assert list(loop.latest_parameters()["limits.joint_torque"]) == [87] * 4 + [12] * 3
    assert not math.isnan(loop.latest_parameters()["filter.pose.time"])
