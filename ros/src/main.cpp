// cartesian_impedance_node: hosts cartesian_impedance::ControlLoop in ROS 1 (see ros/README.md).
// Bad parameters, a missing or invalid URDF or MJCF end the node at start with the library's
// message and exit code 1.

#include <ros/ros.h>

#include <exception>
#include <memory>

#include "node.hpp"

int main(int argc, char** argv) {
  ros::init(argc, argv, "cartesian_impedance_node");
  ros::NodeHandle node;
  ros::NodeHandle private_node("~");
  std::unique_ptr<cartesian_impedance_ros::CartesianImpedanceNode> instance;
  try {
    instance =
        std::make_unique<cartesian_impedance_ros::CartesianImpedanceNode>(node, private_node);
  } catch (const std::exception& error) {
    ROS_FATAL("%s: %s", ros::this_node::getName().c_str(), error.what());
    return 1;
  }
  return instance->run();
}
