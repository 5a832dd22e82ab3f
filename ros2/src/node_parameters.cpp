#include "node_parameters.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>

#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/core/parameter_tree.hpp>
#include <cartesian_impedance/node/startup_report.hpp>
#include <cartesian_impedance/sim/engine.hpp>

#include "log.hpp"

namespace cartesian_impedance_ros2 {

namespace ci = cartesian_impedance;
using ci::ParameterValue;
using ci::node::NodeSettingInfo;

std::uint8_t ros_type_of(const ci::ParameterInfo& row) {
  ci::Parameters probe;
  const ci::ParameterField field = row.in(probe);
  if (std::holds_alternative<double*>(field)) return ros_type::kDouble;
  if (std::holds_alternative<bool*>(field)) return ros_type::kBool;
  if (!ci::choice_names(field).empty()) return ros_type::kString;
  return ros_type::kDoubleArray;  // three axes, per joint
}

ParameterValue to_tree(const RosValue& value, const std::string& location) {
  const auto numbers = [&](const auto& items) {
    ci::ParameterList list;
    for (const auto item : items) list.push_back(ParameterValue::number(double(item), location));
    return ParameterValue::list(std::move(list), location);
  };
  switch (value.type) {
    case ros_type::kNotSet:
      return ParameterValue();  // the decoder: "no value"
    case ros_type::kBool:
      return ParameterValue::boolean(value.boolean, location);
    case ros_type::kInteger:
      return ParameterValue::number(double(value.integer), location);
    case ros_type::kDouble:
      return ParameterValue::number(value.number, location);
    case ros_type::kString:
      return ParameterValue::string(value.text, location);
    case ros_type::kByteArray:
      return numbers(value.bytes);
    case ros_type::kIntegerArray:
      return numbers(value.integers);
    case ros_type::kDoubleArray:
      return numbers(value.numbers);
    case ros_type::kBoolArray: {
      ci::ParameterList list;
      for (const std::uint8_t item : value.booleans) {
        list.push_back(ParameterValue::boolean(item != 0, location));
      }
      return ParameterValue::list(std::move(list), location);
    }
    case ros_type::kStringArray: {
      ci::ParameterList list;
      for (const std::string& item : value.texts)
        list.push_back(ParameterValue::string(item, location));
      return ParameterValue::list(std::move(list), location);
    }
    default:
      throw ci::Error(ci::with_location(location, "type " + std::to_string(int(value.type)) +
                                                      " is not a ROS 2 parameter type (valid: 0 "
                                                      "to 9, rcl_interfaces/msg/ParameterType)"));
  }
}

namespace {

// The value of an encoded parameter (encode_parameter()) as ROS 2 shows a row of `type`.
RosValue from_tree(const ParameterValue& tree, std::uint8_t type) {
  RosValue value;
  value.type = type;
  switch (type) {
    case ros_type::kDouble:
      value.number = tree.as_number();
      break;
    case ros_type::kBool:
      value.boolean = tree.as_boolean();
      break;
    case ros_type::kString:
      value.text = tree.as_string();
      break;
    default:
      if (tree.is(ParameterValue::Kind::list)) {
        for (const ParameterValue& item : tree.as_list()) value.numbers.push_back(item.as_number());
      } else {
        value.numbers.push_back(tree.as_number());
      }
  }
  return value;
}

RosValue text_value(std::string text) {
  RosValue value;
  value.type = ros_type::kString;
  value.text = std::move(text);
  return value;
}

// The value of node setting `name` (a row of node_settings_table()).
RosValue setting_value(const ci::node::NodeSettings& settings, const NodeSettingInfo& row) {
  RosValue value;
  const std::string_view name = row.name;
  if (name == "mode") return text_value(ci::node::to_string(settings.mode));
  if (name == "base_link") return text_value(settings.base_link);
  if (name == "tip_link") return text_value(settings.tip_link);
  if (name == "mjcf_path") return text_value(settings.mjcf_path);
  if (name == "engine") return text_value(ci::sim::engine_name(settings.engine));
  if (name == "tf_prefix") return text_value(settings.tf_prefix);
  if (name == "control_rate" || name == "publish_rate" || name == "joint_states_timeout") {
    value.type = ros_type::kDouble;
    value.number = name == "control_rate"   ? settings.control_rate
                   : name == "publish_rate" ? settings.publish_rate
                                            : settings.joint_states_timeout;
    return value;
  }
  if (name == "start_q") {
    value.type = ros_type::kDoubleArray;
    value.numbers = settings.start_q;
    return value;
  }
  if (name == "realtime_priority") {
    value.type = ros_type::kInteger;
    value.integer = settings.realtime_priority;
    return value;
  }
  if (name == "publish_tf" || name == "allow_runtime_safety_changes") {
    value.type = ros_type::kBool;
    value.boolean =
        name == "publish_tf" ? settings.publish_tf : settings.allow_runtime_safety_changes;
    return value;
  }
  // A new row of the settings table must be shown here too.
  throw ci::Error("node setting '" + std::string(name) + "' has no ROS 2 parameter value");
}

std::uint8_t setting_type(NodeSettingInfo::Kind kind) {
  switch (kind) {
    case NodeSettingInfo::Kind::name:
      return ros_type::kString;
    case NodeSettingInfo::Kind::number:
      return ros_type::kDouble;
    case NodeSettingInfo::Kind::integer:
      return ros_type::kInteger;
    case NodeSettingInfo::Kind::numbers:
      return ros_type::kDoubleArray;
    case NodeSettingInfo::Kind::flag:
      break;
  }
  return ros_type::kBool;
}

std::string with_unit(std::string_view text, std::string_view unit) {
  std::string out(text);
  if (!unit.empty() && unit != "-") out += " [" + std::string(unit) + "]";
  return out;
}

const char kReadOnly[] = "; read-only: fixed when the node starts";
// What the descriptor of a safety setting adds: rqt_reconfigure and `ros2 param describe` show
// why it cannot be set and how that is changed.
const char kLocked[] =
    "; read-only while the controller runs: safety settings are locked (start the node with "
    "allow_runtime_safety_changes: true to allow run-time changes)";
const char kUnlocked[] =
    "; a safety setting: allow_runtime_safety_changes is true, so it may change while the "
    "controller runs, and each change is logged as a warning";

// A row's value with its unit, as the loop's messages show it: "1 m/s", "[0, 0, 0] m", "true".
std::string shown(const ci::Parameters& parameters, const ci::ParameterInfo& row) {
  const bool unit = !row.unit.empty() && row.unit != "-";
  return ci::value_text(parameters, row) + (unit ? " " + std::string(row.unit) : std::string());
}

}  // namespace

std::vector<NodeParameters::Extra> shell_settings(const Ros2Configuration& configuration) {
  std::vector<NodeParameters::Extra> extras;
  if (configuration.urdf_source == "robot_description") {
    extras.push_back({"robot_description", text_value(configuration.urdf), "the robot's URDF"});
  } else {
    extras.push_back({"urdf_path", text_value(configuration.urdf_source), "the robot's URDF file"});
  }
  if (configuration.common.settings.mode == ci::node::Mode::topics) {
    extras.push_back({"effort_controller", text_value(configuration.effort_controller),
                      "the effort controller whose commands topic takes the torques"});
  }
  extras.push_back({"ros_distro", text_value(to_string(configuration.ros_distro)),
                    "the ROS 2 distribution whose ros_discovery_info layout the node announces "
                    "(humble: 24-octet GIDs; iron and later: 16)"});
  RosValue sim_time;
  sim_time.type = ros_type::kBool;
  extras.push_back({"use_sim_time", sim_time, "the node runs on the system clock"});
  return extras;
}

NodeParameters::NodeParameters(ci::ControlLoop& loop, const ci::node::NodeSettings& settings,
                               const std::vector<Extra>& extras, std::function<bool()> accepting,
                               std::string node_name)
    : loop_(loop),
      control_rate_(settings.control_rate),
      safety_locked_(!loop.runtime_safety_changes_allowed()),
      accepting_(std::move(accepting)),
      node_name_(std::move(node_name)),
      shown_(loop.latest_parameters()) {
  for (const ci::ParameterInfo& row : ci::parameter_table()) {
    Entry entry;
    entry.row = &row;
    RosDescriptor& d = entry.descriptor;
    d.name = std::string(row.name);
    d.type = ros_type_of(row);
    d.description = with_unit(row.description, row.unit);
    if (ci::is_safety_setting(row.name)) {
      // As rclcpp shows a parameter it refuses to set: read_only, so that GUIs grey it out.
      d.read_only = safety_locked_;
      d.description += safety_locked_ ? kLocked : kUnlocked;
    }
    if (d.type == ros_type::kDouble || d.type == ros_type::kDoubleArray) {
      d.additional_constraints =
          "each value in " + row.range_text() +
          (row.unit.empty() || row.unit == "-" ? std::string() : " " + std::string(row.unit)) +
          (d.type == ros_type::kDoubleArray ? "; a number sets every element" : "");
      // ROS 2's ranges are closed and finite in practice (rqt_reconfigure draws a slider): an
      // infinite bound is stated in additional_constraints only.
      if (std::isfinite(row.min) && std::isfinite(row.max)) {
        d.floating_point_range = std::make_pair(row.min, row.max);
      }
    } else if (d.type == ros_type::kString) {
      d.additional_constraints = "base or end_effector";
    }
    entries_.emplace(d.name, std::move(entry));
  }
  for (const NodeSettingInfo& row : ci::node::node_settings_table()) {
    Entry entry;
    entry.value = setting_value(settings, row);
    RosDescriptor& d = entry.descriptor;
    d.name = std::string(row.name);
    d.type = setting_type(row.kind);
    d.description = with_unit(row.description, row.unit) + kReadOnly;
    d.additional_constraints = row.accepts();
    d.read_only = true;
    if (row.kind == NodeSettingInfo::Kind::integer) {
      d.integer_range = std::make_pair(std::int64_t(row.min), std::int64_t(row.max));
    } else if (row.kind == NodeSettingInfo::Kind::number ||
               row.kind == NodeSettingInfo::Kind::numbers) {
      d.floating_point_range = std::make_pair(row.min, row.max);
    }
    entries_.emplace(d.name, std::move(entry));
  }
  for (const Extra& extra : extras) {
    Entry entry;
    entry.value = extra.value;
    entry.descriptor.name = extra.name;
    entry.descriptor.type = extra.value.type;
    entry.descriptor.description = extra.description + kReadOnly;
    entry.descriptor.read_only = true;
    entries_.emplace(extra.name, std::move(entry));
  }
}

RosValue NodeParameters::value_of(const Entry& entry, const ci::Parameters& parameters) const {
  if (entry.row == nullptr) return entry.value;
  return from_tree(ci::encode_parameter(parameters, *entry.row), entry.descriptor.type);
}

ListResult NodeParameters::list(const std::vector<std::string>& prefixes,
                                std::uint64_t depth) const {
  const auto dots = [](std::string_view text) {
    return static_cast<std::uint64_t>(std::count(text.begin(), text.end(), '.'));
  };
  ListResult result;
  for (const auto& [name, entry] : entries_) {
    const bool all = prefixes.empty() && (depth == 0 || dots(name) < depth);
    const bool matches = std::any_of(prefixes.begin(), prefixes.end(), [&](const std::string& p) {
      if (name == p) return true;
      if (name.rfind(p + ".", 0) != 0) return false;
      return depth == 0 || dots(std::string_view(name).substr(p.size())) < depth;
    });
    if (!all && !matches) continue;
    result.names.push_back(name);
    const std::size_t last = name.rfind('.');
    if (last != std::string::npos) {
      const std::string prefix = name.substr(0, last);
      if (std::find(result.prefixes.begin(), result.prefixes.end(), prefix) ==
          result.prefixes.end()) {
        result.prefixes.push_back(prefix);
      }
    }
  }
  return result;
}

std::optional<std::vector<RosValue>> NodeParameters::get(
    const std::vector<std::string>& names) const {
  const ci::Parameters parameters = loop_.latest_parameters();
  std::vector<RosValue> values;
  for (const std::string& name : names) {
    const auto found = entries_.find(name);
    if (found == entries_.end()) return std::nullopt;
    values.push_back(value_of(found->second, parameters));
  }
  return values;
}

std::optional<std::vector<RosDescriptor>> NodeParameters::describe(
    const std::vector<std::string>& names) const {
  std::vector<RosDescriptor> descriptors;
  for (const std::string& name : names) {
    const auto found = entries_.find(name);
    if (found == entries_.end()) return std::nullopt;
    descriptors.push_back(found->second.descriptor);
  }
  return descriptors;
}

std::optional<std::vector<std::uint8_t>> NodeParameters::types(
    const std::vector<std::string>& names) const {
  std::vector<std::uint8_t> types;
  for (const std::string& name : names) {
    const auto found = entries_.find(name);
    if (found == entries_.end()) return std::nullopt;
    types.push_back(found->second.descriptor.type);
  }
  return types;
}

std::vector<NamedValue> NodeParameters::all() {
  shown_ = loop_.latest_parameters();
  std::vector<NamedValue> values;
  for (const auto& [name, entry] : entries_) values.emplace_back(name, value_of(entry, shown_));
  return values;
}

std::vector<NamedValue> NodeParameters::changes() {
  const ci::Parameters now = loop_.latest_parameters();
  const ci::ParameterNames changed = ci::changed_parameters(shown_, now);
  std::vector<NamedValue> values;
  if (changed.none()) return values;
  const std::vector<ci::ParameterInfo>& table = ci::parameter_table();
  for (std::size_t i = 0; i < table.size(); ++i) {
    if (!changed[i]) continue;
    const auto found = entries_.find(std::string(table[i].name));
    if (found != entries_.end()) values.emplace_back(found->first, value_of(found->second, now));
  }
  shown_ = now;
  return values;
}

std::optional<SetResult> NodeParameters::refuse_locked(const std::vector<NamedValue>& parameters,
                                                       const ci::Parameters& in_force) const {
  if (!safety_locked_) return std::nullopt;
  std::string names;
  std::string values;
  for (const auto& [name, value] : parameters) {
    const auto found = entries_.find(name);
    if (found == entries_.end() || found->second.row == nullptr) continue;
    const ci::ParameterInfo& row = *found->second.row;
    if (!ci::is_safety_setting(row.name)) continue;
    // The value asked for as the loop would show it; one that does not decode as the decoder
    // describes it (it is refused either way: the lock is the first reason).
    std::string asked;
    try {
      ci::Parameters probe = in_force;
      ci::assign_parameter(probe, row.name, to_tree(value, name));
      asked = shown(probe, row);
    } catch (const std::exception&) {
      asked = "a value of type " + std::to_string(int(value.type));
      try {
        asked = to_tree(value, name).describe();
      } catch (const std::exception&) {  // not a ROS 2 type: the type code says it
      }
    }
    names += (names.empty() ? "'" : ", '") + name + "'";
    values += (values.empty() ? "" : ", ") + name + " = " + asked +
              " (in force: " + shown(in_force, row) + ")";
  }
  if (names.empty()) return std::nullopt;
  // Refused whatever the value, as rclcpp refuses a read-only parameter: the descriptor says
  // read_only, and a set to the value in force would change nothing anyway.
  return SetResult{false, "parameter " + names + " of " + node_name_ +
                              " is read-only: safety settings are locked while the controller "
                              "runs (" +
                              values +
                              "); only the node's configuration can allow run-time changes, "
                              "before it starts (allow_runtime_safety_changes: true); nothing "
                              "was changed"};
}

SetResult NodeParameters::set(const std::vector<NamedValue>& parameters,
                              std::vector<NamedValue>* changed) {
  if (parameters.empty()) return {true, ""};
  ci::ParameterMap members;
  try {
    for (const auto& [name, value] : parameters) {
      const auto found = entries_.find(name);
      if (found != entries_.end() && found->second.row == nullptr) {
        return {false, "parameter '" + name + "' of " + node_name_ +
                           " is read-only: a setting of the node, fixed when it starts"};
      }
      const std::string location = "parameter '" + name + "' of " + node_name_;
      members.push_back({name, to_tree(value, location), location});
    }
  } catch (const std::exception& error) {
    return {false, error.what()};
  }
  if (!accepting_()) {
    return {false, "the controller of " + node_name_ +
                       " is not running yet (it starts at the first joint states it can start "
                       "from); nothing was changed"};
  }
  const ci::Parameters in_force = loop_.latest_parameters();
  if (std::optional<SetResult> refused = refuse_locked(parameters, in_force)) return *refused;
  ci::ParameterUpdate update;
  try {
    // The one decoder, on the parameters in force: unknown names, types, shapes, ranges and the
    // whole set's validation are its messages. The update names only the rows given, so that
    // whatever else changed since (a stiffness on a topic, another client's set) is kept; the
    // loop checks what depends on the robot, and the lock again.
    update = ci::decode_parameter_update(ParameterValue::map(std::move(members)), in_force,
                                         "parameters of " + node_name_);
    // control_rate is fixed while the node runs: a plausibility.dt its period does not fit
    // would fail cycles closed as invalid_dt, so it is refused as it is at start.
    static const ci::ParameterNames dt_rows =
        ci::ParameterUpdate::of(ci::Parameters{}, {"plausibility.dt"}).names;
    if ((update.names & dt_rows).any()) {
      try {
        ci::node::check_control_period(control_rate_, update.values.plausibility.dt);
      } catch (const ci::Error& error) {
        return {false, "parameters of " + node_name_ + ": " + error.what() +
                           " (control_rate is fixed while the node runs); nothing was changed"};
      }
    }
    loop_.update_parameters(update);
  } catch (const std::exception& error) {
    return {false, error.what()};
  }
  // Until the loop has applied it (a cycle or two), latest_parameters() shows the old values: a
  // get right after this set would show them.
  const auto applied = [&] {
    const ci::Parameters now = loop_.latest_parameters();
    return std::all_of(parameters.begin(), parameters.end(), [&](const NamedValue& p) {
      const auto found = entries_.find(p.first);
      if (found == entries_.end() || found->second.row == nullptr) return true;
      const ci::ParameterInfo& row = *found->second.row;
      return ci::encode_parameter(now, row) == ci::encode_parameter(update.values, row);
    });
  };
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(1);
  while (!applied() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  // A safety setting changed while the robot runs (only possible when the node's configuration
  // allowed it): said loudly, so that the log shows who relaxed a cap and when.
  bool safety_changed = false;
  for (const auto& [name, value] : parameters) {
    const auto found = entries_.find(name);
    if (found == entries_.end() || found->second.row == nullptr) continue;
    const ci::ParameterInfo& row = *found->second.row;
    if (!ci::is_safety_setting(row.name)) continue;
    if (ci::encode_parameter(in_force, row) == ci::encode_parameter(update.values, row)) continue;
    log(LogLevel::warn, "safety setting " + name +
                            " changed while the controller runs: " + shown(in_force, row) + " -> " +
                            shown(update.values, row) + " (parameter set on " + node_name_ +
                            "; allow_runtime_safety_changes is true)");
    safety_changed = true;
  }
  // The torque-rate check the node makes at start (node::startup_report()) reads the limits:
  // made again, by the same function, when they change at run time, at the arm's configuration.
  if (safety_changed) {
    for (const ci::node::ReportLine& line :
         ci::node::rate_check_report(loop_.latest_parameters(), loop_.model(),
                                     loop_.latest_state().q, "the current configuration")) {
      log(LogLevel::warn, line.text);
    }
  }
  // The set's own event shows these rows: changes() reports them only if the loop stored them
  // otherwise, or something else changed them since.
  ci::copy_parameters(update.values, shown_, update.names);
  if (changed != nullptr) {
    changed->clear();
    for (const auto& p : parameters) {
      const auto found = entries_.find(p.first);
      if (found != entries_.end()) {
        changed->emplace_back(p.first, value_of(found->second, update.values));
      }
    }
  }
  return {true, ""};
}

}  // namespace cartesian_impedance_ros2
