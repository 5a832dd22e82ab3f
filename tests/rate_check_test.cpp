// The torque-rate limit against the stiffness limits (model/rate_check.hpp): the arithmetic it
// reports holds together, the shipped Panda configuration passes, and the stiffness that drove
// the Panda into a limit cycle on MuJoCo (30,000 N/m at 1000 Nm/s, behaviour_tests
// HaltAfterImplausibleMotion) is named with its numbers.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/model/rate_check.hpp"
#include "support/robots.hpp"

namespace ci = cartesian_impedance;

namespace {

TEST(RateCheck, TheShippedPandaConfigurationIsFollowed) {
  const ci::RobotModel model = robots::panda();
  const ci::Parameters p =
      ci::load_parameters(std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/config/panda.yaml");
  const ci::RateCheck check = ci::check_rate_limit(model, robots::panda_ready(), p);
  EXPECT_TRUE(check.warnings.empty()) << check.warnings.front();
  for (int axis = 0; axis < 6; ++axis) {
    EXPECT_GE(check.followed[axis], axis < 3 ? ci::kFollowedTranslation : ci::kFollowedRotation)
        << axis;
  }
}

TEST(RateCheck, AStiffnessTheRateCannotFollowIsNamedWithItsArithmetic) {
  const ci::RobotModel model = robots::panda();
  ci::Parameters p =
      ci::load_parameters(std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/config/panda.yaml");
  p.limits.stiffness.translation.max = 30000.0;
  const ci::RateCheck check = ci::check_rate_limit(model, robots::panda_ready(), p);
  ASSERT_FALSE(check.warnings.empty());
  EXPECT_NE(check.warnings.front().find("limits.stiffness.translation.max = 30000 N/m is more than "
                                        "limits.joint_torque_rate can follow"),
            std::string::npos)
      << check.warnings.front();
  for (int axis = 0; axis < 3; ++axis) {
    // The numbers are those of the formula: w = sqrt(k / m), followed = R / (k l w).
    EXPECT_NEAR(check.frequency[axis], std::sqrt(30000.0 / check.mass[axis]), 1e-9);
    ASSERT_GE(check.joint[axis], 0);
    EXPECT_NEAR(check.followed[axis],
                1000.0 / (30000.0 * check.lever[axis] * check.frequency[axis]), 1e-15);
    // The Panda's end effector weighs a few kilograms along each axis, armature included.
    EXPECT_GT(check.mass[axis], 1.0);
    EXPECT_LT(check.mass[axis], 20.0);
  }
  // Raising the rate limit tenfold follows ten times the oscillation.
  ci::Parameters faster = p;
  faster.limits.joint_torque_rate = ci::JointVector::Constant(1, 10000.0);
  const ci::RateCheck fast = ci::check_rate_limit(model, robots::panda_ready(), faster);
  for (int axis = 0; axis < 3; ++axis) {
    EXPECT_NEAR(fast.followed[axis], 10.0 * check.followed[axis], 1e-12 * fast.followed[axis]);
  }
  EXPECT_THROW(ci::check_rate_limit(model, ci::JointVector::Zero(6), p), ci::Error);
}

}  // namespace
