#include "cartesian_impedance/node/node_settings.hpp"

#include <algorithm>
#include <optional>
#include <utility>

#include "cartesian_impedance/core/error.hpp"

// The shells' common settings, decoded with the parameter decoder's own functions so that their
// messages read like every other parameter's.

namespace cartesian_impedance::node {
namespace {

// Ranges of the numeric settings, in the form of the parameter table's rows.
const ParameterInfo kControlRate{"control_rate",       "Hz",   0, 10000, true,
                                 "control cycle rate", nullptr};
const ParameterInfo kPublishRate{"publish_rate", "Hz", 0, 10000, true, "rate of the state topics",
                                 nullptr};
const ParameterInfo kJointStatesTimeout{
    "joint_states_timeout", "s", 0, 10, true, "age at which joint states count as lost", nullptr};
// A joint position: radians or metres, bounded like a URDF's prismatic travel (1 km), which
// catches degrees and typos; check_start_q() checks each against its joint's URDF limits.
const ParameterInfo kStartQ{"start_q", "rad or m", -1000, 1000, false, "start configuration",
                            nullptr};
const ParameterInfo kRealtimePriority{
    "realtime_priority", "", 0, 99, false, "SCHED_FIFO priority; 0 = normal", nullptr};

class Reader {
 public:
  Reader(const ParameterValue& tree, const KeyLocation& location_of)
      : tree_(tree), location_of_(location_of) {}

  const ParameterValue* setting(std::string_view key) const { return tree_.member(key); }

  [[noreturn]] void fail(std::string_view key, const std::string& what) const {
    throw ParameterError(ParameterError::Reason::no_value, with_location(location_of_(key), what));
  }

  double number(const ParameterInfo& row, double fallback) const {
    const ParameterValue* value = setting(row.name);
    return value ? decode_number(*value, row, row.name) : fallback;
  }

  std::string name(std::string_view key, std::string_view what) const {
    const ParameterValue* value = setting(key);
    return value ? decode_name(*value, key, what) : std::string();
  }

 private:
  const ParameterValue& tree_;
  const KeyLocation& location_of_;
};

}  // namespace

const char* to_string(Mode mode) noexcept {
  return mode == Mode::sim ? "sim" : "topics";
}

const std::vector<std::string_view>& node_setting_names() {
  static const std::vector<std::string_view> names = {"mode",
                                                      "control_rate",
                                                      "publish_rate",
                                                      "base_link",
                                                      "tip_link",
                                                      "mjcf_path",
                                                      "start_q",
                                                      "engine",
                                                      "joint_states_timeout",
                                                      "realtime_priority",
                                                      "publish_tf",
                                                      "tf_prefix"};
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
  configuration.parameters =
      decode_parameters(ParameterValue::map(std::move(groups)), Parameters{}, source);

  NodeSettings& settings = configuration.settings;
  if (const ParameterValue* mode = reader.setting("mode")) {
    const std::string name =
        decode_name(*mode, "mode", "a mode", {to_string(Mode::sim), to_string(Mode::topics)});
    settings.mode = name == to_string(Mode::sim) ? Mode::sim : Mode::topics;
  }
  settings.control_rate = reader.number(kControlRate, settings.control_rate);
  settings.publish_rate = reader.number(kPublishRate, settings.publish_rate);
  if (settings.publish_rate > settings.control_rate) {
    reader.fail("publish_rate", format_number(settings.publish_rate) +
                                    " Hz is above control_rate (" +
                                    format_number(settings.control_rate) + " Hz)");
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
    for (std::size_t i = 0; i < items.size(); ++i) {
      settings.start_q.push_back(
          decode_number(items[i], kStartQ, "start_q[" + std::to_string(i) + "]"));
    }
    if (settings.mode == Mode::topics && !settings.start_q.empty()) {
      reader.fail(
          "start_q",
          "start_q is set in topics mode, where the robot's joint_states are the start; remove it "
          "(it is for sim mode)");
    }
  }
  if (const ParameterValue* engine = reader.setting("engine")) {
    settings.engine = sim::engine_from_name(
        decode_name(*engine, "engine", "an engine",
                    {sim::engine_name(sim::Engine::mujoco), sim::engine_name(sim::Engine::dart)}));
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
  settings.joint_states_timeout = reader.number(kJointStatesTimeout, settings.joint_states_timeout);
  if (const ParameterValue* priority = reader.setting("realtime_priority")) {
    settings.realtime_priority =
        decode_integer(*priority, kRealtimePriority, kRealtimePriority.name);
  }
  if (const ParameterValue* publish_tf = reader.setting("publish_tf")) {
    if (!publish_tf->is(ParameterValue::Kind::boolean)) {
      throw ParameterError(
          ParameterError::Reason::wrong_type,
          with_location(
              publish_tf->location.empty() ? location_of("publish_tf") : publish_tf->location,
              "publish_tf = " + publish_tf->describe() + " is not true or false"));
    }
    settings.publish_tf = publish_tf->as_boolean();
  }
  settings.tf_prefix = reader.name("tf_prefix", "a frame prefix");
  return configuration;
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
