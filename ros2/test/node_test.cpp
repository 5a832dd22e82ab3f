// The ROS 2 node end to end over DDS: the node runs as its own process in a private domain; the
// test talks to it as a ROS 2 node would (same topics, types, QoS) and checks what the simulated
// arm does. Tolerances: at the Panda's 500 N/m the MuJoCo model's joint friction (the frictionloss
// of panda.xml, through the Jacobian) holds the flange within about 1.1 mm of where the spring
// alone would (5.5 mm at 100 N/m, as measured in the ROS 1 node's tests, scales with 1/K).

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include <cartesian_impedance/model/start_configuration.hpp>
#include <cartesian_impedance/sim/simulation.hpp>

#include "client.hpp"
#include "harness.hpp"

namespace cartesian_impedance_ros2::test {
namespace {

namespace ci = cartesian_impedance;

const Eigen::Vector3d kStep(0.0, 0.05, -0.05);  // 7 cm: well outside every tolerance below

TEST(Ros2Node, ReferencePoseMovesTheArmThere) {
  NodeProcess node({"--ros-args", "--params-file", sim_params()});
  Client client;
  const State start = client.running();
  // The ready pose of panda.xml: the flange at (0.307, 0, 0.590) m.
  EXPECT_NEAR(start.position.x(), 0.3069, 2e-3);
  EXPECT_NEAR(start.position.z(), 0.5903, 2e-3);
  const Eigen::Vector3d target = start.position + kStep;
  client.pose(target, start.orientation);
  // Filter 0.2 s to 95 %, then the arm (critically damped at 500 N/m): settled within 3 s.
  const State end = client.settle(3.0);
  EXPECT_LT((end.position - target).norm(), 1.5e-3)
      << "at " << end.position.transpose() << ", target " << target.transpose();
  EXPECT_EQ(end.status, "ok");
  EXPECT_TRUE(node.running());
  EXPECT_EQ(node.stop(), 0) << node.log();
}

TEST(Ros2Node, BadCommandsAreRejectedByFieldAndChangeNothing) {
  NodeProcess node({"--ros-args", "--params-file", sim_params()});
  Client client;
  const State start = client.running();
  const double nan = std::nan("");
  client.pose({nan, 0.0, 0.5}, start.orientation);
  client.pose(start.position + kStep, {0, 0, 0, 2});  // quaternion of norm 2
  client.pose(start.position + kStep, start.orientation, "world");
  client.stiffness((ci::Vector6d() << -5, 500, 500, 50, 50, 50).finished());
  client.stiffness((ci::Vector6d() << 800, 800, 800, 50, 50, 50).finished(), "camera");
  client.wrench(
      (ci::Vector6d() << 0, 0, std::numeric_limits<double>::infinity(), 0, 0, 0).finished());
  client.config(ci::Vector6d::Constant(300), ci::Vector6d::Ones(), 10, 1, {0.1, 0.2, 0.3});
  const State after = client.settle(1.0);
  EXPECT_LT((after.position - start.position).norm(), 1e-3) << "the arm moved";
  EXPECT_LT((after.commanded_position - start.commanded_position).norm(), 1e-12);
  EXPECT_EQ(after.commanded_stiffness, start.commanded_stiffness);
  EXPECT_EQ(after.commanded_wrench, start.commanded_wrench);
  EXPECT_EQ(after.status, "ok");
  const std::string log = node.log();
  for (const char* expected : {"reference_pose rejected", "nan", "set_cartesian_stiffness rejected",
                               "-5", "'camera' is not a frame", "set_cartesian_wrench rejected",
                               "set_config rejected", "q_d_nullspace has 3 values"}) {
    EXPECT_NE(log.find(expected), std::string::npos) << "no '" << expected << "' in\n" << log;
  }
  // And a good command still works.
  client.pose(start.position + kStep, start.orientation);
  EXPECT_TRUE(client.wait(3.0, [&](const State& s) {
    return (s.position - (start.position + kStep)).norm() < 1.5e-3;
  }));
}

TEST(Ros2Node, WrenchTopicPushesAgainstTheSpring) {
  NodeProcess node({"--ros-args", "--params-file", sim_params()});
  Client client;
  const State start = client.running();
  client.wrench((ci::Vector6d() << 0, 0, -5, 0, 0, 0).finished());
  // 5 N on 500 N/m: 10 mm down, within the friction band.
  const State end = client.settle(3.0);
  EXPECT_NEAR(end.position.z() - start.position.z(), -0.010, 1.5e-3);
  EXPECT_NEAR(end.commanded_wrench[2], -5.0, 1e-12);
}

TEST(Ros2Node, StiffnessAndConfigTopicsSetTheController) {
  NodeProcess node({"--ros-args", "--params-file", sim_params()});
  Client client;
  const State start = client.running();
  const ci::Vector6d k = (ci::Vector6d() << 300, 400, 600, 30, 40, 60).finished();
  client.stiffness(k, "panda_link0");
  EXPECT_TRUE(client.wait(2.0, [&](const State& s) { return s.commanded_stiffness == k; }));
  // The published controller's set_config: stiffness, damping, nullspace stiffness and target.
  std::vector<double> q_d = start.q;
  q_d[0] += 0.2;
  const ci::Vector6d k2 = (ci::Vector6d() << 700, 700, 700, 70, 70, 70).finished();
  client.config(k2, ci::Vector6d::Constant(0.9), 20.0, 1.0, q_d);
  ASSERT_TRUE(client.wait(2.0, [&](const State& s) {
    return s.commanded_stiffness == k2 && std::abs(s.nullspace_config[0] - q_d[0]) < 1e-3;
  }));
  // Filtered toward 20 Nm/rad; the energy tank pays for the raise as it does for the Cartesian
  // stiffness (the 500 -> 700 N/m raise drains it too), so it may arrive after the target.
  EXPECT_TRUE(client.wait(2.0, [&](const State& s) {
    return std::abs(s.nullspace_stiffness[6] - 20.0) < 0.5;
  })) << client.settle(0.0).nullspace_stiffness[6];
}

TEST(Ros2Node, JointTrajectoryRunsAndAnEmptyOneCancels) {
  NodeProcess node({"--ros-args", "--params-file", sim_params()});
  Client client;
  const State start = client.running();
  Writer<JointTrajectoryMessage> writer(Client::participant(), "rt/joint_trajectory", TopicQos{});
  ASSERT_TRUE(eventually(5.0, [&] { return writer.matched() > 0; }));
  std::vector<std::string> names;
  for (int i = 1; i <= 7; ++i) names.push_back("panda_joint" + std::to_string(i));
  std::vector<char*> name_pointers;
  for (std::string& name : names) name_pointers.push_back(name.data());
  std::vector<double> goal = start.q;
  goal[0] += 0.15;
  trajectory_msgs_msg_dds__JointTrajectoryPoint_ point{};
  point.positions._buffer = goal.data();
  point.positions._length = point.positions._maximum = 7;
  point.time_from_start.sec = 1;
  JointTrajectoryMessage m{};
  m.header.frame_id = const_cast<char*>("");
  m.joint_names._buffer = name_pointers.data();
  m.joint_names._length = m.joint_names._maximum = 7;
  m.points._buffer = &point;
  m.points._length = m.points._maximum = 1;
  ASSERT_TRUE(writer.write(m));
  ASSERT_TRUE(client.wait(4.0, [](const State& s) { return s.trajectory_state == "finished"; }))
      << client.settle(0).trajectory_state;
  const State end = client.settle(0.5);
  EXPECT_NEAR(end.q[0], goal[0], 0.01);
  EXPECT_LT(end.trajectory_goal_error, 0.01);

  // A second one, cancelled by an empty trajectory half-way.
  goal[0] -= 0.3;
  point.time_from_start.sec = 2;
  ASSERT_TRUE(writer.write(m));
  ASSERT_TRUE(client.wait(2.0, [](const State& s) { return s.trajectory_state == "executing"; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  JointTrajectoryMessage cancel{};
  cancel.header.frame_id = const_cast<char*>("");
  ASSERT_TRUE(writer.write(cancel));
  EXPECT_TRUE(client.wait(1.0, [](const State& s) { return s.trajectory_state == "cancelled"; }));
  const State stopped = client.settle(1.0);
  EXPECT_GT(stopped.q[0] - goal[0], 0.05) << "it went on to the goal";
}

TEST(Ros2Node, TwoNamespacedArmsAreIndependent) {
  NodeProcess left({"--ros-args", "-r", "__ns:=/left", "--params-file", sim_params()});
  NodeProcess right(
      {"--ros-args", "-r", "__ns:=/right", "-r", "__node:=arm", "--params-file", sim_params()});
  Client left_client("/left/cartesian_impedance_controller");
  Client right_client("/right/arm");
  const State left_start = left_client.running();
  const State right_start = right_client.running();
  left_client.pose(left_start.position + kStep, left_start.orientation);
  const State left_end = left_client.settle(3.0);
  const State right_end = right_client.settle(0.0);
  EXPECT_LT((left_end.position - (left_start.position + kStep)).norm(), 1.5e-3);
  EXPECT_LT((right_end.position - right_start.position).norm(), 1e-3) << "the other arm moved";
}

// ---- tf ----------------------------------------------------------------------------------------

// A Franka hand on the flange with two fingers (prismatic, outside the chain): links with visuals
// that a robot display needs transforms for.
std::string panda_with_hand() {
  std::ifstream file(repository() + "/models/panda/panda.urdf");
  std::stringstream text;
  text << file.rdbuf();
  std::string urdf = text.str();
  urdf.insert(urdf.rfind("</robot>"), R"(
  <link name="panda_hand"><visual><geometry><box size="0.05 0.2 0.06"/></geometry></visual></link>
  <link name="panda_leftfinger"><visual><geometry><box size="0.02 0.02 0.05"/></geometry></visual></link>
  <link name="panda_rightfinger"><visual><geometry><box size="0.02 0.02 0.05"/></geometry></visual></link>
  <joint name="panda_hand_joint" type="fixed">
    <parent link="panda_link8"/><child link="panda_hand"/><origin rpy="0 0 -0.7853981633974483"/>
  </joint>
  <joint name="panda_finger_joint1" type="prismatic">
    <parent link="panda_hand"/><child link="panda_leftfinger"/><origin xyz="0 0 0.0584"/>
    <axis xyz="0 1 0"/><limit effort="20" lower="0" upper="0.04" velocity="0.2"/>
  </joint>
  <joint name="panda_finger_joint2" type="prismatic">
    <parent link="panda_hand"/><child link="panda_rightfinger"/><origin xyz="0 0 0.0584"/>
    <axis xyz="0 -1 0"/><limit effort="20" lower="0" upper="0.04" velocity="0.2"/>
    <mimic joint="panda_finger_joint1"/>
  </joint>
)");
  const std::string path = std::string(CARTESIAN_IMPEDANCE_BINARY_DIR) + "/panda_hand.urdf";
  std::ofstream(path) << urdf;
  return path;
}

std::int64_t nanoseconds(const builtin_interfaces_msg_dds__Time_& t) {
  return std::int64_t{t.sec} * 1000000000 + t.nanosec;
}

// Every transform of /tf by stamp, and of /tf_static (transient local: also what was written
// before this reader existed), as tf2's buffer would hold them: child -> (parent, T).
class TfRecorder {
 public:
  using Tree = std::map<std::string, std::pair<std::string, Eigen::Isometry3d>>;
  explicit TfRecorder(const Participant& participant)
      : moving_(participant, "rt/tf", TopicQos{true, false, 100}),
        fixed_(participant, "rt/tf_static", TopicQos{true, true, 10}) {}

  void poll() {
    moving_.take([&](const TFMessage& m) { add(m, by_stamp_); });
    fixed_.take([&](const TFMessage& m) { add(m, by_stamp_, &fixed_tree_); });
  }
  const Tree& fixed() const { return fixed_tree_; }
  // The static transforms and the moving ones of `stamp`; empty if no /tf message has it.
  Tree tree(std::int64_t stamp) const {
    const auto found = by_stamp_.find(stamp);
    if (found == by_stamp_.end()) return {};
    Tree tree = fixed_tree_;
    for (const auto& [child, entry] : found->second) tree[child] = entry;
    return tree;
  }

 private:
  static void add(const TFMessage& m, std::map<std::int64_t, Tree>& by_stamp,
                  Tree* fixed = nullptr) {
    for (std::uint32_t i = 0; i < m.transforms._length; ++i) {
      const geometry_msgs_msg_dds__TransformStamped_& t = m.transforms._buffer[i];
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation() = Eigen::Vector3d(t.transform.translation.x, t.transform.translation.y,
                                        t.transform.translation.z);
      T.linear() = Eigen::Quaterniond(t.transform.rotation.w, t.transform.rotation.x,
                                      t.transform.rotation.y, t.transform.rotation.z)
                       .toRotationMatrix();
      Tree& tree = fixed ? *fixed : by_stamp[nanoseconds(t.header.stamp)];
      tree[t.child_frame_id] = {t.header.frame_id, T};
    }
  }
  Reader<TFMessage> moving_;
  Reader<TFMessage> fixed_;
  std::map<std::int64_t, Tree> by_stamp_;
  Tree fixed_tree_;
};

// T_root_frame composed from the tree; nullopt if a transform on the way is missing.
std::optional<Eigen::Isometry3d> compose(const TfRecorder::Tree& tree, const std::string& root,
                                         std::string frame) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  while (frame != root) {
    const auto found = tree.find(frame);
    if (found == tree.end()) return std::nullopt;
    T = found->second.second * T;
    frame = found->second.first;
  }
  return T;
}

struct Stamped {
  std::int64_t stamp = 0;
  std::string frame_id;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};

// The tip composed from tf at the stamp of a full_state equals its current_pose: one sample of
// the loop gives both (same q, same stamp), so only rounding separates them. Returns the state.
Stamped check_tf_matches_state(TfRecorder& tf, const std::string& node, const std::string& root,
                               const std::string& tip) {
  Latest<FullState, Stamped (*)(const FullState&)> states(
      Client::participant(), "rt" + node + "/full_state", +[](const FullState& m) {
        Stamped s;
        s.stamp = nanoseconds(m.header.stamp);
        s.frame_id = m.header.frame_id;
        s.pose.translation() = Eigen::Vector3d(m.current_pose.position.x, m.current_pose.position.y,
                                               m.current_pose.position.z);
        s.pose.linear() =
            Eigen::Quaterniond(m.current_pose.orientation.w, m.current_pose.orientation.x,
                               m.current_pose.orientation.y, m.current_pose.orientation.z)
                .toRotationMatrix();
        return s;
      });
  std::optional<Eigen::Isometry3d> composed;
  const bool matched = states.wait(10.0, [&](const Stamped& s) {
    tf.poll();
    composed = compose(tf.tree(s.stamp), root, tip);
    return composed.has_value();
  });
  EXPECT_TRUE(matched) << "no /tf at the stamp of a full_state from " << node << " composing "
                       << root << " -> " << tip;
  if (!matched) return {};
  const Stamped state = states.value();
  EXPECT_LT((composed->translation() - state.pose.translation()).norm(), 1e-9);
  EXPECT_LT((composed->linear() - state.pose.linear()).norm(), 1e-9);
  return state;
}

// The node as robot_state_publisher: /tf at publish_rate with the state's stamp, /tf_static and
// robot_description transient local, every frame prefixed.
TEST(Ros2Node, PublishesTheRobotsTransformsAndDescription) {
  const std::string urdf = panda_with_hand();
  const std::string params = params_file("tf_panda.yaml", R"(
/**:
  ros__parameters:
    urdf_path: )" + urdf + R"(
    mjcf_path: )" + repository() + R"(/models/panda/panda.xml
    base_link: panda_link0
    tip_link: panda_link8
    tf_prefix: arm/
    parameters_file: )" + repository() + R"(/config/panda.yaml
)");
  NodeProcess node({"--ros-args", "--params-file", params});
  Client client;
  const State start = client.running();
  // Readers created after the node wrote /tf_static and robot_description: transient local.
  TfRecorder tf(Client::participant());
  Latest<StringMessage, std::string (*)(const StringMessage&)> description(
      Client::participant(), "rt/robot_description",
      +[](const StringMessage& m) { return std::string(m.data); }, TopicQos{true, true, 1});
  ASSERT_TRUE(description.wait(5.0, [](const std::string&) { return true; }));
  std::ifstream file(urdf);
  std::stringstream text;
  text << file.rdbuf();
  EXPECT_EQ(description.value(), text.str());

  const Stamped state = check_tf_matches_state(tf, "/cartesian_impedance_controller",
                                               "arm/panda_link0", "arm/panda_link8");
  EXPECT_EQ(state.frame_id, "arm/panda_link0");
  std::map<std::string, std::string> parents;
  for (const auto& [child, entry] : tf.tree(state.stamp)) parents[child] = entry.first;
  std::map<std::string, std::string> expected = {{"arm/panda_link8", "arm/panda_link7"},
                                                 {"arm/panda_hand", "arm/panda_link8"},
                                                 {"arm/panda_leftfinger", "arm/panda_hand"},
                                                 {"arm/panda_rightfinger", "arm/panda_hand"}};
  EXPECT_EQ(tf.fixed().size(), expected.size());
  for (int i = 1; i <= 7; ++i) {
    expected["arm/panda_link" + std::to_string(i)] = "arm/panda_link" + std::to_string(i - 1);
  }
  EXPECT_EQ(parents, expected);
  EXPECT_LT(
      (tf.fixed().at("arm/panda_leftfinger").second.translation() - Eigen::Vector3d(0, 0, 0.0584))
          .norm(),
      1e-12);

  // After a move (a reference in the prefixed base frame), tf follows.
  client.pose(start.position + kStep, start.orientation, "arm/panda_link0");
  ASSERT_TRUE(client.wait(4.0, [&](const State& s) {
    return (s.position - (start.position + kStep)).norm() < 1.5e-3;
  }));
  const Stamped moved = check_tf_matches_state(tf, "/cartesian_impedance_controller",
                                               "arm/panda_link0", "arm/panda_link8");
  EXPECT_GT((moved.pose.translation() - start.position).norm(), 0.05);
}

// sim mode without mjcf_path (ros2/config/sim_ur5e.yaml): MuJoCo simulates the URDF, started at
// start_q.
TEST(Ros2Node, SimulatesTheUrdfFromStartQ) {
  const std::string params = repository() + "/ros2/config/sim_ur5e.yaml";
  NodeProcess node({"--ros-args", "--params-file", params});
  Client client;
  const State start = client.running();
  const std::vector<double> start_q = {M_PI, -M_PI / 2, M_PI / 2, -M_PI / 2, -M_PI / 2, 0.0};
  ASSERT_EQ(start.q.size(), 6u);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(start.q[i], start_q[i], 0.02) << i;
  EXPECT_NE(node.log().find("(the URDF simulated)"), std::string::npos) << node.log();
  TfRecorder tf(Client::participant());
  check_tf_matches_state(tf, "/cartesian_impedance_controller", "base_link", "tool0");
  const Eigen::Vector3d step(0.0, 0.04, 0.03);
  client.pose(start.position + step, start.orientation);
  EXPECT_TRUE(client.wait(4.0, [&](const State& s) {
    return (s.position - (start.position + step)).norm() < 3e-3;
  })) << client.settle(0).position.transpose();
}

// sim mode without mjcf_path and without start_q: q = 0 is singular on the UR5e, so the node
// starts where find_start_configuration() chooses, says so, and moves from there.
TEST(Ros2Node, SimulatesTheUrdfFromAChosenStartWithoutStartQ) {
  const std::string urdf = repository() + "/models/ur5e/ur5e.urdf";
  const std::string params = params_file("ur5e_no_start.yaml", R"(
/**:
  ros__parameters:
    mode: sim
    urdf_path: )" + urdf + R"(
    base_link: base_link
    tip_link: tool0
    parameters_file: )" + repository() + R"(/config/ur5e.yaml
)");
  NodeProcess node({"--ros-args", "--params-file", params});
  Client client;
  const State start = client.running();
  const ci::JointVector chosen =
      ci::find_start_configuration(ci::RobotModel::from_urdf_file(urdf, "base_link", "tool0")).q;
  ASSERT_EQ(start.q.size(), 6u);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(start.q[i], chosen[i], 0.02) << i;
  EXPECT_NE(node.log().find("start configuration (chosen, no start_q set: smallest singular"),
            std::string::npos)
      << node.log();
  const Eigen::Vector3d step(0.0, 0.04, 0.03);
  client.pose(start.position + step, start.orientation);
  EXPECT_TRUE(client.wait(4.0, [&](const State& s) {
    return (s.position - (start.position + step)).norm() < 3e-3;
  })) << client.settle(0).position.transpose();
}

// The same with DART (engine: dart) integrating the URDF instead of MuJoCo.
TEST(Ros2Node, SimulatesTheUrdfWithDart) {
  std::string reason;
  if (!ci::sim::engine_available(ci::sim::Engine::dart, &reason)) GTEST_SKIP() << reason;
  const std::string params = repository() + "/ros2/config/sim_ur5e.yaml";
  NodeProcess node({"--ros-args", "--params-file", params, "-p", "engine:=dart"});
  Client client;
  const State start = client.running();
  const std::vector<double> start_q = {M_PI, -M_PI / 2, M_PI / 2, -M_PI / 2, -M_PI / 2, 0.0};
  ASSERT_EQ(start.q.size(), 6u);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(start.q[i], start_q[i], 0.02) << i;
  EXPECT_NE(node.log().find("mode sim, engine dart"), std::string::npos) << node.log();
  EXPECT_NE(node.log().find("(the URDF simulated)"), std::string::npos) << node.log();
  // DART's joint friction is exact stiction: the arm stops where the spring no longer overcomes
  // it, 3.1 mm short at the UR5e's 500 N/m (MuJoCo's soft friction creeps on to 2.8 mm).
  const Eigen::Vector3d step(0.0, 0.04, 0.03);
  client.pose(start.position + step, start.orientation);
  EXPECT_TRUE(client.wait(4.0, [&](const State& s) {
    return (s.position - (start.position + step)).norm() < 5e-3;
  })) << client.settle(0).position.transpose();
}

// A robot's joint_states at about 500 Hz (as its ros2_control would publish them, with a finger
// joint the arm does not have), standing at the Panda's ready pose, until stopped; `dq4` is the
// fourth arm joint's speed [rad/s].
class JointStatesPlayer {
 public:
  explicit JointStatesPlayer(const std::string& topic)
      : writer_(Client::participant(), topic, TopicQos{}) {
    names_ = {"panda_finger_joint1"};
    for (int i = 1; i <= 7; ++i) names_.push_back("panda_joint" + std::to_string(i));
    for (std::string& name : names_) name_pointers_.push_back(name.data());
    thread_ = std::thread([this] { play(); });
  }
  ~JointStatesPlayer() { stop(); }
  void stop() {
    publishing_ = false;
    if (thread_.joinable()) thread_.join();
  }
  std::atomic<double> dq4{0.0};

 private:
  void play() {
    const std::vector<double> ready = {0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4};
    std::vector<double> q = {0.04}, dq(8, 0.0);
    q.insert(q.end(), ready.begin(), ready.end());
    JointStateMessage m{};
    m.header.frame_id = const_cast<char*>("");
    m.name._buffer = name_pointers_.data();
    m.position._buffer = q.data();
    m.velocity._buffer = dq.data();
    m.name._length = m.position._length = m.velocity._length = 8;
    while (publishing_) {
      dq[4] = dq4;
      writer_.write(m);
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }
  Writer<JointStateMessage> writer_;
  std::vector<std::string> names_;
  std::vector<char*> name_pointers_;
  std::atomic<bool> publishing_{true};
  std::thread thread_;
};

std::string topics_params() {
  return topics_params_file("topics_panda.yaml", "    filter: {pose: {time: 0.0}}\n");
}

// Topics mode: joint_states in (as a robot's ros2_control would publish them), torques out to the
// effort controller, failing closed when joint_states stop.
TEST(Ros2Node, TopicsModeTakesJointStatesAndCommandsTheEffortController) {
  NodeProcess node({"--ros-args", "-r", "__ns:=/robot", "--params-file", topics_params()});
  const Participant& participant = Client::participant();
  Latest<Float64MultiArray, std::vector<double> (*)(const Float64MultiArray&)> commands(
      participant, "rt/robot/effort_controller/commands",
      +[](const Float64MultiArray& m) { return values(m.data); });
  JointStatesPlayer robot("rt/robot/joint_states");
  Client client("/robot/cartesian_impedance_controller");
  const State start = client.running();
  TfRecorder tf(participant);  // tf in topics mode too, from the measured joint positions
  check_tf_matches_state(tf, "/robot/cartesian_impedance_controller", "panda_link0", "panda_link8");
  ASSERT_TRUE(commands.wait(2.0, [](const std::vector<double>& tau) { return tau.size() == 7; }));
  // Held still at the reference: (almost) no torque. Then a reference 1 cm along +x: the
  // arm cannot move (the "robot" replays one state), so the spring torque is J^T K e with
  // |K e| = 5 N, and joint 1 (rotation about z) is not involved in a push along x at y = 0.
  EXPECT_LT(Eigen::Map<const Eigen::VectorXd>(commands.value().data(), 7).norm(), 0.05);
  client.pose(start.position + Eigen::Vector3d(0.01, 0, 0), start.orientation);
  ASSERT_TRUE(commands.wait(2.0, [](const std::vector<double>& tau) {
    return Eigen::Map<const Eigen::VectorXd>(tau.data(), 7).norm() > 1.0;
  }));
  EXPECT_NEAR(commands.value()[0], 0.0, 0.05)
      << Eigen::Map<const Eigen::VectorXd>(commands.value().data(), 7).transpose();
  // joint_states stop: stale, the torque ramps to zero.
  robot.stop();
  EXPECT_TRUE(client.wait(2.0, [](const State& s) { return s.stale_episodes >= 1; }));
  EXPECT_TRUE(commands.wait(3.0, [](const std::vector<double>& tau) {
    return Eigen::Map<const Eigen::VectorXd>(tau.data(), 7).norm() < 1e-9;
  }));
  EXPECT_NE(node.log().find("no joint_states for more than"), std::string::npos) << node.log();
}

// First joint_states the controller cannot start from (a joint at 50 rad/s, beyond
// plausibility.joint_velocity) are what a running cycle fails closed on: the node stays up,
// logs them (throttled: one line per second, however many arrive) and starts at the first good
// one. It used to exit with code 1.
TEST(Ros2Node, TopicsModeStartsAtTheFirstJointStatesItCanStartFrom) {
  NodeProcess node({"--ros-args", "-r", "__ns:=/robot", "--params-file", topics_params()});
  JointStatesPlayer robot("rt/robot/joint_states");
  robot.dq4 = 50.0;
  const std::string rejected =
      "cannot start the controller from /robot/joint_states: dq[3] = 50 is beyond "
      "plausibility.joint_velocity = 10";
  ASSERT_TRUE(eventually(10.0, [&] { return node.log().find(rejected) != std::string::npos; }))
      << node.log();
  // About 500 bad samples a second for 1.5 s: at most 2 lines (at 0 and 1 s), and the node runs.
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  ASSERT_TRUE(node.running()) << node.log();
  const std::string log = node.log();
  int lines = 0;
  for (std::size_t at = log.find(rejected); at != std::string::npos;
       at = log.find(rejected, at + 1)) {
    ++lines;
  }
  EXPECT_GE(lines, 1);
  EXPECT_LE(lines, 3) << log;
  EXPECT_EQ(log.find("controller running"), std::string::npos) << log;

  robot.dq4 = 0.0;
  Client client("/robot/cartesian_impedance_controller");
  const State running = client.running();
  EXPECT_EQ(running.status, "ok");
  EXPECT_NEAR(running.q.at(3), -3 * M_PI / 4, 1e-9);
  EXPECT_TRUE(node.running());
  EXPECT_EQ(node.stop(), 0) << node.log();
}

// Exit code 2 for everything the node was given, found before the control thread starts: the
// command line (remaps too), parameters, the files they name and robot_description.
TEST(Ros2Node, BadParametersExitWithCode2NamingTheParameter) {
  const std::map<std::string, std::vector<std::string>> cases = {
      {"stiffness.translation", {"-p", "stiffness.translation:=-5"}},
      {"mode = 'fly'", {"-p", "mode:=fly"}},
      {"URDF file '/nonexistent.urdf' does not exist", {"-p", "urdf_path:=/nonexistent.urdf"}},
      {"stiffness.tranlation", {"-p", "stiffness.tranlation:=5"}},
      {"start_q has 3 values; expected one per joint", {"-p", "start_q:=[0.0, -0.5, 0.0]"}},
      {"start_q[3] = 0.5 rad for joint 'panda_joint4' is outside its limits",
       {"-p", "start_q:=[0, -0.7, 0, 0.5, 0, 1.5, 0.7]"}},
      {"qos policy 'lifespan'", {"-p", "qos_overrides./x.publisher.lifespan:=1"}},
      // sim_panda.yaml simulates the MJCF, which DART cannot.
      {"engine 'dart' cannot simulate the MJCF of mjcf_path", {"-p", "engine:=dart"}},
      // Every cycle would be invalid_dt (1.5 periods above plausibility.dt.max = 20 ms).
      {"control_rate = 60 Hz does not fit plausibility.dt",
       {"-p", "control_rate:=60", "-p", "publish_rate:=50"}},
      {"publish_rate = 1e-11 Hz is outside [1, 10000]", {"-p", "publish_rate:=1e-11"}},
      {"tf_prefix = 'pppp", {"-p", "tf_prefix:=" + std::string(1000, 'p')}},
      // What only loading shows is as wrong as a bad parameter: the MJCF of another robot.
      {"iiwa14.xml", {"-p", "mjcf_path:=" + repository() + "/models/iiwa14/iiwa14.xml"}},
      {"-r joint_states:=9states: '9states' is not a valid topic name",
       {"-r", "joint_states:=9states"}},
  };
  for (const auto& [expected, extra] : cases) {
    std::vector<std::string> args = {"--ros-args", "--params-file", sim_params()};
    args.insert(args.end(), extra.begin(), extra.end());
    NodeProcess node(args);
    const std::optional<int> code = node.wait_for_exit(10.0);
    ASSERT_TRUE(code.has_value()) << expected;
    EXPECT_EQ(*code, 2) << node.log();
    EXPECT_NE(node.log().find(expected), std::string::npos) << node.log();
  }
  // robot_description that is no URDF.
  NodeProcess description({"--ros-args", "--params-file", params_file("bad_description.yaml", R"(
/**:
  ros__parameters:
    robot_description: "<robot name='arm'><link name='base'/></robot>"
    base_link: panda_link0
    tip_link: panda_link8
)")});
  EXPECT_EQ(description.wait_for_exit(10.0).value_or(-1), 2) << description.log();
  EXPECT_NE(description.log().find("panda_link0"), std::string::npos) << description.log();
  NodeProcess unknown({"--frobnicate"});
  EXPECT_EQ(unknown.wait_for_exit(10.0).value_or(-1), 2);
  EXPECT_NE(unknown.log().find("unknown argument '--frobnicate'"), std::string::npos);
}

}  // namespace
}  // namespace cartesian_impedance_ros2::test
