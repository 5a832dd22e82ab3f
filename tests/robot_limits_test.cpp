// Limits from the URDF (model/robot_limits.hpp): the efforts are the torque bound a configuration
// may lower but not raise, and the derived defaults keep their promise: the stiffest spring they
// allow, at the largest pose error, needs at most kEffortShare of each joint's effort.

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/core/parameter_tree.hpp"
#include "cartesian_impedance/model/rate_check.hpp"
#include "cartesian_impedance/model/robot_limits.hpp"
#include "support/robots.hpp"

namespace ci = cartesian_impedance;

namespace {

ci::RobotModel ur5e() {
  return ci::RobotModel::from_urdf_file(
      std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/ur5e/ur5e.urdf", "base_link", "tool0");
}

TEST(RobotLimits, TheUrdfsEffortsAndVelocitiesBecomeTheDefaults) {
  const ci::RobotModel model = robots::panda();
  const ci::Parameters p = ci::default_parameters(model);
  const ci::JointLimits& urdf = model.limits();
  ASSERT_EQ(p.limits.joint_torque.size(), 7);
  for (int i = 0; i < 7; ++i) {
    EXPECT_EQ(p.limits.joint_torque[i], urdf.effort[i]) << i;  // 87 Nm, and 12 at the wrist
    EXPECT_DOUBLE_EQ(p.limits.joint_torque_rate[i], urdf.effort[i] / ci::kTorqueRiseTime) << i;
    EXPECT_DOUBLE_EQ(p.plausibility.joint_velocity[i], ci::kPlausibleSpeedFactor * urdf.velocity[i])
        << i;
  }
  EXPECT_NO_THROW(ci::validate(p, 7));
}

// The promise of the derived stiffness limits, checked where the arm is, not where the
// derivation looked: at 400 other configurations, the spring at the largest translation (or
// rotation) error needs at most kEffortShare of every joint's effort along any axis.
TEST(RobotLimits, TheDerivedStiffnessAtTheLargestErrorFitsTheEffortsEverywhere) {
  for (const ci::RobotModel& model : {robots::panda(), robots::iiwa(), ur5e()}) {
    SCOPED_TRACE(model.robot_name());
    const ci::Parameters p = ci::default_parameters(model);
    const ci::ArmCapabilities arm = ci::arm_capabilities(model);
    const double force = p.limits.stiffness.translation.max * p.limits.pose_error.translation;
    const double torque = p.limits.stiffness.rotation.max * p.limits.pose_error.rotation;
    EXPECT_GT(force, 0.0);
    EXPECT_GT(torque, 0.0);
    ci::ModelWorkspace workspace(model);
    ci::Kinematics kinematics = workspace.make_kinematics();
    std::mt19937 rng(3);
    const int n = model.num_joints();
    double worst = 0.0;  // largest share of an effort the spring needs
    for (int sample = 0; sample < 400; ++sample) {
      ci::JointVector q(n);
      for (int i = 0; i < n; ++i) {
        q[i] = std::uniform_real_distribution<double>(model.limits().position_lower[i],
                                                      model.limits().position_upper[i])(rng);
      }
      ASSERT_TRUE(workspace.compute(q, ci::JointVector::Zero(n), kinematics, ci::ModelTerms::none));
      for (int i = 0; i < n; ++i) {
        const double translational = kinematics.jacobian.col(i).head<3>().norm() * force;
        const double rotational = kinematics.jacobian.col(i).tail<3>().norm() * torque;
        worst = std::max(worst, std::max(translational, rotational) / arm.effort[i]);
      }
    }
    // The levers were sampled at 256 other configurations: a lever they missed may be a few
    // percent longer.
    EXPECT_LE(worst, ci::kEffortShare * 1.05);
    // And the derivation is not needlessly timid: some joint somewhere needs most of its share
    // (the rounding to two digits takes up to 10 %, the sampled levers a few percent).
    EXPECT_GE(worst, ci::kEffortShare * 0.6);
  }
}

TEST(RobotLimits, ATorqueLimitAboveTheUrdfsIsRefusedNamingBoth) {
  const ci::RobotModel model = robots::panda();
  ci::Parameters p;
  p.limits.joint_torque = ci::JointVector::Constant(1, 50.0);  // above the wrists' 12 Nm
  try {
    ci::with_robot_limits(p, model);
    FAIL() << "50 Nm on a 12 Nm wrist was accepted";
  } catch (const ci::Error& error) {
    EXPECT_EQ(std::string(error.what()),
              "limits.joint_torque[4] = 50 Nm is above the effort limit of joint 'panda_joint5' in "
              "the URDF (12 Nm): a configuration may lower the URDF's limits, not raise them");
    EXPECT_EQ(error.fault().index, 4);
    EXPECT_EQ(error.fault().bound, 12.0);
  }
  p.limits.joint_torque = ci::JointVector::Constant(1, 10.0);  // lower: kept as given
  EXPECT_EQ(ci::with_robot_limits(p, model).limits.joint_torque, p.limits.joint_torque);
  p.limits.joint_torque = ci::JointVector();  // left to the URDF
  EXPECT_EQ(ci::with_robot_limits(p, model).limits.joint_torque, model.limits().effort);
}

TEST(RobotLimits, ALimitLeftToTheUrdfIsWrittenAndReadAsAnEmptyList) {
  ci::Parameters p;
  EXPECT_EQ(p.limits.joint_torque.size(), 0);
  const ci::Parameters back = ci::parameters_from_yaml(ci::parameters_to_yaml(p));
  EXPECT_EQ(back.limits.joint_torque.size(), 0);
  EXPECT_EQ(ci::parameters_from_yaml("limits: {joint_torque: []}").limits.joint_torque.size(), 0);
  // Only where the robot can fill it in: another per-joint list may not be empty.
  EXPECT_THROW(ci::parameters_from_yaml("limits: {joint_torque_rate: []}"), ci::Error);
}

// A configuration file is read on top of the robot's defaults: what it leaves out is derived,
// what it gives is kept.
TEST(RobotLimits, AFileReadOnTopOfTheRobotsDefaultsKeepsWhatItLeavesOut) {
  const ci::RobotModel model = ur5e();
  const ci::Parameters defaults = ci::default_parameters(model);
  const ci::Parameters p =
      ci::parameters_from_yaml("stiffness: {translation: [200, 200, 200]}", "<test>", defaults);
  EXPECT_EQ(p.stiffness.translation, Eigen::Vector3d::Constant(200.0));
  EXPECT_EQ(p.limits.joint_torque, defaults.limits.joint_torque);
  EXPECT_EQ(p.limits.stiffness.translation.max, defaults.limits.stiffness.translation.max);
  EXPECT_LT(defaults.limits.stiffness.translation.max,
            ci::Parameters{}.limits.stiffness.translation.max);
}

// The derived stiffness and rate limits are ones the torque-rate limit follows (rate_check.hpp)
// where the shipped robots start.
TEST(RobotLimits, TheDerivedDefaultsPassTheRateCheck) {
  for (const auto& [model, q] : {std::pair{robots::panda(), robots::panda_ready()},
                                 std::pair{robots::iiwa(), robots::iiwa_ready()}}) {
    const ci::RateCheck check = ci::check_rate_limit(model, q, ci::default_parameters(model));
    EXPECT_TRUE(check.warnings.empty()) << model.robot_name() << ": " << check.warnings.front();
  }
}

}  // namespace
