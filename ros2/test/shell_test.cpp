// The ROS 2 shell without DDS traffic: command line, names, params files.

#include <gtest/gtest.h>

#include <fstream>

#include <cartesian_impedance/error.hpp>

#include "arguments.hpp"
#include "parameters.hpp"

namespace cartesian_impedance_ros2 {
namespace {

namespace ci = cartesian_impedance;

RosArguments parse(const std::vector<std::string>& a) {
  return parse_arguments(a);
}

TEST(Ros2Arguments, NamesResolveAsInRos2) {
  const RosArguments root = parse({});
  EXPECT_EQ(root.fully_qualified_name(), "/cartesian_impedance_controller");
  EXPECT_EQ(root.dds_topic("~/reference_pose"), "rt/cartesian_impedance_controller/reference_pose");
  EXPECT_EQ(root.dds_topic("joint_states"), "rt/joint_states");

  const RosArguments left =
      parse({"--ros-args", "-r", "__ns:=/left", "-r", "__node:=ctrl", "-r", "joint_states:=/js"});
  EXPECT_EQ(left.fully_qualified_name(), "/left/ctrl");
  EXPECT_EQ(left.dds_topic("~/reference_pose"), "rt/left/ctrl/reference_pose");
  EXPECT_EQ(left.dds_topic("joint_trajectory"), "rt/left/joint_trajectory");
  EXPECT_EQ(left.dds_topic("/absolute"), "rt/absolute");
  EXPECT_EQ(left.dds_topic("joint_states"), "rt/js");  // remapped by its relative name
  const RosArguments remapped = parse({"--ros-args", "-r", "/left/ctrl/reference_pose:=target"});
  EXPECT_EQ(remapped.resolve("~/reference_pose"), "/cartesian_impedance_controller/reference_pose");
  EXPECT_EQ(parse({"--ros-args", "-r", "__ns:=/left", "-r", "__node:=ctrl", "-r",
                   "/left/ctrl/reference_pose:=target"})
                .resolve("~/reference_pose"),
            "/left/target");
}

TEST(Ros2Arguments, BadArgumentsNameThemselves) {
  const auto message = [](const std::vector<std::string>& a) {
    try {
      parse(a);
    } catch (const UsageError& error) {
      return std::string(error.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message({"--ros-args", "-r", "__ns:=left"}).find("absolute"), std::string::npos);
  EXPECT_NE(message({"--ros-args", "-r", "__node:=9lives"}).find("9lives"), std::string::npos);
  EXPECT_NE(message({"--ros-args", "-p", "mode"}).find("NAME:=VALUE"), std::string::npos);
  EXPECT_NE(message({"--ros-args", "--params-file"}).find("needs a value"), std::string::npos);
  EXPECT_NE(message({"--ros-args", "--bogus"}).find("'--bogus'"), std::string::npos);
  EXPECT_NE(message({"mode:=sim"}).find("--ros-args"), std::string::npos);
  EXPECT_THROW(parse({}).resolve("bad name"), UsageError);
}

std::string write(const std::string& name, const std::string& text) {
  const std::string path = std::string(CARTESIAN_IMPEDANCE_BINARY_DIR) + "/" + name;
  std::ofstream(path) << text;
  return path;
}

const std::string kRobot = "    urdf_path: " CARTESIAN_IMPEDANCE_SOURCE_DIR
                           "/models/panda/panda.urdf\n"
                           "    base_link: panda_link0\n    tip_link: panda_link8\n"
                           "    mode: topics\n";

TEST(Ros2Parameters, FilesMatchTheNodeAndLaterValuesWin) {
  const std::string file = write("layers.yaml", "/**:\n  ros__parameters:\n" + kRobot +
                                                    "    stiffness: {translation: 300}\n"
                                                    "/left/ctrl:\n  ros__parameters:\n"
                                                    "    stiffness.translation: [100, 200, 300]\n"
                                                    "/right/ctrl:\n  ros__parameters:\n"
                                                    "    stiffness.translation: 999\n");
  const RosArguments left = parse({"--ros-args", "-r", "__ns:=/left", "-r", "__node:=ctrl",
                                   "--params-file", file, "-p", "stiffness.rotation:=[1, 2, 3]"});
  const Ros2Configuration c = read_configuration(left);
  EXPECT_EQ(c.common.parameters.stiffness.translation, Eigen::Vector3d(100, 200, 300));
  EXPECT_EQ(c.common.parameters.stiffness.rotation, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(c.common.settings.mode, ci::runtime::Mode::topics);
  EXPECT_NE(c.urdf.find("panda_joint7"), std::string::npos);
  // Another node's entry does not apply; /** does.
  const Ros2Configuration other = read_configuration(parse({"--ros-args", "--params-file", file}));
  EXPECT_EQ(other.common.parameters.stiffness.translation, Eigen::Vector3d::Constant(300));
}

TEST(Ros2Parameters, ParametersFileLiesUnderAndPathsAreRelativeToTheFile) {
  const std::string file = write("relative.yaml",
                                 "/**:\n  ros__parameters:\n"
                                 "    urdf_path: ../../../models/panda/panda.urdf\n"
                                 "    mjcf_path: ../../../models/panda/panda.xml\n"
                                 "    base_link: panda_link0\n    tip_link: panda_link8\n"
                                 "    parameters_file: ../../../config/panda.yaml\n"
                                 "    nullspace: {damping_ratio: 0.5}\n");
  const Ros2Configuration c = read_configuration(parse({"--ros-args", "--params-file", file}));
  EXPECT_EQ(c.common.settings.mode, ci::runtime::Mode::sim);
  EXPECT_NE(c.common.settings.mjcf_path.find("models/panda/panda.xml"), std::string::npos);
  EXPECT_EQ(c.common.parameters.nullspace.damping_ratio, 0.5);  // from the params file
  EXPECT_EQ(c.common.parameters.nullspace.stiffness[4], 5.0);   // from config/panda.yaml
}

TEST(Ros2Parameters, QosOverridesFollowRclcppsNames) {
  const std::string file =
      write("qos.yaml", "/**:\n  ros__parameters:\n" + kRobot +
                            "    qos_overrides:\n"
                            "      /cartesian_impedance_controller/controller_state:\n"
                            "        publisher: {reliability: best_effort, depth: 1}\n"
                            "      /joint_states:\n"
                            "        subscription: {durability: transient_local}\n");
  const Ros2Configuration c = read_configuration(parse({"--ros-args", "--params-file", file}));
  const TopicQos state = c.publisher("/cartesian_impedance_controller/controller_state");
  EXPECT_FALSE(state.reliable);
  EXPECT_EQ(state.depth, 1);
  EXPECT_TRUE(c.subscription("/joint_states").transient_local);
  EXPECT_TRUE(c.publisher("/joint_states").reliable);  // not overridden: ROS 2's default
  EXPECT_EQ(c.publisher("/joint_states").depth, 10);
}

TEST(Ros2Parameters, ErrorsNameFileLineParameterAndValue) {
  const auto message = [](const std::string& body) {
    const std::string file = write("bad.yaml", body);
    try {
      read_configuration(parse({"--ros-args", "--params-file", file}));
    } catch (const ci::Error& error) {
      return std::string(error.what());
    }
    return std::string("accepted");
  };
  const std::string head = "/**:\n  ros__parameters:\n" + kRobot;
  const std::string negative = message(head + "    stiffness: {translation: -5}\n");
  EXPECT_NE(negative.find("bad.yaml:7"), std::string::npos) << negative;
  EXPECT_NE(negative.find("stiffness.translation"), std::string::npos) << negative;
  EXPECT_NE(negative.find("-5"), std::string::npos) << negative;
  EXPECT_NE(message(head + "    control_rate: fast\n").find("control_rate"), std::string::npos);
  EXPECT_NE(message("/**:\n  parameters: {}\n").find("ros__parameters"), std::string::npos);
  EXPECT_NE(message("/**:\n  ros__parameters:\n    mode: sim\n").find("base_link"),
            std::string::npos);
  EXPECT_NE(message(head + "    robot_description: '<robot/>'\n").find("both are set"),
            std::string::npos);
  EXPECT_NE(message("- a list\n").find("map of node names"), std::string::npos);
}

}  // namespace
}  // namespace cartesian_impedance_ros2
