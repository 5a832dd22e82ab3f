"""Failing closed through Python: a bad measurement or time step gives a status and a named fault,
and the torque ramps toward zero within the rate limit; the next good cycle resumes."""

import math

import numpy as np
import pytest

import cartesian_impedance as ci

from conftest import PANDA_XML, requires_sim

RATE = 1000.0  # [Nm/s], the default limits.joint_torque_rate


def pulling_loop(panda, ready, **options):
    """A loop pulling toward a reference 5 cm away, so that the joints carry torque."""
    loop = ci.ControlLoop(panda, **options)
    loop.start(ready, np.zeros(7))
    pose = loop.state.controller.pose
    loop.set_reference_pose((pose.position + [0.05, 0, -0.03], pose.orientation))
    for _ in range(30):
        loop.step(ready, np.zeros(7), 0.001)
    assert np.abs(loop.state.controller.tau).max() > 1.0
    return loop


@pytest.fixture
def pulling(panda, ready):
    return pulling_loop(panda, ready)


def expect_ramped_toward_zero(before, after, dt=0.001):
    step = RATE * dt
    expected = np.where(np.abs(before) <= step, 0.0, before - np.sign(before) * step)
    np.testing.assert_allclose(after, expected, atol=1e-12)


@pytest.mark.parametrize("bad, index", [(np.nan, 4), (math.inf, 4), (1e300, 4), (10.5, 4)])
def test_a_bad_joint_velocity_with_a_good_position_fails_closed(pulling, ready, bad, index):
    before = pulling.state.controller.tau.copy()
    dq = np.zeros(7)
    dq[index] = bad
    q = ready.copy()
    q[1] += 0.3
    tau = pulling.step(q, dq, 0.001)
    state = pulling.state.controller
    assert state.status == ci.Status.invalid_robot_state
    assert state.fault.input == "dq" and state.fault.index == index
    assert str(state.fault).startswith("dq[4] = ")
    expect_ramped_toward_zero(before, tau)
    pulling.step(ready, np.zeros(7), 0.001)
    assert pulling.state.controller.status == ci.Status.ok
    assert not pulling.state.controller.fault


@pytest.mark.parametrize("dt", [1e9, 0.05, 1e-300, 0.0, -1.0, math.nan])
def test_an_implausible_time_step_fails_closed_at_the_last_valid_rate(pulling, ready, dt):
    before = pulling.state.controller.tau.copy()
    tau = pulling.step(ready, np.zeros(7), dt)
    state = pulling.state.controller
    assert state.status == ci.Status.invalid_dt
    assert state.fault.input == "dt"
    expect_ramped_toward_zero(before, tau)


def test_the_fault_names_the_bound_it_broke(pulling, ready):
    pulling.step(ready, np.zeros(7), 1e9)
    fault = pulling.state.controller.fault
    assert fault.bound == 0.02
    assert str(fault) == "dt = 1000000000 is above plausibility.dt.max = 0.02"


def test_a_lowered_torque_limit_ramps_down_within_the_rate(panda, ready):
    # limits.* are safety settings, locked once a loop runs unless its owner allowed changes.
    pulling = pulling_loop(panda, ready, allow_runtime_safety_changes=True)
    before = pulling.state.controller.tau.copy()
    parameters = pulling.latest_parameters()
    parameters["limits.joint_torque"] = 0.5
    pulling.set_parameters(parameters)
    previous = before
    for k in range(int(np.abs(before).max() / (RATE * 0.001)) + 5):
        tau = pulling.step(ready, np.zeros(7), 0.001)
        state = pulling.state.controller
        assert np.all(np.abs(tau - previous) <= RATE * 0.001 + 1e-12)
        assert np.all(np.abs(tau) <= state.joint_torque_limit + 1e-12)
        previous = tau.copy()
    assert np.abs(tau).max() <= 0.5 + 1e-12
    assert not pulling.state.controller.limits.joint_torque_limit_ramping


@requires_sim
def test_the_simulation_reports_the_armature_the_controller_needs():
    sim = ci.sim.Simulation.from_mjcf_file(PANDA_XML)
    np.testing.assert_array_equal(sim.armature, [0.1, 0.1, 0.1, 0.1, 0.04, 0.04, 0.04])
    assert np.all(sim.friction_loss > 0)


def test_a_full_inbox_is_a_queue_full_not_a_bad_argument(panda):
    loop = ci.ControlLoop(panda, command_capacity=2)
    loop.set_nullspace_damping_ratio(0.5)
    loop.set_nullspace_damping_ratio(0.5)
    with pytest.raises(ci.QueueFull, match="inbox is full"):
        loop.set_nullspace_damping_ratio(0.5)
    assert not issubclass(ci.QueueFull, ValueError)
    with pytest.raises(ci.Error):
        loop.set_nullspace_damping_ratio(-1.0)
