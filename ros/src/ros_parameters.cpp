#include "ros_parameters.hpp"

#include <optional>
#include <set>
#include <string_view>
#include <utility>

#include <cartesian_impedance/error.hpp>
#include <cartesian_impedance/parameter_tree.hpp>

// The ROS 1 adapter of the library's parameter decoder (parameter_tree.hpp): XmlRpc values ->
// ParameterValue, located by their ROS names, then decode_parameters(). The node's own settings
// are decoded with the same functions, so their messages read like every other.

namespace cartesian_impedance_ros {
namespace {

namespace ci = cartesian_impedance;
using XmlRpc::XmlRpcValue;

// The dynamic_reconfigure servers of the node keep their values under these private names.
constexpr const char* kReconfigureNamespaces[] = {
    "stiffness_reconfigure", "damping_factors_reconfigure", "cartesian_wrench_reconfigure"};

// Settings of the node itself; the controller parameters come from the library's table.
constexpr const char* kSettingNames[] = {
    "mode",      "control_rate", "publish_rate",         "base_link",         "tip_link",
    "mjcf_path", "tf_timeout",   "joint_states_timeout", "realtime_priority",
};

// Ranges of the numeric settings, in the form of the parameter table's rows.
const ci::ParameterInfo kControlRate{"control_rate",       "Hz",   0, 10000, true,
                                     "control cycle rate", nullptr};
const ci::ParameterInfo kPublishRate{
    "publish_rate", "Hz", 0, 10000, true, "rate of the state topics", nullptr};
const ci::ParameterInfo kJointStatesTimeout{
    "joint_states_timeout", "s", 0, 10, true, "age at which joint states count as lost", nullptr};
const ci::ParameterInfo kTfTimeout{"tf_timeout", "s", 0, 10, false, "longest wait for a transform",
                                   nullptr};
const ci::ParameterInfo kRealtimePriority{
    "realtime_priority", "", 0, 99, false, "SCHED_FIFO priority; 0 = normal", nullptr};

class Reader {
 public:
  explicit Reader(std::string namespace_name) : namespace_(std::move(namespace_name)) {}

  std::string full(const std::string& relative) const { return namespace_ + "/" + relative; }
  std::string location(const std::string& relative) const {
    return "ROS parameter " + full(relative);
  }

  [[noreturn]] void fail(const std::string& relative, const std::string& what) const {
    throw ci::Error(ci::with_location(location(relative), what));
  }

  // `value` (at `relative`, e.g. "stiffness/translation") as the decoder's value.
  ci::ParameterValue convert(XmlRpcValue& value, const std::string& relative) const {
    const std::string where = location(relative);
    switch (value.getType()) {
      case XmlRpcValue::TypeInvalid: {
        ci::ParameterValue empty;
        empty.location = where;
        return empty;
      }
      case XmlRpcValue::TypeBoolean:
        return ci::ParameterValue::boolean(static_cast<bool&>(value), where);
      case XmlRpcValue::TypeInt:
        return ci::ParameterValue::number(static_cast<int&>(value), where);
      case XmlRpcValue::TypeDouble:
        return ci::ParameterValue::number(static_cast<double&>(value), where);
      case XmlRpcValue::TypeString:
        return ci::ParameterValue::string(static_cast<std::string&>(value), where);
      case XmlRpcValue::TypeArray: {
        ci::ParameterList items;
        for (int i = 0; i < value.size(); ++i) items.push_back(convert(value[i], relative));
        return ci::ParameterValue::list(std::move(items), where);
      }
      case XmlRpcValue::TypeStruct: {
        ci::ParameterMap members;
        for (auto& member : value) {
          const std::string child = relative + "/" + member.first;
          members.push_back({member.first, convert(member.second, child), location(child)});
        }
        return ci::ParameterValue::map(std::move(members), where);
      }
      default:
        fail(relative, "a date/time or binary value, which no parameter or setting takes");
    }
  }

  // The setting `name` of `root`, if it is given.
  std::optional<ci::ParameterValue> setting(XmlRpcValue& root, const std::string& name) const {
    if (root.getType() != XmlRpcValue::TypeStruct || !root.hasMember(name)) return std::nullopt;
    return convert(root[name], name);
  }

  double number(XmlRpcValue& root, const ci::ParameterInfo& row, double fallback) const {
    const std::optional<ci::ParameterValue> value = setting(root, std::string(row.name));
    return value ? ci::decode_number(*value, row, row.name) : fallback;
  }

  std::string name(XmlRpcValue& root, const std::string& key, std::string_view what) const {
    const std::optional<ci::ParameterValue> value = setting(root, key);
    return value ? ci::decode_name(*value, key, what) : std::string();
  }

 private:
  std::string namespace_;
};

}  // namespace

const char* to_string(Mode mode) noexcept {
  return mode == Mode::sim ? "sim" : "topics";
}

NodeConfiguration configuration_from_xmlrpc(XmlRpcValue& private_namespace,
                                            const std::string& namespace_name) {
  NodeConfiguration configuration;
  // Anything but a struct (nothing set: an invalid value) has no members: every default holds.
  XmlRpcValue& root = private_namespace;
  const Reader reader(namespace_name);

  // Controller parameters: every member that names a parameter group (nested, or dotted as
  // "stiffness.translation") goes to the decoder, which rejects unknown keys inside the groups.
  // Other unknown keys are only warnings (other tools may keep values there).
  std::set<std::string> known(std::begin(kSettingNames), std::end(kSettingNames));
  known.insert(std::begin(kReconfigureNamespaces), std::end(kReconfigureNamespaces));
  ci::ParameterMap groups;
  if (root.getType() == XmlRpcValue::TypeStruct) {
    for (auto& member : root) {
      const std::string& key = member.first;
      if (ci::is_parameter_group(key.substr(0, key.find('.')))) {
        groups.push_back({key, reader.convert(member.second, key), reader.location(key)});
      } else if (known.count(key) == 0) {
        configuration.unknown_keys.push_back(reader.full(key));
      }
    }
  }
  configuration.parameters =
      ci::decode_parameters(ci::ParameterValue::map(std::move(groups)), ci::Parameters{},
                            "ROS parameters in " + namespace_name);

  // The node's settings.
  NodeSettings& settings = configuration.settings;
  if (const std::optional<ci::ParameterValue> mode = reader.setting(root, "mode")) {
    const std::string name =
        ci::decode_name(*mode, "mode", "a mode", {to_string(Mode::sim), to_string(Mode::topics)});
    settings.mode = name == to_string(Mode::sim) ? Mode::sim : Mode::topics;
  }
  settings.control_rate = reader.number(root, kControlRate, settings.control_rate);
  settings.publish_rate = reader.number(root, kPublishRate, settings.publish_rate);
  if (settings.publish_rate > settings.control_rate) {
    reader.fail("publish_rate", ci::format_number(settings.publish_rate) +
                                    " Hz is above control_rate (" +
                                    ci::format_number(settings.control_rate) + " Hz)");
  }
  settings.base_link = reader.name(root, "base_link", "a link name");
  settings.tip_link = reader.name(root, "tip_link", "a link name");
  if (settings.base_link.empty()) reader.fail("base_link", "is not set (the chain's root link)");
  if (settings.tip_link.empty()) reader.fail("tip_link", "is not set (the end-effector link)");
  settings.mjcf_path = reader.name(root, "mjcf_path", "a file path");
  if (settings.mode == Mode::sim && settings.mjcf_path.empty()) {
    reader.fail("mjcf_path", "is not set (sim mode needs the MuJoCo model of the robot)");
  }
  settings.joint_states_timeout =
      reader.number(root, kJointStatesTimeout, settings.joint_states_timeout);
  settings.tf_timeout = reader.number(root, kTfTimeout, settings.tf_timeout);
  if (const std::optional<ci::ParameterValue> priority =
          reader.setting(root, "realtime_priority")) {
    settings.realtime_priority =
        ci::decode_integer(*priority, kRealtimePriority, kRealtimePriority.name);
  }
  return configuration;
}

}  // namespace cartesian_impedance_ros
