#pragma once
/// @file
/// ROS 2's command line and names, for a node that is not built on rcl: the `--ros-args` part of
/// the arguments (`-r __ns:=/left`, `-r __node:=NAME`, `-r FROM:=TO` topic remaps,
/// `--params-file FILE`, `-p NAME:=VALUE`), and the resolution of topic names (absolute `/x`,
/// relative `x` in the namespace, private `~/x` under the node) into fully-qualified names and
/// DDS topic names (`rt` + the fully-qualified name).

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace cartesian_impedance_ros2 {

/// A command line that is not what the node takes: the message says what and why (exit code 2).
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct RosArguments {
  std::string node_name = "cartesian_impedance_controller";
  std::string node_namespace = "/";
  std::vector<std::string> params_files;                    ///< in the order given
  std::vector<std::pair<std::string, std::string>> params;  ///< -p NAME:=VALUE, in order
  std::vector<std::pair<std::string, std::string>> remaps;  ///< topic remaps FROM:=TO, in order
  bool help = false;

  /// `/ns/name` (`/name` in the root namespace).
  std::string fully_qualified_name() const;
  /// The fully-qualified name of topic `name` (absolute, relative or private), after remapping.
  /// @throws UsageError for a name that is not a valid ROS name.
  std::string resolve(const std::string& name) const;
  /// "rt" + resolve(name): the DDS topic ROS 2 uses for it.
  std::string dds_topic(const std::string& name) const { return "rt" + resolve(name); }

 private:
  std::string expand(const std::string& name) const;
};

/// Parses argv (without argv[0]). Arguments outside `--ros-args ... [--]` are rejected, since the
/// node has no options of its own besides `--help`.
/// @throws UsageError naming the argument, e.g. a remap whose names are not valid ROS names.
RosArguments parse_arguments(const std::vector<std::string>& arguments);

/// The help text.
std::string usage();

}  // namespace cartesian_impedance_ros2
