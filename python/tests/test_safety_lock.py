"""Parameter changes from Python (issue 40): set_parameters with a dict is a partial update that
changes only what it names, a Parameters object still replaces the whole configuration, and a
running ControlLoop refuses to change a safety setting (safety.*, limits.*, plausibility.*,
payload.*) unless it was made with allow_runtime_safety_changes=True."""

import numpy as np
import pytest

import cartesian_impedance as ci

from conftest import PANDA_YAML


def step(loop, ready, n=2):
    for _ in range(n):
        loop.step(ready, np.zeros(7), 0.001)


@pytest.fixture
def shipped():
    """config/panda.yaml: the caps on (1 m/s, 100 N, walls)."""
    return ci.load_parameters(PANDA_YAML)


def test_a_dict_before_start_changes_only_what_it_names(panda, ready, shipped):
    # The row: landed code read the dict onto the library's defaults and replaced the
    # whole configuration, so the speed cap (1 m/s in config/panda.yaml) fell back to 0 (off).
    loop = ci.ControlLoop(panda, shipped)
    loop.set_parameters({"payload.mass": 1.0})
    loop.start(ready, np.zeros(7))
    p = loop.latest_parameters()
    assert p["payload.mass"] == 1.0
    assert p["safety.max_speed.translation"] == 1.0
    assert p["safety.max_force.force"] == 100.0
    assert list(p["stiffness.translation"]) == [500.0] * 3
    # Everything but the named row is as configured.
    expected = shipped.copy()
    expected["payload.mass"] = 1.0
    changed = {name for name in p if not np.array_equal(np.asarray(p[name]),
                                                        np.asarray(expected[name]))}
    assert changed <= {"limits.joint_torque"}, changed  # filled in from the URDF's efforts


def test_allowed_after_start_a_dict_changes_only_what_it_names(panda, ready, shipped):
    loop = ci.ControlLoop(panda, shipped, allow_runtime_safety_changes=True)
    assert loop.runtime_safety_changes_allowed
    loop.start(ready, np.zeros(7))
    step(loop, ready)
    loop.set_parameters({"payload.mass": 1.0})
    step(loop, ready)
    p = loop.latest_parameters()
    assert p["payload.mass"] == 1.0
    assert p["safety.max_speed.translation"] == 1.0
    assert loop.latest_state().safety_changes == 1
    # And the change acts: the declared payload is compensated (filtered toward 1 kg).
    step(loop, ready, 1000)
    assert loop.state.controller.safety.payload_mass == pytest.approx(1.0, abs=0.05)


def test_a_running_loop_refuses_to_switch_a_cap_off(panda, ready, shipped):
    loop = ci.ControlLoop(panda, shipped)
    assert not loop.runtime_safety_changes_allowed
    loop.start(ready, np.zeros(7))
    step(loop, ready)
    with pytest.raises(ci.Error, match=r"safety settings are locked while the robot runs, and "
                                       r"this would change safety\.max_speed\.translation = 0 m/s "
                                       r"\(in force: 1 m/s\).*allow_runtime_safety_changes"):
        loop.set_parameters({"safety.max_speed.translation": 0.0})
    # Every group, through either call, and a whole Parameters object too.
    for name, value in [("safety.max_force.force", 0.0), ("safety.workspace.stiffness", 0.0),
                        ("safety.energy_tank.enabled", False),
                        ("limits.joint_torque_rate", 1e6), ("plausibility.dt.max", 0.5),
                        ("payload.mass", 2.0)]:
        with pytest.raises(ci.Error, match="locked"):
            loop.update_parameters({name: value})
    off = loop.latest_parameters()
    off["safety.max_force.force"] = 0.0
    with pytest.raises(ci.Error, match=r"safety\.max_force\.force = 0 N \(in force: 100 N\)"):
        loop.set_parameters(off)
    step(loop, ready)
    p = loop.latest_parameters()
    assert p["safety.max_speed.translation"] == 1.0
    assert p["safety.max_force.force"] == 100.0
    assert loop.latest_state().safety_changes == 0
    # What is not a safety setting still changes while it runs.
    loop.set_parameters({"filter.pose.time": 0.4})
    step(loop, ready)
    assert loop.latest_parameters()["filter.pose.time"] == 0.4
    # The owner decides before start, not after.
    with pytest.raises(ci.Error, match=r"after start\(\)"):
        loop.allow_runtime_safety_changes()


def test_a_dict_keeps_a_stiffness_commanded_before_it(panda, ready, shipped):
    # Issue 41 at the Python level: a stiffness commanded and a dict of something else sent
    # before the next step; the dict names only filter.pose.time, so the matrix stays.
    loop = ci.ControlLoop(panda, shipped)
    loop.start(ready, np.zeros(7))
    step(loop, ready)
    full = np.diag([337.0] * 3 + [30.0] * 3)  # within limits.stiffness: not saturated
    full[0, 2] = full[2, 0] = 20.0
    loop.set_stiffness(full)
    loop.set_parameters({"filter.pose.time": 0.3})
    step(loop, ready)
    np.testing.assert_array_equal(loop.state.controller.commanded.stiffness, full)
    assert loop.latest_parameters()["filter.pose.time"] == 0.3
    # A Parameters object is a whole configuration: it re-commands the stiffness it holds.
    whole = loop.latest_parameters()
    whole["filter.pose.time"] = 0.25
    loop.set_parameters(whole)
    step(loop, ready)
    np.testing.assert_array_equal(loop.state.controller.commanded.stiffness,
                                  np.diag([337.0] * 3 + [30.0] * 3))


def test_the_controller_takes_dicts_as_partial_updates(shipped):
    controller = ci.CartesianImpedanceController(7, shipped)
    controller.set_parameters({"filter.pose.time": 0.3})
    assert controller.parameters["filter.pose.time"] == 0.3
    assert controller.parameters["safety.max_speed.translation"] == 1.0
    controller.update_parameters({"stiffness": {"rotation": 20}})
    assert list(controller.parameters["stiffness.rotation"]) == [20.0] * 3
    assert list(controller.parameters["stiffness.translation"]) == [500.0] * 3
    # Validated against the parameters in force: a box whose min passes the max in force.
    with pytest.raises(ci.Error, match=r"safety\.workspace\.min\.x = 1 m is greater than"):
        controller.update_parameters({"safety.workspace.min": [1.0, -0.9, 0.0]})
    with pytest.raises(TypeError, match="dict"):
        controller.update_parameters(shipped)
    with pytest.raises(TypeError):
        controller.set_parameters({"filter.pose.time": "fast"})
    # A Parameters object replaces everything: the caps go back to the library's defaults (off).
    controller.set_parameters(ci.Parameters({"filter.pose.time": 0.3}))
    assert controller.parameters["safety.max_speed.translation"] == 0.0


def test_a_payload_must_fit_under_the_force_cap(panda, ready, shipped):
    # consistency_fault(): 20 kg weigh 196 N, beyond the 100 N cap in force.
    loop = ci.ControlLoop(panda, shipped, allow_runtime_safety_changes=True)
    loop.start(ready, np.zeros(7))
    with pytest.raises(ci.Error, match="payload"):
        loop.set_parameters({"payload.mass": 20.0})
    step(loop, ready)
    assert loop.latest_parameters()["payload.mass"] == 0.0


def test_the_state_reports_the_safety_layer_in_force(panda, ready, shipped):
    loop = ci.ControlLoop(panda, shipped)
    loop.start(ready, np.zeros(7))
    step(loop, ready)
    state = loop.latest_state()
    assert state.updates_refused == 0 and state.safety_changes == 0
    safety = state.controller.safety
    assert safety.pose_error_in_force.translation == shipped["limits.pose_error.translation"]
    assert safety.pose_error_in_force.rotation == shipped["limits.pose_error.rotation"]
    np.testing.assert_array_equal(safety.workspace_in_force.min, shipped["safety.workspace.min"])
    np.testing.assert_array_equal(safety.workspace_in_force.max, shipped["safety.workspace.max"])
    assert safety.workspace_in_force.stiffness == shipped["safety.workspace.stiffness"]
    assert safety.nullspace_scale == 1.0
    assert not safety.settings_held and not safety.joint_limit_wall
    assert not safety.static_wrench_unexplained and not safety.payload_mismatch
    assert "Workspace(min=[" in repr(safety.workspace_in_force)
