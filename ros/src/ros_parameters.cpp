#include "ros_parameters.hpp"

#include <algorithm>
#include <iterator>
#include <string_view>
#include <utility>
#include <vector>

#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/core/parameter_tree.hpp>

// The ROS 1 adapter of the shared node configuration (runtime/node_settings.hpp): XmlRpc values
// -> ParameterValue, located by their ROS names, then decode_node_configuration(). Only
// tf_timeout is decoded here, with the same functions, so its messages read like every other.

namespace cartesian_impedance_ros {
namespace {

namespace ci = cartesian_impedance;
using XmlRpc::XmlRpcValue;

// The dynamic_reconfigure servers of the node keep their values under these private names.
constexpr const char* kReconfigureNamespaces[] = {
    "stiffness_reconfigure", "damping_factors_reconfigure", "cartesian_wrench_reconfigure"};

// The one setting of this node that the shared decoder does not read (other shells have no tf).
const ci::ParameterInfo kTfTimeout{"tf_timeout", "s", 0, 10, false, "longest wait for a transform",
                                   nullptr};

class Converter {
 public:
  explicit Converter(std::string namespace_name) : namespace_(std::move(namespace_name)) {}

  std::string full(const std::string& relative) const { return namespace_ + "/" + relative; }
  std::string location(const std::string& relative) const {
    return "ROS parameter " + full(relative);
  }

  // `value` (at `relative`, e.g. "stiffness/translation", which locates it; `path` adds the index
  // of a list's item) as the decoder's value. `guard` bounds the depth and size of what it builds
  // (XmlRpc values are copies, so none contains itself).
  ci::ParameterValue convert(XmlRpcValue& value, const std::string& relative,
                             const std::string& path, ci::ParameterTreeGuard& guard) const {
    const std::string where = location(relative);
    guard.count(path, where);
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
        const ci::ParameterTreeGuard::Level level = guard.enter(nullptr, path, where);
        ci::ParameterList items;
        for (int i = 0; i < value.size(); ++i) {
          items.push_back(convert(value[i], relative, path + "[" + std::to_string(i) + "]", guard));
        }
        return ci::ParameterValue::list(std::move(items), where);
      }
      case XmlRpcValue::TypeStruct: {
        const ci::ParameterTreeGuard::Level level = guard.enter(nullptr, path, where);
        ci::ParameterMap members;
        for (auto& member : value) {
          const std::string child = relative + "/" + member.first;
          const std::string child_path = path + "/" + member.first;
          guard.count(child_path, location(child));
          members.push_back(
              {member.first, convert(member.second, child, child_path, guard), location(child)});
        }
        return ci::ParameterValue::map(std::move(members), where);
      }
      default:
        throw ci::Error(ci::with_location(
            where, "a date/time or binary value, which no parameter or setting takes"));
    }
  }

 private:
  std::string namespace_;
};

// Whether the node reads the top-level key `key`: a setting or a parameter group (nested, or
// dotted as "stiffness.translation").
bool is_read(const std::string& key) {
  const auto& settings = ci::node::node_setting_names();
  return key == kTfTimeout.name ||
         std::find(settings.begin(), settings.end(), key) != settings.end() ||
         ci::is_parameter_group(key.substr(0, key.find('.')));
}

}  // namespace

NodeConfiguration configuration_from_xmlrpc(XmlRpcValue& private_namespace,
                                            const std::string& namespace_name) {
  const Converter converter(namespace_name);
  // Anything but a struct (nothing set: an invalid value) has no members: every default holds.
  // Keys the node does not read go in without their values: only their names are reported, and
  // a value no parameter takes (a date) there must not stop the node.
  ci::ParameterMap members;
  ci::ParameterTreeGuard guard;
  if (private_namespace.getType() == XmlRpcValue::TypeStruct) {
    for (auto& [key, value] : private_namespace) {
      members.push_back(
          {key, is_read(key) ? converter.convert(value, key, key, guard) : ci::ParameterValue(),
           converter.location(key)});
    }
  }
  const ci::ParameterValue tree = ci::ParameterValue::map(std::move(members));

  // Not unknown: what its dynamic_reconfigure servers keep, and what this node reads itself.
  std::vector<std::string> shell_keys(std::begin(kReconfigureNamespaces),
                                      std::end(kReconfigureNamespaces));
  shell_keys.emplace_back(kTfTimeout.name);
  NodeConfiguration configuration{ci::node::decode_node_configuration(
      tree, [&](std::string_view key) { return converter.location(std::string(key)); }, shell_keys,
      "ROS parameters in " + namespace_name)};
  for (std::string& key : configuration.unknown_keys) key = converter.full(key);

  if (const ci::ParameterValue* value = tree.member(kTfTimeout.name)) {
    configuration.tf_timeout = ci::decode_number(*value, kTfTimeout, kTfTimeout.name);
  }
  return configuration;
}

}  // namespace cartesian_impedance_ros
