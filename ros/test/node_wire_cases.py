"""The topics mode closed over the wire (cases of node_test.py): the simulated robot
(cartesian_impedance_sim_robot, the Panda's MJCF in MuJoCo) in one process, publishing stamped
joint_states at 1 kHz and taking effort_command; the controller in topics mode in another; the test
a third, over a real rosmaster. Bounds as in sim mode (node_test.py, ros2/test/node_test.cpp): the
wire adds a delay of a cycle or two, which moves no equilibrium."""

import os
import signal
import tempfile
import time

from node_harness import (
    REPO, Latest, controller_state, distance, holds, init_rospy, pose_stamped, position, publisher,
    quaternion_of, reach_pose, vector6, wait_until, wrench_stamped,
)

PANDA = {"urdf": "%s/models/panda/panda.urdf" % REPO, "config": "%s/config/panda.yaml" % REPO,
         "base_link": "panda_link0", "tip_link": "panda_link8"}


def launch_wire(processes, args, **robot):
    """The robot (its parameters as sim_robot.launch sets them; one roslaunch per master, so
    started as a plain process), then the controller in topics mode on its joint_states."""
    import rosparam
    with open(PANDA["urdf"]) as f:
        rosparam.set_param_raw("/robot_description", f.read())
    for values, namespace in rosparam.load_file(PANDA["config"], "/sim_robot"):
        rosparam.upload_params(namespace, values)
    settings = dict(mjcf_path="%s/models/panda/panda.xml" % REPO, base_link=PANDA["base_link"],
                    tip_link=PANDA["tip_link"], **robot)
    for name, value in settings.items():
        rosparam.set_param_raw("/sim_robot/" + name, value)
    robot_node = os.path.join(os.path.dirname(args.node), "cartesian_impedance_sim_robot")
    processes.start("robot", [robot_node, "__name:=sim_robot"])
    processes.launch("launch", "cartesian_impedance.launch", "mode:=topics",
                     *["%s:=%s" % item for item in sorted(PANDA.items())])
    init_rospy()
    return controller_state()


def stop(processes, name):
    for started, process, _ in processes.started:
        if started == name:
            os.killpg(process.pid, signal.SIGINT)
            process.wait(10)


def case_wire_reference_step(processes, args):
    """A reference step across processes is reached and held; the age of the joint states the
    controller used is reported; when the controller stops, the robot brakes and holds the arm
    still (instead of applying the last torque on)."""
    state = launch_wire(processes, args)
    from geometry_msgs.msg import PoseStamped
    from sensor_msgs.msg import JointState
    start = state.get()
    p0, q0 = position(start.current_pose), quaternion_of(start.current_pose)
    target = (p0[0], p0[1] + 0.05, p0[2] - 0.05)
    took = reach_pose(state, "/cartesian_impedance_controller/reference_pose", "panda_link0",
                      target, q0, tolerance=0.0015)
    print("over the wire: reference reached within 1.5 mm after %.2f s" % took)
    time.sleep(1.0)
    moved = state.get()
    time.sleep(2.0)
    held = state.get()
    drift = distance(position(held.current_pose), position(moved.current_pose))
    assert drift < 0.0005, "drifted %.2f mm in 2 s" % (1e3 * drift)  # the demo's hold bound
    assert held.status == "ok" and held.oscillations == 0 and held.stale_episodes == 0, held.status
    assert 0.0 < held.measurement_age_p50_us <= held.measurement_age_p99_us \
        <= held.measurement_age_max_us < 100000.0, (
            held.measurement_age_p50_us, held.measurement_age_p99_us, held.measurement_age_max_us)
    print("round trip, nominal plant: joint_states age at the controller's cycle p50 %.0f us, "
          "p99 %.0f us, max %.0f us" % (held.measurement_age_p50_us, held.measurement_age_p99_us,
                                        held.measurement_age_max_us))

    # Stopped mid-move: the last torque drives the arm toward a target 7 cm away.
    joints = Latest("/joint_states", JointState)
    pub = publisher("/cartesian_impedance_controller/reference_pose", PoseStamped)
    pub.publish(pose_stamped("", p0, q0))
    time.sleep(0.15)
    stop(processes, "launch")
    time.sleep(0.1)
    braked = joints.wait(what="joint_states after the controller stopped").position
    time.sleep(1.0)
    assert tuple(joints.get().position) == tuple(braked), (joints.get().position, braked)
    wait_until(lambda: "1 brakes after the torque timeout" in processes.log("robot"), 7.0,
               "the robot's report of the brake")


def case_wire_realistic_plant(processes, args):
    """The realistic plant over the wire (model error, readings 1 ms old, torques 1 ms late,
    noise): a reference step settles; the readings' stamps carry their age to the controller."""
    state = launch_wire(processes, args, plant="realistic", plant_seed=3)
    start = state.get()
    p0, q0 = position(start.current_pose), quaternion_of(start.current_pose)
    target = (p0[0], p0[1] + 0.05, p0[2] - 0.05)
    # The sim-mode bound with the plant's friction up to 1.5 times the model's.
    reach_pose(state, "/cartesian_impedance_controller/reference_pose", "panda_link0", target,
               q0, tolerance=0.00225)
    time.sleep(1.0)
    m = state.get()
    assert m.status == "ok" and m.oscillations == 0, (m.status, m.oscillations)
    assert max(abs(v) for v in m.joint_state.velocity) < 0.05, m.joint_state.velocity
    # At least the plant's 1 ms: the age comes from the stamp, not from the sample's arrival.
    assert 1000.0 <= m.measurement_age_p50_us and m.measurement_age_max_us < 100000.0, (
        m.measurement_age_p50_us, m.measurement_age_max_us)
    print("round trip, realistic plant: joint_states age p50 %.0f us, p99 %.0f us, max %.0f us"
          % (m.measurement_age_p50_us, m.measurement_age_p99_us, m.measurement_age_max_us))


def case_wire_table(processes, args):
    """The demo's table scenario across processes: a table 3 cm under the flange, the vertical
    stiffness released, 10 N commanded down: the robot measures 10 N of contact. Both from
    topics_panda.launch, as a user starts them."""
    processes.launch("launch", "topics_panda.launch", "table_under_flange:=0.03")
    init_rospy()
    state = controller_state()
    from geometry_msgs.msg import WrenchStamped
    contact = Latest("/sim_robot/contact_wrench", WrenchStamped)
    assert contact.wait(what="the contact wrench").wrench.force.z == 0.0  # not touching yet
    start = state.get()
    stiffness = vector6(start.commanded_cartesian_stiffness)
    pub = publisher("/cartesian_impedance_controller/set_cartesian_stiffness", WrenchStamped)
    pub.publish(wrench_stamped("", (stiffness[0], stiffness[1], 0.0), stiffness[3:]))
    state.wait(lambda m: m.commanded_cartesian_stiffness.force.z == 0.0, timeout=3.0,
               what="the vertical stiffness released")
    pub = publisher("/cartesian_impedance_controller/set_cartesian_wrench", WrenchStamped)
    pub.publish(wrench_stamped("", (0.0, 0.0, -10.0), (0.0, 0.0, 0.0)))
    time.sleep(3.0)
    pressing = state.get()
    down = position(start.current_pose)[2] - position(pressing.current_pose)[2]
    assert abs(down - 0.03) < 0.001, "the flange went %.2f mm down" % (1e3 * down)
    forces = []
    for _ in range(100):  # 1 s at 100 Hz
        count = contact.count
        wait_until(lambda: contact.count > count, 1.0, "a contact wrench")
        forces.append(contact.get().wrench.force.z)
    mean = sum(forces) / len(forces)
    # The demo's bound for the Panda: 5 % and the joints' friction band along z (0.45 N).
    assert abs(mean - 10.0) < 0.95, mean
    assert pressing.status == "ok", pressing.status
    print("table over the wire: flange %.2f mm down, contact force %.3f N for 10 N"
          % (1e3 * down, mean))


def case_wire_collision_resume(processes, args):
    """A collision reaction held until ~resume: with collision.reaction stop, a reference 3 cm into
    a table 3 cm under the flange is a collision; the arm stops, a reference back up is not
    followed; after an empty message on ~resume the next reference is."""
    with open(PANDA["config"]) as f:
        config = f.read()
    assert "  reaction: report" in config, "config/panda.yaml changed"
    handle, path = tempfile.mkstemp(suffix=".yaml")
    with os.fdopen(handle, "w") as f:
        f.write(config.replace("  reaction: report", "  reaction: stop"))
    try:
        processes.launch("launch", "topics_panda.launch", "table_under_flange:=0.03",
                         "config:=" + path)
        init_rospy()
        state = controller_state()
        from geometry_msgs.msg import PoseStamped
        from std_msgs.msg import Empty
        start = state.get()
        assert not start.collision_detected and start.collisions == 0, start.collision_reaction
        p0, q0 = position(start.current_pose), quaternion_of(start.current_pose)
        topic = "/cartesian_impedance_controller/reference_pose"
        pub = publisher(topic, PoseStamped)
        pub.publish(pose_stamped("", (p0[0], p0[1], p0[2] - 0.06), q0))
        hit = state.wait(lambda m: m.collision_detected, timeout=5.0, what="the collision")
        assert hit.collision_reaction == "stop", hit.collision_reaction
        time.sleep(0.5)
        stopped = position(state.get().current_pose)
        assert p0[2] - 0.035 < stopped[2] < p0[2] - 0.02, (p0, stopped)  # on the table
        pub.publish(pose_stamped("", (p0[0], p0[1], p0[2] + 0.03), q0))
        holds(state, 1.0, lambda m: m.collision_detected and
              distance(position(m.current_pose), stopped) < 0.002,
              "the stopped arm followed a reference before resume")
        resume = publisher("/cartesian_impedance_controller/resume", Empty)
        resume.publish(Empty())
        state.wait(lambda m: not m.collision_detected, timeout=3.0, what="the reaction to end")
        took = reach_pose(state, topic, "", (p0[0], p0[1], p0[2] + 0.03), q0)
        ended = state.get()
        assert ended.collisions == 1 and ended.status == "ok", (ended.collisions, ended.status)
        wait_until(lambda: "resume" in processes.log("launch"), 3.0, "the resume to be logged")
        print("collision found and stopped %.1f mm above the table's surface; after resume the "
              "reference 3 cm above the start was reached in %.2f s"
              % (1e3 * (stopped[2] - (p0[2] - 0.03)), took))
    finally:
        os.remove(path)
