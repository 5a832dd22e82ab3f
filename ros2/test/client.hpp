#pragma once
// A client of one node over DDS, as a ROS 2 node would use it (its topics, types and QoS), and
// what the tests read of its full_state. Shared by the node's tests and the tests over the wire.

#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "harness.hpp"

namespace cartesian_impedance_ros2::test {

namespace ci = cartesian_impedance;

// What the tests read of full_state, copied out of DDS's memory.
struct State {
  std::string status;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector4d orientation = Eigen::Vector4d::Zero();  // x, y, z, w
  Eigen::Vector3d commanded_position = Eigen::Vector3d::Zero();
  ci::Vector6d commanded_stiffness = ci::Vector6d::Zero();
  ci::Vector6d commanded_wrench = ci::Vector6d::Zero();
  std::vector<double> q, nullspace_config, nullspace_stiffness, tau;
  std::string trajectory_state;
  std::uint64_t trajectory_id = 0;
  double trajectory_goal_error = 0.0;
  std::uint64_t stale_episodes = 0;
  double period_p50_us = 0.0;
  std::vector<double> dq;
  double measurement_age_p50_us = 0.0, measurement_age_p99_us = 0.0, measurement_age_max_us = 0.0;
  double oscillation_scale = 1.0;
  std::uint64_t oscillations = 0;
  bool collision_detected = false;
  std::string collision_reaction;
  std::uint64_t collisions = 0;
};

inline std::vector<double> values(const dds_sequence_double& s) {
  return std::vector<double>(s._buffer, s._buffer + s._length);
}

inline ci::Vector6d six(const geometry_msgs_msg_dds__Wrench_& w) {
  return vector_from_wrench(w);
}

inline State copy_state(const FullState& m) {
  State s;
  s.status = m.status;
  s.position = {m.current_pose.position.x, m.current_pose.position.y, m.current_pose.position.z};
  s.orientation = {m.current_pose.orientation.x, m.current_pose.orientation.y,
                   m.current_pose.orientation.z, m.current_pose.orientation.w};
  s.commanded_position = {m.commanded_reference_pose.position.x,
                          m.commanded_reference_pose.position.y,
                          m.commanded_reference_pose.position.z};
  s.commanded_stiffness = six(m.commanded_cartesian_stiffness);
  s.commanded_wrench = six(m.commanded_wrench);
  s.q = values(m.joint_state.position);
  s.nullspace_config = values(m.nullspace_config);
  s.nullspace_stiffness = values(m.nullspace_stiffness);
  s.tau = values(m.commanded_torques);
  s.trajectory_state = m.trajectory_state;
  s.trajectory_id = m.trajectory_id;
  s.trajectory_goal_error = m.trajectory_goal_error;
  s.stale_episodes = m.stale_episodes;
  s.period_p50_us = m.period_p50_us;
  s.dq = values(m.joint_state.velocity);
  s.measurement_age_p50_us = m.measurement_age_p50_us;
  s.measurement_age_p99_us = m.measurement_age_p99_us;
  s.measurement_age_max_us = m.measurement_age_max_us;
  s.oscillation_scale = m.oscillation_scale;
  s.oscillations = m.oscillations;
  s.collision_detected = m.collision_detected;
  s.collision_reaction = m.collision_reaction;
  s.collisions = m.collisions;
  return s;
}

using StateReader = Latest<FullState, State (*)(const FullState&)>;

inline std::string sim_params() {
  return repository() + "/ros2/config/sim_panda.yaml";
}

// A params file of the test's own (for the error cases and topics mode).
inline std::string params_file(const std::string& name, const std::string& body) {
  const std::string path = std::string(CARTESIAN_IMPEDANCE_BINARY_DIR) + "/" + name;
  std::ofstream(path) << body;
  return path;
}

// A params file named `name` for the node in topics mode on the Panda's URDF, with `extra`
// parameters (YAML lines indented by four spaces) after the common ones.
inline std::string topics_params_file(const std::string& name, const std::string& extra = "") {
  return params_file(name, R"(
/**:
  ros__parameters:
    mode: topics
    urdf_path: )" + repository() +
                               R"(/models/panda/panda.urdf
    base_link: panda_link0
    tip_link: panda_link8
    parameters_file: )" + repository() +
                               R"(/config/panda.yaml
)" + extra);
}

// A client of one node: its topics, as a ROS 2 node would use them.
class Client {
 public:
  explicit Client(const std::string& node = "/cartesian_impedance_controller")
      : node_(node),
        state_(participant(), "rt" + node + "/full_state", &copy_state),
        reference_(participant(), "rt" + node + "/reference_pose", TopicQos{}),
        stiffness_(participant(), "rt" + node + "/set_cartesian_stiffness", TopicQos{}),
        wrench_(participant(), "rt" + node + "/set_cartesian_wrench", TopicQos{}),
        config_(participant(), "rt" + node + "/set_config", TopicQos{}),
        resume_(participant(), "rt" + node + "/resume", TopicQos{}) {}

  static const Participant& participant() {
    use_private_domain();
    static const Participant instance;
    return instance;
  }

  // The first state with status ok, and every writer matched (the node reads commands once its
  // controller runs; its readers exist from the start).
  State running() {
    EXPECT_TRUE(state_.wait(15.0, [](const State& s) { return s.status == "ok"; }))
        << "no full_state with status ok from " << node_;
    EXPECT_TRUE(eventually(5.0, [&] {
      return reference_.matched() > 0 && stiffness_.matched() > 0 && wrench_.matched() > 0 &&
             config_.matched() > 0 && resume_.matched() > 0;
    }));
    return state_.value();
  }

  bool wait(double seconds, const std::function<bool(const State&)>& condition) {
    return state_.wait(seconds, condition);
  }
  // The newest state after `seconds`.
  State settle(double seconds) {
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    state_.poll();
    return state_.value();
  }

  void pose(const Eigen::Vector3d& p, const Eigen::Vector4d& xyzw, const char* frame = "") {
    PoseStamped m{};
    m.header.frame_id = const_cast<char*>(frame);
    m.pose.position = {p.x(), p.y(), p.z()};
    m.pose.orientation = {xyzw[0], xyzw[1], xyzw[2], xyzw[3]};
    ASSERT_TRUE(reference_.write(m));
  }
  void stiffness(const ci::Vector6d& k, const char* frame = "") {
    ASSERT_TRUE(stiffness_.write(stamped(k, frame)));
  }
  void wrench(const ci::Vector6d& f, const char* frame = "") {
    ASSERT_TRUE(wrench_.write(stamped(f, frame)));
  }
  void config(const ci::Vector6d& k, const ci::Vector6d& zeta, double k_ns, double zeta_ns,
              std::vector<double> q) {
    ControllerConfig m{};
    m.cartesian_stiffness = wrench_of(k);
    m.cartesian_damping_factors = wrench_of(zeta);
    m.nullspace_stiffness = k_ns;
    m.nullspace_damping_factor = zeta_ns;
    m.q_d_nullspace._buffer = q.data();
    m.q_d_nullspace._length = m.q_d_nullspace._maximum = static_cast<std::uint32_t>(q.size());
    ASSERT_TRUE(config_.write(m));
  }
  void resume() {
    EmptyMessage m{};
    ASSERT_TRUE(resume_.write(m));
  }

 private:
  static WrenchMessage wrench_of(const ci::Vector6d& v) {
    WrenchMessage w{};
    w.force = {v[0], v[1], v[2]};
    w.torque = {v[3], v[4], v[5]};
    return w;
  }
  static WrenchStamped stamped(const ci::Vector6d& v, const char* frame) {
    WrenchStamped m{};
    m.header.frame_id = const_cast<char*>(frame);
    m.wrench = wrench_of(v);
    return m;
  }

  std::string node_;
  StateReader state_;
  Writer<PoseStamped> reference_;
  Writer<WrenchStamped> stiffness_;
  Writer<WrenchStamped> wrench_;
  Writer<ControllerConfig> config_;
  Writer<EmptyMessage> resume_;
};

}  // namespace cartesian_impedance_ros2::test
