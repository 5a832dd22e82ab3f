// The control cycle never throws: bad measurements or a bad dt give a status and a torque that
// ramps to exactly zero within the rate limit, and valid input afterwards is ok again.

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "cartesian_impedance/core/controller.hpp"
#include "cartesian_impedance/core/parameters.hpp"
#include "support/validation_harness.hpp"

namespace ci = cartesian_impedance;
using namespace validation_harness;

namespace {

// ---------------------------------------------------------------------------------------------
// The control cycle never throws; bad input gives a status and a torque ramped to zero

/// Largest |change| of each joint's torque per cycle [Nm] for a cycle of `dt` seconds.
ci::JointVector rate_steps(const ci::CartesianImpedanceController& controller, double dt) {
  return ci::per_joint(controller.parameters().limits.joint_torque_rate, controller.num_joints()) *
         dt;
}

/// Runs bad cycles on a running rig and checks: each returns `expected`, the torque is finite,
/// moves toward zero on every joint (never past it) by at most the rate limit times `step_dt`,
/// and becomes exactly zero when the rate limit allows; then one valid cycle returns ok.
void expect_ramp_to_zero(const std::string& label, const std::function<ci::Status(Rig&)>& bad_cycle,
                         ci::Status expected, double step_dt) {
  SCOPED_TRACE(label);
  Rig rig = make_running_rig();
  ci::JointVector previous = rig.controller.torque();
  ASSERT_GT(previous.cwiseAbs().maxCoeff(), 3.0) << "the rig should hold a sizeable torque";
  const ci::JointVector max_step = rate_steps(rig.controller, step_dt);
  // With one scale factor for all joints the slowest joint sets the number of cycles.
  const int cycles_to_zero =
      static_cast<int>(std::ceil(previous.cwiseAbs().cwiseQuotient(max_step).maxCoeff()));
  ASSERT_GT(cycles_to_zero, 2);
  int zero_at = -1;
  for (int cycle = 0; cycle < cycles_to_zero + 5; ++cycle) {
    // update() is noexcept: a throw inside it would terminate the test program.
    const ci::Status status = bad_cycle(rig);
    ASSERT_STREQ(ci::to_string(status), ci::to_string(expected)) << "cycle " << cycle;
    ASSERT_STREQ(ci::to_string(rig.controller.state().status), ci::to_string(expected));
    const ci::JointVector& tau = rig.controller.torque();
    ASSERT_EQ(tau.size(), kJoints);
    ASSERT_TRUE(tau.allFinite()) << "cycle " << cycle << ": " << tau.transpose();
    for (Eigen::Index i = 0; i < kJoints; ++i) {
      EXPECT_LE(std::abs(tau[i] - previous[i]), max_step[i] * (1 + 1e-12))
          << "cycle " << cycle << ", joint " << i;
      EXPECT_LE(std::abs(tau[i]), std::abs(previous[i])) << "cycle " << cycle << ", joint " << i;
      EXPECT_GE(tau[i] * previous[i], 0.0) << "sign flipped: cycle " << cycle << ", joint " << i;
    }
    if (zero_at < 0 && (tau.array() == 0.0).all()) zero_at = cycle;
    previous = tau;
  }
  EXPECT_TRUE((previous.array() == 0.0).all()) << previous.transpose();
  EXPECT_GE(zero_at, cycles_to_zero - 2);
  EXPECT_LE(zero_at, cycles_to_zero);
  EXPECT_TRUE(same_bits(rig.controller.state().tau_cartesian, ci::JointVector::Zero(kJoints)));

  // Valid input again: back to ok, and the torque rises from zero within the rate limit.
  ASSERT_EQ(rig.controller.update(rig.robot, kDt), ci::Status::ok);
  const ci::JointVector& tau = rig.controller.torque();
  ASSERT_TRUE(tau.allFinite());
  EXPECT_GT(tau.cwiseAbs().maxCoeff(), 0.0);
  const ci::JointVector valid_step = rate_steps(rig.controller, kDt);
  for (Eigen::Index i = 0; i < kJoints; ++i) {
    EXPECT_LE(std::abs(tau[i]), valid_step[i] * (1 + 1e-12)) << "joint " << i;
  }
}

TEST(CycleSafety, UpdateBeforeStartReturnsNotStartedWithZeroTorque) {
  ci::CartesianImpedanceController controller(kJoints, rig_parameters());
  ci::RobotState bad = rig_robot();
  bad.q[0] = kNaN;
  for (const ci::RobotState& robot : {rig_robot(), bad}) {
    for (double dt : {kDt, 0.0, kNaN}) {
      EXPECT_EQ(controller.update(robot, dt), ci::Status::not_started);
      EXPECT_EQ(controller.state().status, ci::Status::not_started);
      EXPECT_TRUE(same_bits(controller.torque(), ci::JointVector::Zero(kJoints)));
    }
  }
}

TEST(CycleSafety, NonFiniteOrWronglySizedRobotStateRampsTorqueToZero) {
  struct Case {
    std::string label;
    std::function<void(ci::RobotState&)> spoil;
  };
  std::vector<Case> cases;
  for (const Poison& poison : kPoisons) {
    const double value = poison.value;
    const std::string text = std::string(" = ") + poison.text;
    cases.push_back({"q[3]" + text, [value](auto& r) { r.q[3] = value; }});
    cases.push_back({"dq[6]" + text, [value](auto& r) { r.dq[6] = value; }});
    cases.push_back({"jacobian(4, 2)" + text, [value](auto& r) { r.jacobian(4, 2) = value; }});
    cases.push_back({"position.z" + text, [value](auto& r) { r.pose.position.z() = value; }});
    cases.push_back({"orientation.w" + text, [value](auto& r) { r.pose.orientation.w() = value; }});
  }
  cases.push_back({"orientation norm 0", [](auto& r) { r.pose.orientation.coeffs().setZero(); }});
  cases.push_back({"orientation norm 2", [](auto& r) { r.pose.orientation.coeffs() *= 2; }});
  cases.push_back({"q of 6", [](auto& r) { r.q = ci::JointVector::Zero(kJoints - 1); }});
  cases.push_back({"dq of 8", [](auto& r) { r.dq = ci::JointVector::Zero(kJoints + 1); }});
  cases.push_back({"jacobian 6 x 6", [](auto& r) { r.jacobian = ci::Jacobian::Ones(6, 6); }});
  cases.push_back({"6-joint state", [](auto& r) { r = ci::make_robot_state(kJoints - 1); }});
  for (const Case& c : cases) {
    // A longer dt than the rig's shows the ramp uses the dt of the cycle.
    constexpr double kBadCycleDt = 2e-3;
    expect_ramp_to_zero(
        c.label,
        [&](Rig& rig) {
          ci::RobotState robot = rig.robot;
          c.spoil(robot);
          return rig.controller.update(robot, kBadCycleDt);
        },
        ci::Status::invalid_robot_state, kBadCycleDt);
  }
}

TEST(CycleSafety, InvalidDtRampsTorqueToZeroAtTheLastValidRate) {
  // There is no usable dt in these cycles; the ramp runs at the last valid one (the rig's kDt).
  for (double dt : {0.0, -kDt, -1.0, kNaN, kInf, -kInf}) {
    expect_ramp_to_zero(
        "dt = " + ci::format_number(dt),
        [dt](Rig& rig) { return rig.controller.update(rig.robot, dt); }, ci::Status::invalid_dt,
        kDt);
  }
}

// A term of the law that cannot be evaluated fails the cycle closed and names the term, not only
// "tau is not finite": the damping (an indefinite M(q) cannot shape it), the dynamically
// consistent projection (nor project), a spring-damper torque that overflows.
TEST(CycleSafety, ALawTermThatCannotBeEvaluatedNamesItself) {
  {
    Rig rig = make_running_rig();
    ci::RobotState robot = rig.robot;
    robot.mass = -robot.mass;
    EXPECT_EQ(rig.controller.update(robot, kDt), ci::Status::numerical_error);
    EXPECT_STREQ(rig.controller.state().fault.input, "damping");
    EXPECT_NE(ci::to_string(rig.controller.state().fault).find("positive definite"),
              std::string::npos);
    EXPECT_TRUE(rig.controller.torque().allFinite());
  }
  {
    Rig rig = make_running_rig();
    ci::Parameters p = rig.controller.parameters();
    p.dynamics.inertia_shaped_damping = false;
    p.dynamics.dynamically_consistent_nullspace = true;
    rig.controller.set_parameters(p);
    ASSERT_EQ(rig.controller.update(rig.robot, kDt), ci::Status::ok);
    ci::RobotState robot = rig.robot;
    robot.mass = -robot.mass;
    EXPECT_EQ(rig.controller.update(robot, kDt), ci::Status::numerical_error);
    EXPECT_STREQ(rig.controller.state().fault.input, "nullspace");
  }
  {
    Rig rig = make_running_rig();
    ci::Parameters p = rig.controller.parameters();
    p.dynamics.inertia_shaped_damping = false;
    rig.controller.set_parameters(p);
    ci::RobotState robot = rig.robot;
    robot.jacobian *= 1e300;  // finite, but J^T D J dq is not
    EXPECT_EQ(rig.controller.update(robot, kDt), ci::Status::numerical_error);
    EXPECT_STREQ(rig.controller.state().fault.input, "tau_cartesian");
    EXPECT_TRUE(rig.controller.torque().allFinite());
  }
}

TEST(CycleSafety, OneBadCycleThenValidInputIsOkAgain) {
  Rig rig = make_running_rig();
  const ci::JointVector before = rig.controller.torque();
  ci::RobotState bad = rig.robot;
  bad.dq[1] = kNaN;
  EXPECT_EQ(rig.controller.update(bad, kDt), ci::Status::invalid_robot_state);
  EXPECT_EQ(rig.controller.update(rig.robot, 0.0), ci::Status::invalid_dt);
  EXPECT_EQ(rig.controller.update(rig.robot, kDt), ci::Status::ok);
  EXPECT_EQ(rig.controller.state().status, ci::Status::ok);
  EXPECT_TRUE(rig.controller.torque().allFinite());
  // Two cycles of ramp-down and one of ramp-up: within three rate steps of where it was.
  const ci::JointVector step = rate_steps(rig.controller, kDt);
  for (Eigen::Index i = 0; i < kJoints; ++i) {
    EXPECT_LE(std::abs(rig.controller.torque()[i] - before[i]), 3 * step[i] * (1 + 1e-12));
  }
}

}  // namespace
