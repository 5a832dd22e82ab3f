#pragma once
/// @file
/// The node's configuration from the ROS parameter server: the controller parameters under the
/// node's private namespace with the names of config/*.yaml (`~stiffness/translation`,
/// `~limits/joint_torque`, ..., or dotted: `~stiffness.translation`), decoded by the library's
/// decode_parameters() (parameter_tree.hpp) from the XmlRpc values, plus the node's own settings
/// (`~mode`, `~control_rate`, ...), decoded by the same functions. Everything is read from one
/// XmlRpc value (the whole private namespace), so the parsing is testable without a ROS master.

#include <xmlrpcpp/XmlRpcValue.h>

#include <string>
#include <vector>

#include <cartesian_impedance/parameters.hpp>

namespace cartesian_impedance_ros {

/// How the node talks to the robot.
enum class Mode {
  sim,    ///< MuJoCo simulation of the robot, stepped in the control thread
  topics  ///< joint_states in, effort_command out (a robot bridge or an effort controller)
};

/// The node's own settings (not controller parameters). Units in brackets.
struct NodeSettings {
  Mode mode = Mode::sim;
  double control_rate = 1000.0;       ///< [Hz] control cycle rate
  double publish_rate = 100.0;        ///< [Hz] controller_state, commanded_torques, joint_states
  std::string base_link;              ///< root of the controlled chain; frame of every pose
  std::string tip_link;               ///< end-effector link
  std::string mjcf_path;              ///< sim mode: MuJoCo model of the same robot
  double joint_states_timeout = 0.1;  ///< [s] topics mode: older joint states count as lost
  double tf_timeout = 0.1;            ///< [s] longest wait for a tf2 transform in a callback
  int realtime_priority = 0;          ///< SCHED_FIFO priority of the control thread; 0 = normal
};

struct NodeConfiguration {
  NodeSettings settings;
  cartesian_impedance::Parameters parameters;
  /// Keys under the private namespace that are neither settings, parameter groups nor the
  /// node's dynamic_reconfigure namespaces (reported as warnings, e.g. a misspelt group).
  std::vector<std::string> unknown_keys;
};

/// Parses the private namespace `private_namespace` (a struct; anything else counts as empty),
/// whose resolved name `namespace_name` (e.g. "/left/cartesian_impedance_controller") is used in
/// messages. Parameters not given keep the library's defaults.
/// @throws cartesian_impedance::Error naming the parameter (`ROS parameter <name>: ...`), the
///         value and what is expected: a value of the wrong type or shape, a value out of range,
///         an unknown parameter inside a parameter group (e.g. `~stiffness/tranlation`), a
///         parameter given twice (nested and dotted), a set that fails validate(), or an invalid
///         setting. Messages after the location are the decoder's, as for a YAML file.
NodeConfiguration configuration_from_xmlrpc(XmlRpc::XmlRpcValue& private_namespace,
                                            const std::string& namespace_name);

/// "sim" / "topics".
const char* to_string(Mode mode) noexcept;

}  // namespace cartesian_impedance_ros
