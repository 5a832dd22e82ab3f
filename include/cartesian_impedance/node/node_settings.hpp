#pragma once
/// @file
/// What every ROS shell (the ROS 1 node, the ROS 2 node) reads from its parameters, decoded once
/// here: the controller parameters (the table's groups, nested or dotted) and the node's own
/// settings (mode, rates, links, the simulation model, engine and start configuration, the
/// joint-state timeout, the thread priority, the transforms for tf). A shell turns its parameter
/// source (the ROS 1 parameter server, a ROS 2 params file) into a ParameterValue map and calls
/// decode_node_configuration(); messages read like every other parameter's, placed by the source's
/// locations.

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "cartesian_impedance/core/parameter_tree.hpp"
#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "cartesian_impedance/sim/engine.hpp"

namespace cartesian_impedance::node {

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
  double control_rate = 1000.0;  ///< [Hz] control cycle rate
  double publish_rate = 100.0;   ///< [Hz] state topics
  std::string base_link;         ///< root of the controlled chain; frame of every pose
  std::string tip_link;          ///< end-effector link
  /// sim mode: MuJoCo model of the same robot; empty: MuJoCo simulates the URDF itself (no
  /// actuators, torques unlimited, no keyframe: set start_q).
  std::string mjcf_path;
  /// sim mode: start configuration [rad or m], one value per joint of the chain (base to tip);
  /// empty: the model's own (the MJCF's keyframe "ready", else q = 0). Each within its joint's
  /// URDF limits (check_start_q()). Rejected in topics mode, where the robot's joint_states are
  /// the start.
  std::vector<double> start_q;
  /// sim mode: the physics engine. DART simulates the URDF itself, so it excludes mjcf_path.
  /// Rejected in topics mode, where nothing is simulated.
  sim::Engine engine = sim::Engine::mujoco;
  double joint_states_timeout = 0.1;  ///< [s] topics mode: older joint states count as lost
  int realtime_priority = 0;          ///< SCHED_FIFO priority of the control thread; 0 = normal
  /// Publish the transforms of the URDF's links below base_link (tf), as robot_state_publisher
  /// would; false if another node does.
  bool publish_tf = true;
  /// Put in front of every link name in the transforms and in the frame ids the node writes
  /// ("left/" makes "left/panda_link0"), so that two robots share one tf tree. Incoming messages
  /// may name a frame with or without it.
  std::string tf_prefix;
};

struct NodeConfiguration {
  NodeSettings settings;
  Parameters parameters;
  /// Keys of the map that are neither settings, parameter groups nor the shell's own keys, as
  /// the shell names them (reported as warnings, e.g. a misspelt group).
  std::vector<std::string> unknown_keys;
  /// Where start_q was given, for check_start_q()'s message (empty if not given).
  std::string start_q_location;
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
///         publish_rate above the control_rate, a start_q that is not a list of finite numbers
///         (the message names the index and the value) or that is given in topics mode, an
///         engine that is not "mujoco" or "dart", given in topics mode or "dart" with an
///         mjcf_path. A sim mode without mjcf_path is valid: the URDF is simulated.
NodeConfiguration decode_node_configuration(const ParameterValue& tree,
                                            const KeyLocation& location_of,
                                            const std::vector<std::string>& shell_keys,
                                            std::string_view source);

/// Checks the settings that depend on the loaded chain: start_q has one value per joint, each
/// within its joint's position limits in the URDF.
/// @throws ParameterError naming start_q's location, its count and the chain's joints, or the
///         index, value, joint and limits.
void check_start_q(const NodeConfiguration& configuration, const RobotModel& model);

/// The tf frame of a link: tf_prefix + link.
std::string tf_frame(const NodeSettings& settings, const std::string& link);

}  // namespace cartesian_impedance::node
