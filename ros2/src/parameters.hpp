#pragma once
/// @file
/// The node's configuration from ROS 2 parameters: params files (`--params-file`, ROS 2's format:
/// `<node>: ros__parameters: {...}`, where <node> is `/**`, the fully-qualified node name with or
/// without its leading '/', or `/**/<name>`; later files and entries override earlier ones) and
/// `-p NAME:=VALUE` (YAML values, applied last). Nested maps and dotted names are the same
/// parameter (`stiffness: {translation: 500}` is `stiffness.translation`), as in ROS 2. Values go
/// through the library's one decoder (the YAML adapter, then decode_node_configuration()), so
/// names, units, ranges and messages are those of every other source. `parameters_file` names a
/// parameter file of the library (config/*.yaml) whose values lie under all others.

#include <map>
#include <string>
#include <vector>

#include <cartesian_impedance/node/node_settings.hpp>

#include "arguments.hpp"
#include "dds.hpp"
#include "graph.hpp"

namespace cartesian_impedance_ros2 {

/// The ROS 2 node's configuration.
struct Ros2Configuration {
  cartesian_impedance::node::NodeConfiguration common;
  std::string urdf;         ///< the robot's URDF (from urdf_path or robot_description)
  std::string urdf_source;  ///< where it came from, for messages
  /// topics mode: the ros2_control JointGroupEffortController whose `commands` topic takes the
  /// torques (relative names resolve in the node's namespace).
  std::string effort_controller = "effort_controller";
  /// The distribution whose ros_discovery_info layout the node announces (ROS 2 Humble's GIDs
  /// are 24 octets, later distributions' 16). It cannot change at run time.
  RosDistro ros_distro = kDefaultRosDistro;
  /// QoS overrides by fully-qualified topic name (qos_overrides.<topic>.publisher|subscription.
  /// reliability|durability|depth|history, as rclcpp names them).
  std::map<std::string, TopicQos> publisher_qos;
  std::map<std::string, TopicQos> subscription_qos;

  /// The QoS of a topic this node publishes or subscribes to (ROS 2's default if not overridden).
  TopicQos publisher(const std::string& fully_qualified_topic) const;
  TopicQos subscription(const std::string& fully_qualified_topic) const;
};

/// Reads every params file and -p value of `arguments` for this node.
/// @throws cartesian_impedance::Error naming the file and line (or -p NAME), the parameter, the
///         value and what is expected.
Ros2Configuration read_configuration(const RosArguments& arguments);

}  // namespace cartesian_impedance_ros2
