#include "cartesian_impedance/runtime/node_settings.hpp"

#include <algorithm>
#include <optional>
#include <utility>

#include "cartesian_impedance/error.hpp"

// The shells' common settings, decoded with the parameter decoder's own functions so that their
// messages read like every other parameter's.

namespace cartesian_impedance::runtime {
namespace {

// Ranges of the numeric settings, in the form of the parameter table's rows.
const ParameterInfo kControlRate{"control_rate",       "Hz",   0, 10000, true,
                                 "control cycle rate", nullptr};
const ParameterInfo kPublishRate{"publish_rate", "Hz", 0, 10000, true, "rate of the state topics",
                                 nullptr};
const ParameterInfo kJointStatesTimeout{
    "joint_states_timeout", "s", 0, 10, true, "age at which joint states count as lost", nullptr};
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
  static const std::vector<std::string_view> names = {
      "mode",     "control_rate", "publish_rate",         "base_link",
      "tip_link", "mjcf_path",    "joint_states_timeout", "realtime_priority"};
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
  if (settings.mode == Mode::sim && settings.mjcf_path.empty()) {
    reader.fail("mjcf_path", "is not set (sim mode needs the MuJoCo model of the robot)");
  }
  settings.joint_states_timeout = reader.number(kJointStatesTimeout, settings.joint_states_timeout);
  if (const ParameterValue* priority = reader.setting("realtime_priority")) {
    settings.realtime_priority =
        decode_integer(*priority, kRealtimePriority, kRealtimePriority.name);
  }
  return configuration;
}

}  // namespace cartesian_impedance::runtime
