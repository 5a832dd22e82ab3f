// Unit tests of the ROS shell that need no ROS master: parameters read from the parameter
// server's XmlRpc values (the same names and values as config/*.yaml give the same Parameters as
// the library's YAML loader). The message conversions are in conversions_test.cpp, the record of
// commanded values that the dynamic_reconfigure servers build their commands from in
// command_record_test.cpp.

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <ctime>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <cartesian_impedance/config/yaml.hpp>
#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/core/parameter_tree.hpp>
#include <cartesian_impedance/loop/control_loop.hpp>

#include "conversions.hpp"
#include "ros_parameters.hpp"

namespace ci = cartesian_impedance;
namespace cir = cartesian_impedance_ros;
using XmlRpc::XmlRpcValue;

namespace {

const std::string kSource = CARTESIAN_IMPEDANCE_SOURCE_DIR;
const std::string kNamespace = "/arm/cartesian_impedance_controller";

// What `rosparam load` makes of a YAML document: ints stay ints, floats doubles.
XmlRpcValue to_xmlrpc(const YAML::Node& node) {
  XmlRpcValue value;
  if (node.IsMap()) {
    for (const auto& entry : node) value[entry.first.as<std::string>()] = to_xmlrpc(entry.second);
  } else if (node.IsSequence()) {
    value.setSize(static_cast<int>(node.size()));
    for (std::size_t i = 0; i < node.size(); ++i) value[static_cast<int>(i)] = to_xmlrpc(node[i]);
  } else if (node.IsScalar()) {
    const std::string& text = node.Scalar();
    bool flag = false;
    int integer = 0;
    double number = 0.0;
    if (text == "true" || text == "false") {
      flag = text == "true";
      value = flag;
    } else if (YAML::convert<int>::decode(node, integer) &&
               text.find_first_of(".eE") == std::string::npos) {
      value = integer;
    } else if (YAML::convert<double>::decode(node, number)) {
      value = number;
    } else {
      value = text;
    }
  }
  return value;
}

XmlRpcValue required_settings() {
  XmlRpcValue root;
  root["base_link"] = std::string("panda_link0");
  root["tip_link"] = std::string("panda_link8");
  root["mjcf_path"] = std::string("panda.xml");
  return root;
}

std::string error_of(XmlRpcValue& root) {
  try {
    cir::configuration_from_xmlrpc(root, kNamespace);
  } catch (const ci::Error& error) {
    return error.what();
  }
  return "";
}

ci::RobotModel panda() {
  return ci::RobotModel::from_urdf_file(kSource + "/models/panda/panda.urdf", "panda_link0",
                                        "panda_link8");
}

}  // namespace

// ---- parameters -----------------------------------------------------------------------------

class RosParametersFromConfigFile : public testing::TestWithParam<const char*> {};

TEST_P(RosParametersFromConfigFile, SameAsTheYamlLoader) {
  const std::string path = kSource + "/config/" + GetParam();
  XmlRpcValue root = to_xmlrpc(YAML::LoadFile(path));
  for (const char* key : {"base_link", "tip_link", "mjcf_path"}) root[key] = std::string("x");
  const cir::NodeConfiguration configuration = cir::configuration_from_xmlrpc(root, kNamespace);
  EXPECT_EQ(ci::parameters_to_yaml(configuration.parameters),
            ci::parameters_to_yaml(ci::load_parameters(path)));
  EXPECT_TRUE(configuration.unknown_keys.empty());
}

INSTANTIATE_TEST_SUITE_P(Configs, RosParametersFromConfigFile,
                         testing::Values("panda.yaml", "iiwa14.yaml"));

TEST(RosParameters, EveryRowOfTheTableIsRead) {
  // Non-default values for every parameter, written as YAML by the library, read back through
  // the parameter-server path: each row of the table must arrive.
  ci::Parameters changed;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    const ci::ParameterField field = info.in(changed);
    const double value = std::isfinite(info.max)   ? info.max
                         : std::isfinite(info.min) ? info.min + 1.5
                                                   : 1.5;
    if (auto* scalar = std::get_if<double*>(&field)) {
      **scalar = value;
    } else if (auto* vector = std::get_if<Eigen::Vector3d*>(&field)) {
      (*vector)->setConstant(value);
    } else if (auto* joints = std::get_if<ci::JointVector*>(&field)) {
      **joints = ci::JointVector::Constant(7, value);
    } else if (auto* flag = std::get_if<bool*>(&field)) {
      **flag = !**flag;
    } else if (auto* frame = std::get_if<ci::Frame*>(&field)) {
      **frame = ci::Frame::end_effector;
    } else if (auto* reaction = std::get_if<ci::CollisionReaction*>(&field)) {
      **reaction = ci::CollisionReaction::reflex;
    } else if (auto* region = std::get_if<ci::BodyRegion*>(&field)) {
      **region = ci::BodyRegion::chest;
    }
  }
  // Limits stay ordered (min <= max), and the default control period (1 ms) fits plausibility.dt.
  changed.plausibility.dt.min = 1e-4;  // not the default either
  // The payload's moment must fit under the torque cap (consistency_fault()): 1000 kg at 0.1 m
  // would need 981 Nm of the cap's 1000.
  changed.payload.center_of_mass = Eigen::Vector3d(0.075, 0.05, 0.025);
  XmlRpcValue root = to_xmlrpc(YAML::Load(ci::parameters_to_yaml(changed)));
  for (const char* key : {"base_link", "tip_link", "mjcf_path"}) root[key] = std::string("x");
  const ci::Parameters read = cir::configuration_from_xmlrpc(root, kNamespace).parameters;
  EXPECT_EQ(ci::parameters_to_yaml(read), ci::parameters_to_yaml(changed));
  EXPECT_NE(ci::parameters_to_yaml(read), ci::parameters_to_yaml(ci::Parameters{}));
}

TEST(RosParameters, DefaultsAndSettings) {
  XmlRpcValue root = required_settings();
  const cir::NodeConfiguration configuration = cir::configuration_from_xmlrpc(root, kNamespace);
  EXPECT_EQ(ci::parameters_to_yaml(configuration.parameters),
            ci::parameters_to_yaml(ci::Parameters{}));
  EXPECT_EQ(configuration.settings.mode, cir::Mode::sim);
  EXPECT_EQ(configuration.settings.control_rate, 1000.0);
  EXPECT_EQ(configuration.settings.publish_rate, 100.0);
  EXPECT_EQ(configuration.settings.base_link, "panda_link0");

  root["mode"] = std::string("topics");
  root["control_rate"] = 500;  // an int is a number too
  root["publish_rate"] = 50.0;
  root["realtime_priority"] = 80;
  root["stiffness_reconfigure"]["translation_x"] = 3.0;  // left by dynamic_reconfigure: fine
  const cir::NodeSettings settings = cir::configuration_from_xmlrpc(root, kNamespace).settings;
  EXPECT_EQ(settings.mode, cir::Mode::topics);
  EXPECT_EQ(settings.control_rate, 500.0);
  EXPECT_EQ(settings.publish_rate, 50.0);
  EXPECT_EQ(settings.realtime_priority, 80);
}

TEST(RosParameters, TfTimeoutIsThisNodesOwnSetting) {
  // The one setting the shared decoder leaves to this node: read here, range as the others.
  XmlRpcValue root = required_settings();
  EXPECT_EQ(cir::configuration_from_xmlrpc(root, kNamespace).tf_timeout, 0.1);
  root["tf_timeout"] = 0;  // no wait: only transforms already in the buffer
  const cir::NodeConfiguration configuration = cir::configuration_from_xmlrpc(root, kNamespace);
  EXPECT_EQ(configuration.tf_timeout, 0.0);
  EXPECT_TRUE(configuration.unknown_keys.empty());
  root["tf_timeout"] = 11.0;
  EXPECT_EQ(error_of(root),
            "ROS parameter " + kNamespace + "/tf_timeout: tf_timeout = 11 s is outside [0, 10]");
}

TEST(RosParameters, NothingSetNamesTheMissingSetting) {
  XmlRpcValue nothing;  // what the master gives for an empty namespace
  EXPECT_EQ(error_of(nothing),
            "ROS parameter " + kNamespace + "/base_link: is not set (the chain's root link)");
}

TEST(RosParameters, ErrorsNameParameterValueAndRange) {
  {
    XmlRpcValue root = required_settings();
    root["stiffness"]["translation"] = -5;
    EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                  "/stiffness/translation: stiffness.translation = -5 N/m is "
                                  "outside [0, 100000]");
  }
  {
    XmlRpcValue root = required_settings();
    XmlRpcValue& list = root["stiffness"]["rotation"];
    list.setSize(3);
    list[0] = 1.0;
    list[1] = std::numeric_limits<double>::quiet_NaN();
    list[2] = 1.0;
    const std::string error = error_of(root);
    EXPECT_NE(error.find("stiffness.rotation.y = nan"), std::string::npos) << error;
    EXPECT_NE(error.find("not finite"), std::string::npos) << error;
  }
  {
    XmlRpcValue root = required_settings();
    root["stiffness"]["tranlation"] = 500;
    EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                  "/stiffness/tranlation: unknown parameter "
                                  "'stiffness.tranlation' (did you mean 'stiffness.translation'? "
                                  "valid in 'stiffness': translation, rotation, frame)");
  }
  {
    XmlRpcValue root = required_settings();
    root["filter"]["pose"]["time"] = std::string("fast");
    EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                  "/filter/pose/time: filter.pose.time = 'fast' is not a number "
                                  "[s]");
  }
  {
    XmlRpcValue root = required_settings();
    XmlRpcValue& list = root["limits"]["joint_torque"];
    list.setSize(ci::kMaxJoints + 1);
    for (int i = 0; i <= ci::kMaxJoints; ++i) list[i] = 10.0;
    EXPECT_NE(error_of(root).find("list of 1 to " + std::to_string(ci::kMaxJoints) +
                                  " numbers (one per joint), got a list of " +
                                  std::to_string(ci::kMaxJoints + 1)),
              std::string::npos);
  }
  {
    XmlRpcValue root = required_settings();
    root["wrench"]["frame"] = std::string("tool");
    EXPECT_NE(error_of(root).find("/wrench/frame: "), std::string::npos);
    EXPECT_NE(error_of(root).find("tool"), std::string::npos);
  }
  {
    XmlRpcValue root = required_settings();
    root["dynamics"]["gravity_compensation"] = 1;
    EXPECT_NE(error_of(root).find("dynamics.gravity_compensation = 1 is not true or false"),
              std::string::npos);
  }
  {
    XmlRpcValue root = required_settings();
    root["mode"] = std::string("hardware");
    EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                  "/mode: mode = 'hardware' is not a mode (valid: sim, topics)");
  }
  {
    XmlRpcValue root = required_settings();
    root["publish_rate"] = 2000;
    EXPECT_NE(error_of(root).find("above control_rate"), std::string::npos);
  }
  {
    XmlRpcValue root = required_settings();
    root["control_rate"] = 0;
    EXPECT_NE(error_of(root).find("/control_rate: control_rate = 0 Hz is outside [1, 10000]"),
              std::string::npos);
  }
  {
    // Without an MJCF the sim mode simulates the URDF.
    XmlRpcValue root = required_settings();
    root["mjcf_path"] = std::string("");
    EXPECT_EQ(error_of(root), "");
    root["mode"] = std::string("topics");
    EXPECT_EQ(error_of(root), "");
  }
  {
    XmlRpcValue root = required_settings();
    root["start_q"][0] = 0.1;
    root["start_q"][1] = std::string("up");
    EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                  "/start_q: start_q[1] = 'up' is not a number [rad or m]");
    root["start_q"][1] = std::nan("");
    EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                  "/start_q: start_q[1] = nan rad or m is not finite (valid: "
                                  "[-1000, 1000])");
    root["start_q"] = 0.5;
    EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                  "/start_q: start_q = 0.5 is not a list of joint positions "
                                  "[rad or m]");
    root["start_q"] = XmlRpcValue();
    root["start_q"][0] = -0.2;
    root["start_q"][1] = 0.3;
    EXPECT_EQ(error_of(root), "");
    const cir::NodeConfiguration configuration = cir::configuration_from_xmlrpc(root, kNamespace);
    EXPECT_EQ(configuration.settings.start_q, (std::vector<double>{-0.2, 0.3}));
    EXPECT_EQ(configuration.start_q_location, "ROS parameter " + kNamespace + "/start_q");
    root["mode"] = std::string("topics");  // meaningless there: refused, not ignored
    EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                  "/start_q: start_q is set in topics mode, where the robot's "
                                  "joint_states are the start; remove it (it is for sim mode)");
  }
  {
    XmlRpcValue root = required_settings();
    EXPECT_TRUE(cir::configuration_from_xmlrpc(root, kNamespace).settings.publish_tf);
    root["publish_tf"] = false;
    root["tf_prefix"] = std::string("left/");
    const cir::NodeConfiguration configuration = cir::configuration_from_xmlrpc(root, kNamespace);
    EXPECT_FALSE(configuration.settings.publish_tf);
    EXPECT_EQ(cir::tf_frame(configuration.settings, "panda_link0"), "left/panda_link0");
    root["publish_tf"] = 1;
    EXPECT_EQ(error_of(root),
              "ROS parameter " + kNamespace + "/publish_tf: publish_tf = 1 is not true or false");
  }
}

TEST(RosParameters, EngineIsASimModeSettingForTheUrdf) {
  XmlRpcValue root = required_settings();
  EXPECT_EQ(cir::configuration_from_xmlrpc(root, kNamespace).settings.engine,
            ci::sim::Engine::mujoco);
  root["engine"] = std::string("mujoco");
  EXPECT_EQ(error_of(root), "");
  root["engine"] = std::string("dart");  // DART simulates the URDF: not with an MJCF
  EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                "/engine: engine 'dart' cannot simulate the MJCF of mjcf_path "
                                "('panda.xml'): DART simulates the robot's URDF; remove mjcf_path "
                                "or use engine 'mujoco'");
  root["mjcf_path"] = std::string("");
  const cir::NodeSettings settings = cir::configuration_from_xmlrpc(root, kNamespace).settings;
  EXPECT_EQ(settings.engine, ci::sim::Engine::dart);
  EXPECT_STREQ(ci::sim::engine_name(settings.engine), "dart");
  root["engine"] = std::string("bullet");
  EXPECT_EQ(error_of(root),
            "ROS parameter " + kNamespace +
                "/engine: engine = 'bullet' is not an engine (valid: mujoco, dart)");
  root["engine"] = std::string("mujoco");
  root["mode"] = std::string("topics");  // nothing is simulated there: refused, not ignored
  EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                "/engine: engine is set in topics mode, where nothing is "
                                "simulated; remove it (it is for sim mode)");
}

TEST(RosParameters, UnknownTopLevelKeysAreWarnings) {
  XmlRpcValue root = required_settings();
  root["stifness"]["translation"] = 500;  // not a group: only a warning
  const cir::NodeConfiguration configuration = cir::configuration_from_xmlrpc(root, kNamespace);
  ASSERT_EQ(configuration.unknown_keys.size(), 1u);
  EXPECT_EQ(configuration.unknown_keys[0], kNamespace + "/stifness");

  // Only an unknown key's name matters: a value no parameter takes (a date) is no error there,
  // but it is in a parameter group.
  std::tm date{};
  root["stifness"] = XmlRpcValue(&date);
  EXPECT_EQ(error_of(root), "");
  root["stiffness"]["translation"] = XmlRpcValue(&date);
  EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                "/stiffness/translation: a date/time or binary value, which no "
                                "parameter or setting takes");
}

TEST(RosParameters, SameMistakeSameMessageAsTheYamlLoaderAndTheDecoder) {
  // Each mistake as YAML text, as the parameter server holds it (rosparam load of that text) and
  // as a value without location for its dotted name (how a Python dict arrives): one message
  // after the location.
  const auto body = [](const std::string& message) {
    const std::size_t colon = message.find(": ");
    return colon == std::string::npos ? message : message.substr(colon + 2);
  };
  using Value = ci::ParameterValue;
  const std::vector<std::tuple<std::string, std::string, Value>> mistakes{
      {"filter:\n  pose:\n    time: fast\n", "filter.pose.time", Value::string("fast")},
      {"stiffness:\n  translation: [500, 500]\n", "stiffness.translation",
       Value::list({Value::number(500), Value::number(500)})},
      {"stiffness:\n  rotation: -1\n", "stiffness.rotation", Value::number(-1)},
      {"limits:\n  joint_torque_rate: []\n", "limits.joint_torque_rate", Value::list({})},
      {"wrench:\n  frame: tool\n", "wrench.frame", Value::string("tool")},
      {"dynamics:\n  gravity_compensation: 1\n", "dynamics.gravity_compensation", Value::number(1)},
      {"stiffness:\n  tranlation: 1\n", "stiffness.tranlation", Value::number(1)},
      {"limits:\n  stiffness: 100\n", "limits.stiffness", Value::number(100)},
      {"limits:\n  damping_ratio:\n    min: 3\n    max: 2\n", "", Value()},
  };
  for (const auto& [yaml, name, value] : mistakes) {
    SCOPED_TRACE(yaml);
    std::string from_yaml;
    try {
      ci::parameters_from_yaml(yaml, "test.yaml");
    } catch (const ci::Error& error) {
      from_yaml = error.what();
    }
    XmlRpcValue root = to_xmlrpc(YAML::Load(yaml));
    for (const char* key : {"base_link", "tip_link", "mjcf_path"}) root[key] = std::string("x");
    const std::string from_ros = error_of(root);
    ASSERT_FALSE(from_yaml.empty());
    EXPECT_EQ(from_ros.rfind("ROS parameter", 0), 0u) << from_ros;
    EXPECT_EQ(body(from_ros), body(from_yaml));
    if (name.empty()) continue;  // a rule across parameters: no single name
    ci::Parameters parameters;
    try {
      ci::assign_parameter(parameters, name, value);
      ADD_FAILURE() << name << " accepted";
    } catch (const ci::Error& error) {
      EXPECT_EQ(error.what(), body(from_yaml));
    }
  }
}

TEST(RosParameters, DottedNamesAndWholeNumbersAreRead) {
  XmlRpcValue root = required_settings();
  root["stiffness.translation"] = 700;  // as a Python dict or a dotted rosparam key gives it
  root["limits"]["stiffness.rotation.max"] = 400.0;
  root["realtime_priority"] = 80.0;  // a whole number, if a double
  const cir::NodeConfiguration configuration = cir::configuration_from_xmlrpc(root, kNamespace);
  EXPECT_EQ(configuration.parameters.stiffness.translation, Eigen::Vector3d::Constant(700));
  EXPECT_EQ(configuration.parameters.limits.stiffness.rotation.max, 400.0);
  EXPECT_EQ(configuration.settings.realtime_priority, 80);
  EXPECT_TRUE(configuration.unknown_keys.empty());
  root["realtime_priority"] = 80.5;
  EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                "/realtime_priority: realtime_priority = 80.5 is not a whole "
                                "number");
  root["realtime_priority"] = 0;
  root["stiffness"]["translation"] = 600;
  // The server sorts names: the nested one comes first.
  EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                "/stiffness.translation: 'stiffness.translation' is given twice "
                                "(first at ROS parameter " +
                                kNamespace + "/stiffness/translation); expected each key once");
}

TEST(RosParameters, PerJointValuesAreCheckedAgainstTheModel) {
  XmlRpcValue root = required_settings();
  XmlRpcValue& list = root["nullspace"]["stiffness"];
  list.setSize(6);
  for (int i = 0; i < 6; ++i) list[i] = 10;
  const ci::Parameters parameters = cir::configuration_from_xmlrpc(root, kNamespace).parameters;
  try {
    ci::ControlLoop loop(panda(), parameters);
    FAIL() << "6 nullspace stiffnesses for 7 joints were accepted";
  } catch (const ci::Error& error) {
    EXPECT_NE(std::string(error.what()).find("nullspace.stiffness"), std::string::npos);
  }
}
