#!/usr/bin/python3
"""What the tests of cartesian_impedance_node share (node_test.py): the processes of one case
(master, launches, nodes) and stopping them, rospy helpers, geometry, and the checks several
cases make."""

import ctypes
import math
import os
import signal
import socket
import subprocess
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
LAUNCH = os.path.join(HERE, "..", "launch")
REPO = os.path.abspath(os.path.join(HERE, "..", ".."))
CONTROLLER = "cartesian_impedance_controller"
CASE_BUDGET = 50  # [s] per case; CTest's TIMEOUT (60 s) is the backstop

PANDA_JOINTS = ["panda_joint%d" % i for i in range(1, 8)]
PANDA_READY = [0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4]


class CaseTimeout(BaseException):  # not swallowed by "except Exception" in rospy
    pass


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _die_with_parent():
    # Runs in the child before exec: a new process group (so the whole tree can be signalled) and
    # SIGTERM if this driver dies, even by SIGKILL.
    os.setpgrp()
    ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    # A driver started in the background of a shell ignores SIGINT; the children must not.
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


class Processes:
    """Master, launches and nodes of one test, each in its own process group."""

    def __init__(self):
        self.folder = tempfile.mkdtemp(prefix="cartesian_impedance_ros_test_")
        self.port = free_port()
        self.env = dict(os.environ)
        self.env.update({
            "ROS_MASTER_URI": "http://127.0.0.1:%d" % self.port,
            "ROS_HOSTNAME": "127.0.0.1",
            "ROS_HOME": os.path.join(self.folder, "home"),
            "ROS_LOG_DIR": os.path.join(self.folder, "log"),
        })
        self.env.pop("ROS_IP", None)
        os.environ.update(self.env)
        os.environ.pop("ROS_IP", None)
        self.started = []  # (name, Popen, log path)

    def start(self, name, command):
        log = os.path.join(self.folder, name + ".log")
        with open(log, "wb") as out:
            process = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT,
                                       env=self.env, preexec_fn=_die_with_parent)
        self.started.append((name, process, log))
        return process

    def start_master(self):
        self.start("master", ["rosmaster", "--core", "-p", str(self.port)])
        import rosgraph
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            try:
                rosgraph.Master("/node_test").getPid()
                return
            except Exception:
                time.sleep(0.05)
        raise RuntimeError("rosmaster did not come up on port %d" % self.port)

    def launch(self, name, launch_file, *arguments):
        return self.start(name, ["roslaunch", os.path.join(LAUNCH, launch_file)] +
                          list(arguments))

    def log(self, name):
        for started_name, _, log in self.started:
            if started_name == name:
                with open(log, errors="replace") as f:
                    return f.read()
        return ""

    def stop(self):
        # Newest first (nodes before the master); SIGINT lets roslaunch stop its nodes.
        for _, process, _ in reversed(self.started):
            if process.poll() is None:
                try:
                    os.killpg(process.pid, signal.SIGINT)
                except ProcessLookupError:
                    pass
        deadline = time.monotonic() + 5
        for name, process, _ in reversed(self.started):
            try:
                process.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                print("%s did not stop on SIGINT: killed" % name)
            try:
                os.killpg(process.pid, signal.SIGKILL)  # anything left in the group
            except ProcessLookupError:
                pass
            process.wait()

    def report(self):
        for name, _, log in self.started:
            with open(log, errors="replace") as f:
                text = f.read()
            print("---- %s (last 40 lines of %s) ----" % (name, log))
            print("\n".join(text.splitlines()[-40:]))


# ---- helpers over rospy (imported after the environment is set) ---------------------------------

def init_rospy():
    import rospy
    rospy.init_node("node_test", anonymous=True, disable_signals=True)


def wait_until(condition, timeout, what):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.01)
    raise AssertionError("timed out after %g s waiting for %s" % (timeout, what))


class Latest:
    """The newest message on a topic."""

    def __init__(self, topic, message_type):
        import rospy
        self.message = None
        self.count = 0
        self.lock = threading.Lock()
        self.subscriber = rospy.Subscriber(topic, message_type, self._store, queue_size=1,
                                           tcp_nodelay=True)
        self.topic = topic

    def _store(self, message):
        with self.lock:
            self.message = message
            self.count += 1

    def get(self):
        with self.lock:
            return self.message

    def wait(self, condition=lambda m: True, timeout=10.0, what=None):
        def check():
            message = self.get()
            return message if message is not None and condition(message) else None
        try:
            return wait_until(check, timeout, what or "a message on " + self.topic)
        except AssertionError as error:
            raise AssertionError("%s; last message: %s" % (error, summary(self.get()))) from None


def summary(state):
    if state is None or not hasattr(state, "current_pose"):
        return repr(state)[:400]
    p = state.current_pose.position
    r = state.commanded_reference_pose.position
    return ("status=%s cycle=%d pose=(%.4f %.4f %.4f) commanded=(%.4f %.4f %.4f) trajectory=%s %d"
            " stiffness=%s commanded stiffness=%s wrench=%s saturated: stiffness %s wrench %s"
            % (state.status, state.cycle, p.x, p.y, p.z, r.x, r.y, r.z, state.trajectory_state,
               state.trajectory_id, vector6(state.cartesian_stiffness),
               vector6(state.commanded_cartesian_stiffness), vector6(state.wrench),
               state.stiffness_saturated, state.wrench_saturated))


def publisher(topic, message_type, subscribers=1, timeout=10.0):
    import rospy
    pub = rospy.Publisher(topic, message_type, queue_size=10)
    wait_until(lambda: pub.get_num_connections() >= subscribers, timeout,
               "a subscriber on " + topic)
    return pub


def controller_state(namespace=""):
    from cartesian_impedance_ros.msg import ControllerState
    state = Latest(namespace + "/" + CONTROLLER + "/controller_state", ControllerState)
    state.wait(lambda m: m.status == "ok", timeout=20.0, what="the controller to run")
    return state


def position(pose):
    return (pose.position.x, pose.position.y, pose.position.z)


def distance(a, b):
    return math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b)))


def pose_stamped(frame, xyz, quaternion):
    from geometry_msgs.msg import PoseStamped
    message = PoseStamped()
    message.header.frame_id = frame
    message.pose.position.x, message.pose.position.y, message.pose.position.z = xyz
    (message.pose.orientation.x, message.pose.orientation.y, message.pose.orientation.z,
     message.pose.orientation.w) = quaternion
    return message


def quaternion_of(pose):
    o = pose.orientation
    return (o.x, o.y, o.z, o.w)


def wrench_stamped(frame, force, torque):
    from geometry_msgs.msg import WrenchStamped
    message = WrenchStamped()
    message.header.frame_id = frame
    message.wrench.force.x, message.wrench.force.y, message.wrench.force.z = force
    message.wrench.torque.x, message.wrench.torque.y, message.wrench.torque.z = torque
    return message


def vector6(wrench):
    return (wrench.force.x, wrench.force.y, wrench.force.z, wrench.torque.x, wrench.torque.y,
            wrench.torque.z)


def close(a, b, tolerance):
    return all(abs(x - y) <= tolerance for x, y in zip(a, b))


def reach_pose(state, reference_topic, frame, target_base, quaternion, sent=None, tolerance=0.003,
               timeout=10.0):
    """Publishes a reference and waits until the measured pose is within tolerance of target."""
    from geometry_msgs.msg import PoseStamped
    pub = publisher(reference_topic, PoseStamped)
    pub.publish(pose_stamped(frame, sent or target_base, quaternion))
    start = time.monotonic()
    state.wait(lambda m: close(position(m.commanded_reference_pose), target_base, 1e-6),
               timeout=3.0, what="the reference to be taken")
    state.wait(lambda m: distance(position(m.current_pose), target_base) < tolerance,
               timeout=timeout, what="the arm to reach %s" % (target_base,))
    return time.monotonic() - start


def holds(state, seconds, condition, what):
    """Checks condition on every state for `seconds`."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        message = state.get()
        if not condition(message):
            raise AssertionError("%s: %s" % (what, summary(message)))
        time.sleep(0.01)


def check_timing(processes, state, launched, control_rate=1000.0):
    """The control thread's timing in controller_state is sane and agrees with the log: the median
    period near 1 / control_rate (loosely: a shared VM delays wake-ups), the quantiles ordered,
    overruns counted and summarised in the log at most once per 5 s with no more overruns than
    the state reports."""
    import re
    first = state.wait(lambda m: m.period_p50_us > 0.0, timeout=3.0, what="a measured period")
    period_us = 1e6 / control_rate
    m = first
    assert 0.5 * period_us < m.period_p50_us < 2.0 * period_us, m.period_p50_us
    assert 0.0 < m.period_min_us <= m.period_p50_us <= m.period_p99_us <= m.period_max_us, (
        m.period_min_us, m.period_p50_us, m.period_p99_us, m.period_max_us)
    assert m.overruns <= m.cycle + 100, (m.overruns, m.cycle)
    assert (m.worst_lateness_us > 0.0) == (m.overruns > 0), (m.overruns, m.worst_lateness_us)
    assert 0.0 <= m.latest_lateness_us <= m.worst_lateness_us, (
        m.latest_lateness_us, m.worst_lateness_us)
    print("timing: period p50 %.0f us, p99 %.0f us, max %.0f us; %d overruns in %d cycles, worst "
          "%.0f us late" % (m.period_p50_us, m.period_p99_us, m.period_max_us, m.overruns, m.cycle,
                            m.worst_lateness_us))

    summary = re.compile(r"control cycle: (\d+) overruns? of the 1 ms period in the last (\d+) s "
                         r"\(worst (\d+) us late\); period p50 (\d+) us, p99 (\d+) us, max (\d+) us")
    if m.overruns > 0:
        # Overruns get a summary within one 5 s window (and the publisher thread's period).
        wait_until(lambda: summary.search(processes.log("launch")), 7.0,
                   "a summary of the overruns in the log")
    lines = summary.findall(processes.log("launch"))
    time.sleep(0.2)  # a state published after the last line read
    last = state.get()
    assert last.overruns >= m.overruns, (last.overruns, m.overruns)
    logged = sum(int(line[0]) for line in lines)
    assert logged <= last.overruns, "the log summed %d overruns, the state says %d" % (
        logged, last.overruns)
    assert all(int(line[0]) > 0 and int(line[1]) >= 5 for line in lines), lines
    elapsed = time.monotonic() - launched
    assert len(lines) <= elapsed / 5.0 + 1, "%d summaries in %.1f s: %s" % (len(lines), elapsed,
                                                                           lines)
    print("log: %d overrun summaries in %.0f s, %d overruns in them" % (len(lines), elapsed,
                                                                      logged))


# ---- cases ----------------------------------------------------------------------------------------

def settle(state, what, window=0.5, tolerance=1e-4, timeout=10.0):
    """Waits until the measured position moves less than `tolerance` [m] over `window` [s]."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        before = state.get()
        time.sleep(window)
        after = state.get()
        if distance(position(before.current_pose), position(after.current_pose)) < tolerance:
            return after
    raise AssertionError("%s did not settle within %g s: %s" % (what, timeout, summary(state.get())))


def friction_losses(joints):
    """The simulated joints' dry friction [Nm] (frictionloss in the Panda's MJCF)."""
    import xml.etree.ElementTree as ElementTree
    root = ElementTree.parse(os.path.join(REPO, "models", "panda", "panda.xml")).getroot()
    losses = {j.get("name"): float(j.get("frictionloss", "0")) for j in root.iter("joint")}
    return [losses[name] for name in joints]


def reconfigure_client(server):
    import dynamic_reconfigure.client
    return dynamic_reconfigure.client.Client("/%s/%s" % (CONTROLLER, server), timeout=10)


def dynparam_get(processes, server):
    """The configuration as `dynparam get` prints it (a dict)."""
    import ast
    output = subprocess.run(
        ["/usr/bin/python3", "/usr/lib/dynamic_reconfigure/dynparam", "get",
         "/%s/%s" % (CONTROLLER, server)], env=processes.env, capture_output=True, text=True,
        timeout=20, check=True).stdout
    return ast.literal_eval(output.strip().splitlines()[-1])


# ---- tf ---------------------------------------------------------------------------------------------

# A Franka hand on the Panda's flange (as franka_description mounts it: -45 degrees about z), with
# its two fingers on prismatic joints: links with visuals outside the chain panda_link0 ->
# panda_link8, for the transforms a robot display needs.
PANDA_HAND = """
  <link name="panda_hand">
    <visual><geometry><box size="0.05 0.2 0.06"/></geometry></visual>
  </link>
  <link name="panda_leftfinger">
    <visual><geometry><box size="0.02 0.02 0.05"/></geometry></visual>
  </link>
  <link name="panda_rightfinger">
    <visual><geometry><box size="0.02 0.02 0.05"/></geometry></visual>
  </link>
  <joint name="panda_hand_joint" type="fixed">
    <parent link="panda_link8"/><child link="panda_hand"/><origin xyz="0 0 0" rpy="0 0 -0.7853981633974483"/>
  </joint>
  <joint name="panda_finger_joint1" type="prismatic">
    <parent link="panda_hand"/><child link="panda_leftfinger"/><origin xyz="0 0 0.0584"/>
    <axis xyz="0 1 0"/><limit effort="20" lower="0.0" upper="0.04" velocity="0.2"/>
  </joint>
  <joint name="panda_finger_joint2" type="prismatic">
    <parent link="panda_hand"/><child link="panda_rightfinger"/><origin xyz="0 0 0.0584"/>
    <axis xyz="0 -1 0"/><limit effort="20" lower="0.0" upper="0.04" velocity="0.2"/>
    <mimic joint="panda_finger_joint1"/>
  </joint>
"""


def panda_with_hand(folder):
    """models/panda/panda.urdf with PANDA_HAND, written into `folder`; returns the path."""
    with open(os.path.join(REPO, "models", "panda", "panda.urdf")) as f:
        text = f.read()
    end = text.rindex("</robot>")
    path = os.path.join(folder, "panda_hand.urdf")
    with open(path, "w") as f:
        f.write(text[:end] + PANDA_HAND + text[end:])
    return path


class TfRecorder:
    """Every transform on /tf (by stamp, the newest 200 stamps) and /tf_static (latched)."""

    def __init__(self):
        import rospy
        from tf2_msgs.msg import TFMessage
        self.lock = threading.Lock()
        self.moving = {}  # stamp (ns) -> {child: (parent, transform)}
        self.fixed = {}  # child -> (parent, transform)
        self.subscribers = [
            rospy.Subscriber("/tf", TFMessage, self._moving, queue_size=100, tcp_nodelay=True),
            rospy.Subscriber("/tf_static", TFMessage, self._fixed, queue_size=10)]

    def _moving(self, message):
        with self.lock:
            for t in message.transforms:
                stamp = t.header.stamp.to_nsec()
                self.moving.setdefault(stamp, {})[t.child_frame_id] = (t.header.frame_id,
                                                                       t.transform)
            while len(self.moving) > 200:
                del self.moving[min(self.moving)]

    def _fixed(self, message):
        with self.lock:
            for t in message.transforms:
                self.fixed[t.child_frame_id] = (t.header.frame_id, t.transform)

    def tree(self, stamp):
        """child -> (parent, transform): the static ones and the moving ones of `stamp`."""
        with self.lock:
            tree = dict(self.fixed)
            tree.update(self.moving.get(stamp, {}))
            return tree

    def stamps(self):
        with self.lock:
            return sorted(self.moving)


def compose(tree, root, frame):
    """T_root_frame as (translation, quaternion xyzw), following parents from `frame` up."""
    chain = []
    while frame != root:
        if frame not in tree:
            raise AssertionError("no transform to frame '%s' (frames: %s)" % (frame,
                                                                            sorted(tree)))
        parent, transform = tree[frame]
        chain.append(transform)
        frame = parent
    p, q = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)
    for transform in reversed(chain):  # T = T_root_1 T_1_2 ...
        t, r = transform.translation, transform.rotation
        p = tuple(a + b for a, b in zip(p, rotate(q, (t.x, t.y, t.z))))
        q = multiply(q, (r.x, r.y, r.z, r.w))
    return p, q


def multiply(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def rotate(q, v):
    conjugate = (-q[0], -q[1], -q[2], q[3])
    return multiply(multiply(q, (v[0], v[1], v[2], 0.0)), conjugate)[:3]


def check_tf_matches_state(tf, state, root, tip, tolerance=1e-9):
    """The tip's transform composed from /tf and /tf_static at the stamp of a controller_state
    equals that state's current_pose: both come from one sample of the control loop (same q,
    same stamp), so only rounding separates them. Returns the matched state."""
    deadline = time.monotonic() + 10.0
    missing = None
    while time.monotonic() < deadline:
        m = state.get()
        stamp = m.header.stamp.to_nsec()
        if stamp in tf.stamps():
            try:
                p, q = compose(tf.tree(stamp), root, tip)
            except AssertionError as error:  # a latched /tf_static message still on its way
                missing = error
                time.sleep(0.02)
                continue
            expected_q = quaternion_of(m.current_pose)
            dot = abs(sum(a * b for a, b in zip(q, expected_q)))
            error = distance(p, position(m.current_pose))
            print("tf %s -> %s at the state's stamp: position error %.2e m, 1 - |q.q'| = %.1e"
                  % (root, tip, error, 1 - dot))
            assert error < tolerance, (p, position(m.current_pose))
            assert 1 - dot < tolerance, (q, expected_q)
            return m
        time.sleep(0.02)
    if missing is not None:
        raise missing
    raise AssertionError("no /tf message with the stamp of a controller_state (tf stamps %s, "
                         "state %s)" % (tf.stamps()[-3:], state.get().header.stamp.to_nsec()))
