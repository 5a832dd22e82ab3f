#pragma once
/// @file
/// The generated message types under test, as gtest type lists, named after their ROS 2 names.

#include <string>

#include <gtest/gtest.h>

#include "ros2_messages.hpp"

namespace ros2_messages_test {

/// Every type of the generated header (the golden test checks that none is missing).
using AllMessages = ::testing::Types<
    builtin_interfaces_msg_dds__Duration_, builtin_interfaces_msg_dds__Time_,
    std_msgs_msg_dds__Header_, std_msgs_msg_dds__MultiArrayDimension_,
    std_msgs_msg_dds__MultiArrayLayout_, std_msgs_msg_dds__Float64MultiArray_,
    geometry_msgs_msg_dds__Point_, geometry_msgs_msg_dds__Quaternion_, geometry_msgs_msg_dds__Pose_,
    geometry_msgs_msg_dds__PoseStamped_, geometry_msgs_msg_dds__Vector3_,
    geometry_msgs_msg_dds__Wrench_, geometry_msgs_msg_dds__WrenchStamped_,
    geometry_msgs_msg_dds__Transform_, geometry_msgs_msg_dds__TransformStamped_,
    tf2_msgs_msg_dds__TFMessage_, std_msgs_msg_dds__String_, std_msgs_msg_dds__Empty_,
    sensor_msgs_msg_dds__JointState_, trajectory_msgs_msg_dds__JointTrajectoryPoint_,
    trajectory_msgs_msg_dds__JointTrajectory_,
    cartesian_impedance_controller_msg_dds__ControllerConfig_,
    cartesian_impedance_controller_msg_dds__ControllerState_,
    cartesian_impedance_msgs_msg_dds__ControllerState_, rmw_dds_common_msg_dds__Gid_,
    rmw_dds_common_msg_dds__NodeEntitiesInfo_, rmw_dds_common_msg_dds__ParticipantEntitiesInfo_>;
constexpr int kAllMessagesCount = 27;

/// The types the node receives from other nodes.
using ReceivedMessages =
    ::testing::Types<geometry_msgs_msg_dds__PoseStamped_, geometry_msgs_msg_dds__WrenchStamped_,
                     geometry_msgs_msg_dds__Wrench_,
                     cartesian_impedance_controller_msg_dds__ControllerConfig_,
                     trajectory_msgs_msg_dds__JointTrajectory_, sensor_msgs_msg_dds__JointState_,
                     std_msgs_msg_dds__Empty_>;

/// Test names: geometry_msgs_msg_PoseStamped rather than 0, 1, ...
struct RosNames {
  template <class T>
  static std::string GetName(int) {
    std::string name = cartesian_impedance_ros2::MessageType<T>::ros_name;
    for (char& c : name)
      if (c == '/') c = '_';
    return name;
  }
};

}  // namespace ros2_messages_test
