// The node settings as the ROS 1 shell reads them (the same decoder as the ROS 2 node's): the
// rates' ranges and the control period against the plausible dt, the strings' length limits, and
// the settings table of ros/README.md against the one table of the settings.

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include <cartesian_impedance/core/error.hpp>
#include <cartesian_impedance/model/robot_limits.hpp>
#include <cartesian_impedance/node/node_settings.hpp>
#include <cartesian_impedance/node/startup_report.hpp>

#include "ros_parameters.hpp"

namespace ci = cartesian_impedance;
namespace cir = cartesian_impedance_ros;
using XmlRpc::XmlRpcValue;

namespace {

const std::string kNamespace = "/arm/cartesian_impedance_controller";

XmlRpcValue robot_settings() {
  XmlRpcValue root;
  root["base_link"] = std::string("panda_link0");
  root["tip_link"] = std::string("panda_link8");
  root["mode"] = std::string("topics");
  return root;
}

std::string error_of(XmlRpcValue& root) {
  try {
    cir::configuration_from_xmlrpc(root, kNamespace);
  } catch (const ci::Error& error) {
    return error.what();
  }
  return "accepted";
}

}  // namespace

TEST(RosNodeSettings, RatesAreSaneAndTheControlPeriodFitsThePlausibleDt) {
  {
    XmlRpcValue root = robot_settings();
    root["publish_rate"] = 1e-11;
    EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                  "/publish_rate: publish_rate = 1e-11 Hz is outside [1, 10000]");
  }
  {
    XmlRpcValue root = robot_settings();
    root["control_rate"] = 1e-11;
    EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                  "/control_rate: control_rate = 1e-11 Hz is outside [1, 10000]");
  }
  {
    // 40 Hz: a 25 ms period, beyond plausibility.dt.max = 20 ms: every cycle was invalid_dt.
    XmlRpcValue root = robot_settings();
    root["control_rate"] = 40;
    root["publish_rate"] = 20;
    const std::string error = error_of(root);
    EXPECT_NE(error.find("/control_rate: control_rate = 40 Hz does not fit plausibility.dt"),
              std::string::npos)
        << error;
    EXPECT_NE(error.find("plausibility.dt.max = 0.02 s"), std::string::npos) << error;
    root["plausibility"]["dt"]["max"] = 0.05;
    EXPECT_EQ(error_of(root), "accepted");
  }
}

TEST(RosNodeSettings, StringSettingsHaveALengthLimit) {
  XmlRpcValue root = robot_settings();
  root["tf_prefix"] = std::string(1000, 'x');
  EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace + "/tf_prefix: tf_prefix = '" +
                                std::string(40, 'x') +
                                "...' has 1000 characters; at most 256 are accepted");
  root["tf_prefix"] = std::string("left/");
  EXPECT_EQ(error_of(root), "accepted");
}

// The safety lock's switch: off unless set to true, and only a boolean sets it (a string "true"
// or a 1 is refused rather than guessed: the switch lets parameter sets relax caps at run time).
TEST(RosNodeSettings, RuntimeSafetyChangesAreOffUnlessSetToTrue) {
  XmlRpcValue root = robot_settings();
  EXPECT_FALSE(
      cir::configuration_from_xmlrpc(root, kNamespace).settings.allow_runtime_safety_changes);
  EXPECT_NE(ci::node::safety_lock_line(cir::configuration_from_xmlrpc(root, kNamespace).settings)
                .find("are locked while the controller runs"),
            std::string::npos);
  root["allow_runtime_safety_changes"] = true;
  const cir::NodeConfiguration unlocked = cir::configuration_from_xmlrpc(root, kNamespace);
  EXPECT_TRUE(unlocked.settings.allow_runtime_safety_changes);
  EXPECT_NE(ci::node::safety_lock_line(unlocked.settings)
                .find("may change while the controller "
                      "runs"),
            std::string::npos);
  root["allow_runtime_safety_changes"] = std::string("true");
  EXPECT_EQ(error_of(root), "ROS parameter " + kNamespace +
                                "/allow_runtime_safety_changes: allow_runtime_safety_changes = "
                                "'true' is not true or false");
  root["allow_runtime_safety_changes"] = 1;
  EXPECT_NE(error_of(root).find("allow_runtime_safety_changes = 1 is not true or false"),
            std::string::npos);
}

// The rule that ties control_rate to plausibility.dt, as the ROS 2 node also applies it to a
// parameter set at run time: thrown without a location, which the caller adds.
TEST(RosNodeSettings, TheControlPeriodRuleIsOneFunction) {
  EXPECT_NO_THROW(ci::node::check_control_period(1000.0, {1e-5, 0.0015}));
  try {
    ci::node::check_control_period(1000.0, {1e-5, 0.001});
    ADD_FAILURE() << "plausibility.dt.max = 1 ms accepted for a 1 ms period";
  } catch (const ci::ParameterError& error) {
    EXPECT_EQ(error.reason(), ci::ParameterError::Reason::invalid);
    EXPECT_EQ(std::string(error.what()),
              "control_rate = 1000 Hz does not fit plausibility.dt = [1e-05, 0.001] s: its period "
              "of 0.001 s, late by half a period (0.0015 s), is above plausibility.dt.max = 0.001 "
              "s, so cycles would fail closed as invalid_dt; raise control_rate to at least 1500 "
              "Hz or plausibility.dt.max to at least 0.0015 s");
  }
  EXPECT_THROW(ci::node::check_control_period(1000.0, {0.0006, 0.02}), ci::ParameterError);
}

// Every setting is a row of ros/README.md's settings table that says what it accepts, as the
// table of the settings does.
TEST(RosNodeSettings, TheReadmeSaysWhatEachSettingAccepts) {
  std::ifstream file(std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/ros/README.md");
  std::stringstream text;
  text << file.rdbuf();
  const std::string readme = text.str();
  for (const ci::node::NodeSettingInfo& row : ci::node::node_settings_table()) {
    const std::string name = "`" + std::string(row.name) + "`";
    const std::size_t at = readme.find("\n| " + name);
    const std::size_t alone = readme.find(", " + name + " |");
    const std::size_t line_start = at != std::string::npos ? at + 1 : readme.rfind('\n', alone) + 1;
    ASSERT_TRUE(at != std::string::npos || alone != std::string::npos)
        << name << " has no row in ros/README.md";
    const std::string line = readme.substr(line_start, readme.find('\n', line_start) - line_start);
    EXPECT_NE(line.find(row.accepts()), std::string::npos)
        << name << ": ros/README.md should say it accepts " << row.accepts() << "\n"
        << line;
  }
}

// What both nodes log once at start: the limits in force, derived from the URDF where the
// configuration leaves them out, and the torque-rate check's warnings where the arm starts.
TEST(RosNodeSettings, StartupReportShowsTheLimitsInForceAndTheRateCheck) {
  const ci::RobotModel model = ci::RobotModel::from_urdf_file(
      std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf", "panda_link0",
      "panda_link8");
  ci::JointVector ready(7);
  ready << 0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785;

  const auto report = ci::node::startup_report(ci::default_parameters(model), model, &ready);
  ASSERT_FALSE(report.empty());
  const std::string& limits = report.front().text;
  EXPECT_EQ(report.front().level, ci::node::ReportLine::Level::info);
  // The Panda's efforts (87 Nm on joints 1-4, 12 on 5-7) and the stiffness they allow.
  EXPECT_NE(limits.find("joint torque [87, 87, 87, 87, 12, 12, 12] Nm"), std::string::npos)
      << limits;
  EXPECT_NE(limits.find("stiffness up to 430 N/m and 12 Nm/rad"), std::string::npos) << limits;
  EXPECT_EQ(report.size(), 1u) << "the derived defaults pass the rate check: "
                               << report.back().text;

  // A rate limit far too slow for the stiffest spring allowed is said, at the start.
  ci::Parameters slow = ci::default_parameters(model);
  slow.limits.joint_torque_rate = ci::JointVector::Constant(1, 2.0);
  const auto warned = ci::node::startup_report(slow, model, &ready);
  ASSERT_GE(warned.size(), 2u);
  EXPECT_EQ(warned[1].level, ci::node::ReportLine::Level::warning);
  EXPECT_NE(warned[1].text.find("at the start configuration"), std::string::npos) << warned[1].text;
  EXPECT_NE(warned.front().text.find("torque rate 2 Nm/s"), std::string::npos)
      << warned.front().text;

  // No start known (topics mode): the limits only. A start the check cannot use: said why.
  EXPECT_EQ(ci::node::startup_report(slow, model, nullptr).size(), 1u);
  const ci::JointVector wrong = ci::JointVector::Zero(3);
  const auto unusable = ci::node::startup_report(slow, model, &wrong);
  ASSERT_EQ(unusable.size(), 2u);
  EXPECT_NE(unusable[1].text.find("cannot be made"), std::string::npos) << unusable[1].text;
}
