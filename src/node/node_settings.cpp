#include "cartesian_impedance/node/node_settings.hpp"

#include <algorithm>
#include <optional>
#include <sstream>
#include <utility>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/robot_limits.hpp"
#include "cartesian_impedance/model/start_configuration.hpp"

// The shells' common settings, decoded with the parameter decoder's own functions so that their
// messages read like every other parameter's.

namespace cartesian_impedance::node {
namespace {

using Kind = NodeSettingInfo::Kind;

// The one table of the settings: what each accepts. Ranges are closed and sane, so that no value
// in them breaks the node: rates whose periods the control thread and the publisher count in
// nanoseconds (1 Hz and slower would also delay stopping by a period), a joint-state timeout
// from a millisecond (a 1 kHz robot's period) to a second (longer, the arm would be controlled
// from a state that old), strings short enough to copy into every message (a 50 MB tf_prefix is
// written into each transform of each /tf message).
constexpr std::size_t kMaxNameLength = 256;   // link names, tf_prefix
constexpr std::size_t kMaxPathLength = 4096;  // PATH_MAX
constexpr std::size_t kMaxChoiceLength = 16;  // mode, engine
std::vector<NodeSettingInfo> make_table() {
  return {
      {"mode", Kind::name, "", 0, 0, kMaxChoiceLength, "sim, topics",
       "how the node reaches the robot"},
      {"control_rate", Kind::number, "Hz", 1, 10000, 0, "",
       "control cycle rate; its period must fit plausibility.dt"},
      {"publish_rate", Kind::number, "Hz", 1, 10000, 0, "",
       "rate of the state topics, at most control_rate"},
      {"base_link", Kind::name, "", 0, 0, kMaxNameLength, "", "root link of the controlled chain"},
      {"tip_link", Kind::name, "", 0, 0, kMaxNameLength, "", "end-effector link"},
      {"mjcf_path", Kind::name, "", 0, 0, kMaxPathLength, "",
       "MuJoCo model of the robot (sim mode)"},
      // A joint position: radians or metres, bounded like a URDF's prismatic travel (1 km), which
      // catches degrees and typos; check_start_q() checks each against its joint's URDF limits.
      {"start_q", Kind::numbers, "rad or m", -1000, 1000, static_cast<std::size_t>(kMaxJoints), "",
       "start configuration (sim mode)"},
      {"engine", Kind::name, "", 0, 0, kMaxChoiceLength, "mujoco, dart",
       "physics engine (sim mode)"},
      {"joint_states_timeout", Kind::number, "s", 0.001, 1, 0, "",
       "age at which joint states count as lost"},
      {"realtime_priority", Kind::integer, "", 0, 99, 0, "", "SCHED_FIFO priority; 0 = normal"},
      {"publish_tf", Kind::flag, "", 0, 0, 0, "", "publish the robot's transforms"},
      {"tf_prefix", Kind::name, "", 0, 0, kMaxNameLength, "",
       "put in front of every frame written"},
      {"allow_runtime_safety_changes", Kind::flag, "", 0, 0, 0, "",
       "let parameter sets change safety.*, limits.*, plausibility.* and payload.* while the "
       "controller runs (default: locked)"},
  };
}

// How much of a string that is too long a message shows.
constexpr std::size_t kShownCharacters = 40;

// True if `name` is one of `choices` ("sim, topics").
bool is_choice(std::string_view choices, std::string_view name) {
  while (!choices.empty()) {
    const std::size_t end = choices.find(", ");
    if (choices.substr(0, end) == name) return true;
    choices = end == std::string_view::npos ? std::string_view() : choices.substr(end + 2);
  }
  return false;
}

class Reader {
 public:
  Reader(const ParameterValue& tree, const KeyLocation& location_of)
      : tree_(tree), location_of_(location_of) {}

  const ParameterValue* setting(std::string_view key) const { return tree_.member(key); }

  [[noreturn]] void fail(std::string_view key, const std::string& what,
                         ParameterError::Reason reason = ParameterError::Reason::no_value) const {
    throw ParameterError(reason, with_location(location_of_(key), what));
  }

  double number(std::string_view key, double fallback) const {
    const NodeSettingInfo& row = node_setting_info(key);
    const ParameterValue* value = setting(key);
    return value ? decode_number(*value, row.range(), row.name) : fallback;
  }

  // A string of at most its row's length (checked before the decoder sees it, whose messages
  // show the value), one of its row's choices if it has any.
  std::string name(std::string_view key, std::string_view what) const {
    const ParameterValue* value = setting(key);
    if (value == nullptr) return std::string();
    const NodeSettingInfo& row = node_setting_info(key);
    if (value->is(ParameterValue::Kind::string) && value->as_string().size() > row.max_length) {
      const std::string& text = value->as_string();
      throw ParameterError(
          ParameterError::Reason::out_of_range,
          with_location(value->location.empty() ? location_of_(key) : value->location,
                        std::string(key) + " = '" + text.substr(0, kShownCharacters) + "...' has " +
                            std::to_string(text.size()) + " characters; at most " +
                            std::to_string(row.max_length) + " are accepted"));
    }
    std::string name = decode_name(*value, key, what);
    if (!row.choices.empty() && !is_choice(row.choices, name)) {
      throw ParameterError(
          ParameterError::Reason::out_of_range,
          with_location(value->location.empty() ? location_of_(key) : value->location,
                        std::string(key) + " = " + value->describe() + " is not " +
                            std::string(what) + " (valid: " + std::string(row.choices) + ")"));
    }
    return name;
  }

  // true or false; `fallback` if not given. A number or a string ("true") is refused rather
  // than read as one: a switch of the safety lock must say what it means.
  bool flag(std::string_view key, bool fallback) const {
    const ParameterValue* value = setting(key);
    if (value == nullptr) return fallback;
    if (!value->is(ParameterValue::Kind::boolean)) {
      throw ParameterError(
          ParameterError::Reason::wrong_type,
          with_location(value->location.empty() ? location_of_(key) : value->location,
                        std::string(key) + " = " + value->describe() + " is not true or false"));
    }
    return value->as_boolean();
  }

  std::string location(std::string_view key) const { return location_of_(key); }

 private:
  const ParameterValue& tree_;
  const KeyLocation& location_of_;
};

}  // namespace

// The control thread's period is the dt of every cycle, give or take its jitter: a cycle that
// starts late by part of a period has a longer dt, and the next one (on its absolute deadline) a
// shorter one by as much. The period must stay a believable dt (plausibility.dt) with half a
// period of that either way; a period near plausibility.dt.max would fail every other cycle
// closed (invalid_dt), one beyond it every cycle, while the node reports itself running.
void check_control_period(double control_rate, const Range& plausible) {
  const double period = 1.0 / control_rate;
  const std::string rate_text = "control_rate = " + format_number(control_rate) + " Hz";
  const std::string range_text = "plausibility.dt = [" + format_number(plausible.min) + ", " +
                                 format_number(plausible.max) + "] s";
  if (1.5 * period > plausible.max) {
    throw ParameterError(
        ParameterError::Reason::invalid,
        rate_text + " does not fit " + range_text + ": its period of " + format_number(period) +
            " s, late by half a period (" + format_number(1.5 * period) +
            " s), is above plausibility.dt.max = " + format_number(plausible.max) +
            " s, so cycles would fail closed as invalid_dt; raise control_rate to at least " +
            format_number(1.5 / plausible.max) + " Hz or plausibility.dt.max to at least " +
            format_number(1.5 * period) + " s");
  }
  if (0.5 * period < plausible.min) {
    throw ParameterError(
        ParameterError::Reason::invalid,
        rate_text + " does not fit " + range_text + ": its period of " + format_number(period) +
            " s, early by half a period (" + format_number(0.5 * period) +
            " s), is below plausibility.dt.min = " + format_number(plausible.min) +
            " s, so cycles would fail closed as invalid_dt; lower control_rate to at most " +
            format_number(0.5 / plausible.min) + " Hz or plausibility.dt.min to at most " +
            format_number(0.5 * period) + " s");
  }
}

std::string safety_lock_line(const NodeSettings& settings) {
  if (settings.allow_runtime_safety_changes) {
    return "safety settings (safety.*, limits.*, plausibility.*, payload.*, collision.*) may "
           "change while the controller runs (allow_runtime_safety_changes: true): every accepted "
           "change is logged as a warning";
  }
  return "safety settings (safety.*, limits.*, plausibility.*, payload.*, collision.*) are locked "
         "while the controller runs: commands that would change one are refused (to allow them, "
         "start the node with allow_runtime_safety_changes: true)";
}

ParameterInfo NodeSettingInfo::range() const {
  return ParameterInfo{name, unit, min, max, false, description, nullptr};
}

std::string NodeSettingInfo::accepts() const {
  switch (kind) {
    case Kind::name:
      return choices.empty() ? "a string of at most " + std::to_string(max_length) + " characters"
                             : "one of: " + std::string(choices);
    case Kind::number:
    case Kind::integer:
      return (kind == Kind::integer ? "a whole number in " : "") + range().range_text() +
             (unit.empty() ? "" : " " + std::string(unit));
    case Kind::numbers:
      return "at most " + std::to_string(max_length) + " numbers in " + range().range_text() + " " +
             std::string(unit);
    case Kind::flag:
      return "true or false";
  }
  return "";
}

const std::vector<NodeSettingInfo>& node_settings_table() {
  static const std::vector<NodeSettingInfo> table = make_table();
  return table;
}

const NodeSettingInfo& node_setting_info(std::string_view name) {
  for (const NodeSettingInfo& row : node_settings_table()) {
    if (row.name == name) return row;
  }
  throw Error("'" + std::string(name) + "' is not a node setting");
}

const char* to_string(Mode mode) noexcept {
  return mode == Mode::sim ? "sim" : "topics";
}

const std::vector<std::string_view>& node_setting_names() {
  static const std::vector<std::string_view> names = [] {
    std::vector<std::string_view> all;
    for (const NodeSettingInfo& row : node_settings_table()) all.push_back(row.name);
    return all;
  }();
  return names;
}

NodeConfiguration decode_node_configuration(const ParameterValue& tree,
                                            const KeyLocation& location_of,
                                            const std::vector<std::string>& shell_keys,
                                            std::string_view source) {
  static const ParameterValue kEmpty = ParameterValue::map({});
  const ParameterValue& root = tree.is(ParameterValue::Kind::map) ? tree : kEmpty;
  NodeConfiguration configuration;
  const Reader reader(root, location_of);

  // Controller parameters: every member that names a parameter group (nested, or dotted as
  // "stiffness.translation") goes to the decoder, which rejects unknown keys inside the groups.
  // Other unknown keys are only warnings (other tools may keep values there).
  const std::vector<std::string_view>& settings_names = node_setting_names();
  ParameterMap groups;
  for (const ParameterMember& member : root.as_map()) {
    const std::string& key = member.key;
    if (is_parameter_group(key.substr(0, key.find('.')))) {
      groups.push_back(member);
    } else if (std::find(settings_names.begin(), settings_names.end(), key) ==
                   settings_names.end() &&
               std::find(shell_keys.begin(), shell_keys.end(), key) == shell_keys.end()) {
      configuration.unknown_keys.push_back(key);
    }
  }
  configuration.given_parameters = ParameterValue::map(std::move(groups));
  configuration.parameters_source = std::string(source);
  configuration.parameters =
      decode_parameters(configuration.given_parameters, Parameters{}, source);

  NodeSettings& settings = configuration.settings;
  if (reader.setting("mode") != nullptr) {
    const std::string name = reader.name("mode", "a mode");
    settings.mode = name == to_string(Mode::sim) ? Mode::sim : Mode::topics;
  }
  settings.control_rate = reader.number("control_rate", settings.control_rate);
  settings.publish_rate = reader.number("publish_rate", settings.publish_rate);
  if (settings.publish_rate > settings.control_rate) {
    reader.fail("publish_rate",
                "publish_rate = " + format_number(settings.publish_rate) +
                    " Hz is above control_rate = " + format_number(settings.control_rate) + " Hz");
  }
  try {
    check_control_period(settings.control_rate, configuration.parameters.plausibility.dt);
  } catch (const ParameterError& error) {
    reader.fail("control_rate", error.what(), error.reason());
  }
  settings.base_link = reader.name("base_link", "a link name");
  settings.tip_link = reader.name("tip_link", "a link name");
  if (settings.base_link.empty()) reader.fail("base_link", "is not set (the chain's root link)");
  if (settings.tip_link.empty()) reader.fail("tip_link", "is not set (the end-effector link)");
  settings.mjcf_path = reader.name("mjcf_path", "a file path");
  if (const ParameterValue* start_q = reader.setting("start_q")) {
    configuration.start_q_location = location_of("start_q");
    if (!start_q->is(ParameterValue::Kind::list)) {
      throw ParameterError(
          ParameterError::Reason::wrong_shape,
          with_location(
              start_q->location.empty() ? configuration.start_q_location : start_q->location,
              "start_q = " + start_q->describe() + " is not a list of joint positions [rad or m]"));
    }
    const ParameterList& items = start_q->as_list();
    const NodeSettingInfo& row = node_setting_info("start_q");
    if (items.size() > row.max_length) {
      reader.fail("start_q",
                  "start_q has " + std::to_string(items.size()) + " values; a chain has at most " +
                      std::to_string(row.max_length) + " joints",
                  ParameterError::Reason::wrong_shape);
    }
    for (std::size_t i = 0; i < items.size(); ++i) {
      settings.start_q.push_back(
          decode_number(items[i], row.range(), "start_q[" + std::to_string(i) + "]"));
    }
    if (settings.mode == Mode::topics && !settings.start_q.empty()) {
      reader.fail(
          "start_q",
          "start_q is set in topics mode, where the robot's joint_states are the start; remove it "
          "(it is for sim mode)");
    }
  }
  if (reader.setting("engine") != nullptr) {
    settings.engine = sim::engine_from_name(reader.name("engine", "an engine"));
    // Like start_q: a value that would do nothing is refused rather than ignored.
    if (settings.mode == Mode::topics) {
      reader.fail("engine",
                  "engine is set in topics mode, where nothing is simulated; remove it "
                  "(it is for sim mode)");
    }
    // The simulation would refuse it too, but only after the model is loaded and without the
    // place where the setting was made.
    if (settings.engine == sim::Engine::dart && !settings.mjcf_path.empty()) {
      reader.fail("engine", "engine 'dart' cannot simulate the MJCF of mjcf_path ('" +
                                settings.mjcf_path +
                                "'): DART simulates the robot's URDF; remove mjcf_path or "
                                "use engine 'mujoco'");
    }
  }
  settings.joint_states_timeout =
      reader.number("joint_states_timeout", settings.joint_states_timeout);
  if (const ParameterValue* priority = reader.setting("realtime_priority")) {
    const NodeSettingInfo& row = node_setting_info("realtime_priority");
    settings.realtime_priority = decode_integer(*priority, row.range(), row.name);
  }
  settings.publish_tf = reader.flag("publish_tf", settings.publish_tf);
  settings.tf_prefix = reader.name("tf_prefix", "a frame prefix");
  settings.allow_runtime_safety_changes =
      reader.flag("allow_runtime_safety_changes", settings.allow_runtime_safety_changes);
  return configuration;
}

SimulationStart simulation_start(const NodeSettings& settings, const RobotModel& model) {
  SimulationStart start;
  start.q = Eigen::Map<const Eigen::VectorXd>(settings.start_q.data(),
                                              static_cast<Eigen::Index>(settings.start_q.size()));
  if (start.q.size() != 0 || !settings.mjcf_path.empty()) return start;
  try {
    const StartChoice choice = find_start_configuration(model);
    start.q = choice.q;
    std::ostringstream q;
    q << choice.q.transpose().format(Eigen::IOFormat(5, Eigen::DontAlignCols, ", ", ", "));
    start.message = "start configuration (chosen, no start_q set: " + choice.description +
                    "): q = [" + q.str() + "]";
  } catch (const Error& error) {
    start.message = std::string("start configuration: ") + error.what() + "; starting at q = 0";
    start.warning = true;
  }
  return start;
}

void apply_robot_defaults(NodeConfiguration& configuration, const RobotModel& model) {
  configuration.parameters = decode_parameters(
      configuration.given_parameters, default_parameters(model), configuration.parameters_source);
}

void check_start_q(const NodeConfiguration& configuration, const RobotModel& model) {
  const std::vector<double>& start_q = configuration.settings.start_q;
  if (start_q.empty()) return;
  const std::vector<std::string>& joint_names = model.joint_names();
  const auto fail = [&](const std::string& message) {
    throw ParameterError(start_q.size() == joint_names.size() ? ParameterError::Reason::out_of_range
                                                              : ParameterError::Reason::wrong_shape,
                         with_location(configuration.start_q_location, message));
  };
  if (start_q.size() != joint_names.size()) {
    std::string joints;
    for (const std::string& name : joint_names) joints += (joints.empty() ? "" : ", ") + name;
    fail("start_q has " + std::to_string(start_q.size()) +
         " values; expected one per joint of the chain " + model.base_link() + " -> " +
         model.tip_link() + " (" + std::to_string(joint_names.size()) + ": " + joints + ")");
  }
  const JointLimits& limits = model.limits();
  for (std::size_t i = 0; i < start_q.size(); ++i) {
    const Eigen::Index j = static_cast<Eigen::Index>(i);
    if (start_q[i] < limits.position_lower[j] || start_q[i] > limits.position_upper[j]) {
      const bool prismatic = model.joint_types()[i] == JointType::prismatic;
      fail("start_q[" + std::to_string(i) + "] = " + format_number(start_q[i]) +
           (prismatic ? " m" : " rad") + " for joint '" + joint_names[i] +
           "' is outside its limits [" + format_number(limits.position_lower[j]) + ", " +
           format_number(limits.position_upper[j]) + "] in the URDF");
    }
  }
}

std::string tf_frame(const NodeSettings& settings, const std::string& link) {
  return settings.tf_prefix + link;
}

}  // namespace cartesian_impedance::node
