#!/usr/bin/python3
"""The ROS 2 node against an independent DDS peer: ros2_fastdds_peer (Fast DDS 2.9, what a stock
ROS 2 node on rmw_fastrtps speaks) drives cartesian_impedance_ros2 (Cyclone DDS) over loopback.

    test_fastdds_peer.py --peer PEER --pose-writer WRITER --node NODE [--models DIR] [--standin]
                         CASE...

CASE: reference_pose echo wrong_type_name xcdr2 fuzz topics. --standin: NODE is ros2_cyclone_echo,
the peer's own check (no physics: its current pose is the last reference received).
Each run uses a domain of its own (ROS_DOMAIN_ID), loopback-only Cyclone and Fast DDS
configurations in a temporary folder, and writes the node's output there (kept on failure).
"""

import argparse
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback

FQ = "/cartesian_impedance_controller"
JOINTS = ["panda_joint%d" % i for i in range(1, 8)]
READY_Q = [0, -math.pi / 4, 0, -3 * math.pi / 4, 0, math.pi / 2, math.pi / 4]
READY_FLANGE = (0.3069, 0.0, 0.5903)  # Craig DH of the Panda at READY_Q
TORQUE_LIMITS = [87, 87, 87, 87, 12, 12, 12]  # [Nm], the Panda's
TANK_CAPACITY = 0.005  # [J], the library's default safety.energy_tank.capacity

# The converged pose is checked to 5 mm. The joints' Coulomb friction (frictionloss 0.1 Nm on
# J1-J4, 0.05 Nm on J5-J7 in panda.xml) holds the arm wherever the Cartesian spring force is
# below it: 0.1 Nm over lever arms of 0.3 m or more is 0.3 N per proximal joint, about 1.5 N for
# all together, i.e. 3 mm against 500 N/m. 5 mm covers that with margin and is a tenth of the
# 5 cm step, so an arm that stays put (or stops halfway) fails.
TOLERANCE = 0.005
STEP = 0.05
# A node that ignores a command holds the start pose: friction and the settled spring keep it
# within a fraction of a millimetre, a command that got through moves it centimetres.
AT_REST = 0.002

CYCLONE_XML = """<?xml version="1.0" encoding="UTF-8"?>
<CycloneDDS xmlns="https://cdds.io/config">
  <Domain Id="any">
    <General>
      <Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces>
      <AllowMulticast>false</AllowMulticast>
    </General>
    <Discovery>
      <ParticipantIndex>auto</ParticipantIndex>
      <MaxAutoParticipantIndex>30</MaxAutoParticipantIndex>
      <Peers><Peer address="127.0.0.1"/></Peers>
    </Discovery>
  </Domain>
</CycloneDDS>
"""

# Fast DDS on 127.0.0.1 only: UDPv4 restricted to loopback (no shared memory, which Cyclone does
# not speak), initial peers 127.0.0.1 on the unicast discovery ports of participants 0..31, the
# same range Cyclone announces to (MaxAutoParticipantIndex 30).
FASTDDS_XML = """<?xml version="1.0" encoding="UTF-8"?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
    <transport_descriptor>
      <transport_id>loopback</transport_id>
      <type>UDPv4</type>
      <interfaceWhiteList><address>127.0.0.1</address></interfaceWhiteList>
      <maxInitialPeersRange>32</maxInitialPeersRange>
    </transport_descriptor>
  </transport_descriptors>
  <participant profile_name="loopback" is_default_profile="true">
    <rtps>
      <userTransports><transport_id>loopback</transport_id></userTransports>
      <useBuiltinTransports>false</useBuiltinTransports>
      <builtin>
        <initialPeersList>
          <locator><udpv4><address>127.0.0.1</address></udpv4></locator>
        </initialPeersList>
      </builtin>
    </rtps>
  </participant>
</profiles>
"""


def parse(output):
    """The peer's JSON lines (Python's json reads its NaN and Infinity)."""
    return [json.loads(line) for line in output.splitlines() if line.startswith("{")]


def distance(a, b):
    return math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b)))


def csv(values):
    return ",".join(repr(float(v)) for v in values)


class Harness:
    def __init__(self, args):
        self.args = args
        self.standin = args.standin
        self.dir = tempfile.mkdtemp(prefix="ros2_fastdds_")
        # A domain per run: parallel runs (other build trees) must not see each other. 232 is the
        # largest domain whose ports fit; 100.. keeps clear of the usual 0.
        domain = 100 + os.getpid() % 130
        for name, text in (("cyclone.xml", CYCLONE_XML), ("fastdds.xml", FASTDDS_XML)):
            with open(os.path.join(self.dir, name), "w") as f:
                f.write(text)
        self.env = dict(os.environ)
        self.env.update(
            ROS_DOMAIN_ID=str(domain),
            CYCLONEDDS_URI="file://" + os.path.join(self.dir, "cyclone.xml"),
            FASTRTPS_DEFAULT_PROFILES_FILE=os.path.join(self.dir, "fastdds.xml"),
        )
        self.nodes = []
        self.log("domain %d, files in %s" % (domain, self.dir))

    def log(self, text):
        print("# " + text, flush=True)

    # ---- the node --------------------------------------------------------------------------------

    def start_node(self, ns="/", mode="sim"):
        params = os.path.join(self.dir, "params_%s.yaml" % mode)
        models = self.args.models or ""
        with open(params, "w") as f:
            f.write(
                "/**:\n  ros__parameters:\n    mode: %s\n    urdf_path: %s/panda.urdf\n"
                "    mjcf_path: %s/panda.xml\n    base_link: panda_link0\n"
                "    tip_link: panda_link8\n"
                "    stiffness: {translation: 500, rotation: 50}\n" % (mode, models, models)
            )
        index = len(self.nodes)
        out = open(os.path.join(self.dir, "node%d.out" % index), "w")
        err = open(os.path.join(self.dir, "node%d.err" % index), "w")
        command = [self.args.node, "--ros-args", "-r", "__ns:=" + ns, "--params-file", params]
        self.log(" ".join(command))
        # Output to files: Cyclone's per-sample warnings during the fuzz would fill a pipe.
        proc = subprocess.Popen(command, env=self.env, stdout=out, stderr=err)
        self.nodes.append((proc, out, err))
        return proc

    def stop_node(self, proc):
        assert proc.poll() is None, "the node exited early with %s" % proc.returncode
        proc.send_signal(signal.SIGINT)
        try:
            code = proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise AssertionError("the node did not stop within 10 s of SIGINT")
        assert code == 0, "the node exited with %d after SIGINT" % code

    def close(self, ok):
        for proc, out, err in self.nodes:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            out.close()
            err.close()
        if ok:
            shutil.rmtree(self.dir)
        else:
            for proc, out, err in self.nodes:
                with open(err.name, errors="replace") as f:
                    lines = f.readlines()
                self.log("%s (last lines):\n%s" % (err.name, "".join(lines[-20:])))
            self.log("kept " + self.dir)

    # ---- peers -----------------------------------------------------------------------------------

    def run(self, command, timeout):
        self.log(" ".join(command))
        done = subprocess.run(command, env=self.env, capture_output=True, text=True,
                              timeout=timeout)
        events = parse(done.stdout)
        if done.stderr.strip():
            self.log("stderr: " + done.stderr.strip()[-2000:])
        return done.returncode, events

    def peer(self, *args, timeout=40):
        return self.run([self.args.peer] + [str(a) for a in args], timeout)

    def peer_background(self, *args):
        command = [self.args.peer] + [str(a) for a in args]
        self.log(" ".join(command) + " &")
        return subprocess.Popen(command, env=self.env, stdout=subprocess.PIPE, text=True)

    @staticmethod
    def collect(proc, timeout):
        out, _ = proc.communicate(timeout=timeout)
        return proc.returncode, parse(out)

    def states(self, count, ns=FQ, timeout=15):
        """The next `count` controller states (the node's topics are up once this returns)."""
        code, events = self.peer(
            "echo", ns + "/controller_state", "cartesian_impedance_controller/msg/ControllerState",
            "--count", count, "--timeout", timeout,
        )
        samples = [e["data"] for e in events if e["event"] == "sample"]
        assert code == 0 and len(samples) == count, "controller_state: %d of %d samples" % (
            len(samples), count)
        return samples


def first(events, name):
    found = [e for e in events if e["event"] == name]
    assert found, "no %s event in %s" % (name, events[-3:])
    return found[0]


def position(state, pose="current_pose"):
    return state[pose]["position"]


# ---- cases ---------------------------------------------------------------------------------------


def case_reference_pose(h):
    """(a) A reference pose 5 cm from the start, published by Fast DDS, is reached (5 mm)."""
    node = h.start_node()
    code, events = h.peer("pose", "--ns", FQ, "--dx", STEP, "--tolerance", TOLERANCE,
                          "--timeout", 30)
    start = first(events, "start")["position"]
    result = first(events, "result")
    h.log("start %s, result %s" % (start, result))
    assert distance(start, READY_FLANGE) < 0.01, "start %s is not the ready pose" % start
    assert code == 0 and result["converged"], "did not converge: %s" % result
    states = [e for e in events if e["event"] == "state"]
    target = [start[0] + STEP, start[1], start[2]]
    assert distance(states[-1]["position"], target) <= TOLERANCE
    assert result["max_deviation_from_start"] >= STEP - TOLERANCE
    h.stop_node(node)


def check_full_state_at_rest(h, ns):
    """full_state through Fast DDS's decoder, to the fields appended after the timing (the torque
    shaping, the hold, the safety layer; the last of them the message's last field): an arm at
    rest with the library's defaults, nothing shaped, held or capped, the energy tank within its
    capacity and not drawn from. Exact values: a field read from the wrong place of the sample
    would not give 1.0, 0.0 or "none"."""
    code, events = h.peer("echo", ns + "/full_state", "cartesian_impedance_msgs/msg/ControllerState",
                          "--count", 1, "--timeout", 10)
    samples = [e["data"] for e in events if e["event"] == "sample"]
    assert code == 0 and len(samples) == 1, events[-2:]
    state = samples[0]
    h.log("full_state: torque_shaping %s, holding %s, safety %s"
          % (state["torque_shaping"], state["holding"], state["safety"]))
    assert state["status"] == "ok", state["status"]
    assert (state["torque_shaping"], state["torque_shaping_scale"], state["holding"]) == (
        "none", 1.0, False), state
    safety = state["safety"]
    expected = {"reference_speed_limited": False, "translation_drive_scale": 1.0,
                "rotation_drive_scale": 1.0, "braking": False, "force_scale": 1.0,
                "torque_scale": 1.0, "reference_clipped": False,
                "workspace_penetration": [0.0, 0.0, 0.0], "wall_force": [0.0, 0.0, 0.0],
                "tank_draw": 0.0, "stiffness_change_scale": 1.0, "payload_mass": 0.0,
                "payload_center_of_mass": [0.0, 0.0, 0.0]}
    wrong = {k: safety[k] for k, v in expected.items() if safety[k] != v}
    assert not wrong, wrong
    assert 0.0 < safety["tank_level"] <= TANK_CAPACITY, safety["tank_level"]
    estimate = [safety["payload_estimate_mass"]] + safety["payload_estimate_center_of_mass"]
    assert len(estimate) == 4 and all(map(math.isfinite, estimate)), safety


def case_echo(h):
    """(b) Fast DDS reads the node's joint_states, commanded_torques and full_state (in a
    namespace)."""
    node = h.start_node(ns="/left")
    h.states(1, ns="/left" + FQ)
    code, events = h.peer("echo", "/left/joint_states", "sensor_msgs/msg/JointState",
                          "--count", 50, "--timeout", 10)
    joints = [e["data"] for e in events if e["event"] == "sample"]
    assert code == 0 and len(joints) == 50
    for sample in joints:
        assert sample["name"] == JOINTS, sample["name"]
        assert len(sample["position"]) == 7 and all(map(math.isfinite, sample["position"]))
    stamps = [s["stamp"] for s in joints]
    assert all(b > a for a, b in zip(stamps, stamps[1:])), "stamps not increasing"
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    h.log("joint_states at %.1f Hz" % rate)
    # publish_rate 100 Hz; a loaded 2-core machine stretches periods, it does not halve them.
    assert 50 < rate < 150, rate
    if not h.standin:
        # At rest at the start: the ready pose, held against friction.
        assert distance(joints[-1]["position"], READY_Q) < 0.02, joints[-1]["position"]
    code, events = h.peer("echo", "/left" + FQ + "/commanded_torques",
                          "std_msgs/msg/Float64MultiArray", "--count", 20, "--timeout", 10)
    torques = [e["data"]["data"] for e in events if e["event"] == "sample"]
    assert code == 0 and len(torques) == 20
    for tau in torques:
        assert len(tau) == 7 and all(abs(t) <= limit for t, limit in zip(tau, TORQUE_LIMITS)), tau
    if not h.standin:
        check_full_state_at_rest(h, "/left" + FQ)
    h.stop_node(node)


def assert_at_rest(h, states, start):
    moved = max(distance(position(s), start) for s in states)
    reference = max(distance(position(s, "reference_pose"), start) for s in states)
    h.log("%d states, moved %.6f m, reference moved %.6f m" % (len(states), moved, reference))
    assert moved < AT_REST and reference < AT_REST, (moved, reference)


def case_wrong_type_name(h):
    """(c) A writer whose type name has a typo (PoseStampd_) does not match; the arm stays."""
    node = h.start_node()
    code, events = h.peer("pose", "--ns", FQ, "--dx", STEP, "--wrong-type-name",
                          "--match-wait", 3, "--timeout", 8)
    start = first(events, "start")["position"]
    result = first(events, "result")
    assert first(events, "matched")["count"] == 0 and result["matched"] == 0, result
    assert code == 1 and not result["converged"] and result["published"] >= 3, result
    states = [e for e in events if e["event"] == "state"]
    assert len(states) > 100, "too few states to judge: %d" % len(states)
    assert_at_rest(h, [{"current_pose": {"position": s["position"]},
                        "reference_pose": {"position": s["reference"]}} for s in states], start)
    h.stop_node(node)


def pose_writer(h, representation, target, seconds, observe):
    """ros2_cyclone_pose_writer for `seconds` while Fast DDS records `observe` states."""
    echo = h.peer_background("echo", FQ + "/controller_state",
                             "cartesian_impedance_controller/msg/ControllerState",
                             "--count", observe, "--timeout", seconds + 10)
    code, events = h.run([h.args.pose_writer, representation, FQ + "/reference_pose"]
                         + [repr(v) for v in target] + [str(seconds)], timeout=seconds + 20)
    assert code == 0, code
    echo_code, echoed = Harness.collect(echo, timeout=seconds + 20)
    states = [e["data"] for e in echoed if e["event"] == "sample"]
    assert echo_code == 0 and len(states) == observe, (echo_code, len(states))
    return first(events, "result"), states


def case_xcdr2(h):
    """(d) A writer that offers XCDR2 only does not match; the same writer on XCDR1 does.

    The XCDR2 writer is Cyclone's: Fast DDS 2.9 never announces its DataRepresentation QoS in
    discovery (the parameter is commented out in its SEDP code), so its "XCDR2" writer looks
    like XCDR1, matches every reader, and Cyclone then decodes the PLAIN_CDR2 samples by their
    encapsulation header. The stand-in run pins that behaviour down."""
    node = h.start_node()
    start_state = h.states(1)[0]
    start = position(start_state)
    q = start_state["current_pose"]["orientation"]
    target = [start[0] + STEP, start[1], start[2]] + q
    result, states = pose_writer(h, "xcdr2", target, 3, 200)
    h.log("xcdr2 writer: %s" % result)
    assert result["matched"] == 0 and result["total_matched"] == 0 and result["written"] >= 20
    assert_at_rest(h, states, start)
    # Control: the same writer offering XCDR1 matches and moves the arm.
    result, states = pose_writer(h, "xcdr1", target, 3, 250)
    h.log("xcdr1 writer: %s, final %s" % (result, position(states[-1])))
    assert result["matched"] == 1, result
    # The state's reference may be the filtered one (0.2 s to 95 %): settled after 2 s.
    assert distance(position(states[-1], "reference_pose"), target[:3]) < 1e-3
    assert distance(position(states[-1]), start) > STEP / 2
    if h.standin:
        code, events = h.peer("pose", "--ns", FQ, "--dx", -STEP, "--xcdr2", "--match-wait", 1,
                              "--timeout", 4)
        xcdr2 = first(events, "result")
        h.log("Fast DDS writer with XCDR2 QoS: %s" % xcdr2)
        assert xcdr2["matched"] == 1 and xcdr2["error"] < 1e-9, xcdr2
    h.stop_node(node)


def fuzz_inputs(start, orientation):
    pose = ["position=" + csv(start), "orientation=" + csv(orientation), "frame_id=panda_link0"]
    return [
        (FQ + "/reference_pose", "geometry_msgs/msg/PoseStamped", pose),
        (FQ + "/set_cartesian_stiffness", "geometry_msgs/msg/WrenchStamped",
         ["force=500,500,500", "torque=50,50,50"]),
        (FQ + "/set_cartesian_wrench", "geometry_msgs/msg/WrenchStamped",
         ["force=0,0,0", "torque=0,0,0"]),
        (FQ + "/set_damping_factors", "geometry_msgs/msg/Wrench", ["force=1,1,1", "torque=1,1,1"]),
        (FQ + "/set_config", "cartesian_impedance_controller/msg/ControllerConfig",
         ["stiffness=500,500,500,50,50,50", "damping=1,1,1,1,1,1", "nullspace_stiffness=10",
          "nullspace_damping=1", "q_d_nullspace=" + csv(READY_Q)]),
        ("/joint_trajectory", "trajectory_msgs/msg/JointTrajectory",
         ["joint_names=" + ",".join(JOINTS), "point=1:" + csv(READY_Q)]),
    ]


def case_fuzz(h):
    """(e) Thousands of malformed samples on every input; the node keeps running, its state keeps
    coming, and once valid settings are sent again a valid pose is reached as in (a)."""
    node = h.start_node()
    start_state = h.states(1)[0]
    start = position(start_state)
    orientation = start_state["current_pose"]["orientation"]
    inputs = fuzz_inputs(start, orientation)
    # The trajectory first, reference_pose last: a mutation that happens to be a valid command
    # (a trajectory somewhere else) is then superseded before the final pose.
    for seed, (topic, type_name, base) in enumerate(reversed(inputs), 1):
        code, events = h.peer("fuzz", topic, type_name, *base, "--seed", seed, "--count",
                              h.args.fuzz_count, "--rate", 4000, "--timeout", 10)
        h.log(json.dumps(events))
        published = first(events, "published")
        assert code == 0 and published["matched"] >= 1 and published["failed"] == 0, events
        assert node.poll() is None, "the node died fuzzing %s" % topic
    h.states(20)
    # Whatever the valid-looking mutations set, these restore it; the last sample wins.
    for topic, type_name, base in inputs[1:5]:
        code, events = h.peer("pub", topic, type_name, *base, "--count", 1)
        assert code == 0, events
    code, events = h.peer("pose", "--ns", FQ, "--x", start[0] + STEP, "--y", start[1], "--z",
                          start[2], "--qx", orientation[0], "--qy", orientation[1], "--qz",
                          orientation[2], "--qw", orientation[3], "--tolerance", TOLERANCE,
                          "--timeout", 20)
    result = first(events, "result")
    h.log("after the fuzz: %s" % result)
    assert code == 0 and result["converged"], result
    h.stop_node(node)


def case_topics(h):
    """Topics mode: Fast DDS feeds joint_states (the ready pose) and reads the torques the node
    commands on effort_controller/commands; a fuzzed joint_states does not stop it."""
    node = h.start_node(mode="topics")
    feed = ["name=" + ",".join(JOINTS), "position=" + csv(READY_Q), "velocity=" + csv([0] * 7),
            "effort=" + csv([0] * 7)]
    publisher = h.peer_background("pub", "/joint_states", "sensor_msgs/msg/JointState", *feed,
                                  "--count", 1200, "--rate", 200, "--timeout", 15)
    code, events = h.peer("echo", "/effort_controller/commands", "std_msgs/msg/Float64MultiArray",
                          "--count", 20, "--timeout", 15)
    commands = [e["data"]["data"] for e in events if e["event"] == "sample"]
    assert code == 0 and len(commands) == 20, events[-2:]
    for tau in commands:
        assert len(tau) == 7 and all(abs(t) <= limit for t, limit in zip(tau, TORQUE_LIMITS)), tau
    code, events = h.peer("fuzz", "/joint_states", "sensor_msgs/msg/JointState", *feed, "--seed",
                          7, "--count", h.args.fuzz_count, "--rate", 4000, "--timeout", 10)
    assert code == 0, events
    code, events = h.peer("echo", "/effort_controller/commands", "std_msgs/msg/Float64MultiArray",
                          "--count", 20, "--timeout", 10)
    assert code == 0, "no commands after the fuzz"
    publisher_code, _ = Harness.collect(publisher, timeout=20)
    assert publisher_code == 0
    h.stop_node(node)


CASES = {name[5:]: f for name, f in globals().items() if name.startswith("case_")}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--peer", required=True, help="ros2_fastdds_peer")
    parser.add_argument("--pose-writer", required=True, help="ros2_cyclone_pose_writer")
    parser.add_argument("--node", required=True, help="cartesian_impedance_ros2 (or the stand-in)")
    parser.add_argument("--models", help="folder of panda.urdf and panda.xml")
    parser.add_argument("--standin", action="store_true", help="NODE is ros2_cyclone_echo")
    parser.add_argument("--fuzz-count", type=int, default=2000, help="samples per input topic")
    parser.add_argument("cases", nargs="+", choices=sorted(CASES))
    args = parser.parse_args()
    failed = []
    for name in args.cases:
        h = Harness(args)
        ok = False
        started = time.monotonic()
        try:
            CASES[name](h)
            ok = True
        except Exception as error:  # a failed assertion, a peer that hung, ...
            h.log("FAIL %s: %s" % (name, error))
            traceback.print_exc()
        finally:
            h.close(ok)
        print("%s %s (%.1f s)" % ("PASS" if ok else "FAIL", name, time.monotonic() - started),
              flush=True)
        if not ok:
            failed.append(name)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
