// The ROS 2 shell without DDS traffic: command line, names, params files.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <cartesian_impedance/config/yaml.hpp>
#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/core/parameter_tree.hpp>
#include <cartesian_impedance/loop/control_loop.hpp>
#include <cartesian_impedance/node/temporary_file.hpp>

#include "arguments.hpp"
#include "messages.hpp"
#include "parameters.hpp"
#include "support/fifo.hpp"

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
  // A remap is checked on the command line (exit code 2), not when the node first uses it.
  EXPECT_EQ(message({"--ros-args", "-r", "joint_states:=9states"}),
            "-r joint_states:=9states: '9states' is not a valid topic name");
  EXPECT_EQ(message({"--ros-args", "-r", "__ns:=/left", "-r", "bad name:=/js"}),
            "-r bad name:=/js: 'bad name' is not a valid topic name");
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
  EXPECT_EQ(c.common.settings.mode, ci::node::Mode::topics);
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
  EXPECT_EQ(c.common.settings.mode, ci::node::Mode::sim);
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
  const std::string distro = message(head + "    ros_distro: galactic\n");
  EXPECT_NE(distro.find("bad.yaml:7"), std::string::npos) << distro;
  EXPECT_NE(distro.find("ros_distro = 'galactic'"), std::string::npos) << distro;
  EXPECT_NE(distro.find("humble"), std::string::npos) << distro;
}

// The graph layout: the current LTS unless the distribution is named; only Humble's GID differs.
TEST(Ros2Parameters, RosDistroChoosesTheGraphLayout) {
  const auto distro = [](const std::string& line) {
    const std::string file = write("distro.yaml", "/**:\n  ros__parameters:\n" + kRobot + line);
    return read_configuration(parse({"--ros-args", "--params-file", file})).ros_distro;
  };
  EXPECT_EQ(distro(""), RosDistro::lyrical);
  EXPECT_EQ(distro("    ros_distro: humble\n"), RosDistro::humble);
  EXPECT_EQ(distro("    ros_distro: jazzy\n"), RosDistro::jazzy);
  EXPECT_EQ(gid_size(RosDistro::humble), 24);
  for (const RosDistro later : {RosDistro::iron, RosDistro::jazzy, RosDistro::kilted,
                                RosDistro::lyrical, RosDistro::rolling}) {
    EXPECT_EQ(gid_size(later), 16) << to_string(later);
    EXPECT_EQ(ros_distro_from_string(to_string(later)), later);
  }
}

// start_q, tf_prefix, publish_tf and a sim mode without mjcf_path, through the shared decoder.
TEST(Ros2Parameters, StartConfigurationAndTransformSettings) {
  const std::string sim = "/**:\n  ros__parameters:\n    urdf_path: " CARTESIAN_IMPEDANCE_SOURCE_DIR
                          "/models/ur5e/ur5e.urdf\n    base_link: base_link\n"
                          "    tip_link: tool0\n";
  const std::string file = write("start.yaml", sim +
                                                   "    start_q: [3.1416, -1.5708, 1.5708, "
                                                   "-1.5708, -1.5708, 0]\n"
                                                   "    tf_prefix: arm/\n    publish_tf: false\n");
  const Ros2Configuration c = read_configuration(parse({"--ros-args", "--params-file", file}));
  EXPECT_EQ(c.common.settings.mode, ci::node::Mode::sim);
  EXPECT_TRUE(c.common.settings.mjcf_path.empty());  // the URDF is simulated
  EXPECT_EQ(c.common.settings.start_q,
            (std::vector<double>{3.1416, -1.5708, 1.5708, -1.5708, -1.5708, 0}));
  EXPECT_EQ(c.common.settings.tf_prefix, "arm/");
  EXPECT_FALSE(c.common.settings.publish_tf);
  EXPECT_EQ(ci::node::tf_frame(c.common.settings, "tool0"), "arm/tool0");
  EXPECT_NE(c.common.start_q_location.find("start.yaml:6"), std::string::npos)
      << c.common.start_q_location;
  const Ros2Configuration defaults =
      read_configuration(parse({"--ros-args", "--params-file", write("defaults.yaml", sim)}));
  EXPECT_TRUE(defaults.common.settings.start_q.empty());
  EXPECT_TRUE(defaults.common.settings.publish_tf);
  EXPECT_EQ(defaults.common.settings.tf_prefix, "");
  // One value per joint of the chain, each within its limits, checked once the model is loaded.
  const ci::RobotModel ur5e = ci::RobotModel::from_urdf_string(c.urdf, "base_link", "tool0");
  EXPECT_NO_THROW(ci::node::check_start_q(c.common, ur5e));
  const auto check = [](const ci::node::NodeConfiguration& configuration,
                        const ci::RobotModel& model) {
    try {
      ci::node::check_start_q(configuration, model);
    } catch (const ci::ParameterError& error) {
      return std::string(error.what());
    }
    return std::string("accepted");
  };
  const ci::RobotModel shorter =
      ci::RobotModel::from_urdf_string(c.urdf, "base_link", "wrist_2_link");
  EXPECT_THAT(check(c.common, shorter),
              testing::EndsWith("start.yaml:6: start_q has 6 values; expected one per joint of the "
                                "chain base_link -> wrist_2_link (5: shoulder_pan_joint, "
                                "shoulder_lift_joint, elbow_joint, wrist_1_joint, wrist_2_joint)"));
  ci::node::NodeConfiguration outside = c.common;
  outside.settings.start_q[2] = 7.0;
  EXPECT_THAT(check(outside, ur5e),
              testing::EndsWith("start.yaml:6: start_q[2] = 7 rad for joint 'elbow_joint' is "
                                "outside its limits [-6.283185307, 6.283185307] in the URDF"));

  const auto message = [&](const std::vector<std::string>& extra) {
    std::vector<std::string> args = {"--ros-args", "--params-file", write("defaults.yaml", sim)};
    args.insert(args.end(), extra.begin(), extra.end());
    try {
      read_configuration(parse(args));
    } catch (const ci::Error& error) {
      return std::string(error.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message({"-p", "start_q:=[0.0, .nan, 1.0]"}),
            "-p start_q:1: start_q[1] = nan rad or m is not finite (valid: [-1000, 1000])");
  EXPECT_EQ(message({"-p", "start_q:=[0.0, 1e6]"}),
            "-p start_q:1: start_q[1] = 1000000 rad or m is outside [-1000, 1000]");
  EXPECT_EQ(message({"-p", "start_q:=[0.0, fast]"}),
            "-p start_q:1: start_q[1] = 'fast' is not a number [rad or m]");
  EXPECT_EQ(message({"-p", "start_q:=0.5"}),
            "-p start_q: start_q = 0.5 is not a list of joint positions [rad or m]");
  EXPECT_NE(message({"-p", "mode:=topics", "-p", "start_q:=[0, 0, 0, 0, 0, 0]"})
                .find("start_q is set in topics mode"),
            std::string::npos);
  EXPECT_EQ(message({"-p", "mode:=topics", "-p", "start_q:=[]"}), "accepted");
  EXPECT_EQ(message({"-p", "publish_tf:=1"}), "-p publish_tf: publish_tf = 1 is not true or false");
}

// engine, through the shared decoder: a sim-mode setting, DART for the URDF only.
TEST(Ros2Parameters, EngineIsASimModeSettingForTheUrdf) {
  const std::string sim = "/**:\n  ros__parameters:\n    urdf_path: " CARTESIAN_IMPEDANCE_SOURCE_DIR
                          "/models/ur5e/ur5e.urdf\n    base_link: base_link\n"
                          "    tip_link: tool0\n";
  const Ros2Configuration dart = read_configuration(
      parse({"--ros-args", "--params-file", write("engine.yaml", sim + "    engine: dart\n")}));
  EXPECT_EQ(dart.common.settings.engine, ci::sim::Engine::dart);
  const Ros2Configuration defaults =
      read_configuration(parse({"--ros-args", "--params-file", write("engine.yaml", sim)}));
  EXPECT_EQ(defaults.common.settings.engine, ci::sim::Engine::mujoco);

  const auto message = [&](const std::vector<std::string>& extra) {
    std::vector<std::string> args = {"--ros-args", "--params-file", write("engine.yaml", sim)};
    args.insert(args.end(), extra.begin(), extra.end());
    try {
      read_configuration(parse(args));
    } catch (const ci::Error& error) {
      return std::string(error.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message({"-p", "engine:=mujoco"}), "accepted");
  EXPECT_EQ(message({"-p", "engine:=bullet"}),
            "-p engine: engine = 'bullet' is not an engine (valid: mujoco, dart)");
  EXPECT_EQ(message({"-p", "mode:=topics", "-p", "engine:=dart"}),
            "-p engine: engine is set in topics mode, where nothing is simulated; remove it (it "
            "is for sim mode)");
  EXPECT_THAT(message({"-p", "engine:=dart", "-p", "mjcf_path:=/models/panda.xml"}),
              testing::EndsWith("engine 'dart' cannot simulate the MJCF of mjcf_path "
                                "('/models/panda.xml'): DART simulates the robot's URDF; remove "
                                "mjcf_path or use engine 'mujoco'"));
}

// What a node is configured with, with the settings of `extra` (-p NAME:=VALUE) in topics mode:
// "accepted" or the error.
std::string configuration_error(const std::vector<std::string>& extra) {
  std::vector<std::string> args = {"--ros-args", "--params-file",
                                   write("settings.yaml", "/**:\n  ros__parameters:\n" + kRobot)};
  args.insert(args.end(), extra.begin(), extra.end());
  try {
    read_configuration(parse(args));
  } catch (const ci::Error& error) {
    return error.what();
  }
  return "accepted";
}

// The rates' ranges in the settings table are sane: a period counted in nanoseconds cannot
// overflow (1e-11 Hz was 1e20 ns: the publisher spun, the control thread ran every ns), and the
// control period must be a dt the controller believes, with half a period of jitter either way
// (below 75 Hz every cycle was invalid_dt at the default plausibility.dt.max of 20 ms while the
// node said "controller running").
TEST(Ros2Parameters, RatesAreSaneAndTheControlPeriodFitsThePlausibleDt) {
  EXPECT_EQ(configuration_error({"-p", "publish_rate:=1e-11"}),
            "-p publish_rate: publish_rate = 1e-11 Hz is outside [1, 10000]");
  EXPECT_EQ(configuration_error({"-p", "control_rate:=1e-11"}),
            "-p control_rate: control_rate = 1e-11 Hz is outside [1, 10000]");
  EXPECT_EQ(configuration_error({"-p", "joint_states_timeout:=1e-11"}),
            "-p joint_states_timeout: joint_states_timeout = 1e-11 s is outside [0.001, 1]");
  EXPECT_EQ(configuration_error({"-p", "control_rate:=50", "-p", "publish_rate:=50"}),
            "-p control_rate: control_rate = 50 Hz does not fit plausibility.dt = [1e-05, 0.02] "
            "s: its period of 0.02 s, late by half a period (0.03 s), is above "
            "plausibility.dt.max = 0.02 s, so cycles would fail closed as invalid_dt; raise "
            "control_rate to at least 75 Hz or plausibility.dt.max to at least 0.03 s");
  EXPECT_EQ(configuration_error({"-p", "control_rate:=75", "-p", "publish_rate:=50"}), "accepted");
  EXPECT_EQ(configuration_error({"-p", "control_rate:=50", "-p", "publish_rate:=50", "-p",
                                 "plausibility.dt.max:=0.05"}),
            "accepted");
  EXPECT_THAT(configuration_error({"-p", "control_rate:=10000", "-p", "plausibility.dt.min:=1e-4"}),
              testing::HasSubstr("control_rate = 10000 Hz does not fit plausibility.dt = [0.0001, "
                                 "0.02] s: its period of 0.0001 s, early by half a period (5e-05 "
                                 "s), is below plausibility.dt.min = 0.0001 s"));
  EXPECT_THAT(configuration_error({"-p", "publish_rate:=2000"}),
              testing::HasSubstr("publish_rate = 2000 Hz is above control_rate = 1000 Hz"));
}

// Strings are bounded (a 50 MB tf_prefix went into every transform of every /tf message: 1.7 GB
// at 103 % CPU), and a message about one does not repeat it whole.
TEST(Ros2Parameters, StringSettingsHaveALengthLimit) {
  const std::string long_prefix(300, 'a');
  EXPECT_EQ(configuration_error({"-p", "tf_prefix:=" + long_prefix}),
            "-p tf_prefix: tf_prefix = '" + std::string(40, 'a') +
                "...' has 300 characters; at most 256 are accepted");
  EXPECT_EQ(configuration_error({"-p", "tf_prefix:=" + std::string(256, 'a')}), "accepted");
  EXPECT_THAT(configuration_error({"-p", "base_link:=" + long_prefix}),
              testing::HasSubstr("base_link = 'aaa"));
  EXPECT_THAT(configuration_error({"-p", "mode:=" + long_prefix}),
              testing::HasSubstr("has 300 characters; at most 16 are accepted"));
  EXPECT_THAT(configuration_error({"-p", "mjcf_path:=/" + std::string(5000, 'm')}),
              testing::HasSubstr("has 5001 characters; at most 4096 are accepted"));
}

// What both shells simulate robot_description's text from: a file of its own, gone afterwards.
// Every file the node reads by name goes through ci::read_regular_file(): a FIFO (whose open
// waits for a writer forever) and /dev/zero (which never ends) are refused before reading.
TEST(Ros2Parameters, SpecialFilesAreRefusedWherePathsAreRead) {
  const auto message = [](const std::vector<std::string>& arguments) {
    std::vector<std::string> all = {"--ros-args"};
    all.insert(all.end(), arguments.begin(), arguments.end());
    try {
      read_configuration(parse(all));
    } catch (const ci::LoadError& error) {
      return std::string(error.what());
    } catch (const std::exception& error) {
      return std::string("not a LoadError: ") + error.what();
    }
    return std::string("accepted");
  };
  const std::string robot =
      "/**:\n  ros__parameters:\n    base_link: panda_link0\n"
      "    tip_link: panda_link8\n    mode: topics\n";
  const std::string panda_urdf = CARTESIAN_IMPEDANCE_SOURCE_DIR "/models/panda/panda.urdf";
  for (const char* device : {"fifo", "/dev/zero"}) {
    const ci::test::Fifo fifo("ros2_shell");
    const std::string path = std::string(device) == "fifo" ? fifo.path() : device;
    const std::string is =
        std::string(device) == "fifo" ? "' is a FIFO (named pipe)" : "' is a character device";
    EXPECT_THAT(message({"--params-file", path}),
                ::testing::StartsWith("params file '" + path + is));
    EXPECT_THAT(message({"--params-file",
                         write("special_urdf.yaml", robot + "    urdf_path: " + path + "\n")}),
                ::testing::StartsWith("URDF file '" + path + is));
    EXPECT_THAT(message({"--params-file", write("special_parameters.yaml",
                                                robot + "    urdf_path: " + panda_urdf +
                                                    "\n    parameters_file: " + path + "\n")}),
                ::testing::StartsWith("parameter file '" + path + is));
  }
}

// Within one node's ros__parameters, as in the library's parameter files, a parameter is given
// once: dotted and nested is refused naming both lines, not decided by which came last.
TEST(Ros2Parameters, ADottedAndANestedKeyForOneParameterAreRefused) {
  const std::string file = write("dotted_nested.yaml", "/**:\n  ros__parameters:\n" + kRobot +
                                                           "    stiffness.translation: 100\n"
                                                           "    stiffness:\n"
                                                           "      translation: 200\n");
  const std::string params = "--params-file";
  try {
    read_configuration(parse({"--ros-args", params, file}));
    ADD_FAILURE() << "accepted";
  } catch (const ci::Error& error) {
    EXPECT_EQ(std::string(error.what()),
              file + ":9: 'stiffness.translation' is given twice (first at " + file +
                  ":7); expected each key once");
  }
  // The library's loader says the same of the same text.
  try {
    ci::parameters_from_yaml("stiffness.translation: 100\nstiffness:\n  translation: 200\n",
                             "library.yaml");
    ADD_FAILURE() << "accepted";
  } catch (const ci::Error& error) {
    EXPECT_EQ(std::string(error.what()),
              "library.yaml:3: 'stiffness.translation' is given twice (first at library.yaml:1); "
              "expected each key once");
  }
}

// A params file is a tree like any other: at most ci::ParameterTreeGuard::kMaxValues values,
// each key counted. 40,000 keys (80,013 values with the robot's) are read, in several files too,
// each flattened with one look-up per key; 80,000 keys (160,013) are refused while the file is
// read.
TEST(Ros2Parameters, ManyKeysAreReadUpToTheCapAndRefusedBeyondIt) {
  const auto keys = [](const std::string& prefix, int count) {
    std::string text = "/**:\n  ros__parameters:\n" + kRobot;
    for (int i = 0; i < count; ++i) text += "    " + prefix + std::to_string(i) + ": 1\n";
    return text;
  };
  std::vector<std::string> arguments = {"--ros-args"};
  for (const char* prefix : {"a", "b", "c"}) {
    arguments.push_back("--params-file");
    arguments.push_back(write(std::string("keys_") + prefix + ".yaml", keys(prefix, 40000)));
  }
  const Ros2Configuration c = read_configuration(parse(arguments));
  ASSERT_EQ(c.common.unknown_keys.size(), 120000u);
  EXPECT_EQ(c.common.unknown_keys.front(), "a0");
  EXPECT_EQ(c.common.unknown_keys.back(), "c39999");

  const std::string too_many = write("keys_80k.yaml", keys("k", 80000));
  try {
    read_configuration(parse({"--ros-args", "--params-file", too_many}));
    ADD_FAILURE() << "accepted";
  } catch (const ci::Error& error) {
    EXPECT_THAT(
        std::string(error.what()),
        ::testing::HasSubstr("more than 100000 values; a parameter set holds a few hundred"));
  }
}

TEST(Ros2Parameters, TemporaryFileHoldsTheTextUntilDestroyed) {
  std::string first_path;
  {
    const ci::node::TemporaryFile first("<robot name='a'/>", ".urdf");
    const ci::node::TemporaryFile second("<robot name='b'/>", ".urdf");
    first_path = first.path();
    EXPECT_NE(first.path(), second.path());
    EXPECT_THAT(first.path(), testing::EndsWith(".urdf"));
    std::ifstream file(first.path());
    const std::string text((std::istreambuf_iterator<char>(file)), {});
    EXPECT_EQ(text, "<robot name='a'/>");
  }
  EXPECT_FALSE(std::ifstream(first_path).good()) << first_path;
}

TEST(Ros2Messages, FramesAreNamedWithOrWithoutTheTfPrefix) {
  const Frames frames{"panda_link0", "panda_link8", "left/"};
  EXPECT_TRUE(frames.is_base("panda_link0"));
  EXPECT_TRUE(frames.is_base("left/panda_link0"));
  EXPECT_FALSE(frames.is_base("right/panda_link0"));
  EXPECT_FALSE(frames.is_base("left/panda_link8"));
  EXPECT_TRUE(frames.is_tip("left/panda_link8"));
  EXPECT_EQ(frames.base_frame(), "left/panda_link0");
  PoseStamped pose{};
  pose.header.frame_id = const_cast<char*>("left/panda_link0");
  pose.pose.orientation.w = 1.0;
  EXPECT_NO_THROW(reference_from_message(pose, frames));
  pose.header.frame_id = const_cast<char*>("right/panda_link0");
  EXPECT_THROW(reference_from_message(pose, frames), ci::Error);
}

// A peer's frame_id is named, not echoed: an 8 MiB one made a log line of 8 MiB per second (the
// throttle's one line), and a newline in it a second, forged line.
TEST(Ros2Messages, AnUnknownFrameIsNamedNotEchoed) {
  const Frames frames{"panda_link0", "panda_link8", ""};
  std::string huge(8 << 20, 'f');
  const auto message_of = [](const auto& convert) {
    try {
      convert();
    } catch (const ci::Error& error) {
      return std::string(error.what());
    }
    return std::string("accepted");
  };
  PoseStamped pose{};
  pose.pose.orientation.w = 1.0;
  pose.header.frame_id = huge.data();
  const std::string reference = message_of([&] { reference_from_message(pose, frames); });
  EXPECT_LT(reference.size(), 300u);
  EXPECT_NE(reference.find("header.frame_id = 'ffff"), std::string::npos) << reference;
  EXPECT_NE(reference.find("...' (8388608 characters) is not the base frame"), std::string::npos)
      << reference;
  WrenchStamped wrench{};
  wrench.header.frame_id = huge.data();
  const std::string stiffness = message_of([&] { stiffness_from_message(wrench, frames); });
  EXPECT_LT(stiffness.size(), 400u);
  EXPECT_NE(stiffness.find("(8388608 characters) is not a frame of this controller"),
            std::string::npos)
      << stiffness;
  std::string forged = "x\n[INFO] [0.0] [cartesian_impedance_controller]: all is well";
  wrench.header.frame_id = forged.data();
  const std::string line = message_of([&] { wrench_from_message(wrench, frames); });
  EXPECT_EQ(line.find('\n'), std::string::npos) << line;
  EXPECT_NE(line.find("'x?[INFO]"), std::string::npos) << line;
}

// A trajectory larger than the loop takes is refused before the node copies it: a million points
// were a million allocations on the command thread before the loop refused them.
TEST(Ros2Messages, ATrajectoryBeyondTheLoopsCapacityIsRefusedBeforeItIsCopied) {
  std::vector<trajectory_msgs_msg_dds__JointTrajectoryPoint_> points(10001);
  std::vector<double> q(7, 0.0);
  for (auto& point : points) {
    point.positions._buffer = q.data();
    point.positions._length = point.positions._maximum = 7;
  }
  JointTrajectoryMessage message{};
  message.points._buffer = points.data();
  message.points._length = message.points._maximum = 10001;
  const auto message_of = [&](std::uint32_t max_points) {
    try {
      trajectory_from_message(message, max_points);
    } catch (const ci::Error& error) {
      return std::string(error.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message_of(10000), "joint_trajectory: 10001 points; at most 10000 are accepted");
  EXPECT_EQ(message_of(10001), "accepted");
  message.points._length = 1;
  std::vector<double> many(17, 0.0);
  points[0].velocities._buffer = many.data();
  points[0].velocities._length = points[0].velocities._maximum = 17;
  EXPECT_EQ(message_of(10000),
            "joint_trajectory: points[0] has 17 values in an array; a chain has at most 16 "
            "joints");
  points[0].velocities._length = 0;
  std::string long_name(300, 'j');
  char* names[] = {long_name.data()};
  message.joint_names._buffer = names;
  message.joint_names._length = message.joint_names._maximum = 1;
  EXPECT_NE(message_of(10000).find("joint_names[0] = 'jjjj"), std::string::npos);
  EXPECT_NE(message_of(10000).find("(300 characters) is longer than 256 characters"),
            std::string::npos)
      << message_of(10000);
}

// full_state carries the torque shaping, the hold and every field of the safety layer, each in
// its own field of the generated C type: every value distinct, so a field filled from the wrong
// member shows.
TEST(Ros2Messages, FullStateCarriesTheLimitsAndTheSafetyLayer) {
  const ci::RobotModel model = ci::RobotModel::from_urdf_file(
      std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf", "panda_link0",
      "panda_link8");
  ci::ControlLoop loop(model);
  ci::JointVector q(7);
  q << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4;
  loop.start(q, ci::JointVector::Zero(7));
  loop.step(q, ci::JointVector::Zero(7), 0.001);
  ci::LoopState state = loop.state();
  state.controller.limits.torque_shaping = ci::TorqueShaping::damping;
  state.controller.limits.torque_shaping_scale = 0.35;
  state.controller.limits.holding = true;
  ci::SafetyState& safety = state.controller.safety;
  safety.reference_speed_limited = true;
  safety.translation_drive_scale = 0.41;
  safety.rotation_drive_scale = 0.42;
  safety.braking = true;
  safety.force_scale = 0.43;
  safety.torque_scale = 0.44;
  safety.reference_clipped = true;
  safety.workspace_penetration = {0.045, -0.046, 0.047};
  safety.wall_force = {-48.0, 49.0, -50.0};
  safety.tank_level = 0.0051;
  safety.tank_draw = -0.0052;
  safety.stiffness_change_scale = 0.53;
  safety.payload_mass = 2.54;
  safety.payload_center_of_mass = {0.055, 0.056, 0.057};
  safety.payload_estimate_valid = true;
  safety.payload_estimate_mass = 2.58;
  safety.payload_estimate_center_of_mass = {0.059, 0.060, 0.061};
  safety.oscillation_scale = 0.25;
  safety.oscillations = 2;
  safety.generated_energy = -0.125;
  safety.passivity_scale = Eigen::Vector3d(0.5, 0.125, 1.0);
  safety.passivity_halvings = 4;
  safety.max_speed_in_force.translation = 0.19;
  safety.max_force_in_force.force = 130.0;
  safety.pfl_speed_limit = 0.19;
  safety.pfl_effective_mass = 2.5;
  ci::CollisionState& collision = state.controller.collision;
  collision.detected = true;
  collision.time = 1.25;
  collision.joint = 6;
  collision.reaction = ci::CollisionReaction::retract;
  collision.collisions = 3;
  collision.residual = ci::JointVector::LinSpaced(7, -3.0, 3.0);
  collision.threshold = ci::JointVector::Constant(7, 6.5);
  ci::runtime::ControlThreadStatistics timing;
  timing.measurement_age_p50_us = 1500.0;
  timing.measurement_age_p99_us = 3250.0;
  timing.measurement_age_max_us = 9000.5;

  OutgoingMessages messages(model, Frames{"panda_link0", "panda_link8", ""});
  messages.fill(state, timing, nullptr);
  const FullState& m = messages.full_state();
  using V = std::vector<double>;
  const auto xyz = [](const geometry_msgs_msg_dds__Vector3_& v) { return V{v.x, v.y, v.z}; };
  EXPECT_STREQ(m.torque_shaping, "damping");
  EXPECT_EQ(m.torque_shaping_scale, 0.35);
  EXPECT_TRUE(m.holding);
  EXPECT_TRUE(m.reference_speed_limited);
  EXPECT_EQ(m.translation_drive_scale, 0.41);
  EXPECT_EQ(m.rotation_drive_scale, 0.42);
  EXPECT_TRUE(m.braking);
  EXPECT_EQ(m.force_scale, 0.43);
  EXPECT_EQ(m.torque_scale, 0.44);
  EXPECT_TRUE(m.reference_clipped);
  EXPECT_EQ(xyz(m.workspace_penetration), (V{0.045, -0.046, 0.047}));
  EXPECT_EQ(xyz(m.wall_force), (V{-48.0, 49.0, -50.0}));
  EXPECT_EQ(m.tank_level, 0.0051);
  EXPECT_EQ(m.tank_draw, -0.0052);
  EXPECT_EQ(m.stiffness_change_scale, 0.53);
  EXPECT_EQ(m.payload_mass, 2.54);
  EXPECT_EQ(xyz(m.payload_center_of_mass), (V{0.055, 0.056, 0.057}));
  EXPECT_TRUE(m.payload_estimate_valid);
  EXPECT_EQ(m.payload_estimate_mass, 2.58);
  EXPECT_EQ(xyz(m.payload_estimate_center_of_mass), (V{0.059, 0.060, 0.061}));
  EXPECT_EQ(m.oscillation_scale, 0.25);
  EXPECT_EQ(m.oscillations, 2u);
  EXPECT_EQ(m.generated_energy, -0.125);
  EXPECT_EQ(m.passivity_scale_translation, 0.5);
  EXPECT_EQ(m.passivity_scale_rotation, 0.125);
  EXPECT_EQ(m.passivity_scale_nullspace, 1.0);
  EXPECT_EQ(m.passivity_halvings, 4u);
  EXPECT_EQ(m.max_speed_translation_in_force, 0.19);
  EXPECT_EQ(m.max_force_in_force, 130.0);
  EXPECT_EQ(m.pfl_speed_limit, 0.19);
  EXPECT_EQ(m.pfl_effective_mass, 2.5);
  EXPECT_TRUE(m.collision_detected);
  EXPECT_EQ(m.collision_time, 1.25);
  EXPECT_STREQ(m.collision_joint, "panda_joint7");
  EXPECT_STREQ(m.collision_reaction, "retract");
  EXPECT_EQ(m.collisions, 3u);
  const auto sequence = [](const auto& s) { return V(s._buffer, s._buffer + s._length); };
  EXPECT_EQ(sequence(m.collision_residual), (V{-3, -2, -1, 0, 1, 2, 3}));
  EXPECT_EQ(sequence(m.collision_threshold), V(7, 6.5));
  EXPECT_EQ(m.measurement_age_p50_us, 1500.0);
  EXPECT_EQ(m.measurement_age_p99_us, 3250.0);
  EXPECT_EQ(m.measurement_age_max_us, 9000.5);

  // A longer name in the same string field afterwards (its storage grows), then a shorter one.
  state.controller.limits.torque_shaping = ci::TorqueShaping::nullspace;
  messages.fill(state, ci::runtime::ControlThreadStatistics{}, nullptr);
  EXPECT_STREQ(messages.full_state().torque_shaping, "nullspace");
  messages.fill(loop.state(), ci::runtime::ControlThreadStatistics{}, nullptr);
  EXPECT_STREQ(messages.full_state().torque_shaping, "none");
  EXPECT_EQ(messages.full_state().tank_level, ci::Parameters{}.safety.energy_tank.initial);
}

}  // namespace
}  // namespace cartesian_impedance_ros2
