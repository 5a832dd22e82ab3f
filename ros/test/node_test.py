#!/usr/bin/python3
"""Tests of cartesian_impedance_node against a real ROS master, driven with rospy.

Each run starts its own rosmaster on a free loopback port (ROS_HOME and ROS_LOG_DIR in a
temporary folder), launches the node(s) with the package's launch files, runs one case and stops
every process it started by process group, also when the case fails or times out. Usage:

    node_test.py CASE --node <path of cartesian_impedance_node>

The environment must let roslaunch find the package and rospy its messages (CTest sets it):
ROS_PACKAGE_PATH=<repo>/ros, CMAKE_PREFIX_PATH=<build>/devel,
PYTHONPATH=<build>/devel/lib/python3/dist-packages.
"""

import argparse
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import traceback

from node_harness import (  # noqa: F401
    CASE_BUDGET, CONTROLLER, CaseTimeout, Latest, PANDA_JOINTS, PANDA_READY, Processes, REPO,
    TfRecorder, check_tf_matches_state, check_timing, close, controller_state, distance, holds,
    init_rospy, panda_with_hand, pose_stamped, position, publisher, quaternion_of, reach_pose,
    vector6, wait_until, wrench_stamped,
)
# dynamic_reconfigure against the topics, and the safety lock, in a file of their own
from node_reconfigure_cases import (  # noqa: F401
    case_reconfigure_keeps_topic_commands, case_reconfigure_shows_topic_values,
    case_reconfigure_update_flag, case_safety_lock,
)
# the topics mode across processes, with the simulated robot, in a file of their own
from node_wire_cases import (  # noqa: F401
    case_wire_collision_resume, case_wire_realistic_plant, case_wire_reference_step, case_wire_table,
)


def case_reference_pose(processes, args):
    """A reference pose is reached, in the base frame and in another frame via tf2; joint_states
    come from the simulation; a pose in an unknown frame is rejected; the control thread reports
    its timing."""
    launched = time.monotonic()
    processes.launch("launch", "sim_panda.launch")
    init_rospy()
    from sensor_msgs.msg import JointState
    joints = Latest("/joint_states", JointState)
    state = controller_state()
    message = joints.wait(what="joint_states from the simulation")
    assert list(message.name) == PANDA_JOINTS, message.name
    assert close(message.position, PANDA_READY, 1e-2), message.position

    start = state.get()
    assert start.header.frame_id == "panda_link0"
    assert list(start.joint_state.name) == PANDA_JOINTS
    p0, q0 = position(start.current_pose), quaternion_of(start.current_pose)
    topic = "/%s/reference_pose" % CONTROLLER
    target = (p0[0] + 0.05, p0[1] - 0.05, p0[2] - 0.04)
    took = reach_pose(state, topic, "panda_link0", target, q0)
    print("base-frame reference reached within 3 mm after %.2f s" % took)

    # A frame 'world' in which the base sits at (0.1, 0.2, 0) rotated 90 degrees about z.
    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage
    import rospy
    transform = TransformStamped()
    transform.header.stamp = rospy.Time.now()
    transform.header.frame_id = "world"
    transform.child_frame_id = "panda_link0"
    transform.transform.translation.x = 0.1
    transform.transform.translation.y = 0.2
    s = math.sqrt(0.5)
    transform.transform.rotation.z = s
    transform.transform.rotation.w = s
    static = rospy.Publisher("/tf_static", TFMessage, queue_size=1, latch=True)
    wait_until(lambda: static.get_num_connections() >= 1, 10.0, "the node's tf2 listener")
    static.publish(TFMessage([transform]))
    time.sleep(0.3)  # delivered to the listener's buffer
    # The same target, written in 'world': x_w = 0.1 - y_b, y_w = 0.2 + x_b; orientation
    # q_w = R_z(90) q_b, so that the node's transform gives back q_b.
    target2 = (target[0] - 0.03, target[1] + 0.06, target[2] + 0.03)
    sent = (0.1 - target2[1], 0.2 + target2[0], target2[2])
    qz = (0.0, 0.0, s, s)
    qw = (qz[3] * q0[0] + qz[0] * q0[3] + qz[1] * q0[2] - qz[2] * q0[1],
          qz[3] * q0[1] - qz[0] * q0[2] + qz[1] * q0[3] + qz[2] * q0[0],
          qz[3] * q0[2] + qz[0] * q0[1] - qz[1] * q0[0] + qz[2] * q0[3],
          qz[3] * q0[3] - qz[0] * q0[0] - qz[1] * q0[1] - qz[2] * q0[2])
    took = reach_pose(state, topic, "world", target2, qw, sent=sent)
    reached = state.get()
    dot = abs(sum(a * b for a, b in zip(quaternion_of(reached.commanded_reference_pose), q0)))
    assert dot > 1 - 1e-9, "orientation not transformed back: %s" % (reached.commanded_reference_pose,)
    print("reference in frame 'world' (tf2) reached after %.2f s" % took)

    # Unknown frame: rejected, nothing changes.
    pub = publisher(topic, type(pose_stamped("", (0, 0, 0), (0, 0, 0, 1))))
    pub.publish(pose_stamped("nowhere", p0, q0))
    holds(state, 0.6, lambda m: close(position(m.commanded_reference_pose), target2, 1e-9),
          "a pose in an unknown frame changed the reference")
    wait_until(lambda: "no transform from frame 'nowhere'" in processes.log("launch"), 3.0,
               "the rejection to be logged")
    check_timing(processes, state, launched)


def case_stiffness(processes, args):
    """set_cartesian_stiffness and set_damping_factors change the controller's stiffness and
    damping; so does dynamic_reconfigure; values beyond the limits are saturated."""
    processes.launch("launch", "sim_panda.launch")
    init_rospy()
    from geometry_msgs.msg import Wrench, WrenchStamped
    state = controller_state()
    stiffness = (300.0, 400.0, 600.0, 30.0, 40.0, 45.0)
    pub = publisher("/%s/set_cartesian_stiffness" % CONTROLLER, WrenchStamped)
    pub.publish(wrench_stamped("", stiffness[:3], stiffness[3:]))
    start = time.monotonic()
    state.wait(lambda m: close(vector6(m.commanded_cartesian_stiffness), stiffness, 1e-9),
               timeout=3.0, what="the commanded stiffness")
    state.wait(lambda m: close(vector6(m.cartesian_stiffness), stiffness, 0.01 * 600),
               timeout=3.0, what="the filtered stiffness")
    print("stiffness applied (filtered to within 1 %%) after %.2f s" % (time.monotonic() - start))
    assert state.get().stiffness_frame == "base"

    ratios = (0.7, 0.8, 0.9, 0.5, 0.6, 0.75)
    pub = publisher("/%s/set_damping_factors" % CONTROLLER, Wrench)
    message = Wrench()
    message.force.x, message.force.y, message.force.z = ratios[:3]
    message.torque.x, message.torque.y, message.torque.z = ratios[3:]
    pub.publish(message)
    m = state.wait(lambda m: close(vector6(m.damping_ratio), ratios, 0.01), timeout=3.0,
                   what="the damping ratios")
    # The damping is shaped by the arm's task-space inertia, D = L (2 Z^1/2 sqrt(L^-1 K L^-T)
    # Z^1/2) L^T, which the message does not carry; but it is linear in the ratios: doubling
    # them doubles D (the arm holds still, so the inertia stays the same).
    d = vector6(m.cartesian_damping)
    message.force.x, message.force.y, message.force.z = [2 * r for r in ratios[:3]]
    message.torque.x, message.torque.y, message.torque.z = [2 * r for r in ratios[3:]]
    pub.publish(message)
    m = state.wait(lambda m: close(vector6(m.damping_ratio), [2 * r for r in ratios], 0.001),
                   timeout=3.0, what="the doubled damping ratios")
    doubled = vector6(m.cartesian_damping)
    for i in range(6):
        assert abs(doubled[i] - 2 * d[i]) <= 0.02 * doubled[i], (i, d, doubled)

    # dynamic_reconfigure; 5000 N/m is above the Panda's limit (3000 N/m): saturated.
    import dynamic_reconfigure.client
    client = dynamic_reconfigure.client.Client("/%s/stiffness_reconfigure" % CONTROLLER,
                                               timeout=10)
    result = client.update_configuration({
        "translation_x": 800.0, "translation_y": 900.0, "translation_z": 5000.0,
        "rotation_x": 20.0, "rotation_y": 25.0, "rotation_z": 35.0,
        "nullspace_stiffness": 15.0, "update_stiffness": True})
    assert result["update_stiffness"] and result["translation_x"] == 800.0, result
    # The ranges shown to GUIs are the node's limits; the library saturates what is beyond.
    ranges = {d["name"]: d for d in client.get_parameter_descriptions()}
    assert ranges["translation_z"]["max"] == 3000.0, ranges["translation_z"]
    expected = (800.0, 900.0, 3000.0, 20.0, 25.0, 35.0)
    state.wait(lambda m: close(vector6(m.commanded_cartesian_stiffness), expected, 1e-9),
               timeout=3.0, what="the stiffness from dynamic_reconfigure")
    state.wait(lambda m: close(m.nullspace_stiffness, [15.0] * 7, 0.5), timeout=3.0,
               what="the nullspace stiffness from dynamic_reconfigure")
    # A negative stiffness is refused on dynamic_reconfigure as on the topic (below), by the same
    # check: before, the server clamped it to its .cfg's minimum, 0, and x went limp.
    result = client.update_configuration({"translation_x": -5.0, "update_stiffness": True})
    assert result["translation_x"] == 800.0, result  # the server shows the value in force
    wait_until(lambda: "stiffness_reconfigure rejected" in processes.log("launch"), 3.0,
               "the reconfigure's rejection to be logged")
    holds(state, 0.5, lambda m: close(vector6(m.commanded_cartesian_stiffness), expected, 1e-9),
          "a negative stiffness from dynamic_reconfigure changed the stiffness")

    # Negative stiffness is invalid (not saturated): rejected, nothing changes.
    pub = publisher("/%s/set_cartesian_stiffness" % CONTROLLER, WrenchStamped)
    pub.publish(wrench_stamped("", (-5.0, 100.0, 100.0), (10.0, 10.0, 10.0)))
    holds(state, 0.5, lambda m: close(vector6(m.commanded_cartesian_stiffness), expected, 1e-9),
          "an invalid stiffness changed the stiffness")
    wait_until(lambda: "set_cartesian_stiffness rejected" in processes.log("launch"), 3.0,
               "the rejection to be logged")
    pub.publish(wrench_stamped("", (5000.0, 100.0, 100.0), (10.0, 10.0, 10.0)))
    # (stiffness_saturated is still set from the reconfigure above: a flag holds until its
    # quantity is commanded again, so wait for the new value itself.)
    m = state.wait(lambda m: m.commanded_cartesian_stiffness.force.x == 3000.0, timeout=3.0,
                   what="the saturated stiffness along x")
    assert m.stiffness_saturated, m


def case_wrench(processes, args):
    """set_cartesian_wrench changes the commanded wrench, in the base frame, in the end-effector
    frame, and saturated at limits/wrench; the arm gives way by F / K."""
    processes.launch("launch", "sim_panda.launch")
    init_rospy()
    from geometry_msgs.msg import WrenchStamped
    state = controller_state()
    start = state.get()
    assert start.wrench_frame == "base" and vector6(start.commanded_wrench) == (0.0,) * 6, start
    p0 = position(start.current_pose)
    pub = publisher("/%s/set_cartesian_wrench" % CONTROLLER, WrenchStamped)
    pub.publish(wrench_stamped("panda_link0", (0.0, 0.0, -5.0), (0.0, 0.0, 0.0)))
    state.wait(lambda m: close(vector6(m.commanded_wrench), (0, 0, -5, 0, 0, 0), 1e-9),
               timeout=3.0, what="the commanded wrench")
    state.wait(lambda m: close(vector6(m.wrench), (0, 0, -5, 0, 0, 0), 0.05), timeout=3.0,
               what="the applied (filtered) wrench")
    # 5 N against 500 N/m: 10 mm down once settled, a little less with the nullspace spring and
    # joint friction holding back.
    m = state.wait(lambda m: abs(m.current_pose.position.z - (p0[2] - 0.010)) < 0.004,
                   timeout=5.0, what="the arm to give way by about 10 mm")
    print("pushed down by %.1f mm" % (1000 * (p0[2] - m.current_pose.position.z)))
    assert m.wrench_frame == "base"

    # The end-effector frame of the Panda at the ready pose points down: +z there is -z in base.
    pub.publish(wrench_stamped("panda_link8", (0.0, 0.0, 4.0), (0.0, 0.0, 0.0)))
    m = state.wait(lambda m: m.wrench_frame == "end_effector" and
                   close(vector6(m.wrench), (0, 0, -4, 0, 0, 0), 0.2), timeout=3.0,
                   what="a wrench in the end-effector frame")

    pub.publish(wrench_stamped("panda_link0", (0.0, 0.0, -1000.0), (0.0, 0.0, 0.0)))
    m = state.wait(lambda m: m.wrench_saturated, timeout=3.0, what="wrench_saturated")
    assert abs(m.commanded_wrench.force.z + 60.0) < 1e-9, m.commanded_wrench  # limits/wrench/force

    pub.publish(wrench_stamped("panda_link0", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    state.wait(lambda m: close(vector6(m.wrench), (0,) * 6, 0.05), timeout=3.0,
               what="the wrench to go back to zero")

    # dynamic_reconfigure: applied while apply_wrench is true, removed when it is switched off.
    import dynamic_reconfigure.client
    client = dynamic_reconfigure.client.Client("/%s/cartesian_wrench_reconfigure" % CONTROLLER,
                                               timeout=10)
    client.update_configuration({"f_x": 3.0, "tau_z": 0.5, "frame": "base", "apply_wrench": True})
    state.wait(lambda m: m.wrench_frame == "base" and
               close(vector6(m.commanded_wrench), (3, 0, 0, 0, 0, 0.5), 1e-9), timeout=3.0,
               what="the wrench from dynamic_reconfigure")
    client.update_configuration({"apply_wrench": False})
    state.wait(lambda m: close(vector6(m.commanded_wrench), (0,) * 6, 1e-12), timeout=3.0,
               what="the wrench to be removed")


def case_trajectory(processes, args):
    """A joint trajectory (joints in another order than the model's) is executed and finishes
    at its last point."""
    processes.launch("launch", "sim_panda.launch")
    init_rospy()
    import rospy
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    state = controller_state()
    # A stiffer nullspace (set_config, keeping the nullspace target) so that friction does not
    # keep the joints from their goal within trajectory/goal_tolerance.
    from cartesian_impedance_ros.msg import NullspaceConfig
    config = NullspaceConfig(q_d_nullspace=[], nullspace_stiffness=[40.0],
                             nullspace_damping_ratio=0.9)
    publisher("/%s/set_config" % CONTROLLER, NullspaceConfig).publish(config)
    state.wait(lambda m: close(m.nullspace_stiffness, [40.0] * 7, 0.4) and
               abs(m.nullspace_damping_ratio - 0.9) < 0.01, timeout=3.0,
               what="the nullspace configuration")
    q0 = list(state.get().joint_state.position)
    goal = [q + d for q, d in zip(q0, (0.3, 0.2, -0.2, 0.3, 0.3, -0.2, 0.4))]
    order = [6, 2, 0, 4, 1, 5, 3]
    message = JointTrajectory()
    message.joint_names = [PANDA_JOINTS[i] for i in order]
    for t in (0.5, 1.0, 1.5):
        point = JointTrajectoryPoint()
        point.positions = [q0[i] + (goal[i] - q0[i]) * t / 1.5 for i in order]
        point.time_from_start = rospy.Duration(t)
        message.points.append(point)
    pub = publisher("/%s/joint_trajectory" % CONTROLLER, JointTrajectory)
    pub.publish(message)
    start = time.monotonic()
    state.wait(lambda m: m.trajectory_id == 1 and m.trajectory_state == "executing", timeout=3.0,
               what="the trajectory to start")
    m = state.wait(lambda m: m.trajectory_state == "finished", timeout=6.0,
                   what="the trajectory to finish")
    print("trajectory finished after %.2f s (duration 1.5 s), goal error %.4f rad"
          % (time.monotonic() - start, m.trajectory_goal_error))
    assert m.trajectory_progress == 1.0 and abs(m.trajectory_duration - 1.5) < 1e-9, m
    assert close(m.joint_state.position, goal, 0.02), (list(m.joint_state.position), goal)

    # A trajectory with an unknown joint is rejected; the robot stays where it is.
    message.joint_names[0] = "elbow"
    pub.publish(message)
    holds(state, 0.5, lambda m: m.trajectory_id == 1 and m.trajectory_state == "finished",
          "a bad trajectory was executed")
    wait_until(lambda: "joint_trajectory rejected" in processes.log("launch"), 3.0,
               "the rejection to be logged")


def case_nan_pose(processes, args):
    """A NaN pose, a non-unit quaternion and a megabyte frame_id are rejected and logged; the
    robot holds and the controller keeps running and accepts the next good pose."""
    processes.launch("launch", "sim_panda.launch")
    init_rospy()
    from geometry_msgs.msg import PoseStamped
    state = controller_state()
    start = state.get()
    p0, q0 = position(start.current_pose), quaternion_of(start.current_pose)
    reference = position(start.commanded_reference_pose)
    pub = publisher("/%s/reference_pose" % CONTROLLER, PoseStamped)
    pub.publish(pose_stamped("", (float("nan"), p0[1], p0[2]), q0))
    time.sleep(0.05)
    pub.publish(pose_stamped("", (p0[0] + 0.1, p0[1], p0[2]), (0.0, 0.0, 0.0, 0.0)))
    holds(state, 1.0, lambda m: m.status == "ok" and
          close(position(m.commanded_reference_pose), reference, 1e-12) and
          distance(position(m.current_pose), p0) < 0.001,
          "the robot did not hold after bad poses")
    wait_until(lambda: "reference_pose rejected" in processes.log("launch"), 3.0,
               "the rejection to be logged")
    log = processes.log("launch")
    assert "nan" in log, log[-2000:]
    # A frame_id of a megabyte is refused by its length and named, not echoed: before, tf2 waited
    # for it and the log line quoted it twice (2 MB).
    pub.publish(pose_stamped("f" * (1 << 20), (p0[0] + 0.1, p0[1], p0[2]), q0))
    wait_until(lambda: "(1048576 characters) is longer than 256 characters"
               in processes.log("launch"), 3.0, "the long frame_id's rejection to be logged")
    assert "f" * 1000 not in processes.log("launch"), "the frame_id was echoed"
    cycle = state.get().cycle
    target = (p0[0], p0[1] + 0.03, p0[2])
    reach_pose(state, "/%s/reference_pose" % CONTROLLER, "", target, q0)
    assert state.get().cycle > cycle


def case_tf(processes, args):
    """The node publishes the robot's transforms: the chain's joints on /tf with each state's
    stamp, the other joints once on latched /tf_static (a subscriber that comes later still gets
    them), every frame with tf_prefix in front. The tip composed from them is controller_state's
    current_pose, before and after the arm moves; links outside the chain (a hand and its
    fingers, at position 0) are there; a reference in the prefixed base frame is the base frame."""
    urdf = panda_with_hand(processes.folder)
    processes.launch(
        "launch", "cartesian_impedance.launch", "urdf:=" + urdf,
        "mjcf:=%s/models/panda/panda.xml" % REPO, "config:=%s/config/panda.yaml" % REPO,
        "base_link:=panda_link0", "tip_link:=panda_link8", "tf_prefix:=arm/")
    init_rospy()
    state = controller_state()
    time.sleep(0.5)  # /tf_static was latched before this subscriber existed
    tf = TfRecorder()
    m = check_tf_matches_state(tf, state, "arm/panda_link0", "arm/panda_link8")
    assert m.header.frame_id == "arm/panda_link0", m.header.frame_id
    tree = tf.tree(tf.stamps()[-1])
    moving = {"arm/panda_link%d" % i: "arm/panda_link%d" % (i - 1) for i in range(1, 8)}
    fixed = {"arm/panda_link8": "arm/panda_link7", "arm/panda_hand": "arm/panda_link8",
             "arm/panda_leftfinger": "arm/panda_hand", "arm/panda_rightfinger": "arm/panda_hand"}
    assert {child: parent for child, (parent, _) in tree.items()} == dict(moving, **fixed), tree
    assert set(tf.fixed) == set(fixed), sorted(tf.fixed)
    finger = tree["arm/panda_leftfinger"][1].translation
    assert close((finger.x, finger.y, finger.z), (0.0, 0.0, 0.0584), 1e-12), finger
    print("frames: %d on /tf, %d on /tf_static" % (len(moving), len(tf.fixed)))

    p0, q0 = position(m.current_pose), quaternion_of(m.current_pose)
    target = (p0[0] + 0.05, p0[1] - 0.04, p0[2] - 0.03)
    reach_pose(state, "/%s/reference_pose" % CONTROLLER, "arm/panda_link0", target, q0)
    moved = check_tf_matches_state(tf, state, "arm/panda_link0", "arm/panda_link8")
    assert distance(position(moved.current_pose), p0) > 0.05


def case_urdf_sim(processes, args):
    """sim_urdf.launch: MuJoCo simulates the URDF itself (no MJCF), a UR5e started at start_q;
    joint_states and tf follow it, and a reference is reached."""
    start_q = [math.pi, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0]
    processes.launch("launch", "sim_urdf.launch")
    init_rospy()
    from sensor_msgs.msg import JointState
    joints = Latest("/joint_states", JointState)
    state = controller_state()
    message = joints.wait(what="joint_states from the simulation")
    assert close(message.position, start_q, 0.02), message.position
    wait_until(lambda: "the URDF simulated" in processes.log("launch"), 3.0, "the log line")
    tf = TfRecorder()
    m = check_tf_matches_state(tf, state, "base_link", "tool0")
    p0, q0 = position(m.current_pose), quaternion_of(m.current_pose)
    target = (p0[0], p0[1] + 0.04, p0[2] + 0.03)
    took = reach_pose(state, "/%s/reference_pose" % CONTROLLER, "", target, q0)
    print("UR5e from its URDF: reference reached after %.2f s" % took)


def case_two_arms(processes, args):
    """Two namespaced arms (a Panda in /left, an iiwa 14 in /right) run at once, each reaching
    its own reference; their transforms share /tf with the prefixes left/ and right/."""
    processes.launch("launch", "sim_two_arms.launch")
    init_rospy()
    from sensor_msgs.msg import JointState
    left, right = controller_state("/left"), controller_state("/right")
    left_joints = Latest("/left/joint_states", JointState)
    right_joints = Latest("/right/joint_states", JointState)
    assert list(left_joints.wait().name) == PANDA_JOINTS
    assert list(right_joints.wait().name) == ["iiwa_joint_%d" % i for i in range(1, 8)]
    assert left.get().header.frame_id == "left/panda_link0"
    assert right.get().header.frame_id == "right/iiwa_link_0"
    tf = TfRecorder()
    check_tf_matches_state(tf, left, "left/panda_link0", "left/panda_link8")
    check_tf_matches_state(tf, right, "right/iiwa_link_0", "right/iiwa_link_ee")

    from geometry_msgs.msg import PoseStamped
    targets = {}
    for name, state in (("left", left), ("right", right)):
        m = state.get()
        p, q = position(m.current_pose), quaternion_of(m.current_pose)
        targets[name] = (p[0] - 0.04, p[1] + 0.04, p[2] + 0.03)
        pub = publisher("/%s/%s/reference_pose" % (name, CONTROLLER), PoseStamped)
        pub.publish(pose_stamped("", targets[name], q))
    for name, state in (("left", left), ("right", right)):
        state.wait(lambda m: distance(position(m.current_pose), targets[name]) < 0.003,
                   timeout=10.0, what="the %s arm to reach its reference" % name)
    print("both arms reached their references")


def case_topics_mode(processes, args):
    """mode topics: first joint_states the controller cannot start from (a joint at 50 rad/s)
    logged while the node waits, then joint_states in (in any order, with other joints),
    effort_command out at the control rate, tf from the measured positions; without joint_states
    the status turns invalid and the torque ramps to zero (a stale episode); the control thread
    reports its timing."""
    launched = time.monotonic()
    processes.launch(
        "launch", "cartesian_impedance.launch", "mode:=topics",
        "urdf:=%s/models/panda/panda.urdf" % REPO, "config:=%s/config/panda.yaml" % REPO,
        "base_link:=panda_link0", "tip_link:=panda_link8")
    init_rospy()
    import rospy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray
    efforts = Latest("/effort_command", Float64MultiArray)

    robot = rospy.Publisher("/joint_states", JointState, queue_size=10)
    wait_until(lambda: robot.get_num_connections() >= 1, 10.0, "the node to subscribe")
    running = {"on": True, "too_fast": True}
    order = [3, 0, 6, 1, 5, 2, 4]

    def play_robot():
        message = JointState()
        message.name = ["panda_finger_joint1"] + [PANDA_JOINTS[i] for i in order]
        message.position = [0.04] + [PANDA_READY[i] for i in order]
        message.effort = [0.0] + [0.5] * 7
        while not rospy.is_shutdown() and running["on"] is not None:
            if running["on"]:
                # The first message's joint panda_joint4 at 50 rad/s, beyond
                # plausibility/joint_velocity (10 rad/s).
                message.velocity = [0.0, 50.0 if running["too_fast"] else 0.0] + [0.0] * 6
                message.header.stamp = rospy.Time.now()
                robot.publish(message)
            time.sleep(0.004)  # about 250 Hz

    player = threading.Thread(target=play_robot, daemon=True)
    player.start()
    try:
        # Not started from, logged (once a second), and the node waits for good ones.
        wait_until(lambda: "cannot start the controller from /joint_states: dq[3] = 50"
                   in processes.log("launch"), 10.0, "the rejected first joint_states in the log")
        time.sleep(1.5)
        assert "controller running" not in processes.log("launch"), processes.log("launch")
        running["too_fast"] = False
        state = controller_state()
        m = state.get()
        assert close(m.joint_state.position, PANDA_READY, 1e-9), m.joint_state.position
        # tf in topics mode too, from the measured joint positions.
        check_tf_matches_state(TfRecorder(), state, "panda_link0", "panda_link8")
        assert close(m.external_torques, [0.5 - t for t in m.commanded_torques], 1e-9)
        efforts.wait(lambda e: len(e.data) == 7, timeout=5.0, what="effort_command")
        count = efforts.count
        time.sleep(1.0)
        rate = efforts.count - count
        print("effort_command: %d messages in 1 s (control rate 1000 Hz)" % rate)
        assert rate > 300, rate

        # A reference 5 cm away: efforts grow (the robot here does not move).
        from geometry_msgs.msg import PoseStamped
        p, q = position(m.current_pose), quaternion_of(m.current_pose)
        pub = publisher("/%s/reference_pose" % CONTROLLER, PoseStamped)
        pub.publish(pose_stamped("", (p[0] + 0.05, p[1], p[2]), q))
        efforts.wait(lambda e: max(abs(x) for x in e.data) > 5.0, timeout=3.0,
                     what="efforts toward the new reference")

        running["on"] = False  # the robot connection is lost
        state.wait(lambda m: m.status == "invalid_robot_state", timeout=2.0,
                   what="invalid_robot_state without joint_states")
        efforts.wait(lambda e: max(abs(x) for x in e.data) < 1e-9, timeout=2.0,
                     what="the torque to ramp to zero")
        running["on"] = True
        state.wait(lambda m: m.status == "ok", timeout=2.0, what="ok once joint_states are back")
        assert state.get().stale_episodes >= 1, state.get().stale_episodes
        check_timing(processes, state, launched)
    finally:
        running["on"] = None


def case_urdf_sim_chosen_start(processes, args):
    """sim_urdf.launch start_q:=[]: without a start the node chooses one (q = 0 is singular on
    the UR5e), logs it, starts there and reaches a reference."""
    processes.launch("launch", "sim_urdf.launch", "start_q:=[]")
    init_rospy()
    from sensor_msgs.msg import JointState
    joints = Latest("/joint_states", JointState)
    state = controller_state()
    message = joints.wait(what="joint_states from the simulation")
    pattern = re.compile(r"start configuration \(chosen, no start_q set: smallest singular value "
                         r"[^\n]*\): q = \[([^\]]*)\]")
    wait_until(lambda: pattern.search(processes.log("launch")), 3.0, "the chosen start's log line")
    chosen = [float(v) for v in pattern.search(processes.log("launch")).group(1).split(",")]
    assert len(chosen) == 6 and max(abs(v) for v in chosen) > 0.5, chosen
    assert close(message.position, chosen, 0.02), (message.position, chosen)
    m = state.get()
    p0, q0 = position(m.current_pose), quaternion_of(m.current_pose)
    target = (p0[0], p0[1] + 0.04, p0[2] + 0.03)
    took = reach_pose(state, "/%s/reference_pose" % CONTROLLER, "", target, q0)
    print("UR5e from its URDF at the chosen start: reference reached after %.2f s" % took)


def case_urdf_sim_dart(processes, args):
    """sim_urdf.launch engine:=dart: DART simulates the UR5e's URDF instead of MuJoCo; the arm
    starts at start_q, holds there and reaches a reference."""
    start_q = [math.pi, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0.0]
    processes.launch("launch", "sim_urdf.launch", "engine:=dart")
    init_rospy()
    from sensor_msgs.msg import JointState
    joints = Latest("/joint_states", JointState)
    state = controller_state()
    message = joints.wait(what="joint_states from the simulation")
    assert close(message.position, start_q, 0.02), message.position
    wait_until(lambda: "mode sim, engine dart (the URDF simulated)" in processes.log("launch"),
               3.0, "the log line")
    m = state.get()
    p0, q0 = position(m.current_pose), quaternion_of(m.current_pose)
    target = (p0[0], p0[1] + 0.04, p0[2] + 0.03)
    # DART's joint friction is exact stiction: the arm stops where the spring no longer
    # overcomes it, 3.1 mm short at the UR5e's 500 N/m (MuJoCo's soft friction creeps on to
    # 2.8 mm), hence 5 mm.
    took = reach_pose(state, "/%s/reference_pose" % CONTROLLER, "", target, q0, tolerance=0.005)
    print("UR5e from its URDF on DART: reference reached after %.2f s" % took)


def case_bad_parameters(processes, args):
    """Invalid parameters, a missing robot_description or a wrong link end the node at start with
    the library's message and a non-zero exit code."""
    init_rospy()
    import rospy
    with open(os.path.join(REPO, "models", "panda", "panda.urdf")) as f:
        urdf = f.read()

    def run(name, parameters, expected):
        for key, value in parameters.items():
            rospy.set_param("/%s/%s" % (name, key), value)
        process = processes.start(name, [args.node, "__name:=" + name])
        try:
            code = process.wait(15)
        except subprocess.TimeoutExpired:
            raise AssertionError("%s: the node did not exit" % name)
        log = processes.log(name)
        assert code == 1, "%s: exit code %s\n%s" % (name, code, log)
        assert expected in log, "%s: %r not in\n%s" % (name, expected, log)
        print("%s: exit code 1: %s" % (name, [l for l in log.splitlines() if expected in l][0]))

    good = {"base_link": "panda_link0", "tip_link": "panda_link8",
            "mjcf_path": os.path.join(REPO, "models", "panda", "panda.xml")}
    run("no_description", good, "parameter /robot_description is not set")
    rospy.set_param("/robot_description", urdf)
    run("negative_stiffness", dict(good, **{"stiffness/translation": [500, -5, 500]}),
        "stiffness.translation.y = -5 N/m is outside [0, 100000]")
    run("misspelt", dict(good, **{"filter/pose/tme": 0.1}),
        "/misspelt/filter/pose/tme: unknown parameter")
    run("wrong_tip", dict(good, tip_link="panda_hand"), "panda_hand")
    run("joint_count", dict(good, **{"limits/joint_torque": [87, 87, 87]}),
        "limits.joint_torque")
    run("bad_mjcf", dict(good, mjcf_path="/nonexistent/panda.xml"), "/nonexistent/panda.xml")
    run("start_q_count", dict(good, start_q=[0.0, -0.5, 0.0]),
        "/start_q_count/start_q: start_q has 3 values; expected one per joint of the chain")
    run("start_q_range", dict(good, start_q=[0.0, -0.7, 0.0, 0.5, 0.0, 1.5, 0.7]),
        "start_q[3] = 0.5 rad for joint 'panda_joint4' is outside its limits [-3.0718, -0.0698]")
    run("dart_mjcf", dict(good, engine="dart"),
        "/dart_mjcf/engine: engine 'dart' cannot simulate the MJCF of mjcf_path")


# ---- dynamic_reconfigure and topics: one owner per commanded value ------------------------------

def case_clear_params(processes, args):
    """A misspelt key ends the node with the library's message (roslaunch then ends too, with
    the exit code ros/README.md gives); fixed, the next launch on the same master starts, since
    clear_params removes the key the first launch left on the parameter server."""
    init_rospy()
    import rospy
    bad = os.path.join(processes.folder, "misspelt.yaml")
    with open(os.path.join(REPO, "config", "panda.yaml")) as f, open(bad, "w") as out:
        out.write(f.read().replace("    time: 0.2\n", "    tme: 0.2\n", 1))  # filter/pose/tme
    arguments = ["urdf:=%s/models/panda/panda.urdf" % REPO,
                 "mjcf:=%s/models/panda/panda.xml" % REPO, "base_link:=panda_link0",
                 "tip_link:=panda_link8"]
    launch = processes.launch("misspelt", "cartesian_impedance.launch", "config:=" + bad,
                              *arguments)
    try:
        code = launch.wait(20)
    except subprocess.TimeoutExpired:
        raise AssertionError("roslaunch did not end when its required node died") from None
    log = processes.log("misspelt")
    message = "unknown parameter 'filter.pose.tme'"
    assert message in log, log[-3000:]
    assert "REQUIRED process [%s-" % CONTROLLER in log and "has died!" in log, log[-3000:]
    print("misspelt key: %s" % [l for l in log.splitlines() if message in l][0].strip())
    print("roslaunch exit code after the required node died: %d" % code)
    assert code == 0, ("roslaunch exited %d; ros/README.md says Debian's roslaunch exits 0 when a "
                       "required node dies: update it" % code)
    stale = "/%s/filter/pose/tme" % CONTROLLER
    assert rospy.has_param(stale), "the misspelt key is expected to stay after the launch"

    processes.launch("fixed", "cartesian_impedance.launch",
                     "config:=%s/config/panda.yaml" % REPO, *arguments)
    controller_state()  # runs: the stale key was cleared
    assert not rospy.has_param(stale)
    print("the fixed launch runs; %s was cleared" % stale)


CASES = {name[len("case_"):]: function for name, function in globals().items()
         if name.startswith("case_")}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", choices=sorted(CASES))
    parser.add_argument("--node", required=True, help="path of cartesian_impedance_node")
    args = parser.parse_args()

    def on_alarm(signum, frame):
        raise CaseTimeout("case '%s' took longer than %d s" % (args.case, CASE_BUDGET))

    def on_term(signum, frame):
        raise CaseTimeout("terminated by signal %d" % signum)

    signal.signal(signal.SIGALRM, on_alarm)
    signal.signal(signal.SIGTERM, on_term)
    signal.alarm(CASE_BUDGET)
    processes = Processes()
    started = time.monotonic()
    ok = False
    try:
        processes.start_master()
        CASES[args.case](processes, args)
        ok = True
    except BaseException:
        traceback.print_exc()
    finally:
        # Cleanup must not be interrupted by a second signal (CTest's timeout kill); if the
        # driver is killed outright, PR_SET_PDEATHSIG still ends its children.
        signal.alarm(0)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            import rospy
            if rospy.core.is_initialized():
                rospy.signal_shutdown("test done")
        except Exception:
            pass
        processes.stop()
        if not ok:
            processes.report()
            print("logs kept in %s" % processes.folder)
        else:
            shutil.rmtree(processes.folder, ignore_errors=True)
    print("%s: %s in %.1f s" % (args.case, "passed" if ok else "FAILED", time.monotonic() - started))
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
