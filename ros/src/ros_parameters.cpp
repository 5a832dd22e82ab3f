#include "ros_parameters.hpp"

#include <cmath>
#include <set>
#include <string_view>

#include <cartesian_impedance/error.hpp>

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

// "stiffness.translation" -> "stiffness/translation"
std::string ros_name(std::string_view dotted) {
  std::string name(dotted);
  for (char& c : name) {
    if (c == '.') c = '/';
  }
  return name;
}

std::vector<std::string> split(std::string_view dotted) {
  std::vector<std::string> parts;
  for (std::size_t dot; (dot = dotted.find('.')) != std::string_view::npos;) {
    parts.emplace_back(dotted.substr(0, dot));
    dotted.remove_prefix(dot + 1);
  }
  parts.emplace_back(dotted);
  return parts;
}

const char* type_name(const XmlRpcValue& value) {
  switch (value.getType()) {
    case XmlRpcValue::TypeBoolean:
      return "a boolean";
    case XmlRpcValue::TypeInt:
      return "an integer";
    case XmlRpcValue::TypeDouble:
      return "a number";
    case XmlRpcValue::TypeString:
      return "a string";
    case XmlRpcValue::TypeArray:
      return "a list";
    case XmlRpcValue::TypeStruct:
      return "a namespace";
    default:
      return "an unsupported type";
  }
}

bool is_number(const XmlRpcValue& value) {
  return value.getType() == XmlRpcValue::TypeInt || value.getType() == XmlRpcValue::TypeDouble;
}

double number(XmlRpcValue& value) {
  return value.getType() == XmlRpcValue::TypeInt ? static_cast<double>(static_cast<int&>(value))
                                                 : static_cast<double&>(value);
}

// Walks `root` along `parts`; nullptr if any level is missing.
XmlRpcValue* find(XmlRpcValue& root, const std::vector<std::string>& parts) {
  XmlRpcValue* node = &root;
  for (const std::string& part : parts) {
    if (node->getType() != XmlRpcValue::TypeStruct || !node->hasMember(part)) return nullptr;
    node = &(*node)[part];
  }
  return node;
}

class Reader {
 public:
  explicit Reader(std::string namespace_name) : namespace_(std::move(namespace_name)) {}

  std::string full(const std::string& relative) const { return namespace_ + "/" + relative; }

  [[noreturn]] void fail(const std::string& relative, const std::string& what) const {
    throw ci::Error("ROS parameter " + full(relative) + ": " + what);
  }

  double read_number(const ci::ParameterInfo& info, const std::string& relative,
                     const std::string& element, XmlRpcValue& value) const {
    if (!is_number(value)) {
      fail(relative,
           element + " is " + type_name(value) + ", expected a number" +
               (info.unit.empty() || info.unit == "-" ? std::string()
                                                      : " [" + std::string(info.unit) + "]"));
    }
    const double x = number(value);
    try {
      info.check(element, x);
    } catch (const ci::Error& error) {
      fail(relative, error.what());
    }
    return x;
  }

  void read_field(const ci::ParameterInfo& info, XmlRpcValue& value,
                  ci::Parameters& parameters) const {
    const std::string element(info.name);
    const std::string relative = ros_name(info.name);
    const ci::ParameterField field = info.in(parameters);
    if (auto* scalar = std::get_if<double*>(&field)) {
      **scalar = read_number(info, relative, element, value);
    } else if (auto* vector = std::get_if<Eigen::Vector3d*>(&field)) {
      static constexpr const char* kAxis[3] = {".x", ".y", ".z"};
      if (is_number(value)) {
        (*vector)->setConstant(read_number(info, relative, element, value));
      } else if (value.getType() == XmlRpcValue::TypeArray && value.size() == 3) {
        for (int i = 0; i < 3; ++i) {
          (**vector)[i] = read_number(info, relative, element + kAxis[i], value[i]);
        }
      } else {
        fail(relative,
             std::string("expected 3 numbers [x, y, z] or one number, got ") + type_name(value) +
                 (value.getType() == XmlRpcValue::TypeArray ? " of " + std::to_string(value.size())
                                                            : std::string()));
      }
    } else if (auto* joints = std::get_if<ci::JointVector*>(&field)) {
      if (is_number(value)) {
        **joints = ci::JointVector::Constant(1, read_number(info, relative, element, value));
      } else if (value.getType() == XmlRpcValue::TypeArray && value.size() >= 1 &&
                 value.size() <= ci::kMaxJoints) {
        ci::JointVector values(value.size());
        for (int i = 0; i < value.size(); ++i) {
          values[i] =
              read_number(info, relative, element + "[" + std::to_string(i) + "]", value[i]);
        }
        **joints = values;
      } else {
        fail(relative,
             "expected one number or a list of 1 to " + std::to_string(ci::kMaxJoints) +
                 " numbers (one per joint), got " + type_name(value) +
                 (value.getType() == XmlRpcValue::TypeArray ? " of " + std::to_string(value.size())
                                                            : std::string()));
      }
    } else if (auto* flag = std::get_if<bool*>(&field)) {
      if (value.getType() != XmlRpcValue::TypeBoolean) {
        fail(relative, std::string("expected true or false, got ") + type_name(value));
      }
      **flag = static_cast<bool&>(value);
    } else if (auto* frame = std::get_if<ci::Frame*>(&field)) {
      if (value.getType() != XmlRpcValue::TypeString) {
        fail(relative, std::string("expected base or end_effector, got ") + type_name(value));
      }
      try {
        **frame = ci::frame_from_name(element, static_cast<std::string&>(value));
      } catch (const ci::Error& error) {
        fail(relative, error.what());
      }
    }
  }

  // Reports every leaf below `node` (at dotted `path`) that is not a row of the table.
  void check_known(XmlRpcValue& node, const std::string& path) const {
    if (node.getType() != XmlRpcValue::TypeStruct) {
      for (const ci::ParameterInfo& info : ci::parameter_table()) {
        if (info.name == path) return;
      }
      fail(ros_name(path), "unknown parameter (see the parameter table in README.md)");
    }
    bool row = false;
    for (const ci::ParameterInfo& info : ci::parameter_table()) row = row || info.name == path;
    if (row) return;  // a struct where a value belongs: read_field reports the shape
    for (auto& member : node) check_known(member.second, path + "." + member.first);
  }

  std::string read_string(XmlRpcValue& root, const std::string& name,
                          const std::string& fallback) const {
    if (!root.hasMember(name)) return fallback;
    XmlRpcValue& value = root[name];
    if (value.getType() != XmlRpcValue::TypeString) {
      fail(name, std::string("expected a string, got ") + type_name(value));
    }
    return static_cast<std::string&>(value);
  }

  double read_positive(XmlRpcValue& root, const std::string& name, double fallback, bool allow_zero,
                       double max) const {
    if (!root.hasMember(name)) return fallback;
    XmlRpcValue& value = root[name];
    if (!is_number(value)) fail(name, std::string("expected a number, got ") + type_name(value));
    const double x = number(value);
    const bool ok = std::isfinite(x) && (allow_zero ? x >= 0.0 : x > 0.0) && x <= max;
    if (!ok) {
      fail(name, ci::format_number(x) + " is outside " + (allow_zero ? "[0, " : "(0, ") +
                     ci::format_number(max) + "]");
    }
    return x;
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

  // Controller parameters: every row of the table, at its nested name.
  std::set<std::string> groups;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    const std::vector<std::string> parts = split(info.name);
    groups.insert(parts.front());
    if (XmlRpcValue* value = find(root, parts)) {
      reader.read_field(info, *value, configuration.parameters);
    }
  }

  // Unknown keys: inside a parameter group they are errors (a misspelt parameter would silently
  // keep its default); at the top level only warnings (other tools may keep values there).
  std::set<std::string> known(std::begin(kSettingNames), std::end(kSettingNames));
  known.insert(std::begin(kReconfigureNamespaces), std::end(kReconfigureNamespaces));
  if (root.getType() == XmlRpcValue::TypeStruct) {
    for (auto& member : root) {
      if (groups.count(member.first) != 0) {
        reader.check_known(member.second, member.first);
      } else if (known.count(member.first) == 0) {
        configuration.unknown_keys.push_back(reader.full(member.first));
      }
    }
  }

  // The node's settings.
  NodeSettings& settings = configuration.settings;
  const std::string mode = reader.read_string(root, "mode", "sim");
  if (mode == "sim") {
    settings.mode = Mode::sim;
  } else if (mode == "topics") {
    settings.mode = Mode::topics;
  } else {
    reader.fail("mode", "'" + mode + "' is not sim or topics");
  }
  settings.control_rate =
      reader.read_positive(root, "control_rate", settings.control_rate, false, 10000.0);
  settings.publish_rate =
      reader.read_positive(root, "publish_rate", settings.publish_rate, false, 10000.0);
  if (settings.publish_rate > settings.control_rate) {
    reader.fail("publish_rate", ci::format_number(settings.publish_rate) +
                                    " Hz is above control_rate (" +
                                    ci::format_number(settings.control_rate) + " Hz)");
  }
  settings.base_link = reader.read_string(root, "base_link", "");
  settings.tip_link = reader.read_string(root, "tip_link", "");
  if (settings.base_link.empty()) reader.fail("base_link", "is not set (the chain's root link)");
  if (settings.tip_link.empty()) reader.fail("tip_link", "is not set (the end-effector link)");
  settings.mjcf_path = reader.read_string(root, "mjcf_path", "");
  if (settings.mode == Mode::sim && settings.mjcf_path.empty()) {
    reader.fail("mjcf_path", "is not set (sim mode needs the MuJoCo model of the robot)");
  }
  settings.joint_states_timeout = reader.read_positive(root, "joint_states_timeout",
                                                       settings.joint_states_timeout, false, 10.0);
  settings.tf_timeout = reader.read_positive(root, "tf_timeout", settings.tf_timeout, true, 10.0);
  if (root.hasMember("realtime_priority")) {
    XmlRpcValue& value = root["realtime_priority"];
    if (value.getType() != XmlRpcValue::TypeInt) {
      reader.fail("realtime_priority", std::string("expected an integer, got ") + type_name(value));
    }
    const int priority = static_cast<int&>(value);
    if (priority < 0 || priority > 99) {
      reader.fail("realtime_priority", std::to_string(priority) + " is outside [0, 99]");
    }
    settings.realtime_priority = priority;
  }
  return configuration;
}

}  // namespace cartesian_impedance_ros
