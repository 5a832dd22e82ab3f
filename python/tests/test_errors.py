"""Every bad-input path: wrong types (TypeError), wrong shapes (ValueError), values the library
rejects (cartesian_impedance.Error, a ValueError, with the library's message), bad files; and
nothing changes when a call is rejected."""

import math
import re

import numpy as np
import pytest

import cartesian_impedance as ci
from conftest import PANDA_URDF, PANDA_XML, requires_sim


@pytest.fixture
def loop(panda, ready):
    loop = ci.ControlLoop(panda)
    loop.start(ready, np.zeros(7))
    return loop


def test_error_is_a_value_error_with_the_library_message():
    assert issubclass(ci.Error, ValueError)
    with pytest.raises(ValueError,
                       match=r"^stiffness\.translation\.x = -5 N/m is outside \[0, 100000\]$"):
        ci.Parameters({"stiffness.translation": [-5, 1, 1]})


# ---- arrays: types and shapes ------------------------------------------------------------------

BAD_TYPES = [
    (np.ones(7, dtype=complex), "dtype complex128"),
    (np.array([object()] * 7), "dtype object"),
    (np.array(["1"] * 7), "dtype <U1"),
    (np.ones(7, dtype=bool), "dtype bool"),
    ([True] * 7, "dtype bool"),
    ("1234567", "got str"),
    (None, "got NoneType"),
]


@pytest.mark.parametrize("value, text", BAD_TYPES)
def test_step_rejects_non_real_arrays_with_a_type_error(loop, ready, value, text):
    with pytest.raises(TypeError, match="q must be real numbers") as error:
        loop.step(value, np.zeros(7), 0.001)
    assert text in str(error.value)
    with pytest.raises(TypeError, match="dq must be real numbers"):
        loop.step(ready, value, 0.001)


@pytest.mark.parametrize("value, got", [
    (np.zeros(6), "shape (6,)"),
    (np.zeros((7, 1)), "shape (7, 1)"),
    (np.zeros((1, 7)), "shape (1, 7)"),
    (np.float64(1.0), "shape ()"),
    ([0.0] * 8, "length 8"),
    ([], "length 0"),
])
def test_step_rejects_wrong_shapes_naming_the_argument(loop, value, got):
    with pytest.raises(ValueError, match=r"q must have shape \(7,\), got " + got.replace("(", r"\(")
                       .replace(")", r"\)")):
        loop.step(value, np.zeros(7), 0.001)


def test_ragged_lists_are_a_value_error(loop):
    with pytest.raises(ValueError, match="q cannot be read as an array of numbers"):
        loop.step([[0.0], [0.0, 1.0]], np.zeros(7), 0.001)


def test_any_real_dtype_and_layout_is_converted(panda, ready):
    results = []
    q_int = np.zeros(7, dtype=np.int32)
    for q in (np.zeros(7), q_int, np.zeros(7, dtype=np.float32), np.zeros(14)[::2], [0] * 7,
              tuple([0.0] * 7), [np.float32(0)] * 7, np.zeros(7, dtype=">f8")):
        loop = ci.ControlLoop(panda)
        loop.start(ready, np.zeros(7))
        loop.set_nullspace_target(ready + q)
        loop.step(ready, q, 0.001)
        results.append(loop.step(ready, q, 0.001))
    for result in results[1:]:
        np.testing.assert_array_equal(result, results[0])


def test_dt_must_be_a_number(loop, ready):
    with pytest.raises(TypeError, match="dt must be a real number, got bool"):
        loop.step(ready, np.zeros(7), True)
    with pytest.raises(TypeError, match="dt must be real numbers, got str"):
        loop.step(ready, np.zeros(7), "0.001")
    with pytest.raises(ValueError, match=r"dt must be a single number, got shape \(2,\)"):
        loop.step(ready, np.zeros(7), np.ones(2))
    loop.step(ready, np.zeros(7), np.float32(0.001))  # NumPy scalars are numbers


# ---- NaN -------------------------------------------------------------------------------------


def test_non_finite_measurements_give_a_status_and_a_finite_torque_not_an_exception(loop, ready):
    # Like the C++ cycle: a bad measurement must never stop a control loop with an exception.
    for _ in range(10):
        loop.step(ready, np.zeros(7), 0.001)
    q = ready.copy()
    q[3] = np.nan
    tau = loop.step(q, np.zeros(7), 0.001)
    assert loop.state.controller.status == ci.Status.invalid_robot_state
    assert np.all(np.isfinite(tau))
    tau = loop.step(ready, np.zeros(7), math.inf)
    assert loop.state.controller.status == ci.Status.invalid_dt
    assert np.all(np.isfinite(tau))


def test_non_finite_commands_raise_naming_the_field(loop, ready):
    with pytest.raises(ci.Error, match=r"wrench.force.y = nan N is not finite"):
        loop.set_wrench([0, np.nan, 0, 0, 0, 0])
    with pytest.raises(ci.Error, match=r"q\[1\] = inf"):
        loop.start(np.where(np.arange(7) == 1, np.inf, ready), np.zeros(7))
    with pytest.raises(ci.Error, match="position"):
        loop.set_reference_pose(([0.3, np.nan, 0.5], [1, 0, 0, 0]))
    with pytest.raises(ci.Error, match=r"filter.pose.time = nan s is not finite"):
        ci.Parameters({"filter.pose.time": float("nan")})


def test_model_compute_rejects_non_finite_joints(panda, ready):
    q = ready.copy()
    q[2] = np.nan
    with pytest.raises(ci.Error, match=r"q\[2\] = nan is not finite"):
        panda.compute(q)
    with pytest.raises(ci.Error, match=r"dq\[0\] = inf is not finite"):
        panda.compute(ready, np.where(np.arange(7) == 0, np.inf, 0.0))
    with pytest.raises(ValueError, match=r"q must have shape \(7,\), got shape \(3,\)"):
        panda.compute_pose(np.zeros(3))


# ---- poses and quaternions -------------------------------------------------------------------


def test_unnormalised_quaternions_are_rejected(loop):
    with pytest.raises(ci.Error, match=r"\(x, y, z, w\) = \(0, 0, 0, 2\) has norm 2; a unit "
                                       r"quaternion is required \(within 0.001\)"):
        loop.set_reference_pose(([0.3, 0, 0.5], [0, 0, 0, 2]))
    with pytest.raises(ci.Error, match="has norm 0"):
        loop.set_reference_pose(ci.Pose([0.3, 0, 0.5], [0, 0, 0, 0]))
    # Rounded to a few digits is fine.
    loop.set_reference_pose(([0.3, 0, 0.5], [1, 0, 0, 0.0004]))


def test_bad_poses_and_transforms(loop):
    scaled = np.diag([2.0, 1.0, 1.0, 1.0])
    with pytest.raises(ci.Error, match=r"rotation part of the 4x4 transform is not a rotation"):
        loop.set_reference_pose(scaled)
    mirrored = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(ci.Error, match=r"det R = -1"):
        loop.set_reference_pose(mirrored)
    bottom = np.eye(4)
    bottom[3, 0] = 1.0
    with pytest.raises(ci.Error, match=r"last row .* must be \[0, 0, 0, 1\], got \[1, 0, 0, 1\]"):
        ci.Pose.from_matrix(bottom)
    with pytest.raises(ValueError, match=r"4x4 homogeneous transform, got shape \(3, 3\)"):
        loop.set_reference_pose(np.eye(3))
    with pytest.raises(TypeError, match=r"pose must be a Pose.*got int"):
        loop.set_reference_pose(3)
    with pytest.raises(ValueError, match=r"pose quaternion \(x, y, z, w\) must have shape \(4,\)"):
        loop.set_reference_pose(([0, 0, 0], [0, 0, 1]))
    with pytest.raises(ValueError, match=r"pose position must have shape \(3,\)"):
        loop.set_reference_pose(([0, 0], [0, 0, 0, 1]))
    with pytest.raises(ValueError, match=r"orientation \(x, y, z, w\) must have shape \(4,\)"):
        ci.Pose([0, 0, 0], [1, 0, 0])


# ---- commands ---------------------------------------------------------------------------------


def test_rejected_commands_change_nothing(loop, ready):
    loop.step(ready, np.zeros(7), 0.001)
    before = loop.state.controller.commanded.stiffness
    with pytest.raises(ci.Error, match=r"stiffness.translation.x = -5 N/m is outside \[0, 100000\]"):
        loop.set_stiffness([-5, 500, 500, 50, 50, 50])
    with pytest.raises(ValueError,
                       match=r"stiffness must have shape \(6,\) or \(6, 6\), got length 5"):
        loop.set_stiffness([500] * 5)
    with pytest.raises(ValueError, match=r"stiffness must have shape \(6, 6\), got shape \(3, 3\)"):
        loop.set_stiffness(np.eye(3))
    with pytest.raises(ci.Error, match="frame = 'world' is not a frame"):
        loop.set_stiffness([500] * 6, frame="world")
    with pytest.raises(TypeError, match="frame must be 'base', 'end_effector', a Frame or None"):
        loop.set_wrench(np.zeros(6), frame=1)
    with pytest.raises(ci.Error, match="nullspace.stiffness has 3 values; expected 1"):
        loop.set_nullspace_stiffness([1, 2, 3])
    with pytest.raises(ValueError, match=r"q_desired must have shape \(7,\)"):
        loop.set_nullspace_target(np.zeros(6))
    loop.step(ready, np.zeros(7), 0.001)
    np.testing.assert_array_equal(loop.state.controller.commanded.stiffness, before)
    assert loop.state.commands_applied == 0


def test_bad_constructor_arguments(panda):
    too_many = ci.MAX_JOINTS + 1
    with pytest.raises(ci.Error, match=r"num_joints = %d is outside \[1, %d\]"
                       % (too_many, ci.MAX_JOINTS)):
        ci.make_robot_state(too_many)
    with pytest.raises(TypeError, match="model must be a RobotModel, got str"):
        ci.ControlLoop("panda")
    with pytest.raises(ci.Error, match="limits.joint_torque has 2 values; expected 1 .* or 7"):
        ci.ControlLoop(panda, {"limits.joint_torque": [1, 2]})
    with pytest.raises(TypeError, match="parameters must be a Parameters, a dict or None, got int"):
        ci.CartesianImpedanceController(7, 5)
    with pytest.raises(ValueError, match=r"jacobian must have shape \(6, n\) with 1 <= n <= %d"
                       % ci.MAX_JOINTS):
        ci.RobotState(np.zeros(7), np.zeros(7), ci.Pose(), np.zeros((7, 6)))
    with pytest.raises(ValueError, match=r"mass must have shape \(n, n\)"):
        ci.RobotState(np.zeros(7), np.zeros(7), ci.Pose(), np.zeros((6, 7)), mass=np.zeros((7, 6)))
    with pytest.raises(ValueError, match=r"q must have shape \(n,\) with 1 <= n <= %d"
                       % ci.MAX_JOINTS):
        ci.RobotState(np.zeros(too_many), np.zeros(7), ci.Pose(), np.zeros((6, 7)))


def test_controller_start_checks_the_robot_state():
    controller = ci.CartesianImpedanceController(7)
    with pytest.raises(ci.Error):
        controller.start(ci.make_robot_state(6))
    robot = ci.make_robot_state(7)
    robot.q = np.full(7, np.nan)
    with pytest.raises(ci.Error, match="nan"):
        controller.start(robot)
    assert not controller.started


def test_bad_trajectories(loop, ready):
    with pytest.raises(ci.Error, match="trajectory.joint_names lacks joint .panda_joint7."):
        loop.execute_trajectory([1.0], [ready], joint_names=[
            "panda_joint%d" % i for i in (1, 2, 3, 4, 5, 6, 9)])
    with pytest.raises(ci.Error, match=r"point 1: time 0.5 s must be finite and greater than 1 s"):
        loop.execute_trajectory([1.0, 0.5], [ready, ready])
    with pytest.raises(ci.Error):
        loop.execute_trajectory([1.0], [ready + 10.0])  # beyond the URDF limits
    with pytest.raises(ci.Error, match="nan"):
        loop.execute_trajectory([1.0], [np.where(np.arange(7) == 0, np.nan, ready)])
    with pytest.raises(ValueError,
                       match=r"positions must have shape \(points, 7\), got shape \(7,\)"):
        loop.execute_trajectory([1.0], ready)
    with pytest.raises(ci.Error):
        loop.execute_trajectory([1.0, 2.0], [ready])  # one time per point
    with pytest.raises(TypeError, match="times must be real numbers"):
        loop.execute_trajectory(["soon"], [ready])
    loop.step(ready, np.zeros(7), 0.001)
    assert loop.state.trajectory.state == ci.TrajectoryState.idle


# ---- parameters ------------------------------------------------------------------------------


def test_unknown_and_malformed_parameter_keys():
    with pytest.raises(ci.Error, match=r"^unknown parameter 'stiffness.tranlation' \(did you mean "
                                      r"'stiffness.translation'\? valid in 'stiffness': "
                                      r"translation, rotation, frame\)$"):
        ci.Parameters({"stiffness.tranlation": [1, 1, 1]})
    with pytest.raises(ci.Error, match=r"unknown parameter 'stiffness.tranlation'"):
        ci.Parameters({"stiffness": {"tranlation": [1, 1, 1]}})
    with pytest.raises(ci.Error, match=r"unknown parameter 'stiffness' \(it is a group"):
        ci.Parameters({"stiffness": 500})
    with pytest.raises(ci.Error, match="unknown parameter 'gains'"):
        ci.Parameters({"gains": {"p": 1}})
    with pytest.raises(ci.Error, match="given twice"):
        ci.Parameters({"filter.pose.time": 0.1, "filter": {"pose": {"time": 0.2}}})
    with pytest.raises(TypeError, match="parameter names must be str, got int"):
        ci.Parameters({1: 2})
    with pytest.raises(TypeError, match="parameters must be given as a dict"):
        ci.Parameters.from_dict([("stiffness.translation", 1)])
    p = ci.Parameters()
    with pytest.raises(ci.Error, match="unknown parameter 'nope'"):
        p["nope"]
    with pytest.raises(ci.Error, match="unknown parameter 'nope'"):
        p["nope"] = 1


@pytest.mark.parametrize("name, value, error, text", [
    ("stiffness.translation", [1, 2], ValueError,
     r"^stiffness.translation must be 3 numbers \[x, y, z\] or one number, got a list of 2$"),
    ("stiffness.translation", "500", TypeError,
     r"^stiffness.translation = '500' is not a number \[N/m\]$"),
    ("filter.pose.time", True, TypeError, r"^filter.pose.time = true is not a number \[s\]$"),
    ("filter.pose.time", [0.1], TypeError,
     r"^filter.pose.time = a list of 1 is not a number \[s\]$"),
    ("filter.pose.fraction", 0, ci.Error, r"filter.pose.fraction = 0 is outside \[0.5, 1\]"),
    ("nullspace.stiffness", np.ones(ci.MAX_JOINTS + 1), ValueError,
     r"^nullspace.stiffness must be one number or a list of 1 to %d numbers \(one per joint\), "
     r"got a list of %d$" % (ci.MAX_JOINTS, ci.MAX_JOINTS + 1)),
    ("nullspace.stiffness", [1, -1], ci.Error, r"nullspace.stiffness\[1\] = -1 Nm/rad"),
    ("stiffness.frame", "world", ci.Error, "stiffness.frame = 'world' is not a frame"),
    ("stiffness.frame", None, TypeError, "^stiffness.frame has no value$"),
    ("dynamics.gravity_compensation", 1, TypeError,
     "^dynamics.gravity_compensation = 1 is not true or false$"),
    ("limits.stiffness.translation.min", 6000, ci.Error,
     "limits.stiffness.translation.min = 6000 N/m is greater than"),
])
def test_bad_parameter_values_leave_the_object_unchanged(name, value, error, text):
    p = ci.Parameters()
    with pytest.raises(error, match=text):
        p[name] = value
    with pytest.raises(error, match=text):
        p.update({name: value})
    with pytest.raises(error, match=text):
        ci.Parameters({name: value})
    assert p == ci.Parameters()


# The same mistake as a nested dict and as YAML: both go through the library's one decoder, so the
# message is the same (YAML puts "<yaml>:line: " in front; a dict has no lines). From a dict, a
# wrong type or a missing value is a TypeError; from YAML every mistake is an Error.
SAME_MISTAKES = [
    ({"stiffness": {"translation": [1, 2]}}, "stiffness:\n  translation: [1, 2]\n", ci.Error),
    ({"stiffness": {"translation": "abc"}}, "stiffness:\n  translation: abc\n", TypeError),
    ({"stiffness": {"rotation": [1, True, 1]}}, "stiffness:\n  rotation: [1, true, 1]\n",
     TypeError),
    ({"filter": {"pose": {"time": -1}}}, "filter:\n  pose:\n    time: -1\n", ci.Error),
    ({"nullspace": {"stiffness": [1, -1]}}, "nullspace:\n  stiffness: [1, -1]\n", ci.Error),
    ({"stiffness": {"frame": "world"}}, "stiffness:\n  frame: world\n", ci.Error),
    ({"stiffness": {"frame": None}}, "stiffness:\n  frame:\n", TypeError),
    ({"dynamics": {"gravity_compensation": 1}}, "dynamics:\n  gravity_compensation: 1\n",
     TypeError),
    ({"stiffness": {"tranlation": 5}}, "stiffness:\n  tranlation: 5\n", ci.Error),
    ({"stiffness": 500}, "stiffness: 500\n", ci.Error),
    ({"filter.pose.time": 10**400}, "filter.pose.time: 1e400\n", ci.Error),
    ({"limits": {"stiffness": {"translation": {"min": 6000}}}},
     "limits:\n  stiffness:\n    translation:\n      min: 6000\n", ci.Error),
]


@pytest.mark.parametrize("mapping, yaml, error", SAME_MISTAKES)
def test_a_dict_and_yaml_give_the_same_message(mapping, yaml, error):
    with pytest.raises(error) as from_dict:
        ci.Parameters(mapping)
    with pytest.raises(ci.Error) as from_yaml:
        ci.Parameters.from_yaml(yaml)
    dict_message = str(from_dict.value)
    if "1e400" in yaml:  # Python writes the int out in full, YAML as written
        dict_message = dict_message.replace(str(10**400), "1e400")
    assert re.sub(r"^<yaml>(:\d+)?: ", "", str(from_yaml.value)) == dict_message


def test_bad_parameter_files(tmp_path):
    with pytest.raises(ci.Error, match="parameter file '.*missing.yaml' does not exist"):
        ci.Parameters.load(tmp_path / "missing.yaml")
    with pytest.raises(ci.Error, match="is a directory"):
        ci.Parameters.load(tmp_path)
    malformed = tmp_path / "malformed.yaml"
    malformed.write_text("stiffness: [1\n")
    with pytest.raises(ci.Error, match="malformed YAML"):
        ci.Parameters.load(malformed)
    unknown = tmp_path / "unknown.yaml"
    unknown.write_text("filter:\n  pose:\n    time: 0.1\nstiffness:\n  tranlation: 5\n")
    with pytest.raises(ci.Error, match=r"unknown.yaml:5: unknown parameter 'stiffness.tranlation'"):
        ci.Parameters.load(unknown)
    negative = tmp_path / "negative.yaml"
    negative.write_text("stiffness:\n  rotation: -1\n")
    with pytest.raises(ci.Error, match=r"negative.yaml:2: stiffness.rotation = -1 Nm/rad"):
        ci.Parameters.load(negative)
    with pytest.raises(TypeError, match="path must be a str or os.PathLike, got int"):
        ci.Parameters.load(5)
    with pytest.raises(ci.Error, match="cannot write parameter file"):
        ci.Parameters().save(tmp_path / "no" / "such" / "dir.yaml")


def test_bad_model_files():
    # A bad file is a LoadError (an Error, so a ValueError), not a QueueFull.
    assert issubclass(ci.LoadError, ci.Error) and not issubclass(ci.QueueFull, ci.LoadError)
    with pytest.raises(ci.LoadError, match="URDF file '/no/such.urdf' does not exist"):
        ci.RobotModel.from_urdf_file("/no/such.urdf", "panda_link0", "panda_link8")
    with pytest.raises(ci.LoadError, match="gripper"):
        ci.RobotModel.from_urdf_file(PANDA_URDF, "panda_link0", "gripper")
    with pytest.raises(ci.LoadError):
        ci.RobotModel.from_urdf_string("<robot", "a", "b")
    with pytest.raises(ValueError, match=r"gravity must have shape \(3,\)"):
        ci.RobotModel.from_urdf_file(PANDA_URDF, "panda_link0", "panda_link8", gravity=[0, -9.81])


# ---- simulation ------------------------------------------------------------------------------


@requires_sim
def test_bad_simulation_input(panda, ready, tmp_path):
    with pytest.raises(ci.Error, match="does not exist"):
        ci.sim.Simulation.from_mjcf_file(tmp_path / "missing.xml")
    with pytest.raises(ci.Error, match="timestep"):
        ci.sim.Simulation.from_mjcf_file(PANDA_XML, timestep=-1.0)
    sim = ci.sim.Simulation.from_mjcf_file(PANDA_XML)
    with pytest.raises(ci.Error, match="gripper"):
        sim.push("gripper", np.zeros(6))
    with pytest.raises(ValueError, match=r"wrench must have shape \(6,\), got length 3"):
        sim.push("flange", [0, 0, 1])
    with pytest.raises(ci.Error, match="duration"):
        sim.push("flange", np.zeros(6), 0.0)
    with pytest.raises(ValueError, match=r"tau must have shape \(7,\)"):
        sim.set_torque(np.zeros(6))
    with pytest.raises(ci.Error, match="nan"):
        sim.set_torque(np.full(7, np.nan))
    with pytest.raises(ci.Error, match="gripper"):
        sim.contact_wrench("gripper")
    loop = ci.ControlLoop(panda)
    with pytest.raises(RuntimeError, match=r"call loop.start\(sim.q, sim.dq\) first"):
        sim.run(loop, 0.1)
    loop.start(sim.q, sim.dq)
    with pytest.raises(ci.Error, match=r"seconds = -1 must be finite and >= 0"):
        sim.run(loop, -1.0)
    reversed_joints = ci.sim.Simulation.from_mjcf_file(PANDA_XML,
                                                       joint_names=panda.joint_names[::-1])
    with pytest.raises(ci.Error, match="joint_names=loop.model.joint_names"):
        reversed_joints.run(loop, 0.1)
    with pytest.raises(TypeError, match="loop"):
        sim.run("loop", 0.1)
    with pytest.raises(ci.Error, match=r"center_xy|half size|half_size"):
        ci.sim.make_scene(PANDA_XML, [ci.sim.Box([0, 0, 0], [0, 1, 1])])
    with pytest.raises(ci.Error, match=r"size"):
        sim.render_png(tmp_path / "x.png", 0, 10)
    assert sim.time == 0.0  # nothing above stepped it
