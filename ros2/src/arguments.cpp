#include "arguments.hpp"

#include <cctype>

namespace cartesian_impedance_ros2 {
namespace {

// A ROS 2 name token: letters, digits and underscores, not starting with a digit.
bool valid_token(const std::string& token) {
  if (token.empty() || std::isdigit(static_cast<unsigned char>(token[0]))) return false;
  for (const char c : token) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') return false;
  }
  return true;
}

// An absolute name: '/' followed by tokens separated by single '/'; "/" alone for namespaces.
bool valid_absolute(const std::string& name, bool allow_root) {
  if (name == "/") return allow_root;
  if (name.size() < 2 || name[0] != '/' || name.back() == '/') return false;
  std::size_t start = 1;
  while (start <= name.size()) {
    const std::size_t end = name.find('/', start);
    const std::string token = name.substr(start, end == std::string::npos ? end : end - start);
    if (!valid_token(token)) return false;
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return true;
}

std::string join(const std::string& prefix, const std::string& name) {
  return prefix == "/" ? "/" + name : prefix + "/" + name;
}

std::pair<std::string, std::string> split_assignment(const std::string& text, const char* flag) {
  const std::size_t at = text.find(":=");
  if (at == std::string::npos || at == 0) {
    throw UsageError(std::string(flag) + " '" + text + "': expected NAME:=VALUE");
  }
  return {text.substr(0, at), text.substr(at + 2)};
}

}  // namespace

std::string RosArguments::fully_qualified_name() const {
  return join(node_namespace, node_name);
}

std::string RosArguments::expand(const std::string& name) const {
  std::string full;
  if (name.rfind("~/", 0) == 0) {
    full = fully_qualified_name() + name.substr(1);
  } else if (!name.empty() && name[0] == '/') {
    full = name;
  } else {
    full = join(node_namespace, name);
  }
  if (!valid_absolute(full, false)) throw UsageError("'" + name + "' is not a valid topic name");
  return full;
}

std::string RosArguments::resolve(const std::string& name) const {
  const std::string full = expand(name);
  // A remap applies to the name as the node uses it or as it resolves (as rcl matches them); its
  // target is resolved in the node's namespace and not remapped again.
  for (const auto& [from, to] : remaps) {
    if (from == name || expand(from) == full) return expand(to);
  }
  return full;
}

RosArguments parse_arguments(const std::vector<std::string>& arguments) {
  RosArguments result;
  bool in_ros_args = false;
  for (std::size_t i = 0; i < arguments.size(); ++i) {
    const std::string& argument = arguments[i];
    if (argument == "--ros-args") {
      in_ros_args = true;
      continue;
    }
    if (!in_ros_args) {
      if (argument == "-h" || argument == "--help") {
        result.help = true;
        continue;
      }
      throw UsageError("unknown argument '" + argument +
                       "' (ROS arguments follow --ros-args; see --help)");
    }
    if (argument == "--") {
      in_ros_args = false;
      continue;
    }
    const auto value = [&](const char* flag) -> const std::string& {
      if (i + 1 >= arguments.size()) throw UsageError(std::string(flag) + " needs a value");
      return arguments[++i];
    };
    if (argument == "-r" || argument == "--remap") {
      auto [from, to] = split_assignment(value("-r"), "-r");
      if (from == "__ns") {
        if (!valid_absolute(to, true)) {
          throw UsageError("-r __ns:=" + to + ": a namespace is absolute, e.g. /left");
        }
        result.node_namespace = to;
      } else if (from == "__node" || from == "__name") {
        if (!valid_token(to)) throw UsageError("-r __node:=" + to + ": not a valid node name");
        result.node_name = to;
      } else {
        result.remaps.emplace_back(std::move(from), std::move(to));
      }
    } else if (argument == "--params-file") {
      result.params_files.push_back(value("--params-file"));
    } else if (argument == "-p" || argument == "--param") {
      result.params.push_back(split_assignment(value("-p"), "-p"));
    } else if (argument == "--log-level" || argument == "--enclave") {
      value(argument.c_str());  // accepted for compatibility with ros2 run / launch; unused
    } else if (argument.rfind("--", 0) == 0 && (argument.find("log") != std::string::npos)) {
      // --disable-rosout-logs, --enable-stdout-logs, ...: launch files pass them; unused here.
    } else {
      throw UsageError("unknown ROS argument '" + argument +
                       "' (valid: -r, --remap, -p, --param, --params-file, --log-level)");
    }
  }
  // Each remap's names are checked here, once the namespace and node name are known, so that a
  // bad one is a bad command line (exit code 2) rather than a failure when the node first uses it.
  for (const auto& [from, to] : result.remaps) {
    try {
      result.resolve(from);
      result.resolve(to);
    } catch (const UsageError& error) {
      throw UsageError("-r " + from + ":=" + to + ": " + error.what());
    }
  }
  return result;
}

std::string usage() {
  return "usage: cartesian_impedance_ros2 [--ros-args [-r __ns:=/NAMESPACE] [-r __node:=NAME]\n"
         "                                [-r TOPIC:=NEW_TOPIC] [--params-file FILE]...\n"
         "                                [-p NAME:=VALUE]...]\n"
         "The Cartesian impedance controller on ROS 2 topics over DDS (Cyclone DDS), with no ROS "
         "2\n"
         "installation. Parameters: a ROS 2 params file (`/**: ros__parameters: {...}` or the\n"
         "node's name) with the settings mode, urdf_path or robot_description, base_link,\n"
         "tip_link, mjcf_path, control_rate, publish_rate, joint_states_timeout,\n"
         "realtime_priority, effort_controller, ros_distro (the graph layout: humble, or lyrical,\n"
         "the default, for Iron and later), and the controller parameters of config/*.yaml.\n"
         "Domain: ROS_DOMAIN_ID; DDS configuration: CYCLONEDDS_URI.\n";
}

}  // namespace cartesian_impedance_ros2
