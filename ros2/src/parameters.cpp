#include "parameters.hpp"

#include <filesystem>
#include <string>
#include <unordered_map>
#include <utility>

#include <cartesian_impedance/config/yaml.hpp>
#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/core/files.hpp>
#include <cartesian_impedance/core/parameter_tree.hpp>

namespace cartesian_impedance_ros2 {
namespace {

namespace ci = cartesian_impedance;
using ci::ParameterValue;

// Keys the ROS 2 shell reads itself (besides the shared settings and the parameter groups).
const std::vector<std::string> kShellKeys = {"urdf_path", "robot_description", "effort_controller",
                                             "parameters_file", "ros_distro"};
// Settings that name files: relative to the params file they are given in.
const char* const kPathKeys[] = {"urdf_path", "mjcf_path", "parameters_file"};

// The parameters as ROS 2 keeps them: one flat list of dotted names, each given once, in the
// order first given; a later source's value replaces an earlier one in place. Indexed by name, so
// that flattening costs one look-up per key (a linear search per key made 80,000 keys take 10 s).
class FlatParameters {
 public:
  void set(const std::string& key, ParameterValue value) {
    const auto [found, inserted] = index_.emplace(key, members_.size());
    if (!inserted) {
      ci::ParameterMember& member = members_[found->second];
      member.key_location = value.location;
      member.value = std::move(value);
      return;
    }
    const std::string location = value.location;
    members_.push_back({key, std::move(value), location});
  }

  // Every leaf of map `value` under `prefix`, as one source (a node's ros__parameters in a params
  // file, a -p, a parameter file); a path setting relative to `directory`. Within one source a
  // parameter is given once, as the library's loaders require: spelled dotted and nested
  // (`stiffness.translation` and `stiffness: {translation}`), it is refused naming both places
  // rather than the later silently winning.
  void add(const std::string& prefix, const ParameterValue& value,
           const std::filesystem::path& directory) {
    std::unordered_map<std::string, std::string> given;  // key -> where this source gave it
    add_leaves(prefix, value, value.location, directory, given);
  }

  const ci::ParameterMap& members() const { return members_; }
  const ParameterValue* find(const std::string& key) const {
    const auto found = index_.find(key);
    return found == index_.end() ? nullptr : &members_[found->second].value;
  }

  std::string location_of(std::string_view key, const std::string& node) const {
    const auto found = index_.find(std::string(key));
    if (found != index_.end() && !members_[found->second].key_location.empty()) {
      return members_[found->second].key_location;
    }
    return "parameter '" + std::string(key) + "' of " + node;
  }

 private:
  // `key_location`: where the key of `value` is written (its line), for a key given twice.
  void add_leaves(const std::string& prefix, const ParameterValue& value,
                  const std::string& key_location, const std::filesystem::path& directory,
                  std::unordered_map<std::string, std::string>& given) {
    if (value.is(ParameterValue::Kind::map)) {
      for (const ci::ParameterMember& member : value.as_map()) {
        add_leaves(prefix.empty() ? member.key : prefix + "." + member.key, member.value,
                   member.key_location.empty() ? member.value.location : member.key_location,
                   directory, given);
      }
      return;
    }
    const auto [first, inserted] = given.emplace(prefix, key_location);
    if (!inserted) {
      throw ci::ParameterError(
          ci::ParameterError::Reason::given_twice,
          ci::with_location(key_location,
                            "'" + prefix + "' is given twice" +
                                (first->second.empty() ? "" : " (first at " + first->second + ")") +
                                "; expected each key once"));
    }
    ParameterValue leaf = value;
    for (const char* key : kPathKeys) {
      if (prefix == key && leaf.is(ParameterValue::Kind::string) && !leaf.as_string().empty() &&
          std::filesystem::path(leaf.as_string()).is_relative() && !directory.empty()) {
        leaf = ParameterValue::string((directory / leaf.as_string()).lexically_normal().string(),
                                      value.location);
      }
    }
    set(prefix, std::move(leaf));
  }

  ci::ParameterMap members_;
  std::unordered_map<std::string, std::size_t> index_;  // key -> its place in members_
};

bool names_this_node(const std::string& key, const RosArguments& arguments) {
  const std::string full = arguments.fully_qualified_name();
  return key == "/**" || key == full || key == full.substr(1) ||
         key == "/**/" + arguments.node_name;
}

TopicQos parse_qos(TopicQos qos, const std::string& policy, const ParameterValue& value) {
  const std::string where = value.location.empty() ? "" : value.location + ": ";
  if (policy == "depth") {
    static const ci::ParameterInfo kDepth{"depth", "", 1, 100000, false, "history depth", nullptr};
    qos.depth = ci::decode_integer(value, kDepth, "qos depth");
  } else if (policy == "reliability") {
    qos.reliable = ci::decode_name(value, "qos reliability", "a reliability",
                                   {"reliable", "best_effort"}) == "reliable";
  } else if (policy == "durability") {
    qos.transient_local = ci::decode_name(value, "qos durability", "a durability",
                                          {"volatile", "transient_local"}) == "transient_local";
  } else if (policy == "history") {
    ci::decode_name(value, "qos history", "a history", {"keep_last"});
  } else {
    throw ci::Error(where + "qos policy '" + policy +
                    "' is not supported (valid: reliability, durability, depth, history)");
  }
  return qos;
}

}  // namespace

TopicQos Ros2Configuration::publisher(const std::string& topic) const {
  const auto found = publisher_qos.find(topic);
  return found == publisher_qos.end() ? TopicQos{} : found->second;
}

TopicQos Ros2Configuration::subscription(const std::string& topic) const {
  const auto found = subscription_qos.find(topic);
  return found == subscription_qos.end() ? TopicQos{} : found->second;
}

Ros2Configuration read_configuration(const RosArguments& arguments) {
  const std::string node = arguments.fully_qualified_name();
  FlatParameters flat;
  for (const std::string& path : arguments.params_files) {
    // Two levels above the parameters: the node's key and ros__parameters.
    const ParameterValue tree =
        ci::parameter_tree_from_yaml(ci::read_regular_file(path, "params file"), path);
    if (tree.is(ParameterValue::Kind::empty)) continue;
    if (!tree.is(ParameterValue::Kind::map)) {
      throw ci::Error(ci::with_location(tree.location, "a params file is a map of node names"));
    }
    const std::filesystem::path directory = std::filesystem::absolute(path).parent_path();
    for (const ci::ParameterMember& entry : tree.as_map()) {
      if (!names_this_node(entry.key, arguments)) continue;
      const ParameterValue* parameters = entry.value.member("ros__parameters");
      if (parameters == nullptr || !parameters->is(ParameterValue::Kind::map)) {
        throw ci::Error(ci::with_location(entry.key_location,
                                          "'" + entry.key + "' has no map 'ros__parameters'"));
      }
      flat.add("", *parameters, directory);
    }
  }
  for (const auto& [name, text] : arguments.params) {
    const std::string source = "-p " + name;
    ParameterValue value = ci::parameter_tree_from_yaml(text, source);
    value.location = source;
    flat.add(name, value, std::filesystem::current_path());
  }

  // parameters_file: a parameter file of the library (config/*.yaml) under everything else.
  if (const ParameterValue* file = flat.find("parameters_file")) {
    const std::string path = ci::decode_name(*file, "parameters_file", "a file path");
    FlatParameters layered;
    layered.add(
        "", ci::parameter_tree_from_yaml(ci::read_regular_file(path, "parameter file"), path), {});
    for (const ci::ParameterMember& member : flat.members()) layered.set(member.key, member.value);
    flat = std::move(layered);
  }

  Ros2Configuration configuration;
  ci::ParameterMap common;
  for (const ci::ParameterMember& member : flat.members()) {
    if (member.key.rfind("qos_overrides.", 0) != 0) {
      common.push_back(member);
      continue;
    }
    // qos_overrides.<topic>.<publisher|subscription>.<policy>; topic names have no dots.
    const std::string rest = member.key.substr(std::string("qos_overrides.").size());
    const std::size_t first = rest.find('.');
    const std::size_t second = first == std::string::npos ? first : rest.find('.', first + 1);
    const std::string entity =
        second == std::string::npos ? "" : rest.substr(first + 1, second - first - 1);
    if (second == std::string::npos || (entity != "publisher" && entity != "subscription")) {
      throw ci::Error(
          ci::with_location(member.key_location, "'" + member.key +
                                                     "': expected qos_overrides.<topic>.publisher|"
                                                     "subscription.<policy>"));
    }
    const std::string topic = arguments.resolve(rest.substr(0, first));
    auto& table =
        entity == "publisher" ? configuration.publisher_qos : configuration.subscription_qos;
    table[topic] = parse_qos(table.count(topic) ? table[topic] : TopicQos{},
                             rest.substr(second + 1), member.value);
  }

  const ParameterValue tree = ParameterValue::map(std::move(common));
  configuration.common = ci::node::decode_node_configuration(
      tree, [&](std::string_view key) { return flat.location_of(key, node); }, kShellKeys,
      "ROS 2 parameters of " + node);

  const ParameterValue* urdf_path = tree.member("urdf_path");
  const ParameterValue* description = tree.member("robot_description");
  if ((urdf_path != nullptr) == (description != nullptr)) {
    throw ci::Error(ci::with_location(
        urdf_path != nullptr ? flat.location_of("robot_description", node) : "",
        "give the robot's URDF as exactly one of urdf_path (a file) and robot_description (its "
        "text)" +
            std::string(urdf_path != nullptr ? "; both are set" : "; neither is set")));
  }
  if (urdf_path != nullptr) {
    const std::string path = ci::decode_name(*urdf_path, "urdf_path", "a file path");
    configuration.urdf = ci::read_regular_file(path, "URDF file");
    configuration.urdf_source = path;
  } else {
    configuration.urdf = ci::decode_name(*description, "robot_description", "the URDF's text");
    configuration.urdf_source = "robot_description";
  }
  if (const ParameterValue* controller = tree.member("effort_controller")) {
    configuration.effort_controller =
        ci::decode_name(*controller, "effort_controller", "a controller name");
  }
  if (const ParameterValue* distro = tree.member("ros_distro")) {
    try {
      configuration.ros_distro =
          ros_distro_from_string(ci::decode_name(*distro, "ros_distro", "a ROS 2 distribution"));
    } catch (const ci::Error& error) {
      throw ci::Error(ci::with_location(flat.location_of("ros_distro", node), error.what()));
    }
  }
  return configuration;
}

}  // namespace cartesian_impedance_ros2
