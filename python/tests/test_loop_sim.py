"""ControlLoop in closed loop with the MuJoCo simulation: compliance, trajectories, the
GIL-released run(), states as NumPy arrays."""

import threading
import time

import numpy as np
import pytest

import cartesian_impedance as ci
from conftest import PANDA_XML, SOURCE_DIR, requires_sim

pytestmark = requires_sim


def panda_sim(**options):
    return ci.sim.Simulation.from_mjcf_file(PANDA_XML, **options)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_push_on_the_flange_displaces_it_by_force_over_stiffness(panda, axis):
    # 10 N against 500 N/m: 20 mm. The simulation compensates gravity itself (like the robot's
    # firmware), so the controller's own gravity compensation stays off.
    sim = panda_sim()
    loop = ci.ControlLoop(panda, {"stiffness.translation": 500})
    loop.start(sim.q, sim.dq)
    start = sim.site_pose("flange").position
    force = np.zeros(6)
    force[axis] = 10.0
    sim.push("flange", force)
    steps = sim.run(loop, 3.0)
    assert steps == 3000 and sim.time == pytest.approx(3.0)
    displacement = sim.site_pose("flange").position - start
    assert displacement[axis] == pytest.approx(10.0 / 500.0, rel=0.05)
    others = np.delete(displacement, axis)
    assert np.all(np.abs(others) < 0.05 * 0.02)
    state = loop.state
    assert state.controller.status == ci.Status.ok
    # The spring balances the push: K e = F along the axis (its force -K e opposes F).
    assert 500 * state.controller.pose_error[axis] == pytest.approx(10.0, rel=0.05)


def test_trajectory_finishes_and_reaches_its_goal(panda):
    sim = panda_sim()
    loop = ci.ControlLoop(panda)
    loop.start(sim.q, sim.dq)
    goal = sim.q + np.array([0.3, -0.2, 0.2, 0.3, 0.2, -0.2, 0.3])
    via = (sim.q + goal) / 2 + 0.05
    trajectory_id = loop.execute_trajectory([1.0, 2.0], np.stack([via, goal]))
    steps = sim.run(loop, 5.0, until_trajectory_done=True)
    progress = loop.state.trajectory
    assert progress.id == trajectory_id
    assert progress.state == ci.TrajectoryState.finished, progress
    assert 2000 <= steps < 5000
    tolerance = loop.latest_parameters()["trajectory.goal_tolerance"]
    assert progress.goal_error <= tolerance
    assert "finished" in repr(loop)
    sim.run(loop, 1.0)  # holds at the goal afterwards
    assert np.abs(sim.q - goal).max() < tolerance


def test_trajectory_with_named_joints_in_another_order_and_velocities(panda):
    sim = panda_sim()
    loop = ci.ControlLoop(panda)
    loop.start(sim.q, sim.dq)
    names = panda.joint_names[::-1]
    goal = sim.q + 0.1
    positions = [list(goal[::-1])]  # a list of lists works as well as an array
    loop.execute_trajectory([1.5], positions, velocities=[[0.0] * 7], joint_names=names)
    sim.run(loop, 4.0, until_trajectory_done=True)
    assert loop.state.trajectory.state == ci.TrajectoryState.finished
    loop.execute_trajectory([3.0], [goal + 0.1])
    sim.run(loop, 0.5)
    loop.cancel_trajectory()
    sim.run(loop, 0.01)
    assert loop.latest_state().trajectory.state == ci.TrajectoryState.cancelled


def test_run_is_the_same_as_stepping_from_python(panda):
    results = []
    for use_run in (True, False):
        sim = panda_sim()
        loop = ci.ControlLoop(panda)
        loop.start(sim.q, sim.dq)
        loop.set_reference_pose((loop.state.controller.pose.position + [0, 0.05, 0],
                                 loop.state.controller.pose.orientation))
        if use_run:
            sim.run(loop, 0.5)
        else:
            for _ in range(500):
                sim.set_torque(loop.step(sim.q, sim.dq, sim.timestep))
                sim.step()
        results.append((sim.q, loop.state.controller.tau))
    np.testing.assert_array_equal(results[0][0], results[1][0])
    np.testing.assert_array_equal(results[0][1], results[1][1])


def test_run_releases_the_gil_and_guards_the_simulation(panda):
    sim = panda_sim()
    loop = ci.ControlLoop(panda)
    loop.start(sim.q, sim.dq)
    seconds = 30.0
    thread = threading.Thread(target=sim.run, args=(loop, seconds))
    seen_cycles, refusals = [], []
    thread.start()
    while thread.is_alive():
        cycle = loop.latest_state().cycle  # any thread may read the published state
        seen_cycles.append(cycle)
        if 0 < cycle and not refusals:
            for use in (lambda: sim.q, lambda: loop.step(sim.q, sim.dq, 0.001), lambda: loop.state):
                try:
                    use()
                except RuntimeError as error:
                    refusals.append(str(error))
            loop.set_stiffness([400, 400, 400, 40, 40, 40])  # commands are fine from any thread
        time.sleep(0.001)
    thread.join()
    final = int(round(seconds / sim.timestep))
    # Python ran here while run() stepped in the other thread: the GIL was released.
    assert any(0 < cycle < final for cycle in seen_cycles)
    assert refusals and all("in use by Simulation.run() or BatchRunner.run() in another thread" in r for r in refusals)
    assert loop.state.cycle == final
    np.testing.assert_allclose(np.diag(loop.state.controller.commanded.stiffness),
                               [400, 400, 400, 40, 40, 40])


def test_states_are_python_objects_with_numpy_arrays(panda, ready):
    loop = ci.ControlLoop(panda)
    assert "not started" in repr(loop) and not loop.started
    loop.start(ready, np.zeros(7))
    tau = loop.step(ready, np.zeros(7), 0.001)
    assert isinstance(tau, np.ndarray) and tau.shape == (7,) and tau.dtype == np.float64
    state = loop.latest_state()
    assert state.cycle == 1 and state.time == pytest.approx(0.001)
    assert state.q.shape == (7,) and state.dq.shape == (7,)
    controller = state.controller
    assert controller.status == ci.Status.ok
    assert controller.pose_error.shape == (6,)
    assert controller.filtered.stiffness.shape == (6, 6)
    assert controller.stiffness_base().shape == (6, 6)
    assert controller.damping_base().shape == (6, 6)
    np.testing.assert_array_equal(controller.tau, tau)
    np.testing.assert_allclose(controller.pose.position, panda.compute_pose(ready).position)
    assert isinstance(controller.limits.torque_rate_limited, bool)
    assert "ActiveLimits(" in repr(controller.limits)
    assert controller.stiffness_frame == ci.Frame.base
    assert "7 joints" in repr(loop) and "started" in repr(loop) and "idle" in repr(loop)
    assert loop.model is panda and loop.num_joints == 7 and loop.started
    # The returned torque is a copy: the next step does not change it.
    before = tau.copy()
    loop.step(ready + 0.01, np.zeros(7), 0.001)
    np.testing.assert_array_equal(tau, before)


def test_table_scene_reports_the_contact_force():
    # A table 4 cm below the flange; a 20 N downward push lowers the gravity-compensated arm on it.
    sim = ci.sim.Simulation.from_mjcf_file(PANDA_XML)
    top = sim.site_pose("flange").position[2] - 0.04
    table = ci.sim.Box.table([0.3, 0.0], [0.2, 0.2], top, name="table")
    assert table.name == "table" and table.center[2] == pytest.approx(top / 2)
    scene = ci.sim.make_scene(PANDA_XML, [table])
    scene.push("flange", [0, 0, -20, 0, 0, 0])
    scene.step(3000)
    wrench = scene.contact_wrench("panda_link8")
    assert wrench[2] == pytest.approx(20.0, rel=0.05)
    assert "panda" in repr(scene) and scene.num_joints == 7


def test_render_png(tmp_path):
    available, reason = ci.sim.offscreen_rendering_available()
    if not available:
        pytest.skip("offscreen rendering unavailable: " + reason)
    path = tmp_path / "panda.png"
    panda_sim().render_png(path, 64, 48)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_start_configuration_and_armature_of_a_urdf_robot():
    # The UR5e ships as a URDF only; it is singular at q = 0 and starts where it is asked to.
    urdf = SOURCE_DIR / "models" / "ur5e" / "ur5e.urdf"
    start = [np.pi, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0]
    sim = ci.sim.Simulation.from_urdf_file(urdf, start_q=start, armature=0.25)
    np.testing.assert_array_equal(sim.q, start)
    np.testing.assert_array_equal(sim.armature, np.full(6, 0.25))
    sim.step(100)  # gravity compensated, no torque: the arm stays (joint damping only)
    sim.reset()
    np.testing.assert_array_equal(sim.q, start)
    # Without them: q = 0 and the import's default rotor inertia.
    plain = ci.sim.Simulation.from_urdf_file(urdf)
    np.testing.assert_array_equal(plain.q, np.zeros(6))
    np.testing.assert_array_equal(plain.armature, np.full(6, 0.1))


def test_a_urdf_robot_with_its_model_starts_where_the_library_chooses():
    # The UR5e's URDF has no start and q = 0 is singular; given the controller's model, the
    # simulation starts (and resets) at the chosen, well-conditioned start.
    urdf = SOURCE_DIR / "models" / "ur5e" / "ur5e.urdf"
    model = ci.RobotModel.from_urdf_file(urdf, "base_link", "tool0")
    choice = ci.find_start_configuration(model)
    assert choice["smallest_singular_value"] >= 0.02 and choice["limit_distance"] >= 0.1
    assert choice["description"].startswith("smallest singular value ")
    # Deterministic: the same start every time.
    np.testing.assert_array_equal(ci.find_start_configuration(model)["q"], choice["q"])
    jacobian = model.compute(choice["q"], dynamics=False).jacobian
    assert np.linalg.svd(jacobian, compute_uv=False)[-1] == pytest.approx(
        choice["smallest_singular_value"], rel=1e-9)
    assert np.linalg.svd(model.compute(np.zeros(6), dynamics=False).jacobian,
                         compute_uv=False)[-1] < 1e-9
    sim = ci.sim.Simulation.from_urdf_file(urdf, model=model)
    assert sim.joint_names == model.joint_names
    np.testing.assert_array_equal(sim.q, choice["q"])
    sim.step(10)
    sim.reset()
    np.testing.assert_array_equal(sim.q, choice["q"])
    # A start given wins over the chosen one.
    start = [np.pi, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0]
    np.testing.assert_array_equal(
        ci.sim.Simulation.from_urdf_file(urdf, model=model, start_q=start).q, start)
    with pytest.raises(ci.Error, match=r"StartSearch::samples = 0 must be >= 1"):
        ci.find_start_configuration(model, samples=0)
    with pytest.raises(ci.Error, match=r"best smallest singular value found"):
        ci.find_start_configuration(model, singular_threshold=100.0)


def test_start_configuration_outside_a_joint_range_names_the_joint():
    with pytest.raises(ci.Error, match=r"start_q\[3\] = 0 for joint 'panda_joint4' is outside"):
        ci.sim.Simulation.from_mjcf_file(PANDA_XML, start_q=np.zeros(7))
    with pytest.raises(ValueError, match=r"start_q must have shape"):
        ci.sim.Simulation.from_mjcf_file(PANDA_XML, start_q=[[0.0]])
