#include "cartesian_impedance/node/joint_states.hpp"

#include <chrono>
#include <string>
#include <utility>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance::node {

std::chrono::steady_clock::time_point sampled_time(std::int64_t stamp_ns) noexcept {
  if (stamp_ns == 0) return {};
  // The stamp is on the system clock (ROS time), the control thread's on the monotonic one: the
  // measurement is as old on both.
  const std::int64_t now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                  std::chrono::system_clock::now().time_since_epoch())
                                  .count();
  return runtime::monotonic_now() - std::chrono::nanoseconds(now_ns - stamp_ns);
}

JointStateMapper::JointStateMapper(std::vector<std::string> joint_names)
    : joint_names_(std::move(joint_names)) {}

bool JointStateMapper::map(const JointStateView& message, runtime::JointMeasurement& out) const {
  const std::size_t count = message.names.size();
  if (message.position.size != count) {
    throw Error("joint_states has " + std::to_string(count) + " names but " +
                std::to_string(message.position.size) + " positions");
  }
  // Index of each model joint in the message, found by name (n is at most kMaxJoints).
  const int n = static_cast<int>(joint_names_.size());
  int index[kMaxJoints];
  int found = 0;
  std::string missing;
  for (int i = 0; i < n; ++i) {
    index[i] = -1;
    for (std::size_t k = 0; k < count; ++k) {
      if (message.names[k] != joint_names_[static_cast<std::size_t>(i)]) continue;
      if (index[i] >= 0)
        throw Error("joint_states lists " + std::string(message.names[k]) + " twice");
      index[i] = static_cast<int>(k);
    }
    if (index[i] >= 0) {
      ++found;
    } else {
      missing += (missing.empty() ? "" : ", ") + joint_names_[static_cast<std::size_t>(i)];
    }
  }
  if (found == 0) return false;
  if (found < n) {
    throw Error("joint_states names some joints of the arm but not " + missing +
                " (publish the whole arm in one message)");
  }
  if (message.velocity.size != count) {
    throw Error("joint_states has " + std::to_string(count) + " names but " +
                std::to_string(message.velocity.size) +
                " velocities (velocities are required: the damping acts on them)");
  }
  const bool has_effort = message.effort.size != 0;
  if (has_effort && message.effort.size != count) {
    throw Error("joint_states has " + std::to_string(count) + " names but " +
                std::to_string(message.effort.size) + " efforts");
  }
  out.q.resize(n);
  out.dq.resize(n);
  out.effort.resize(has_effort ? n : 0);
  for (int i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(index[i]);
    out.q[i] = message.position.data[k];
    out.dq[i] = message.velocity.data[k];
    if (has_effort) out.effort[i] = message.effort.data[k];
  }
  out.sampled = sampled_time(message.stamp_ns);
  return true;
}

}  // namespace cartesian_impedance::node
