#pragma once
/// @file
/// One owner per commanded value. The stiffness, damping ratios, nullspace stiffness and damping
/// ratio and the wrench can each be commanded from a topic and from a dynamic_reconfigure server.
/// The node keeps what it last commanded of each in a CommandRecord, and a reconfigure request
/// changes only the fields the user changed: the commands it makes are the record with those
/// fields replaced, never the server's stored values of the others. The servers show the values
/// in force (the record after the limits), also after a topic changed them.
///
/// A field counts as changed when it differs from the server's `applied` configuration: what the
/// server showed when it last applied a request or a topic last changed that value. An edit made
/// while the server's update flag is false therefore counts when the flag turns true.
///
/// Pure functions over the library's commands and the generated configurations: no ROS master
/// is needed, so they are unit-tested on their own.

#include <optional>
#include <vector>

#include <cartesian_impedance/core/command.hpp>
#include <cartesian_impedance/core/parameters.hpp>

#include <cartesian_impedance_ros/DampingConfig.h>
#include <cartesian_impedance_ros/StiffnessConfig.h>
#include <cartesian_impedance_ros/WrenchConfig.h>

namespace cartesian_impedance_ros {

/// The values that topics and dynamic_reconfigure share, as last commanded (before the limits,
/// which the control loop applies to every command).
struct CommandRecord {
  /// Diagonal, or full when a topic gave a stiffness in a frame rotated into the base by tf2.
  cartesian_impedance::Matrix6d stiffness;
  cartesian_impedance::Frame stiffness_frame = cartesian_impedance::Frame::base;
  cartesian_impedance::Vector6d damping_ratio;
  cartesian_impedance::JointVector nullspace_stiffness;  ///< one value or one per joint
  double nullspace_damping_ratio = 1.0;
  cartesian_impedance::Vector6d wrench;
  cartesian_impedance::Frame wrench_frame = cartesian_impedance::Frame::base;
  /// The configured frames (stiffness.frame, wrench.frame): a command without a frame is in these.
  cartesian_impedance::Frame configured_stiffness_frame = cartesian_impedance::Frame::base;
  cartesian_impedance::Frame configured_wrench_frame = cartesian_impedance::Frame::base;
  /// The limits the loop saturates commands to; the servers show values within them.
  cartesian_impedance::LimitParameters limits;

  /// The values of the parameters the controller started with.
  explicit CommandRecord(const cartesian_impedance::Parameters& parameters);

  /// Records commands the control loop accepted; commands of other kinds are ignored.
  void record(const std::vector<cartesian_impedance::Command>& commands);
};

/// A value of the record, the unit in which the servers' fields are kept up to date.
enum class SharedValue { stiffness, damping_ratio, nullspace_stiffness, nullspace_damping, wrench };

/// Which value of the record a command sets; nullopt for commands the record does not keep.
std::optional<SharedValue> shared_value(const cartesian_impedance::Command& command);

/// The commands of a reconfigure request whose update flag is true: for each field of
/// `requested` that differs from `applied`, the record's value with that field replaced. Empty
/// if nothing changed. A changed nullspace_stiffness sets every joint to it; the six stiffness
/// fields replace the diagonal entries of the recorded matrix (which may then fail validation if
/// it is a full one). A changed wrench field or frame gives the recorded wrench with the changed
/// components replaced, in the requested frame if that changed, else in the recorded one.
/// @throws cartesian_impedance::Error for a wrench frame other than base or end_effector.
std::vector<cartesian_impedance::Command> reconfigure_commands(const CommandRecord& record,
                                                               const StiffnessConfig& applied,
                                                               const StiffnessConfig& requested);
std::vector<cartesian_impedance::Command> reconfigure_commands(const CommandRecord& record,
                                                               const DampingConfig& applied,
                                                               const DampingConfig& requested);
std::vector<cartesian_impedance::Command> reconfigure_commands(const CommandRecord& record,
                                                               const WrenchConfig& applied,
                                                               const WrenchConfig& requested);

/// Sets the fields of `config` that show `value` (none if the server has no such field) to the
/// value in force: the record after the limits (the stiffness saturated like the control loop
/// does, the wrench's force and torque clipped to their largest norms). The update flags are
/// left alone. The nullspace_stiffness field shows the first joint's value: with different
/// values per joint, it cannot show them all.
void show(const CommandRecord& record, SharedValue value, StiffnessConfig& config);
void show(const CommandRecord& record, SharedValue value, DampingConfig& config);
void show(const CommandRecord& record, SharedValue value, WrenchConfig& config);

/// show() of every value.
template <typename Config>
void show_all(const CommandRecord& record, Config& config) {
  for (SharedValue value :
       {SharedValue::stiffness, SharedValue::damping_ratio, SharedValue::nullspace_stiffness,
        SharedValue::nullspace_damping, SharedValue::wrench}) {
    show(record, value, config);
  }
}

}  // namespace cartesian_impedance_ros
