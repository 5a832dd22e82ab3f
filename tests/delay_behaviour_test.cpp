// The closed loop behind a delay, on the realistic Panda in MuJoCo (sim::PlantOptions::realistic:
// inertias x U(0.7, 1.3), centres of mass moved up to 1 cm, friction, noise, 1 ms of actuation
// delay) with the measurement delay set per case: a 5 cm reference step at 3000 N/m and
// 300 Nm/rad. Before the oscillation watch the default damping limit-cycled from 8 ms of delay
// (9.5 rad/s at the wrist, measured on this plant; 4.7 rad/s on the issue's) and the published
// controller's unit-mass damping from 1 ms, all with status ok. Now each case settles, the
// passivity controller and the watch having halved the stiffness as often as its delay needs;
// the passivity controller halves only the springs that generate, so that the translation keeps
// its stiffness far past the margin the watch alone left; and a loop inside its margin is never
// taken for an oscillation.

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>

#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/sim/closed_loop_runner.hpp"
#include "cartesian_impedance/sim/simulation.hpp"

namespace ci = cartesian_impedance;

namespace {

const std::string kSource = CARTESIAN_IMPEDANCE_SOURCE_DIR;

struct Step {
  std::uint64_t plant_seed = 1;
  double measurement_delay = 0.0;  // [s], on top of the plant's 1 ms of actuation delay
  bool inertia_shaped = true;
  double translation_stiffness = 3000.0, rotation_stiffness = 300.0, damping_ratio = 1.0;
  Eigen::Vector3d move = Eigen::Vector3d(0.05, 0.0, 0.0);  // [m]
  Eigen::Vector3d turn = Eigen::Vector3d::Zero();          // [rad], rotation vector
  double seconds = 8.0;
  bool passivity = true;
};

struct Outcome {
  int oscillations = 0;
  double scale = 1.0;
  double fastest_late = 0.0;  // [rad/s] largest true joint speed in the last second
  int not_ok_late = 0;        // cycles of the last second whose status was not ok
  double error_late = 0.0;    // [m] the pose error's translation at the end
  std::string fault;
  int passivity_halvings = 0;
  Eigen::Vector3d kept = Eigen::Vector3d::Ones();  // translation, rotation, nullspace fraction
  double peak = 0.0;  // [rad/s] largest true joint speed after the step's own motion (0.6 s)
};

// The reading noise of the realistic plant (0.005 rad/s) and its torque noise (0.05 Nm) keep
// the wrist of a settled arm moving at 0.01-0.02 rad/s (measured); a limit cycle moves it at
// 2-10 rad/s. The bound lies between, a factor 2.5 above the first.
constexpr double kSettledSpeed = 0.05;

Outcome step_behind_delay(const Step& step) {
  static const ci::RobotModel model = ci::RobotModel::from_urdf_file(
      kSource + "/models/panda/panda.urdf", "panda_link0", "panda_link8");
  ci::Parameters p;  // the library's defaults, as a user stepping ControlLoop by hand has them
  p.stiffness.translation.setConstant(step.translation_stiffness);
  p.stiffness.rotation.setConstant(step.rotation_stiffness);
  p.damping_ratio.translation.setConstant(step.damping_ratio);
  p.damping_ratio.rotation.setConstant(step.damping_ratio);
  p.dynamics.inertia_shaped_damping = step.inertia_shaped;
  // The user knows the loop's delay (the measurement's age, which the control thread reports, and
  // the drive's 1 ms); the passivity controller off is the watch alone.
  p.safety.passivity.delay = step.measurement_delay + 0.001;
  if (!step.passivity) p.safety.passivity.threshold = 0.0;
  ci::sim::SimulationOptions options;
  options.joint_names = model.joint_names();
  options.plant = ci::sim::PlantOptions::realistic(step.plant_seed);
  options.plant.measurement_delay = step.measurement_delay;
  ci::sim::Simulation sim =
      ci::sim::Simulation::from_mjcf_file(kSource + "/models/panda/panda.xml", options);
  ci::ControlLoop loop(model, p);
  loop.start(sim.q(), sim.dq());
  ci::sim::ClosedLoopRunner runner(sim, loop);
  ci::Pose target = loop.state().controller.pose;
  target.position += step.move;
  if (step.turn.norm() > 0.0) {
    target.orientation =
        Eigen::Quaterniond(Eigen::AngleAxisd(step.turn.norm(), step.turn.normalized())) *
        target.orientation;
  }
  loop.set_reference_pose(target);
  Outcome outcome;
  const std::int64_t late = static_cast<std::int64_t>((step.seconds - 1.0) / sim.timestep());
  const std::int64_t moved = static_cast<std::int64_t>(0.6 / sim.timestep());
  runner.run_for(step.seconds, [&](std::int64_t done) {
    if (done > moved) outcome.peak = std::max(outcome.peak, sim.true_dq().cwiseAbs().maxCoeff());
    if (done <= late) return;
    outcome.not_ok_late += loop.state().controller.status != ci::Status::ok;
    outcome.fastest_late = std::max(outcome.fastest_late, sim.true_dq().cwiseAbs().maxCoeff());
  });
  const ci::ControllerState& state = loop.state().controller;
  outcome.oscillations = state.safety.oscillations;
  outcome.scale = state.safety.oscillation_scale;
  outcome.error_late = state.pose_error.head<3>().norm();
  outcome.fault = ci::to_string(state.fault);
  outcome.passivity_halvings = state.safety.passivity_halvings;
  outcome.kept = state.safety.oscillation_scale * state.safety.passivity_scale;
  return outcome;
}

struct DelayCase {
  const char* name;
  bool inertia_shaped;
  double delay;  // [s]
};

class PastTheMargin : public ::testing::TestWithParam<DelayCase> {};

Step step_of(const DelayCase& c) {
  Step step;
  step.inertia_shaped = c.inertia_shaped;
  step.measurement_delay = c.delay;
  return step;
}

std::string case_name(const ::testing::TestParamInfo<DelayCase>& info) {
  return info.param.name;
}

}  // namespace

// The table, re-measured: every case limit-cycled with status ok before. Now the passivity
// controller (or the watch) finds the cycle, the stiffness is halved until the loop is stable,
// and in the last second of eight the arm is at rest, status ok, at the reference (within what
// the joints' friction holds against the stiffness left: 3 mm at 1/32 of 3000 N/m).
TEST_P(PastTheMargin, TheLimitCycleIsFoundAndTheArmSettles) {
  Step step = step_of(GetParam());
  const Outcome outcome = step_behind_delay(step);
  EXPECT_GE(outcome.oscillations + outcome.passivity_halvings, 1);
  EXPECT_LT(outcome.kept.minCoeff(), 1.0);
  EXPECT_EQ(outcome.not_ok_late, 0) << outcome.fault;
  EXPECT_LE(outcome.fastest_late, kSettledSpeed) << "a limit cycle in the last second";
  EXPECT_LE(outcome.error_late, 0.003);
  ::testing::Test::RecordProperty("oscillations", outcome.oscillations);
  ::testing::Test::RecordProperty("passivity_halvings", outcome.passivity_halvings);
  ::testing::Test::RecordProperty("scale", std::to_string(outcome.scale));
}

INSTANTIATE_TEST_SUITE_P(Delays, PastTheMargin,
                         ::testing::Values(DelayCase{"InertiaShaped12ms", true, 0.012},
                                           DelayCase{"InertiaShaped20ms", true, 0.020},
                                           DelayCase{"InertiaShaped50ms", true, 0.050},
                                           DelayCase{"UnitMass2ms", false, 0.002},
                                           DelayCase{"UnitMass4ms", false, 0.004}),
                         case_name);

// The margin of the translation's stiffness: the rotation's spring (a light wrist behind 300
// Nm/rad) is what a delay makes pump first, and the passivity observer names it, so that only it
// is halved and the 5 cm step at 3000 N/m keeps its translation stiffness - behind 8 and 12 ms
// with the default damping, and behind 1 to 10 ms with the published controller's, which on this
// plant holds no 3000 N/m even without a delay. The watch alone halves every spring (measured: to
// 1/2 and 1/4 of the translation stiffness with the default damping, 1/2 to 1/128 with the
// unit-mass one), so each case also runs with the passivity controller off and must lose
// translation stiffness there. The arm is at rest in the last second, and after the step's own
// motion (0.6 s) no joint is faster than 1 rad/s (the watch alone let the 12 ms case swing at
// 7.4 rad/s).
class KeepsTheTranslation : public ::testing::TestWithParam<DelayCase> {};

TEST_P(KeepsTheTranslation, OnlyTheSpringThatPumpsIsHalved) {
  Step step = step_of(GetParam());
  const Outcome outcome = step_behind_delay(step);
  EXPECT_EQ(outcome.kept[0], 1.0) << "translation stiffness lowered";
  EXPECT_LT(outcome.kept[1], 1.0);
  EXPECT_GE(outcome.passivity_halvings, 1);
  EXPECT_EQ(outcome.not_ok_late, 0) << outcome.fault;
  EXPECT_LE(outcome.fastest_late, kSettledSpeed);
  EXPECT_LE(outcome.peak, 1.0);
  EXPECT_LE(outcome.error_late, 0.001);
  step.passivity = false;
  const Outcome watch_alone = step_behind_delay(step);
  EXPECT_LT(watch_alone.kept[0], 1.0) << "the watch alone keeps the translation too";
  ::testing::Test::RecordProperty("passivity_halvings", outcome.passivity_halvings);
  ::testing::Test::RecordProperty("rotation_kept", std::to_string(outcome.kept[1]));
  ::testing::Test::RecordProperty("peak", std::to_string(outcome.peak));
  ::testing::Test::RecordProperty("watch_alone_translation", std::to_string(watch_alone.kept[0]));
}

INSTANTIATE_TEST_SUITE_P(Delays, KeepsTheTranslation,
                         ::testing::Values(DelayCase{"InertiaShaped8ms", true, 0.008},
                                           DelayCase{"InertiaShaped12ms", true, 0.012},
                                           DelayCase{"UnitMass1ms", false, 0.001},
                                           DelayCase{"UnitMass2ms", false, 0.002},
                                           DelayCase{"UnitMass4ms", false, 0.004},
                                           DelayCase{"UnitMass10ms", false, 0.010}),
                         case_name);

// Inside the default design's margin (measured: it settles up to 4 ms at 3000 N/m) a loop must
// never be taken for an oscillation: 16 seeded draws of plant, measurement delay (0-3 ms),
// stiffness (300-3000 N/m, 30-300 Nm/rad), damping ratio (0.7-1.3) and a step (2-8 cm with a
// turn of up to 0.3 rad). Each settles with the stiffness it was given.
TEST(InsideTheMargin, AStableLoopIsNeverTakenForAnOscillation) {
  std::mt19937_64 rng(44);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int draw = 0; draw < 16; ++draw) {
    Step step;
    step.plant_seed = rng();
    step.measurement_delay = 0.001 * std::floor(4.0 * unit(rng));
    const double stiffness = 300.0 + 2700.0 * unit(rng);
    step.translation_stiffness = stiffness;
    step.rotation_stiffness = stiffness / 10.0;
    step.damping_ratio = 0.7 + 0.6 * unit(rng);
    const Eigen::Vector3d direction =
        Eigen::Vector3d(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5).normalized();
    step.move = (0.02 + 0.06 * unit(rng)) * direction;
    step.turn = 0.3 * unit(rng) *
                Eigen::Vector3d(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5).normalized();
    step.seconds = 3.0;
    const Outcome outcome = step_behind_delay(step);
    const std::string what =
        "draw " + std::to_string(draw) + ": " + std::to_string(step.measurement_delay * 1e3) +
        " ms, " + std::to_string(stiffness) + " N/m, zeta " + std::to_string(step.damping_ratio);
    EXPECT_EQ(outcome.oscillations, 0) << what;
    EXPECT_EQ(outcome.passivity_halvings, 0) << what;
    EXPECT_EQ(outcome.not_ok_late, 0) << what << ": " << outcome.fault;
    EXPECT_LE(outcome.fastest_late, kSettledSpeed) << what;
  }
}
