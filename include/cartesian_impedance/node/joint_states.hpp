#pragma once
/// @file
/// Joint-state messages (ROS 1's and ROS 2's sensor_msgs/JointState, a driver's own) name their
/// joints and may come in any order and include joints of other chains (fingers, a second arm).
/// JointStateMapper maps one into the model's joint order, whatever the message type: the shell
/// passes views of its arrays.

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "cartesian_impedance/runtime/robot_io.hpp"

namespace cartesian_impedance::node {

/// A read-only view of `size` doubles (a message's array).
struct DoubleArray {
  const double* data = nullptr;
  std::size_t size = 0;
};

/// A joint-state message, as views of its arrays.
struct JointStateView {
  std::vector<std::string_view> names;
  DoubleArray position;
  DoubleArray velocity;
  DoubleArray effort;  ///< may be empty
  /// header.stamp: when the robot measured it [ns since the Unix epoch, on the system clock, as
  /// ROS time is without a simulated clock]; 0 if the message has none.
  std::int64_t stamp_ns = 0;
};

/// The time on monotonic_now()'s clock that the system-clock stamp `stamp_ns` [ns] stands for
/// (JointMeasurement::sampled); the clock's epoch (none) for 0. A stamp from another machine is
/// only as good as the two clocks' synchronisation (PTP, chrony).
std::chrono::steady_clock::time_point sampled_time(std::int64_t stamp_ns) noexcept;

class JointStateMapper {
 public:
  explicit JointStateMapper(std::vector<std::string> joint_names);

  /// Fills q, dq, effort and sampled (from the stamp) of `out` (not its sequence or received).
  /// Returns false, leaving `out` unchanged, if the message names none of the model's joints (it is
  /// about other joints). Non-finite values are passed on: the control cycle reports them as
  /// invalid_robot_state and ramps the torque down, which is the safe reaction to a bad
  /// measurement.
  /// @throws Error if the message lists some but not all of the model's joints, lists one twice,
  ///         or has position/velocity/effort arrays of the wrong size (velocities are required:
  ///         the damping acts on them).
  bool map(const JointStateView& message, runtime::JointMeasurement& out) const;

  const std::vector<std::string>& joint_names() const noexcept { return joint_names_; }

 private:
  std::vector<std::string> joint_names_;
};

}  // namespace cartesian_impedance::node
