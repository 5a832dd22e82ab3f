#pragma once
/// @file
/// The node's configuration from the ROS parameter server: the controller parameters under the
/// node's private namespace with the names of config/*.yaml (`~stiffness/translation`,
/// `~limits/joint_torque`, ..., or dotted: `~stiffness.translation`) and the node's own settings
/// (`~mode`, `~control_rate`, ...). The XmlRpc values are converted to the library's
/// ParameterValue, located by their ROS names, and decoded by the runtime's
/// decode_node_configuration() (runtime/node_settings.hpp), which every ROS shell shares; only
/// `~tf_timeout` is this node's own. Everything is read from one XmlRpc value (the whole private
/// namespace), so the parsing is testable without a ROS master.

#include <xmlrpcpp/XmlRpcValue.h>

#include <string>

#include <cartesian_impedance/node/node_settings.hpp>

namespace cartesian_impedance_ros {

using cartesian_impedance::node::Mode;
using cartesian_impedance::node::NodeSettings;
using cartesian_impedance::node::tf_frame;
using cartesian_impedance::node::to_string;

/// The shells' common configuration (settings, controller parameters, unknown keys) plus what
/// only this node reads. unknown_keys are full ROS names ("/arm/controller/stifness"); the
/// node's dynamic_reconfigure namespaces are not among them.
struct NodeConfiguration : cartesian_impedance::node::NodeConfiguration {
  double tf_timeout = 0.1;  ///< [s] longest wait for a tf2 transform in a callback
};

/// Parses the private namespace `private_namespace` (a struct; anything else counts as empty),
/// whose resolved name `namespace_name` (e.g. "/left/cartesian_impedance_controller") is used in
/// messages. Parameters not given keep the library's defaults.
/// @throws cartesian_impedance::Error naming the parameter (`ROS parameter <name>: ...`), the
///         value and what is expected: a value of the wrong type or shape, a value out of range,
///         an unknown parameter inside a parameter group (e.g. `~stiffness/tranlation`), a
///         parameter given twice (nested and dotted), a set that fails validate(), or an invalid
///         setting. Messages after the location are the decoder's, as for a YAML file.
NodeConfiguration configuration_from_xmlrpc(XmlRpc::XmlRpcValue& private_namespace,
                                            const std::string& namespace_name);

}  // namespace cartesian_impedance_ros
