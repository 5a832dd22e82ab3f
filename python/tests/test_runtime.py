"""The runtime from Python (cartesian_impedance.runtime): the control thread stepping a loop from
the measurements a driver publishes, the hand-offs, the simulated driver
(cartesian_impedance.sim.SimulatedDriver), what each claims while it runs, that Python's garbage
collector cannot free what a running C++ thread uses, and the errors for bad input."""

import gc
import math
import threading
import time
import weakref

import numpy as np
import pytest

import cartesian_impedance as ci
import cartesian_impedance.runtime as rt
from conftest import PANDA_READY, PANDA_XML, requires_sim


def wait_until(condition, seconds=10.0):
    """Polls `condition` until it holds or `seconds` of wall-clock time passed (a bound far above
    what it takes on an idle machine, so that a loaded one does not fail the test)."""
    give_up = time.monotonic() + seconds
    while not condition():
        if time.monotonic() > give_up:
            return False
        time.sleep(0.002)
    return True


# ---- the hand-offs ----------------------------------------------------------------------------


def test_measurement_buffer_publishes_the_newest_state_with_its_time():
    buffer = rt.MeasurementBuffer(7)
    assert buffer.num_joints == 7
    first = buffer.read()
    assert first.sequence == 0 and np.array_equal(first.q, np.zeros(7))
    assert first.effort is None
    before = time.monotonic()
    buffer.publish(PANDA_READY, np.full(7, 0.1))
    buffer.publish(PANDA_READY + 0.01, np.zeros(7), effort=np.arange(7.0))
    after = time.monotonic()
    newest = buffer.read()
    assert newest.sequence == 2
    np.testing.assert_array_equal(newest.q, PANDA_READY + 0.01)
    np.testing.assert_array_equal(newest.effort, np.arange(7.0))
    assert before <= newest.received <= after  # time.monotonic()'s clock
    assert newest.sampled == newest.received  # no stamp given
    buffer.publish(PANDA_READY, np.zeros(7), sampled=before - 0.004)  # the driver's stamp
    assert buffer.read().sampled == pytest.approx(before - 0.004, abs=1e-9)
    with pytest.raises(ci.Error, match="sampled"):
        buffer.publish(PANDA_READY, np.zeros(7), sampled=float("nan"))


def test_torque_outbox_waits_until_the_timeout_or_a_wake():
    outbox = rt.TorqueOutbox(3)
    assert outbox.num_joints == 3
    assert outbox.wait(0.0) is None
    start = time.monotonic()
    assert outbox.wait(0.05) is None
    assert time.monotonic() - start >= 0.04
    woken = []
    waiter = threading.Thread(target=lambda: woken.append(outbox.wait(5.0)))
    waiter.start()
    time.sleep(0.05)
    outbox.wake()
    waiter.join(5.0)
    assert woken == [None]


def test_a_wait_releases_the_gil():
    # Another Python thread stamps the time as often as it can: while this thread waits in C++
    # it can only if the wait released the GIL.
    outbox = rt.TorqueOutbox(7)
    stamps, done = [], threading.Event()

    def stamp():
        while not done.is_set():
            stamps.append(time.monotonic())

    stamper = threading.Thread(target=stamp)
    stamper.start()
    begin = time.monotonic()
    assert outbox.wait(0.3) is None
    end = time.monotonic()
    done.set()
    stamper.join()
    assert any(begin + 0.1 < t < end - 0.1 for t in stamps)


@pytest.mark.parametrize("make", [rt.MeasurementBuffer, rt.TorqueOutbox])
@pytest.mark.parametrize("num_joints", [0, -1, ci.MAX_JOINTS + 1])
def test_hand_offs_reject_a_joint_count_out_of_range(make, num_joints):
    with pytest.raises(ci.Error, match=rf"num_joints = {num_joints} is outside \[1, "
                                       rf"{ci.MAX_JOINTS}\]"):
        make(num_joints)


def test_publish_rejects_a_wrong_shape_and_passes_non_finite_values_on():
    buffer = rt.MeasurementBuffer(7)
    with pytest.raises(ValueError, match=r"q must have shape \(7,\), got shape \(6,\)"):
        buffer.publish(np.zeros(6), np.zeros(7))
    with pytest.raises(ValueError, match=r"effort must have shape \(7,\)"):
        buffer.publish(np.zeros(7), np.zeros(7), effort=[1.0])
    assert buffer.read().sequence == 0  # nothing published
    # A measurement that is not finite is what was measured: the cycle fails closed on it.
    buffer.publish(np.full(7, np.nan), np.zeros(7))
    assert buffer.read().sequence == 1 and np.isnan(buffer.read().q).all()


@pytest.mark.parametrize("timeout, text", [(-0.1, "-0.1"), (math.nan, "nan"), (math.inf, "inf"),
                                           (2e6, "2000000")])
def test_wait_rejects_a_timeout_out_of_range(timeout, text):
    with pytest.raises(ci.Error, match=rf"timeout = {text} s is outside \[0, 1000000\]"):
        rt.TorqueOutbox(7).wait(timeout)


# ---- the control thread -----------------------------------------------------------------------


@pytest.mark.parametrize("options, message", [
    ({"rate": 0.0}, r"rate = 0 Hz is outside \[0.001, 1000000\]"),
    ({"rate": math.nan}, r"rate = nan Hz is outside"),
    ({"rate": 2e6}, r"rate = 2000000 Hz is outside"),
    ({"measurement_timeout": 0.0}, r"measurement_timeout = 0 s is outside \(0, 1000000\]"),
    ({"measurement_timeout": math.inf}, r"measurement_timeout = inf s is outside"),
    ({"realtime_priority": -1}, r"realtime_priority = -1 is outside \[0, 99\]"),
    ({"realtime_priority": 100}, r"realtime_priority = 100 is outside \[0, 99\]"),
])
def test_control_thread_rejects_options_out_of_range(options, message):
    with pytest.raises(ci.Error, match=message):
        rt.ControlThread(**options)


def test_control_thread_rejects_hand_offs_of_another_joint_count(panda):
    loop = ci.ControlLoop(panda)
    thread = rt.ControlThread()
    with pytest.raises(ci.Error, match="the measurement buffer has 6 joints, the control loop 7"):
        thread.start(loop, rt.MeasurementBuffer(6))
    with pytest.raises(ci.Error, match="the torque outbox has 6 joints, the control loop 7"):
        thread.start(loop, rt.MeasurementBuffer(7), rt.TorqueOutbox(6))
    with pytest.raises(TypeError):
        thread.start("loop", rt.MeasurementBuffer(7))
    # Nothing was started, nothing stays claimed: the loop is the caller's.
    assert thread.state == rt.ControlThreadState.idle
    assert not loop.started


def test_control_thread_steps_the_loop_from_published_measurements(panda):
    # A driver in Python: it publishes the arm at rest; the C++ thread starts the loop from the
    # first measurement and steps it every millisecond, the torque going to the outbox.
    loop = ci.ControlLoop(panda, {"dynamics.gravity_compensation": True})
    measurements, torques = rt.MeasurementBuffer(7), rt.TorqueOutbox(7)
    with rt.ControlThread(rate=1000.0, measurement_timeout=0.5) as thread:
        thread.start(loop, measurements, torques)
        assert thread.state == rt.ControlThreadState.preparing  # no measurement yet
        measurements.publish(PANDA_READY, np.zeros(7))
        assert wait_until(lambda: thread.running)
        sample = torques.wait(1.0)
        assert sample is not None
        tau, cycle = sample
        assert cycle >= 1
        # At rest at its reference, the loop commands g(q) (the gravity compensation).
        gravity = loop.latest_state().controller.tau_gravity
        np.testing.assert_allclose(tau, gravity, atol=1e-6 * np.abs(gravity).max())
        # The loop's cycle is the thread's meanwhile; its state and commands are anyone's.
        with pytest.raises(RuntimeError, match="this ControlLoop is in use by a "
                                               "runtime.ControlThread in another thread"):
            loop.step(PANDA_READY, np.zeros(7), 0.001)
        with pytest.raises(RuntimeError, match="in use by a runtime.ControlThread"):
            loop.state
        assert "in use by a runtime.ControlThread" in repr(loop)
        loop.set_stiffness([400, 400, 400, 40, 40, 40])
        with pytest.raises(ci.Error, match="already running"):
            thread.start(loop, measurements, torques)
        assert wait_until(lambda: thread.statistics().cycles > 20)
    assert thread.state == rt.ControlThreadState.stopped
    statistics = thread.statistics()
    assert statistics.cycles > 20 and statistics.period_p50_us > 0
    assert loop.state.cycle == statistics.cycles  # the loop is the caller's again
    np.testing.assert_allclose(np.diag(loop.state.controller.commanded.stiffness),
                               [400, 400, 400, 40, 40, 40])


class Publisher:
    """A driver in Python: publishes q (and dq = 0) every millisecond on its own thread."""

    def __init__(self, measurements, q):
        self.measurements, self.q = measurements, np.asarray(q, dtype=float)
        self.done = threading.Event()
        self.thread = threading.Thread(target=self.run)
        self.thread.start()

    def run(self):
        while not self.done.is_set():
            self.measurements.publish(self.q, np.zeros(len(self.q)))
            time.sleep(0.001)

    def stop(self):
        self.done.set()
        self.thread.join()


def test_control_thread_fails_closed_on_stale_and_bad_measurements_and_resumes(panda):
    loop = ci.ControlLoop(panda)
    measurements = rt.MeasurementBuffer(7)
    with rt.ControlThread(measurement_timeout=0.1) as thread:
        # A measurement the loop cannot start from is rejected, and the next one tried.
        measurements.publish(np.full(7, np.nan), np.zeros(7))
        thread.start(loop, measurements)
        assert wait_until(lambda: thread.rejected_starts()[0] == 1)
        count, latest = thread.rejected_starts()
        assert "q[0] = nan is not finite" in latest
        assert thread.state == rt.ControlThreadState.preparing
        publisher = Publisher(measurements, PANDA_READY)
        assert wait_until(lambda: thread.running)
        assert wait_until(lambda: loop.latest_state().controller.status == ci.Status.ok)
        # None for longer than the timeout: stale, the controller fails closed.
        publisher.stop()
        assert wait_until(lambda: thread.statistics().stale)
        assert wait_until(
            lambda: loop.latest_state().controller.status == ci.Status.invalid_robot_state)
        # They return: it resumes.
        publisher = Publisher(measurements, PANDA_READY)
        assert wait_until(lambda: loop.latest_state().controller.status == ci.Status.ok)
        assert not thread.statistics().stale
        publisher.stop()
        # One that is not finite fails the cycle closed at once, before any timeout.
        publisher = Publisher(measurements, np.full(7, np.nan))
        try:
            assert wait_until(
                lambda: loop.latest_state().controller.status == ci.Status.invalid_robot_state)
            assert loop.latest_state().controller.fault.input == "q"
            assert not thread.statistics().stale
        finally:
            publisher.stop()
    assert thread.statistics().stale_episodes >= 1


def test_a_running_thread_keeps_what_it_uses_alive(panda):
    # Start, drop every Python reference to the loop and the hand-offs, collect: the C++ thread
    # still runs on them, and stop() releases them.
    thread = rt.ControlThread()
    loop = ci.ControlLoop(panda)
    measurements, torques = rt.MeasurementBuffer(7), rt.TorqueOutbox(7)
    measurements.publish(PANDA_READY, np.zeros(7))
    thread.start(loop, measurements, torques)
    refs = [weakref.ref(loop), weakref.ref(measurements), weakref.ref(torques)]
    del loop, measurements, torques
    gc.collect()
    assert all(ref() is not None for ref in refs)
    assert wait_until(lambda: thread.running)
    cycles = thread.statistics().cycles
    for _ in range(3):  # garbage that the collector frees meanwhile
        [ci.ControlLoop(panda) for _ in range(2)]
        gc.collect()
    assert wait_until(lambda: thread.statistics().cycles > cycles + 50)
    refs[0]().set_stiffness([300, 300, 300, 30, 30, 30])  # still the thread's loop
    thread.stop()
    gc.collect()
    assert all(ref() is None for ref in refs)
    assert thread.statistics().cycles > cycles + 50


def test_dropping_a_running_thread_stops_it(panda):
    loop = ci.ControlLoop(panda)
    measurements = rt.MeasurementBuffer(7)
    measurements.publish(PANDA_READY, np.zeros(7))
    thread = rt.ControlThread()
    thread.start(loop, measurements)
    assert wait_until(lambda: thread.running)
    del thread
    gc.collect()
    cycle = loop.state.cycle  # released: the caller's again, and it no longer steps
    time.sleep(0.02)
    assert loop.state.cycle == cycle


# ---- the simulated driver ---------------------------------------------------------------------


@requires_sim
def test_simulated_driver_and_control_thread_hold_the_arm(panda):
    robot = ci.sim.Simulation.from_mjcf_file(PANDA_XML, joint_names=panda.joint_names)
    start = robot.body_pose("panda_link8").position
    loop = ci.ControlLoop(panda)
    measurements, torques = rt.MeasurementBuffer(7), rt.TorqueOutbox(7)
    with rt.ControlThread() as thread, \
            ci.sim.SimulatedDriver(robot, measurements, torques,
                                   contact_body="panda_link8") as driver:
        thread.start(loop, measurements, torques)
        driver.start()
        assert driver.running
        # The simulation is the driver's while it runs; its state is readable through it.
        with pytest.raises(RuntimeError, match="this Simulation is in use by a "
                                               "sim.SimulatedDriver in another thread"):
            robot.q
        with pytest.raises(RuntimeError, match="in use by a sim.SimulatedDriver"):
            measurements.publish(PANDA_READY, np.zeros(7))
        with pytest.raises(RuntimeError, match="in use by a sim.SimulatedDriver"):
            torques.wait(0.0)
        with pytest.raises(ci.Error, match="already running"):
            driver.start()
        assert wait_until(lambda: driver.state().time >= 0.3)
        state = driver.state()
        assert not state.held and state.torques > 0 and state.rejected_torques == 0
        assert state.q.shape == (7,) and state.tau.shape == (7,)
        np.testing.assert_array_equal(state.contact_wrench, np.zeros(6))  # in free space
        assert thread.statistics().measurement_age_p50_us > 0.0
    assert not driver.running and thread.state == rt.ControlThreadState.stopped
    # The simulated firmware holds the weight, the spring the pose: the arm stays put.
    assert np.linalg.norm(robot.body_pose("panda_link8").position - start) < 1e-3
    assert driver.statistics().cycles == driver.state().ticks > 0
    assert loop.latest_state().controller.status == ci.Status.ok


@requires_sim
def test_simulated_driver_keeps_what_it_uses_alive(panda):
    measurements, torques = rt.MeasurementBuffer(7), rt.TorqueOutbox(7)
    driver = ci.sim.SimulatedDriver(
        ci.sim.Simulation.from_mjcf_file(PANDA_XML, joint_names=panda.joint_names),
        measurements, torques)
    driver.start()
    refs = [weakref.ref(measurements), weakref.ref(torques)]
    del measurements, torques
    gc.collect()
    assert all(ref() is not None for ref in refs)
    assert wait_until(lambda: driver.state().ticks > 50)
    assert refs[0]().read().sequence > 50  # it publishes while held, before any torque
    driver.stop()
    assert driver.state().held and driver.state().steps == 0
    del driver
    gc.collect()
    assert all(ref() is None for ref in refs)


@requires_sim
def test_simulated_driver_rejects_mismatched_hand_offs_and_options(panda):
    robot = ci.sim.Simulation.from_mjcf_file(PANDA_XML, joint_names=panda.joint_names)
    with pytest.raises(ci.Error, match="the simulation has 7 joints, the measurement buffer 6 and "
                                       "the torque outbox 7"):
        ci.sim.SimulatedDriver(robot, rt.MeasurementBuffer(6), rt.TorqueOutbox(7))
    for timeout in (0.0, -1.0, math.nan):
        with pytest.raises(ci.Error, match=rf"torque_timeout = {timeout:g} s is outside "
                                           rf"\(0, 1000000\]"):
            ci.sim.SimulatedDriver(robot, rt.MeasurementBuffer(7), rt.TorqueOutbox(7),
                                   torque_timeout=timeout)
    with pytest.raises(ci.Error, match="body 'gripper' not found"):
        ci.sim.SimulatedDriver(robot, rt.MeasurementBuffer(7), rt.TorqueOutbox(7),
                               contact_body="gripper")
    driver = ci.sim.SimulatedDriver(robot, rt.MeasurementBuffer(7), rt.TorqueOutbox(7))
    with pytest.raises(ci.Error, match=r"seconds = -1 s is outside \[0, 1000000\]"):
        driver.pause_measurements(-1)
    with pytest.raises(ci.Error, match=r"seconds = inf s is outside"):
        driver.pause_measurements(math.inf)
    robot.q  # nothing claimed it
