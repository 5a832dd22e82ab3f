// The topics mode closed over the wire: the simulated robot (cartesian_impedance_ros2_sim_robot,
// the Panda's MJCF in MuJoCo) in one process, publishing stamped joint_states at 1 kHz and taking
// effort commands as a ros2_control JointGroupEffortController does; the node in topics mode in
// another; the test a third. Nothing is shared but DDS. The bounds are those of the node's sim
// mode (node_test.cpp), where the controller steps the same arm in its own cycle: the wire adds a
// delay of a cycle or two, which moves no equilibrium. A realistic plant (model error, 1 ms
// sensing and actuation delay, noise) runs over the wire too.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <regex>

#include "client.hpp"
#include "harness.hpp"

namespace cartesian_impedance_ros2::test {
namespace {

std::string topics_params() {
  return topics_params_file("wire_topics_panda.yaml");
}

// The robot (its own sim-mode params file: the Panda's MJCF at its ready pose) and the node on
// its joint_states, both in /robot.
struct Wire {
  // `node_params`: the node's params file (default: topics_params()).
  explicit Wire(const std::vector<std::string>& robot_options = {},
                const std::string& node_params = topics_params())
      : robot(CARTESIAN_IMPEDANCE_ROS2_SIM_ROBOT,
              with(robot_options,
                   {"--ros-args", "-r", "__ns:=/robot", "--params-file", sim_params()})),
        node({"--ros-args", "-r", "__ns:=/robot", "--params-file", node_params}),
        client("/robot/cartesian_impedance_controller") {}

  static std::vector<std::string> with(std::vector<std::string> first,
                                       const std::vector<std::string>& then) {
    first.insert(first.end(), then.begin(), then.end());
    return first;
  }

  NodeProcess robot;
  NodeProcess node;
  Client client;
};

const Eigen::Vector3d kStep(0.0, 0.05, -0.05);  // as node_test.cpp's

double largest(const std::vector<double>& values) {
  double most = 0.0;
  for (const double v : values) most = std::max(most, std::abs(v));
  return most;
}

// The robot's latest summary: "... N brakes after the torque timeout; effort commands from
// written to taken: COUNT, p50 A us, p99 B us, max C us".
struct RobotReport {
  long brakes = -1;
  long commands = -1;
  double p50_us = -1.0, p99_us = -1.0, max_us = -1.0;
};

RobotReport robot_report(const std::string& log) {
  static const std::regex line(
      "(\\d+) brakes after the torque timeout; effort commands from written to taken: (\\d+), "
      "p50 (\\d+) us, p99 (\\d+) us, max (\\d+) us");
  RobotReport report;
  for (auto it = std::sregex_iterator(log.begin(), log.end(), line); it != std::sregex_iterator();
       ++it) {
    report = {std::stol((*it)[1]), std::stol((*it)[2]), std::stod((*it)[3]), std::stod((*it)[4]),
              std::stod((*it)[5])};
  }
  return report;
}

// A reference step: the arm moves there and stays, as in sim mode; then the round trip.
TEST(Ros2Wire, AReferenceStepMovesTheArmAcrossProcessesAndItHolds) {
  Wire wire;
  const State start = wire.client.running();
  // The ready pose of panda.xml, as the robot measured it.
  EXPECT_NEAR(start.position.x(), 0.3069, 2e-3);
  EXPECT_NEAR(start.position.z(), 0.5903, 2e-3);
  const Eigen::Vector3d target = start.position + kStep;
  wire.client.pose(target, start.orientation);
  const State moved = wire.client.settle(3.0);
  EXPECT_LT((moved.position - target).norm(), 1.5e-3)
      << "at " << moved.position.transpose() << ", target " << target.transpose();
  // Held: the demo's hold bound (0.5 mm over 2 s, MuJoCo's soft joint friction creeping).
  const State held = wire.client.settle(2.0);
  EXPECT_LT((held.position - moved.position).norm(), 0.5e-3);
  EXPECT_LT(largest(held.dq), 0.01);
  EXPECT_EQ(held.status, "ok");
  EXPECT_EQ(held.oscillations, 0u);
  EXPECT_EQ(held.stale_episodes, 0u);
  // The nominal plant's readings are stamped when taken: their age at the cycle is what the
  // wire and the robot's 100 us poll add, well under the 100 ms joint_states_timeout.
  EXPECT_GT(held.measurement_age_p50_us, 0.0);
  EXPECT_LE(held.measurement_age_p50_us, held.measurement_age_p99_us);
  EXPECT_LE(held.measurement_age_p99_us, held.measurement_age_max_us);
  EXPECT_LT(held.measurement_age_max_us, 100000.0);
  std::printf(
      "round trip, nominal plant: joint_states age at the node's cycle p50 %.0f us, "
      "p99 %.0f us, max %.0f us\n",
      held.measurement_age_p50_us, held.measurement_age_p99_us, held.measurement_age_max_us);

  EXPECT_EQ(wire.node.stop(), 0) << wire.node.log();
  EXPECT_EQ(wire.robot.stop(), 0) << wire.robot.log();
  const RobotReport report = robot_report(wire.robot.log());
  EXPECT_GT(report.commands, 4000) << wire.robot.log();  // 1 kHz for 5 s and more
  EXPECT_LE(report.p50_us, report.p99_us);
  std::printf(
      "effort commands from written to taken by the robot: p50 %.0f us, p99 %.0f us, "
      "max %.0f us\n",
      report.p50_us, report.p99_us, report.max_us);
}

// A commanded wrench against the spring over the wire: F / K, as in sim mode.
TEST(Ros2Wire, ACommandedWrenchDisplacesTheArmByForceOverStiffness) {
  Wire wire;
  const State start = wire.client.running();
  wire.client.wrench((ci::Vector6d() << 0, 0, -5, 0, 0, 0).finished());
  // 5 N on 500 N/m: 10 mm down, within the friction band (node_test.cpp).
  const State end = wire.client.settle(3.0);
  EXPECT_NEAR(end.position.z() - start.position.z(), -0.010, 1.5e-3);
  EXPECT_EQ(end.status, "ok");
}

// When the controller stops, the robot brakes within its torque timeout (20 ms) instead of
// applying the last torque on; a controller started again takes the arm from where it was held.
TEST(Ros2Wire, TheRobotBrakesWhenTheControllerStopsAndANewOneTakesOver) {
  std::optional<Wire> wire(std::in_place);
  const State start = wire->client.running();
  Latest<JointStateMessage, std::vector<double> (*)(const JointStateMessage&)> joints(
      Client::participant(), "rt/robot/joint_states",
      +[](const JointStateMessage& m) { return values(m.position); });
  // Stopped mid-move: the last torque accelerates the arm toward a target 7 cm away.
  wire->client.pose(start.position + kStep, start.orientation);
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  EXPECT_EQ(wire->node.stop(), 0) << wire->node.log();
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ASSERT_TRUE(joints.wait(1.0, [](const std::vector<double>& q) { return q.size() == 7; }));
  const std::vector<double> braked = joints.value();
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  ASSERT_TRUE(joints.wait(1.0, [](const std::vector<double>&) { return true; }));
  for (std::size_t i = 0; i < 7; ++i) EXPECT_EQ(joints.value()[i], braked[i]) << "joint " << i;

  // A new controller starts where the brakes hold the arm, and holds it there.
  NodeProcess node({"--ros-args", "-r", "__ns:=/robot", "--params-file", topics_params()});
  Client client("/robot/cartesian_impedance_controller");
  const State taken = client.running();
  const State later = client.settle(1.5);
  EXPECT_LT((later.position - taken.position).norm(), 0.5e-3);
  EXPECT_EQ(later.status, "ok");
  EXPECT_EQ(wire->robot.stop(), 0);
  EXPECT_GE(robot_report(wire->robot.log()).brakes, 1) << wire->robot.log();
}

// The realistic plant over the wire: model error, readings 1 ms old, torques acting 1 ms late,
// noise. The stamps carry the readings' age to the node, which reports it.
TEST(Ros2Wire, ARealisticPlantSettlesOverTheWireAndItsReadingsAgeIsReported) {
  Wire wire({"--plant", "realistic", "--plant-seed", "3"});
  const State start = wire.client.running();
  const Eigen::Vector3d target = start.position + kStep;
  wire.client.pose(target, start.orientation);
  const State end = wire.client.settle(4.0);
  // The friction band of the sim-mode bound (1.5 mm) with the plant's friction up to 1.5 times
  // the model's.
  EXPECT_LT((end.position - target).norm(), 2.25e-3)
      << "at " << end.position.transpose() << ", target " << target.transpose();
  EXPECT_EQ(end.status, "ok");
  EXPECT_EQ(end.oscillations, 0u);
  EXPECT_LT(largest(end.dq), 0.05);  // at rest up to the plant's velocity noise (0.005 rad/s)
  // Each reading is at least the plant's 1 ms old when the node uses it: the age comes from the
  // stamp, not from when the sample arrived.
  EXPECT_GE(end.measurement_age_p50_us, 1000.0);
  EXPECT_LT(end.measurement_age_max_us, 100000.0);
  std::printf(
      "round trip, realistic plant: joint_states age at the node's cycle p50 %.0f us, "
      "p99 %.0f us, max %.0f us\n",
      end.measurement_age_p50_us, end.measurement_age_p99_us, end.measurement_age_max_us);
}

// The demo's table scenario over the wire: a table 3 cm under the flange, the vertical stiffness
// released, 10 N commanded down: the robot measures 10 N of contact.
TEST(Ros2Wire, ACommandedForcePressesOnATableWithThatForce) {
  Wire wire({"--table-under-flange", "0.03"});
  const State start = wire.client.running();
  Reader<WrenchStamped> contact(Client::participant(), "rt/robot/sim_robot/contact_wrench",
                                TopicQos{});
  std::vector<double> forces;  // z, in the order received
  const auto receive = [&](std::size_t count) {
    forces.clear();
    return eventually(3.0, [&] {
      contact.take([&](const WrenchStamped& m) { forces.push_back(m.wrench.force.z); });
      return forces.size() >= count;
    });
  };
  ASSERT_TRUE(receive(10));
  EXPECT_EQ(forces.back(), 0.0);  // not touching yet
  ci::Vector6d stiffness = start.commanded_stiffness;
  stiffness[2] = 0.0;
  wire.client.stiffness(stiffness);
  wire.client.wrench((ci::Vector6d() << 0, 0, -10, 0, 0, 0).finished());
  const State pressing = wire.client.settle(3.0);
  // The flange is on the table, 3 cm down (the contact's give is a fraction of a millimetre).
  EXPECT_NEAR(pressing.position.z() - start.position.z(), -0.03, 1e-3);
  contact.take([](const WrenchStamped&) {});  // what queued up while the arm went down
  ASSERT_TRUE(receive(100));                  // 1 s at 100 Hz
  double mean = 0.0;
  for (const double force : forces) mean += force / static_cast<double>(forces.size());
  // The demo's bound for the Panda: 5 % and the joints' friction band along z (0.45 N), which
  // may hold part of the force where the table stopped the arm.
  EXPECT_NEAR(mean, 10.0, 0.95);
  std::printf("table over the wire: flange %.2f mm down, contact force %.3f N for 10 N\n",
              1e3 * (start.position.z() - pressing.position.z()), mean);
  EXPECT_EQ(pressing.status, "ok");
}

// A collision reaction holds until ~/resume: with collision.reaction stop, a reference 3 cm into
// a table 3 cm under the flange is a collision; the arm stops on the table and a reference back
// up is not followed; after an empty message on ~/resume the next reference is. The observer
// reads the simulated robot's joint torque sensors, the effort of its joint_states
// (collision.measured_torque): without them every cycle would fail closed.
TEST(Ros2Wire, ACollisionStopsTheArmUntilResume) {
  Wire wire({"--table-under-flange", "0.03"},
            topics_params_file("wire_topics_panda_stop.yaml",
                               "    collision.reaction: stop\n"
                               "    collision.measured_torque: true\n"));
  const State start = wire.client.running();
  ASSERT_FALSE(start.collision_detected);
  wire.client.pose(start.position - Eigen::Vector3d(0, 0, 0.06), start.orientation);
  ASSERT_TRUE(wire.client.wait(5.0, [](const State& s) { return s.collision_detected; }));
  const State hit = wire.client.settle(0.5);
  EXPECT_EQ(hit.collision_reaction, "stop");
  EXPECT_GT(hit.position.z() - start.position.z(), -0.035);  // on the table, 3 cm down
  EXPECT_LT(hit.position.z() - start.position.z(), -0.02);
  const Eigen::Vector3d above = start.position + Eigen::Vector3d(0, 0, 0.03);
  wire.client.pose(above, start.orientation);
  const State held = wire.client.settle(1.0);
  EXPECT_TRUE(held.collision_detected);
  EXPECT_LT((held.position - hit.position).norm(), 2e-3) << "followed before resume";
  wire.client.resume();
  ASSERT_TRUE(wire.client.wait(3.0, [](const State& s) { return !s.collision_detected; }));
  wire.client.pose(above, start.orientation);
  EXPECT_TRUE(wire.client.wait(5.0, [&](const State& s) {
    return (s.position - above).norm() < 3e-3;
  })) << wire.client.settle(0.0).position.transpose();
  const State end = wire.client.settle(0.0);
  EXPECT_EQ(end.collisions, 1u);
  EXPECT_EQ(end.status, "ok");
  EXPECT_NE(wire.node.log().find("resume"), std::string::npos);
}

// What the simulated robot cannot simulate ends it with exit code 2 and a message naming it.
TEST(Ros2Wire, TheSimulatedRobotRefusesWhatItCannotSimulate) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--plant", "wobbly"}, "wobbly"},
      {{"--torque-timeout", "-1"}, "--torque-timeout '-1' is not a number > 0"},
      {{"--table-under-flange", "5"}, "--table-under-flange 5 m: the flange is only"},
      {{"--frobnicate"}, "unknown argument '--frobnicate'"},
  };
  for (const auto& [options, message] : cases) {
    NodeProcess robot(CARTESIAN_IMPEDANCE_ROS2_SIM_ROBOT,
                      Wire::with(options, {"--ros-args", "--params-file", sim_params()}));
    EXPECT_EQ(robot.wait_for_exit(20.0), 2) << robot.log();
    EXPECT_NE(robot.log().find(message), std::string::npos) << robot.log();
  }
}

}  // namespace
}  // namespace cartesian_impedance_ros2::test
