// The XmlRpc converter (ros/src/ros_parameters.cpp) recurses into lists and structs inside the
// bounds every converter into the decoder's tree keeps (ci::ParameterTreeGuard): a value nested
// deeper is refused naming its path, not followed.

#include <gtest/gtest.h>

#include <string>

#include <cartesian_impedance/core/error.hpp>

#include "ros_parameters.hpp"

namespace ci = cartesian_impedance;
namespace cir = cartesian_impedance_ros;
using XmlRpc::XmlRpcValue;

TEST(RosParameters, NestingBeyondTheBoundIsRefusedByPath) {
  const std::string ns = "/arm/cartesian_impedance_controller";
  XmlRpcValue deep = 1.0;
  for (int i = 0; i < 100; ++i) {
    XmlRpcValue list;
    list.setSize(1);
    list[0] = deep;
    deep = list;
  }
  XmlRpcValue root;
  root["base_link"] = std::string("panda_link0");
  root["tip_link"] = std::string("panda_link8");
  root["stiffness"]["translation"] = deep;
  std::string path = "stiffness/translation";
  for (int i = 0; i < 31; ++i) path += "[0]";
  try {
    cir::configuration_from_xmlrpc(root, ns);
    ADD_FAILURE() << "accepted";
  } catch (const ci::Error& error) {
    EXPECT_EQ(std::string(error.what()),
              "ROS parameter " + ns + "/stiffness/translation: '" + path +
                  "' is nested too deeply: more than 32 levels of lists and maps; parameters are "
                  "nested at most 4 levels deep, with a list of numbers below");
  }
}
