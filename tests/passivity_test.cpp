// The passivity observer and controller (safety.passivity) on the 6-joint "Cartesian" robot
// (J = I, so dq is the end effector's twist), driven along x as x(t) = A sin(w t), the pose and the
// velocity consistent: the energy it reports matches the delayed spring and damper in closed form,
// it never reports a generation without a delay, and past its threshold it halves the spring that
// generated it, and only that one, down to the floor where the controller fails closed. The
// closed loop behind a delay, on the realistic Panda: delay_behaviour_test.cpp.

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "cartesian_impedance/core/controller.hpp"
#include "support/bare_law.hpp"

namespace ci = cartesian_impedance;
using bare_law::bare_parameters;
using bare_law::cartesian_robot;

namespace {

constexpr double kDt = 0.001;
using Controller = ci::CartesianImpedanceController;

// 1.5 mm at 5 Hz: up to 47 mm/s, below the oscillation watch's 50 mm/s, so that only the
// passivity controller acts on the imposed motion.
struct Motion {
  double amplitude = 0.0015;  // [m]
  double frequency = 5.0;     // [Hz]
};

// The law with its filters off and the observer on (bare_parameters() switches the controller
// off): K along every axis, D = 2 zeta sqrt(K) (unit-mass damping), the torque limits out of the
// way.
ci::Parameters observed(double stiffness, double damping_ratio, int delay_cycles,
                        double threshold) {
  ci::Parameters p = bare_parameters();
  p.stiffness.translation.setConstant(stiffness);
  p.stiffness.rotation.setConstant(stiffness / 10.0);
  p.damping_ratio.translation.setConstant(damping_ratio);
  p.damping_ratio.rotation.setConstant(damping_ratio);
  p.safety.passivity.delay = delay_cycles * kDt;
  p.safety.passivity.threshold = threshold;
  return p;
}

// Moves the robot to time k dt of the motion (from its start pose x0).
void place(ci::RobotState& robot, const Eigen::Vector3d& start, const Motion& motion, int k) {
  const double w = 2.0 * M_PI * motion.frequency;
  robot.pose.position = start;
  robot.pose.position.x() += motion.amplitude * std::sin(w * k * kDt);
  robot.dq.setZero();
  robot.dq[0] = motion.amplitude * w * std::cos(w * k * kDt);
}

}  // namespace

// What the observer must report, computed from the motion alone: the torque that acted at cycle k
// was sent at k - d, F = -K x(k - d) - D v(k - d); the same controller without the delay would
// have sent -K x(k) - D v(k), whose damper part takes energy out. So each cycle adds
// (K (x(k) - x(k - d)) - D v(k - d)) v(k) dt, and the window lets what it holds decay by
// 1 - dt / kPassivityWindow per cycle. Averaged over a period that is the classic power of a
// delayed spring and damper, A^2 w / 2 (K sin(w tau) - D w cos(w tau)): it generates where the
// delay's phase outweighs the damping.
TEST(PassivityObserver, MatchesTheDelayedSpringAndDamperInClosedForm) {
  const Motion motion;
  const double w = 2.0 * M_PI * motion.frequency;
  const double stiffness = 3000.0, damping_ratio = 0.2;
  const double damping = 2.0 * damping_ratio * std::sqrt(stiffness);
  for (const int delay : {0, 5, 20}) {
    SCOPED_TRACE(delay);
    Controller controller(6, observed(stiffness, damping_ratio, delay, 0.0));
    ci::RobotState robot = cartesian_robot();
    const Eigen::Vector3d start = robot.pose.position;
    controller.start(robot);
    const double keep = 1.0 - kDt / Controller::kPassivityWindow;
    const auto x = [&](int k) { return k < 0 ? 0.0 : motion.amplitude * std::sin(w * k * kDt); };
    const auto v = [&](int k) {
      return k < 0 ? 0.0 : motion.amplitude * w * std::cos(w * k * kDt);
    };
    double expected = 0.0;
    const int cycles = 3000;
    for (int k = 1; k <= cycles; ++k) {
      place(robot, start, motion, k);
      ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
      // The observer starts once d torques have been sent (the first at k = 1).
      if (k - 1 >= delay) {
        const double power = (stiffness * (x(k) - x(k - delay)) - damping * v(k - delay)) * v(k);
        expected = keep * expected + power * kDt;
      }
      const ci::SafetyState& safety = controller.state().safety;
      ASSERT_NEAR(safety.generated_energy, expected, 1e-9 + 1e-9 * std::abs(expected)) << k;
    }
    // Steady state: the window holds the average power times its length, give or take the
    // ripple of the power's 2 w part (amplitude at most A^2 w (K + D w) / 2) through the window.
    const double tau = delay * kDt;
    const double average = 0.5 * motion.amplitude * motion.amplitude * w *
                           (stiffness * std::sin(w * tau) - damping * w * std::cos(w * tau));
    const double ripple =
        0.5 * motion.amplitude * motion.amplitude * w * (stiffness + damping * w) / (2.0 * w);
    const double energy = controller.state().safety.generated_energy;
    EXPECT_NEAR(energy, average * Controller::kPassivityWindow, ripple);
    // Passive without the delay (the damper alone) and at 9 degrees behind; at 36 degrees the
    // spring pumps more than the damper takes.
    if (delay == 20) {
      EXPECT_GT(energy, 0.0);
    } else {
      EXPECT_LT(energy, 0.0);
    }
  }
}

// Without a delay the controller is passive whatever it is given: 20 seeded motions (three sines
// on the six axes), stiffnesses and damping ratios, and the energy it reports never rises above
// zero (the damper's dissipation, decaying through the window).
TEST(PassivityObserver, NeverReportsAGenerationWithoutADelay) {
  std::mt19937 rng(44);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int draw = 0; draw < 20; ++draw) {
    SCOPED_TRACE(draw);
    const double stiffness = 100.0 + 2900.0 * unit(rng);
    Controller controller(6, observed(stiffness, 0.1 + 1.4 * unit(rng), 0, 0.0));
    ci::RobotState robot = cartesian_robot();
    const Eigen::Vector3d start = robot.pose.position;
    const Eigen::Quaterniond orientation = robot.pose.orientation;
    controller.start(robot);
    Eigen::Matrix<double, 6, 3> amplitude, frequency;
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 3; ++j) {
        amplitude(i, j) = (i < 3 ? 0.02 : 0.05) * unit(rng);
        frequency(i, j) = 2.0 * M_PI * (0.5 + 5.0 * unit(rng));
      }
    }
    for (int k = 1; k <= 2000; ++k) {
      const double t = k * kDt;
      Eigen::Matrix<double, 6, 1> offset, rate;
      for (int i = 0; i < 6; ++i) {
        offset[i] = rate[i] = 0.0;
        for (int j = 0; j < 3; ++j) {
          offset[i] += amplitude(i, j) * std::sin(frequency(i, j) * t);
          rate[i] += amplitude(i, j) * frequency(i, j) * std::cos(frequency(i, j) * t);
        }
      }
      robot.pose.position = start + offset.head<3>();
      // A turn about a fixed axis, so that its angular velocity is the angle's rate.
      robot.pose.orientation =
          Eigen::Quaterniond(Eigen::AngleAxisd(offset[3], Eigen::Vector3d::UnitX())) * orientation;
      robot.dq = rate;
      robot.dq.segment<2>(4).setZero();
      ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
      ASSERT_LE(controller.state().safety.generated_energy, 1e-12) << k;
    }
  }
}

// Behind 20 cycles the translation's spring generates about 0.05 W (the motion is along x), which
// the window holds as 0.026 J: past the threshold
// the translation stiffness is halved at once, the rotation's and the nullspace's are kept, the
// observer waits for the torques sent before the halving to act, and start() restores it all.
// With the threshold at 0 it only observes.
TEST(PassivityController, HalvesOnlyTheSpringThatGenerates) {
  const Motion motion;
  for (const double threshold : {0.0, 0.01}) {
    SCOPED_TRACE(threshold);
    Controller controller(6, observed(3000.0, 0.1, 20, threshold));
    ci::RobotState robot = cartesian_robot();
    const Eigen::Vector3d start = robot.pose.position;
    controller.start(robot);
    int halved_at = -1;
    double energy_before = 0.0;
    for (int k = 1; k <= 1000 && halved_at < 0; ++k) {
      place(robot, start, motion, k);
      energy_before = controller.state().safety.generated_energy;
      ASSERT_EQ(controller.update(robot, kDt), ci::Status::ok);
      if (controller.state().safety.passivity_halvings > 0) halved_at = k;
    }
    const ci::ControllerState& state = controller.state();
    if (threshold == 0.0) {
      EXPECT_EQ(halved_at, -1);
      EXPECT_GT(state.safety.generated_energy, 0.01);
      EXPECT_EQ(state.safety.passivity_scale, Eigen::Vector3d::Ones());
      continue;
    }
    ASSERT_GT(halved_at, 0);
    EXPECT_LE(energy_before, threshold);
    EXPECT_EQ(state.safety.passivity_halvings, 1);
    EXPECT_EQ(state.safety.passivity_scale, Eigen::Vector3d(0.5, 1.0, 1.0));
    EXPECT_DOUBLE_EQ(state.filtered.stiffness(0, 0), 1500.0);
    EXPECT_DOUBLE_EQ(state.filtered.stiffness(3, 3), 300.0);
    EXPECT_EQ(state.safety.generated_energy, 0.0);  // counted anew
    EXPECT_EQ(state.safety.oscillation_scale, 1.0);
    // The commanded stiffness does not come back through the filter while the scale holds.
    for (int k = halved_at + 1; k <= halved_at + 20; ++k) {
      place(robot, start, motion, k);
      controller.update(robot, kDt);
      EXPECT_EQ(controller.state().safety.generated_energy, 0.0) << "waiting";
    }
    EXPECT_DOUBLE_EQ(controller.state().filtered.stiffness(0, 0), 1500.0);
    place(robot, start, motion, 0);
    controller.start(robot);
    EXPECT_EQ(controller.state().safety.passivity_scale, Eigen::Vector3d::Ones());
    EXPECT_EQ(controller.state().safety.passivity_halvings, 0);
  }
}

// A generation that goes on whatever is halved (the motion is imposed: 0.06 W from an undamped
// spring 20 ms late, 0.2 mW at 1/256) takes the spring down to 1/256 of its stiffness and then
// fails closed, as the oscillation watch does: motion_halted, the fault naming the oscillation.
TEST(PassivityController, FailsClosedPastTheFloor) {
  const Motion motion;
  Controller controller(6, observed(3000.0, 0.0, 20, 1e-5));
  ci::RobotState robot = cartesian_robot();
  const Eigen::Vector3d start = robot.pose.position;
  controller.start(robot);
  int k = 1;
  for (; k <= 20000 && controller.state().status == ci::Status::ok; ++k) {
    place(robot, start, motion, k);
    controller.update(robot, kDt);
  }
  const ci::ControllerState& state = controller.state();
  EXPECT_EQ(state.status, ci::Status::motion_halted);
  EXPECT_EQ(state.fault.input, std::string("oscillation"));
  EXPECT_EQ(state.safety.passivity_halvings, 9);  // eight halvings, the ninth refused
  EXPECT_DOUBLE_EQ(state.safety.passivity_scale[0], 1.0 / 256.0);
}
