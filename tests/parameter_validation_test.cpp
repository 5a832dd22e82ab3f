// Bad parameters: every row of the parameter table rejects non-finite values and values outside its
// range in set_parameters(), validate() and the constructor, with the field, the value and the
// range named; ranges with min > max and per-joint fields of the wrong length are rejected, values
// on the boundary accepted.

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "cartesian_impedance/core/controller.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/parameters.hpp"
#include "support/validation_harness.hpp"

namespace ci = cartesian_impedance;
using namespace validation_harness;

namespace {

// ---------------------------------------------------------------------------------------------
// set_parameters(): every row of the table

TEST(ParameterValidation, EveryTableRowRejectsNanAndInfinityInEveryElement) {
  int elements_checked = 0;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    ci::Parameters template_parameters = other_valid_parameters();
    for_each_element(info, template_parameters, [&](const std::string& element, double&) {
      ++elements_checked;
      for (const Poison& poison : kPoisons) {
        ci::Parameters bad = other_valid_parameters();
        // Poison the same element in the copy (the table hands out the field of `bad`).
        for_each_element(info, bad, [&](const std::string& name, double& value) {
          if (name == element) value = poison.value;
        });
        const std::vector<std::string> expected{assigned(element, poison.text), info.range_text()};
        expect_rejected(
            element + " = " + poison.text, [&](auto& c) { c.set_parameters(bad); }, expected);
        EXPECT_TRUE(rejected_with([&] { ci::validate(bad, kJoints); }, expected)) << element;
        EXPECT_TRUE(rejected_with([&] { ci::validate(bad); }, expected)) << element;
        EXPECT_TRUE(rejected_with(
            [&] { ci::CartesianImpedanceController controller(kJoints, bad); }, expected))
            << element;
      }
    });
  }
  // 9 three-axis rows, 6 per-joint rows of 7, 49 single numbers.
  EXPECT_EQ(elements_checked, 9 * 3 + 6 * 7 + 49);
}

TEST(ParameterValidation, EveryTableRowRejectsValuesOutsideItsRange) {
  int elements_checked = 0;
  for (const ci::ParameterInfo& info : ci::parameter_table()) {
    std::vector<double> outside;
    if (std::isfinite(info.min)) outside.push_back(info.min_exclusive ? info.min : info.min - 1);
    if (std::isfinite(info.max)) outside.push_back(info.max + 0.5);
    ci::Parameters names = other_valid_parameters();
    for_each_element(info, names, [&](const std::string& element, double&) {
      for (double value : outside) {
        ++elements_checked;
        ci::Parameters bad = other_valid_parameters();
        for_each_element(info, bad, [&](const std::string& name, double& target) {
          if (name == element) target = value;
        });
        expect_rejected(
            element + " = " + ci::format_number(value), [&](auto& c) { c.set_parameters(bad); },
            {assigned(element, ci::format_number(value)), "is outside " + info.range_text()});
      }
    });
  }
  EXPECT_GT(elements_checked, 40);
}

TEST(ParameterValidation, RejectsOutOfRangeValuesNamingFieldValueAndRange) {
  struct Case {
    const char* label;
    std::function<void(ci::Parameters&)> change;
    std::vector<std::string> expected;
  };
  const std::vector<Case> cases{
      {"negative stiffness",
       [](auto& p) { p.stiffness.translation.y() = -5; },
       {"stiffness.translation.y = -5 N/m is outside [0, 100000]"}},
      {"negative damping ratio",
       [](auto& p) { p.damping_ratio.rotation.x() = -0.1; },
       {"damping_ratio.rotation.x = -0.1 is outside [0, 10]"}},
      {"negative nullspace stiffness",
       [](auto& p) { p.nullspace.stiffness[3] = -2; },
       {"nullspace.stiffness[3] = -2 Nm/rad is outside [0, 10000]"}},
      {"negative nullspace damping",
       [](auto& p) { p.nullspace.damping_ratio = -1; },
       {"nullspace.damping_ratio = -1 is outside [0, 10]"}},
      {"negative lambda",
       [](auto& p) { p.nullspace.pseudo_inverse_damping = -0.01; },
       {"nullspace.pseudo_inverse_damping = -0.01 is outside [0, 1]"}},
      {"filter fraction 0",
       [](auto& p) { p.filter.pose.fraction = 0; },
       {"filter.pose.fraction = 0 is outside [0.5, 1]"}},
      {"filter fraction 1.5",
       [](auto& p) { p.filter.wrench.fraction = 1.5; },
       {"filter.wrench.fraction = 1.5 is outside [0.5, 1]"}},
      {"negative filter time",
       [](auto& p) { p.filter.stiffness.time = -0.1; },
       {"filter.stiffness.time = -0.1 s is outside [0, 30]"}},
      {"pose error limit 0",
       [](auto& p) { p.limits.pose_error.translation = 0; },
       {"limits.pose_error.translation = 0 m is outside [0.01, 10]"}},
      {"negative rotation error limit",
       [](auto& p) { p.limits.pose_error.rotation = -1; },
       {"limits.pose_error.rotation = -1 rad is outside [0.01, 3.141592654]"}},
      {"zero torque limit",
       [](auto& p) { p.limits.joint_torque[6] = 0; },
       {"limits.joint_torque[6] = 0 Nm is outside [0.1, 10000]"}},
      {"zero torque rate",
       [](auto& p) { p.limits.joint_torque_rate = joints({0}); },
       {"limits.joint_torque_rate[0] = 0 Nm/s is outside [1, 1000000]"}},
      {"negative force limit",
       [](auto& p) { p.limits.wrench.force = -1; },
       {"limits.wrench.force = -1 N is outside [0, 10000]"}},
      {"negative stiffness limit",
       [](auto& p) { p.limits.stiffness.rotation.max = -1; },
       {"limits.stiffness.rotation.max = -1 Nm/rad is outside [0, 10000]"}},
  };
  for (const Case& c : cases) {
    ci::Parameters bad = other_valid_parameters();
    c.change(bad);
    expect_rejected(
        c.label, [&](auto& controller) { controller.set_parameters(bad); }, c.expected);
  }
}

TEST(ParameterValidation, RejectsLimitsWithMinGreaterThanMax) {
  struct Case {
    const char* name;
    std::function<ci::Range&(ci::Parameters&)> range;
    const char* unit;
  };
  const std::vector<Case> cases{
      {"limits.stiffness.translation",
       [](ci::Parameters& p) -> ci::Range& { return p.limits.stiffness.translation; }, " N/m"},
      {"limits.stiffness.rotation",
       [](ci::Parameters& p) -> ci::Range& { return p.limits.stiffness.rotation; }, " Nm/rad"},
      {"limits.damping_ratio",
       [](ci::Parameters& p) -> ci::Range& { return p.limits.damping_ratio; }, ""},
      {"limits.nullspace_stiffness",
       [](ci::Parameters& p) -> ci::Range& { return p.limits.nullspace_stiffness; }, " Nm/rad"},
  };
  for (const Case& c : cases) {
    ci::Parameters bad = other_valid_parameters();
    c.range(bad) = {6, 5};
    const std::string name(c.name);
    expect_rejected(name, [&](auto& controller) { controller.set_parameters(bad); },
                    {assigned(name + ".min", "6" + std::string(c.unit)),
                     assigned(name + ".max", "5" + std::string(c.unit)), "greater than"});
    ci::Parameters equal = other_valid_parameters();
    c.range(equal) = {5, 5};
    Rig rig = make_running_rig();
    EXPECT_NO_THROW(rig.controller.set_parameters(equal)) << name;
  }
}

TEST(ParameterValidation, RejectsPerJointFieldsWithWrongCount) {
  const std::vector<std::pair<const char*, ci::JointVector ci::LimitParameters::*>> limits{
      {"limits.joint_torque", &ci::LimitParameters::joint_torque},
      {"limits.joint_torque_rate", &ci::LimitParameters::joint_torque_rate}};
  for (int size : {2, kJoints - 1, kJoints + 1}) {
    const std::string values = std::to_string(size) + " values";
    ci::Parameters bad = other_valid_parameters();
    bad.nullspace.stiffness = ci::JointVector::Constant(size, 10);
    expect_rejected("nullspace.stiffness, " + values, [&](auto& c) { c.set_parameters(bad); },
                    {"nullspace.stiffness has " + values, "expected 1 (all joints) or 7"});
    for (const auto& [name, member] : limits) {
      ci::Parameters bad_limit = other_valid_parameters();
      bad_limit.limits.*member = ci::JointVector::Constant(size, 50);
      expect_rejected(std::string(name) + ", " + values,
                      [&](auto& c) { c.set_parameters(bad_limit); },
                      {std::string(name) + " has " + values, "expected 1 (all joints) or 7"});
    }
  }
  // An empty list means "from the robot" only where the robot can fill it in.
  ci::Parameters empty = other_valid_parameters();
  empty.limits.joint_torque_rate = ci::JointVector(0);
  expect_rejected("limits.joint_torque_rate, 0 values", [&](auto& c) { c.set_parameters(empty); },
                  {"limits.joint_torque_rate has 0 values"});
}

TEST(ParameterValidation, AcceptsValuesOnTheBoundaryOfTheirRange) {
  ci::Parameters p = other_valid_parameters();
  p.stiffness.translation.setZero();
  p.damping_ratio.rotation.setZero();
  p.nullspace.stiffness = joints({0});
  p.nullspace.pseudo_inverse_damping = 0;
  p.filter.pose = {0.0, 1.0};
  p.filter.wrench.fraction = 1.0;
  p.limits.stiffness.translation = {0, 0};
  p.limits.wrench = {0, 0};
  Rig rig = make_running_rig();
  ASSERT_NO_THROW(rig.controller.set_parameters(p));
  EXPECT_EQ(first_difference(rig.controller.parameters(), p), "");
  EXPECT_EQ(rig.controller.update(rig.robot, kDt), ci::Status::ok);
  EXPECT_TRUE(rig.controller.torque().allFinite());
}

}  // namespace
