// The oscillation watch (CartesianImpedanceController::kOscillationSwings) on the 6-joint
// "Cartesian" robot (J = I, so dq is the end effector's twist): a sustained swing of the error
// rate halves the stiffness after its sixth swing, a decaying ring, a slow motion and a moving
// reference never count, the damping follows the stiffness, and past the floor the controller
// fails closed and holds. The closed loop behind a delay, on the realistic Panda:
// delay_behaviour_test.cpp.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "cartesian_impedance/core/controller.hpp"
#include "support/bare_law.hpp"

namespace ci = cartesian_impedance;
using bare_law::bare_parameters;
using bare_law::cartesian_robot;

namespace {

constexpr double kDt = 0.001;

// The law as written, with its filters off: a halving shows in the next cycle's stiffness.
ci::Parameters watched_parameters() {
  ci::Parameters p = bare_parameters();
  p.minimum_damping = {30.0, 1.0, 0.5};
  return p;
}

// The end effector's twist along `axis` swinging as amplitude(t) sin(2 pi f t), the pose left
// where it is (the watch reads the rate, not the error). Runs `seconds` and returns the time of
// the first halving (-1: none).
struct Swing {
  int axis = 0;
  double amplitude = 0.2;   // [m/s or rad/s]
  double frequency = 10.0;  // [Hz]
  double decay = 1.0;       // the ratio of one half period's peak to the one before
};

double first_halving(ci::CartesianImpedanceController& controller, ci::RobotState& robot,
                     const Swing& swing, double seconds) {
  const double half_period = 0.5 / swing.frequency;
  for (int k = 1; k * kDt <= seconds; ++k) {
    const double t = k * kDt;
    const double envelope = swing.amplitude * std::pow(swing.decay, t / half_period);
    robot.dq.setZero();
    robot.dq[swing.axis] = envelope * std::sin(2.0 * M_PI * swing.frequency * t);
    controller.update(robot, kDt);
    if (controller.state().safety.oscillations > 0) return t;
  }
  return -1.0;
}

}  // namespace

// 10 Hz at 0.2 m/s: the twist crosses +0.05 m/s first at t = asin(0.25) / (2 pi f) = 4.0 ms, and
// every swing after it is one half period (50 ms) later; the sixth ends the first 6 x 50 ms after
// the first crossing. Each axis alone, translation and rotation.
TEST(OscillationWatch, ASustainedSwingHalvesTheStiffnessAtItsSixthSwing) {
  for (int axis = 0; axis < 6; ++axis) {
    ci::CartesianImpedanceController controller(6, watched_parameters());
    ci::RobotState robot = cartesian_robot();
    controller.start(robot);
    const ci::Vector6d stiffness = controller.state().commanded.stiffness.diagonal();
    Swing swing;
    swing.axis = axis;
    swing.amplitude = axis < 3 ? 0.2 : 0.4;  // 4 x the threshold of its kind
    const double crossed = std::asin(0.25) / (2.0 * M_PI * swing.frequency);
    const double found = first_halving(controller, robot, swing, 2.0);
    // The sixth reversal is found in the cycle the twist crosses the other threshold: within
    // one cycle of 6 half periods after the first crossing, plus the crossing's own lag (the
    // other threshold is met 2 x 4.0 ms after the zero, within the half period).
    EXPECT_NEAR(found, crossed + 6 * 0.05, 2 * crossed + kDt) << "axis " << axis;
    EXPECT_EQ(controller.state().safety.oscillation_scale, 0.5);
    EXPECT_EQ(controller.state().status, ci::Status::ok);
    // The filters are off: the next cycle's law has half the stiffness, the commands unchanged.
    robot.dq.setZero();
    controller.update(robot, kDt);
    EXPECT_EQ(controller.state().filtered.stiffness.diagonal(), 0.5 * stiffness);
    EXPECT_EQ(controller.state().commanded.stiffness.diagonal(), stiffness);
    // The damping (unit-mass, from the ratios) follows the stiffness: by its square root.
    const ci::Vector6d damping = controller.state().damping.diagonal();
    EXPECT_NEAR(damping[axis], 2.0 * std::sqrt(0.5 * stiffness[axis]), 1e-9);
  }
}

// The same swing decaying: a ring whose peaks fall to 0.75 of the one before (a damping ratio
// of 0.09) counts one swing at a time, however many it makes past the threshold (18 from 5 m/s);
// at 0.85 (0.05) it is a sustained oscillation. A swing slower than 1 Hz never counts, nor does
// one below the threshold.
TEST(OscillationWatch, ADecayingRingASlowSwingAndASmallOneNeverCount) {
  const auto found = [](const Swing& swing) {
    ci::CartesianImpedanceController controller(6, watched_parameters());
    ci::RobotState robot = cartesian_robot();
    controller.start(robot);
    return first_halving(controller, robot, swing, 5.0);
  };
  Swing ring;
  ring.amplitude = 5.0;
  ring.decay = 0.75;
  EXPECT_LT(found(ring), 0.0) << "a decaying ring";
  ring.decay = 0.85;
  EXPECT_GT(found(ring), 0.0) << "a sustained one, at 0.85";
  Swing slow;
  slow.frequency = 0.9;  // half period 0.56 s > kOscillationHalfPeriod
  slow.amplitude = 1.0;
  EXPECT_LT(found(slow), 0.0) << "a swing at 0.9 Hz";
  slow.frequency = 1.1;
  EXPECT_GT(found(slow), 0.0) << "at 1.1 Hz";
  Swing small;
  small.amplitude = 0.049;
  EXPECT_LT(found(small), 0.0) << "below 0.05 m/s";
  small.axis = 4;
  small.amplitude = 0.099;
  EXPECT_LT(found(small), 0.0) << "below 0.1 rad/s";
}

// An end effector that follows a reference swinging at 5 Hz, 0.5 m/s and 1.5 rad/s: set as a
// pose every cycle (the filter moves it), or tracked with its twist as feed-forward. The error
// rate is the swing of the reference's numerical derivative about its own (a omega^2 dt / 2 =
// 8 mm/s and 0.024 rad/s here), far below the thresholds: no oscillation.
TEST(OscillationWatch, AnEndEffectorFollowingASwingingReferenceIsNotOscillating) {
  for (const bool tracked : {false, true}) {
    ci::CartesianImpedanceController controller(6, watched_parameters());
    ci::RobotState robot = cartesian_robot();
    controller.start(robot);
    const ci::Pose start = robot.pose;
    const double omega = 2.0 * M_PI * 5.0, a = 0.5 / omega, b = 1.5 / omega;
    for (int k = 1; k <= 3000; ++k) {
      const double t = k * kDt;
      ci::Vector6d twist = ci::Vector6d::Zero();
      twist[0] = a * omega * std::cos(omega * t);
      twist[5] = b * omega * std::cos(omega * t);
      robot.pose.position = start.position + Eigen::Vector3d(a * std::sin(omega * t), 0, 0);
      robot.pose.orientation = Eigen::AngleAxisd(b * std::sin(omega * t), Eigen::Vector3d::UnitZ());
      robot.dq = twist;
      if (tracked) {
        controller.track(robot.pose, twist, robot.q, ci::JointVector::Zero(6));
      } else {
        controller.set_reference_pose(robot.pose);
      }
      ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
    }
    EXPECT_EQ(controller.state().safety.oscillations, 0) << (tracked ? "tracked" : "set");
    // The same swing with the reference left behind is an oscillation.
    controller.stop_tracking();
    robot.pose = start;
    controller.set_reference_pose(start);
    Swing swing;
    swing.frequency = 5.0;
    swing.amplitude = 0.5;
    EXPECT_GT(first_halving(controller, robot, swing, 2.0), 0.0);
  }
}

// schedule(): the caller's damping follows the halved stiffness by its square root, as a damping
// from ratios does; the nullspace's too.
TEST(OscillationWatch, AScheduledDampingFollowsTheStiffness) {
  ci::CartesianImpedanceController controller(6, watched_parameters());
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  ci::ScheduledImpedance impedance;
  impedance.reference = robot.pose;
  impedance.stiffness = ci::Vector6d::Constant(400.0).asDiagonal();
  impedance.damping = ci::Vector6d::Constant(90.0).asDiagonal();
  impedance.nullspace_q = robot.q;
  impedance.nullspace_stiffness = ci::JointVector::Constant(6, 8.0);
  impedance.nullspace_damping = ci::JointVector::Constant(6, 4.0);
  impedance.wrench.setZero();
  controller.schedule(impedance);
  ASSERT_GT(first_halving(controller, robot, Swing{}, 2.0), 0.0);
  controller.schedule(impedance);  // a policy schedules every cycle
  robot.dq.setZero();
  controller.update(robot, kDt);
  EXPECT_EQ(controller.state().filtered.stiffness, 0.5 * impedance.stiffness);
  EXPECT_EQ(controller.state().filtered.nullspace_stiffness, 0.5 * impedance.nullspace_stiffness);
  EXPECT_NEAR(controller.state().damping(0, 0), 90.0 * std::sqrt(0.5), 1e-12);
}

// An oscillation no stiffness stops: halved eight times (1/256), the ninth fails closed, the
// springs off and the damping at sqrt(1/256) of its minimum, the fault naming the oscillation;
// at rest the controller holds where the arm stopped, at 1/256. start() restores the stiffness.
TEST(OscillationWatch, PastTheFloorItFailsClosedThenHolds) {
  ci::CartesianImpedanceController controller(6, watched_parameters());
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  const ci::Vector6d stiffness = controller.state().commanded.stiffness.diagonal();
  Swing swing;
  int halted = 0;
  for (int k = 1; k <= 10000 && halted == 0; ++k) {
    robot.dq.setZero();
    robot.dq[0] = swing.amplitude * std::sin(2.0 * M_PI * swing.frequency * k * kDt);
    halted += controller.update(robot, kDt) == ci::Status::motion_halted;
  }
  const ci::ControllerState& state = controller.state();
  ASSERT_EQ(state.status, ci::Status::motion_halted);
  EXPECT_EQ(state.safety.oscillations, 9);
  EXPECT_EQ(state.safety.oscillation_scale, 1.0 / 256.0);
  EXPECT_STREQ(state.fault.input, "oscillation");
  EXPECT_NE(ci::to_string(state.fault).find("persisted at 1/256"), std::string::npos)
      << ci::to_string(state.fault);
  // The halt's damper: the minimum damping, scaled as the law's (1/16 of 30 N s/m).
  robot.dq.setZero();
  robot.dq[0] = 0.1;
  controller.update(robot, kDt);
  EXPECT_NEAR(controller.torque()[0], -0.1 * 30.0 / 16.0, 1e-12);
  robot.dq.setZero();
  for (int k = 0; k < 120; ++k) controller.update(robot, kDt);  // kRestTime at rest
  EXPECT_EQ(state.status, ci::Status::ok);
  EXPECT_TRUE(state.limits.holding);
  EXPECT_EQ(state.filtered.stiffness.diagonal(), stiffness / 256.0);
  controller.start(robot);
  EXPECT_EQ(state.safety.oscillation_scale, 1.0);
  EXPECT_EQ(state.safety.oscillations, 0);
  controller.update(robot, kDt);
  EXPECT_EQ(state.filtered.stiffness.diagonal(), stiffness);
}

// The halt after implausible motion (kHoldEpisodes within kHoldWindow) halves the stiffness too,
// and so does every kHoldWindow the halt's damping takes without bringing the arm to rest.
TEST(OscillationWatch, AHaltAfterImplausibleMotionHalvesTheStiffnessAndSoDoesALongHalt) {
  ci::CartesianImpedanceController controller(6, watched_parameters());
  ci::RobotState robot = cartesian_robot();
  controller.start(robot);
  const double too_fast = controller.joint_velocity_bound()[0] * 1.5;
  for (int episode = 0; episode < 3; ++episode) {
    robot.dq.setZero();
    robot.dq[0] = too_fast;
    controller.update(robot, kDt);
    robot.dq[0] = 0.01;
    controller.update(robot, kDt);
  }
  const ci::ControllerState& state = controller.state();
  ASSERT_EQ(state.status, ci::Status::motion_halted);
  EXPECT_EQ(state.safety.oscillation_scale, 0.5);
  EXPECT_EQ(state.safety.oscillations, 1);
  // Moving (above kRestSpeed) for a further kHoldWindow: halved again.
  robot.dq[0] = 0.2;
  for (int k = 0; k < 1005; ++k) controller.update(robot, kDt);
  EXPECT_EQ(state.status, ci::Status::motion_halted);
  EXPECT_EQ(state.safety.oscillation_scale, 0.25);
  EXPECT_EQ(state.safety.oscillations, 2);
}
