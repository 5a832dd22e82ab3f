// The node's parameters as the services show them, without DDS: rclcpp's list_parameters rules
// (prefixes, depth, the prefixes of the result), one parameter per row of the library's table
// and per node setting, types per ROS 2, and the sets refused before they reach the loop.

#include <gtest/gtest.h>

#include <algorithm>
#include <optional>

#include <cartesian_impedance/core/parameter_tree.hpp>
#include <cartesian_impedance/loop/control_loop.hpp>
#include <cartesian_impedance/model/robot_model.hpp>

#include "node_parameters.hpp"

namespace parameter_services_test {
namespace {

namespace ci = cartesian_impedance;
using cartesian_impedance_ros2::NamedValue;
using cartesian_impedance_ros2::NodeParameters;
using cartesian_impedance_ros2::RosValue;

class NodeParametersTest : public ::testing::Test {
 protected:
  NodeParametersTest()
      : model_(ci::RobotModel::from_urdf_file(
            std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf", "panda_link0",
            "panda_link8")),
        loop_(model_, ci::Parameters{}) {
    settings_.base_link = "panda_link0";
    settings_.tip_link = "panda_link8";
    RosValue path;
    path.type = cartesian_impedance_ros2::ros_type::kString;
    path.text = "panda.urdf";
    parameters_.emplace(
        loop_, settings_, std::vector<NodeParameters::Extra>{{"urdf_path", path, "the URDF"}},
        [this] { return accepting_; }, "/arm");
  }

  ci::RobotModel model_;
  ci::ControlLoop loop_;
  ci::node::NodeSettings settings_;
  bool accepting_ = false;
  std::optional<NodeParameters> parameters_;
};

using Names = std::vector<std::string>;

TEST_F(NodeParametersTest, ListsEveryRowAndSettingInNameOrder) {
  const auto all = parameters_->list({}, 0);
  EXPECT_TRUE(std::is_sorted(all.names.begin(), all.names.end()));
  EXPECT_EQ(all.names.size(),
            ci::parameter_table().size() + ci::node::node_settings_table().size() + 1);
  // Depth 1 without prefixes: the names without a dot.
  const auto top = parameters_->list({}, 1);
  for (const std::string& name : top.names) EXPECT_EQ(name.find('.'), std::string::npos) << name;
  EXPECT_NE(std::find(top.names.begin(), top.names.end(), "control_rate"), top.names.end());
  EXPECT_TRUE(top.prefixes.empty());
}

TEST_F(NodeParametersTest, ListHonoursPrefixesAndDepthAsRclcpp) {
  // A prefix lists the names below it (prefix + '.'), depth counting the dots after it.
  EXPECT_EQ(parameters_->list({"limits.stiffness.translation"}, 0).names,
            (Names{"limits.stiffness.translation.max", "limits.stiffness.translation.min"}));
  EXPECT_EQ(parameters_->list({"limits.stiffness.translation"}, 0).prefixes,
            (Names{"limits.stiffness.translation"}));
  // rclcpp counts the dots of the name after the prefix, the one that follows the prefix
  // included: the children of "stiffness" are at depth 2, not 1.
  EXPECT_TRUE(parameters_->list({"stiffness"}, 1).names.empty());
  const auto stiffness = parameters_->list({"stiffness"}, 2);
  ASSERT_FALSE(stiffness.names.empty());
  for (const std::string& name : stiffness.names) {
    EXPECT_EQ(name.rfind("stiffness.", 0), 0u) << name;
    EXPECT_EQ(std::count(name.begin(), name.end(), '.'), 1) << name;
  }
  EXPECT_EQ(stiffness.prefixes, (Names{"stiffness"}));
  const auto limits = parameters_->list({"limits"}, 2);
  EXPECT_NE(std::find(limits.names.begin(), limits.names.end(), "limits.joint_torque"),
            limits.names.end());
  for (const std::string& name : limits.names) {
    EXPECT_EQ(std::count(name.begin(), name.end(), '.'), 1) << name;
  }
  // A name equal to a prefix is listed whatever the depth; a prefix is a whole name part.
  EXPECT_EQ(parameters_->list({"mode"}, 1).names, (Names{"mode"}));
  EXPECT_TRUE(parameters_->list({"mode"}, 1).prefixes.empty());
  EXPECT_TRUE(parameters_->list({"stiff"}, 0).names.empty());
  // Several prefixes: the union, in name order.
  const auto two = parameters_->list({"stiffness", "mode"}, 2);
  EXPECT_EQ(two.names.front(), "mode");
  EXPECT_EQ(two.names.size(), stiffness.names.size() + 1);
}

TEST_F(NodeParametersTest, ValuesAndDescriptorsCarryRos2Types) {
  const auto values =
      parameters_->get({"stiffness.translation", "stiffness.frame", "dynamics.gravity_compensation",
                        "realtime_priority", "mode", "start_q", "urdf_path"});
  ASSERT_TRUE(values);
  std::vector<std::uint8_t> types;
  for (const RosValue& v : *values) types.push_back(v.type);
  EXPECT_EQ(types, (std::vector<std::uint8_t>{8, 4, 1, 2, 4, 8, 4}));
  EXPECT_EQ((*values)[0].numbers.size(), 3u);
  EXPECT_EQ((*values)[4].text, "sim");
  EXPECT_EQ((*values)[6].text, "panda.urdf");
  EXPECT_FALSE(parameters_->get({"mode", "no.such.name"}));
  EXPECT_FALSE(parameters_->describe({"no.such.name"}));
  EXPECT_FALSE(parameters_->types({"stiffness"}));  // a group is no parameter

  const auto d = parameters_->describe({"stiffness.translation", "control_rate", "urdf_path"});
  ASSERT_TRUE(d && d->size() == 3u);
  const ci::ParameterInfo& row = ci::parameter_info("stiffness.translation");
  EXPECT_FALSE((*d)[0].read_only);
  EXPECT_NE((*d)[0].description.find(std::string(row.unit)), std::string::npos);
  EXPECT_EQ((*d)[0].floating_point_range, std::make_pair(row.min, row.max));
  EXPECT_TRUE((*d)[1].read_only);
  EXPECT_EQ((*d)[1].floating_point_range, std::make_pair(1.0, 10000.0));
  EXPECT_TRUE((*d)[2].read_only);
  // Every number of the table carries its range (all are finite; an infinite bound would be
  // stated in additional_constraints only) and the range's text.
  for (const ci::ParameterInfo& r : ci::parameter_table()) {
    const std::uint8_t type = cartesian_impedance_ros2::ros_type_of(r);
    if (type != 3 && type != 8) continue;
    const auto one = parameters_->describe({std::string(r.name)});
    ASSERT_TRUE(one && one->size() == 1u);
    EXPECT_EQ((*one)[0].floating_point_range, std::make_pair(r.min, r.max)) << r.name;
    EXPECT_NE((*one)[0].additional_constraints.find(r.range_text()), std::string::npos) << r.name;
  }
}

TEST_F(NodeParametersTest, SetsRefusedBeforeTheLoopChangeNothing) {
  const ci::Parameters before = loop_.latest_parameters();
  RosValue value;
  value.type = cartesian_impedance_ros2::ros_type::kDouble;
  value.number = 900.0;
  // Read-only, named.
  auto result = parameters_->set({{"control_rate", value}}, nullptr);
  EXPECT_FALSE(result.successful);
  EXPECT_NE(result.reason.find("control_rate"), std::string::npos);
  EXPECT_NE(result.reason.find("read-only"), std::string::npos);
  // Not a ROS 2 type.
  RosValue odd = value;
  odd.type = 42;
  result = parameters_->set({{"stiffness.translation", odd}}, nullptr);
  EXPECT_FALSE(result.successful);
  EXPECT_NE(result.reason.find("42"), std::string::npos) << result.reason;
  // The controller does not run yet: refused, whatever the value.
  result = parameters_->set({{"stiffness.translation", value}}, nullptr);
  EXPECT_FALSE(result.successful);
  EXPECT_NE(result.reason.find("not running"), std::string::npos);
  // Once it runs, the decoder's messages: unknown name, value out of range, given twice.
  accepting_ = true;
  result = parameters_->set({{"stiffness.no_such", value}}, nullptr);
  EXPECT_FALSE(result.successful);
  EXPECT_NE(result.reason.find("stiffness.no_such"), std::string::npos) << result.reason;
  value.number = -1.0;
  result = parameters_->set({{"stiffness.translation", value}}, nullptr);
  EXPECT_FALSE(result.successful);
  EXPECT_NE(result.reason.find("parameter 'stiffness.translation' of /arm"), std::string::npos)
      << result.reason;
  value.number = 900.0;
  result = parameters_->set({{"stiffness.translation", value}, {"stiffness.translation", value}},
                            nullptr);
  EXPECT_FALSE(result.successful);
  EXPECT_NE(result.reason.find("twice"), std::string::npos) << result.reason;
  // Nothing reached the loop: a step applies whatever was queued, and the parameters are those
  // it started with.
  const ci::JointVector q =
      (ci::JointVector(7) << 0, -0.785, 0, -2.356, 0, 1.571, 0.785).finished();
  loop_.start(q, ci::JointVector::Zero(7));
  loop_.step(q, ci::JointVector::Zero(7), 0.001);
  EXPECT_EQ(loop_.latest_state().commands_applied, 0u);
  EXPECT_EQ(ci::encode_parameters(loop_.latest_parameters()), ci::encode_parameters(before));
  EXPECT_TRUE(parameters_->set({}, nullptr).successful);  // nothing to set: as rclcpp
}

}  // namespace
}  // namespace parameter_services_test
