#pragma once
/// @file
/// The node's parameters as ROS 2's parameter services show them, without DDS: every row of the
/// library's parameter table (read and set at run time, through the one decoder) and the node's
/// settings (read-only: fixed when the node starts). Names are the table's dotted names, as in
/// params files; values have ROS 2's parameter types (rcl_interfaces/msg/ParameterType). The
/// semantics are rclcpp's (its NodeParameters and ParameterService), so that `ros2 param` and
/// rqt_reconfigure see what they see on any rclcpp node.

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <cartesian_impedance/core/parameters.hpp>
#include <cartesian_impedance/loop/control_loop.hpp>
#include <cartesian_impedance/node/node_settings.hpp>

#include "parameters.hpp"

namespace cartesian_impedance_ros2 {

/// rcl_interfaces/msg/ParameterType.
namespace ros_type {
constexpr std::uint8_t kNotSet = 0;
constexpr std::uint8_t kBool = 1;
constexpr std::uint8_t kInteger = 2;
constexpr std::uint8_t kDouble = 3;
constexpr std::uint8_t kString = 4;
constexpr std::uint8_t kByteArray = 5;
constexpr std::uint8_t kBoolArray = 6;
constexpr std::uint8_t kIntegerArray = 7;
constexpr std::uint8_t kDoubleArray = 8;
constexpr std::uint8_t kStringArray = 9;
}  // namespace ros_type

/// One rcl_interfaces/msg/ParameterValue: `type` says which member holds the value.
struct RosValue {
  std::uint8_t type = ros_type::kNotSet;
  bool boolean = false;
  std::int64_t integer = 0;
  double number = 0.0;
  std::string text;
  std::vector<std::uint8_t> bytes;
  std::vector<std::uint8_t> booleans;  // 0 or 1 (not vector<bool>: DDS wants a bool array)
  std::vector<std::int64_t> integers;
  std::vector<double> numbers;
  std::vector<std::string> texts;
};

/// One rcl_interfaces/msg/ParameterDescriptor.
struct RosDescriptor {
  std::string name;
  std::uint8_t type = ros_type::kNotSet;
  std::string description;             ///< the table's description and unit
  std::string additional_constraints;  ///< the valid range as the library states it
  bool read_only = false;
  std::optional<std::pair<double, double>> floating_point_range;       ///< closed, step 0
  std::optional<std::pair<std::int64_t, std::int64_t>> integer_range;  ///< closed, step 0
};

/// rcl_interfaces/msg/SetParametersResult.
struct SetResult {
  bool successful = false;
  std::string reason;
};

/// rcl_interfaces/msg/ListParametersResult.
struct ListResult {
  std::vector<std::string> names;
  std::vector<std::string> prefixes;
};

/// A named value for set() and for parameter events.
using NamedValue = std::pair<std::string, RosValue>;

class NodeParameters {
 public:
  /// A read-only setting besides the library's node settings (the shell's own: the URDF's
  /// source, the effort controller, use_sim_time).
  struct Extra {
    std::string name;
    RosValue value;
    std::string description;
  };

  /// `accepting` says whether the controller runs (sets are refused until it does: a start
  /// resets what was queued before it). `node_name` (fully qualified) places messages. Whether
  /// safety settings are locked is the loop's (ControlLoop::runtime_safety_changes_allowed()),
  /// read here: allow them on the loop before.
  NodeParameters(cartesian_impedance::ControlLoop& loop,
                 const cartesian_impedance::node::NodeSettings& settings,
                 const std::vector<Extra>& extras, std::function<bool()> accepting,
                 std::string node_name);

  /// rclcpp's list_parameters: every name if `prefixes` is empty and the name has fewer than
  /// `depth` dots (0: any), else the names equal to a prefix or below it (prefix + '.') with
  /// fewer than `depth` dots after the prefix, the dot that follows the prefix included (as
  /// rclcpp counts: a prefix's children are at depth 2); `prefixes` of the result: the part
  /// before the last dot of each name listed, once each. Names in sorted order.
  ListResult list(const std::vector<std::string>& prefixes, std::uint64_t depth) const;
  /// The values of `names` in order; nullopt if one is not a parameter (rclcpp answers an empty
  /// list then).
  std::optional<std::vector<RosValue>> get(const std::vector<std::string>& names) const;
  std::optional<std::vector<RosDescriptor>> describe(const std::vector<std::string>& names) const;
  std::optional<std::vector<std::uint8_t>> types(const std::vector<std::string>& names) const;

  /// Sets `parameters` together or not at all, as a partial update (ParameterUpdate) decoded by
  /// the library's decoder onto the parameters in force: only the rows named change, so a value
  /// another channel commanded (a stiffness sent on a topic) is kept. A read-only or unknown
  /// name, a safety setting while they are locked (ControlLoop::allow_runtime_safety_changes()
  /// was not called: the descriptors say read_only), a value of the wrong type, shape or range, a
  /// plausibility.dt the control period does not fit (node::check_control_period(), as at
  /// start), a set that fails validation or that the loop refuses gets successful = false and
  /// the message as reason, and changes nothing. Each accepted change of a safety setting is
  /// logged as a warning (name, old value, new value). On success `changed` (if given) receives
  /// each parameter with its value as get() shows it. Waits (up to 1 s) until the loop has
  /// applied the set, so that a following set or get starts from it.
  SetResult set(const std::vector<NamedValue>& parameters, std::vector<NamedValue>* changed);

  /// Every parameter with its value, in name order (for the first parameter event); what
  /// changes() compares with from then on.
  std::vector<NamedValue> all();

  /// The parameters whose values in force differ from what the parameter events have shown
  /// (all(), set(), the last changes()), with their values in force, in table order; empty if
  /// none. This is how a change that did not come through set() reaches /parameter_events: a
  /// stiffness, damping, wrench or nullspace command on a topic changes the rows it commands
  /// (a full stiffness matrix shows as its diagonal, as get() shows it), and the loop may store
  /// a set's value otherwise than given. Changes between two calls show as one, with the value in
  /// force at the second.
  std::vector<NamedValue> changes();

 private:
  struct Entry {
    const cartesian_impedance::ParameterInfo* row = nullptr;  // a table parameter; else read-only
    RosValue value;                                           // read-only: the value
    RosDescriptor descriptor;
  };
  RosValue value_of(const Entry& entry, const cartesian_impedance::Parameters& parameters) const;

  /// The refusal of a set that names a safety setting while they are locked; nullopt if it
  /// names none. `in_force`: the parameters the values are shown against.
  std::optional<SetResult> refuse_locked(const std::vector<NamedValue>& parameters,
                                         const cartesian_impedance::Parameters& in_force) const;

  cartesian_impedance::ControlLoop& loop_;
  double control_rate_;  // [Hz] fixed while the node runs: plausibility.dt must fit it
  bool safety_locked_;   // safety settings refused while the controller runs
  std::function<bool()> accepting_;
  std::string node_name_;
  std::map<std::string, Entry> entries_;  // sorted, as rclcpp's
  // The values the parameter events have shown: all(), each set's rows, changes().
  cartesian_impedance::Parameters shown_;
};

/// The shell's own read-only settings: the URDF's source (urdf_path, or robot_description with its
/// text), effort_controller (topics mode) and use_sim_time (false: the node runs on the system
/// clock; rclcpp nodes declare it).
std::vector<NodeParameters::Extra> shell_settings(const Ros2Configuration& configuration);

/// The ROS 2 type of a row of the parameter table: double, double[] (three axes, per joint),
/// string (frames) or bool.
std::uint8_t ros_type_of(const cartesian_impedance::ParameterInfo& row);
/// The library's value tree of a ROS 2 value (integers are numbers, as in every source).
/// @throws cartesian_impedance::Error for a type code that is no ROS 2 parameter type.
cartesian_impedance::ParameterValue to_tree(const RosValue& value, const std::string& location);

}  // namespace cartesian_impedance_ros2
