#pragma once
/// @file
/// What every ROS shell (the ROS 1 node, the ROS 2 node) reads from its parameters, decoded once
/// here: the controller parameters (the table's groups, nested or dotted) and the node's own
/// settings (mode, rates, links, the simulation model, engine and start configuration, the
/// joint-state timeout, the thread priority, the transforms for tf). A shell turns its parameter
/// source (the ROS 1 parameter server, a ROS 2 params file) into a ParameterValue map and calls
/// decode_node_configuration(); messages read like every other parameter's, placed by the source's
/// locations.

#include <cstddef>
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

/// A node's own settings (not controller parameters). Units in brackets; what each accepts is in
/// node_settings_table().
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
  /// Let parameter sets change safety settings (safety.*, limits.*, plausibility.*, payload.*,
  /// collision.*) while the controller runs (ControlLoop::allow_runtime_safety_changes()). Off,
  /// they are locked once it runs: anyone on the network who can set a parameter could otherwise
  /// switch a cap off. Only the configuration the node starts with decides.
  bool allow_runtime_safety_changes = false;
};

struct NodeConfiguration {
  NodeSettings settings;
  /// The controller parameters given, on the library's defaults; apply_robot_defaults() reads
  /// them again on the defaults derived from the robot's URDF once it is loaded.
  Parameters parameters;
  /// The parameter groups as given, and where they came from (for apply_robot_defaults()).
  ParameterValue given_parameters = ParameterValue::map({});
  std::string parameters_source;
  /// Keys of the map that are neither settings, parameter groups nor the shell's own keys, as
  /// the shell names them (reported as warnings, e.g. a misspelt group).
  std::vector<std::string> unknown_keys;
  /// Where start_q was given, for check_start_q()'s message (empty if not given).
  std::string start_q_location;
};

/// One of a node's settings as the one table of them describes it: decode_node_configuration()
/// checks every value against its row, and the shells' documentation lists what each accepts.
struct NodeSettingInfo {
  enum class Kind {
    name,     ///< a string of at most max_length characters, one of `choices` if any
    number,   ///< a number within [min, max] (in `unit`)
    integer,  ///< a whole number within [min, max]
    numbers,  ///< a list of at most max_length numbers, each within [min, max] (in `unit`)
    flag,     ///< true or false
  };
  std::string_view name;
  Kind kind;
  std::string_view unit;     ///< of the numbers; "" if none
  double min;                ///< numbers: smallest valid value (closed)
  double max;                ///< numbers: largest valid value (closed)
  std::size_t max_length;    ///< names: characters; numbers: list length
  std::string_view choices;  ///< names: the valid ones, "sim, topics"; "" for any
  std::string_view description;

  /// The range as a parameter table row, for decode_number() and its messages.
  ParameterInfo range() const;
  /// What the row accepts, as the documentation shows it: "[1, 10000] Hz", "a string of at most
  /// 256 characters", "one of: sim, topics", "true or false".
  std::string accepts() const;
};

/// Every setting decode_node_configuration() reads, in documentation order.
const std::vector<NodeSettingInfo>& node_settings_table();

/// The row called `name`. @throws Error if there is none.
const NodeSettingInfo& node_setting_info(std::string_view name);

/// Names of the settings decode_node_configuration() reads (the table's).
const std::vector<std::string_view>& node_setting_names();

/// How a shell names the place of a key of its map in messages, e.g. "ROS parameter
/// /arm/controller/mode" or "params.yaml:7".
using KeyLocation = std::function<std::string(std::string_view key)>;

/// Decodes `tree` (a map; anything else counts as empty). Parameters not given keep the library's
/// defaults. `shell_keys` are keys the shell reads itself (not reported as unknown). `source`
/// prefixes the messages about the whole parameter set ("ROS parameters in /arm/controller").
/// @throws ParameterError naming the key's location, the value and what is expected: a value of
///         the wrong type or shape or outside its row of node_settings_table() (a string longer
///         than its row allows is named by its length, not shown whole), an unknown parameter
///         inside a group, a parameter given twice, a set that fails validate(), a missing
///         base_link or tip_link, a publish_rate above the control_rate, a control_rate whose
///         period does not fit plausibility.dt with half a period of jitter either way (1.5
///         periods at most plausibility.dt.max, half a period at least plausibility.dt.min: else
///         cycles would fail closed as invalid_dt; the message names both settings, their values
///         and what would fit; check_control_period()), a start_q that is not a list of finite
///         numbers (the message names the index and the value) or that is given in topics mode, an
///         engine that is not "mujoco" or "dart", given in topics mode or "dart" with an mjcf_path.
///         A sim mode without mjcf_path is valid: the URDF is simulated.
NodeConfiguration decode_node_configuration(const ParameterValue& tree,
                                            const KeyLocation& location_of,
                                            const std::vector<std::string>& shell_keys,
                                            std::string_view source);

/// The rule that ties the control period to the believable time step: the control thread's period
/// 1 / control_rate, late or early by half a period (its jitter), must lie within
/// plausibility.dt, else cycles would fail closed as invalid_dt while the node reports itself
/// running. Checked when a node starts (decode_node_configuration()) and again for every
/// parameter set that would change plausibility.dt while it runs, since control_rate is fixed.
/// @throws ParameterError (Reason::invalid) naming control_rate, plausibility.dt, their values,
///         which end the period breaks and the values that would fit.
void check_control_period(double control_rate, const Range& plausible_dt);

/// The line a node logs when its controller starts: whether safety settings are locked while it
/// runs, and how to change that.
std::string safety_lock_line(const NodeSettings& settings);

/// Checks the settings that depend on the loaded chain: start_q has one value per joint, each
/// within its joint's position limits in the URDF.
/// @throws ParameterError naming start_q's location, its count and the chain's joints, or the
///         index, value, joint and limits.
void check_start_q(const NodeConfiguration& configuration, const RobotModel& model);

/// Where a node's simulation of the robot starts.
struct SimulationStart {
  JointVector q;  ///< empty: the model's own start (the MJCF's keyframe "ready")
  /// What to log, "" if nothing: the start chosen, or (`warning`) why none could be chosen.
  std::string message;
  bool warning = false;
};

/// start_q if given; else, for a URDF simulated without an MJCF (which has no start of its own,
/// and q = 0 is singular on most arms), find_start_configuration()'s choice, or q = 0 with a
/// warning if it finds none; else the MJCF's own.
SimulationStart simulation_start(const NodeSettings& settings, const RobotModel& model);

/// Reads the given controller parameters again on the defaults derived from `model`'s URDF
/// (default_parameters() in model/robot_limits.hpp: efforts, rates, stiffness and wrench limits
/// that suit the arm), as the demo and Python do: what the parameters leave out suits the arm.
/// @throws ParameterError as decode_node_configuration() if the given values do not fit the
///         derived ones (e.g. a stiffness minimum above the derived maximum).
void apply_robot_defaults(NodeConfiguration& configuration, const RobotModel& model);

/// The tf frame of a link: tf_prefix + link.
std::string tf_frame(const NodeSettings& settings, const std::string& link);

}  // namespace cartesian_impedance::node
