#pragma once
/// @file
/// What every ROS shell (the ROS 1 node, the ROS 2 node) reads from its parameters, decoded once
/// here: the controller parameters (the table's groups, nested or dotted) and the node's own
/// settings (mode, rates, links, the simulation model, the joint-state timeout, the thread
/// priority). A shell turns its parameter source (the ROS 1 parameter server, a ROS 2 params
/// file) into a ParameterValue map and calls decode_node_configuration(); messages read like
/// every other parameter's, placed by the source's locations.

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "cartesian_impedance/parameter_tree.hpp"
#include "cartesian_impedance/parameters.hpp"

namespace cartesian_impedance::runtime {

/// How a node talks to the robot.
enum class Mode {
  sim,    ///< MuJoCo simulation of the robot, stepped in the control thread
  topics  ///< joint states in, torques out (a robot bridge or an effort controller)
};

/// "sim" / "topics".
const char* to_string(Mode mode) noexcept;

/// A node's own settings (not controller parameters). Units in brackets.
struct NodeSettings {
  Mode mode = Mode::sim;
  double control_rate = 1000.0;       ///< [Hz] control cycle rate
  double publish_rate = 100.0;        ///< [Hz] state topics
  std::string base_link;              ///< root of the controlled chain; frame of every pose
  std::string tip_link;               ///< end-effector link
  std::string mjcf_path;              ///< sim mode: MuJoCo model of the same robot
  double joint_states_timeout = 0.1;  ///< [s] topics mode: older joint states count as lost
  int realtime_priority = 0;          ///< SCHED_FIFO priority of the control thread; 0 = normal
};

struct NodeConfiguration {
  NodeSettings settings;
  Parameters parameters;
  /// Keys of the map that are neither settings, parameter groups nor the shell's own keys, as
  /// the shell names them (reported as warnings, e.g. a misspelt group).
  std::vector<std::string> unknown_keys;
};

/// Names of the settings decode_node_configuration() reads.
const std::vector<std::string_view>& node_setting_names();

/// How a shell names the place of a key of its map in messages, e.g. "ROS parameter
/// /arm/controller/mode" or "params.yaml:7".
using KeyLocation = std::function<std::string(std::string_view key)>;

/// Decodes `tree` (a map; anything else counts as empty). Parameters not given keep the library's
/// defaults. `shell_keys` are keys the shell reads itself (not reported as unknown). `source`
/// prefixes the messages about the whole parameter set ("ROS parameters in /arm/controller").
/// @throws ParameterError naming the key's location, the value and what is expected: a value of
///         the wrong type or shape or out of range, an unknown parameter inside a group, a
///         parameter given twice, a set that fails validate(), a missing base_link or tip_link, a
///         sim mode without mjcf_path, a publish_rate above the control_rate.
NodeConfiguration decode_node_configuration(const ParameterValue& tree,
                                            const KeyLocation& location_of,
                                            const std::vector<std::string>& shell_keys,
                                            std::string_view source);

}  // namespace cartesian_impedance::runtime
