// Issue 40's table in closed loop (MuJoCo Panda, config/panda.yaml, the README's caps of 0.25 m/s
// and 40 N unless a test says otherwise): each row the landed safety layer broke, by how the
// terms around a cap composed, as a named regression. Each asserts the promise itself (flange
// speed, settled force, energy, a valid estimate), measured on the simulation's ground truth.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/sim/closed_loop_runner.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "scenarios.hpp"

namespace ci = cartesian_impedance;
namespace scenarios = cartesian_impedance::scenarios;

namespace {

constexpr double kDt = 0.001;
constexpr double kSpeedMargin = 1.1;   // the speed cap's promise: at most 10 % above it
constexpr double kForceMargin = 1.05;  // settled force: the joints' friction holds a few percent

scenarios::RobotSetup panda() {
  return scenarios::builtin_robot("panda", CARTESIAN_IMPEDANCE_SOURCE_DIR);
}

ci::Parameters with_readme_caps(ci::Parameters p) {
  p.safety.max_speed.translation = 0.25;
  p.safety.max_force.force = 40.0;
  return p;
}

// Steps a rig one cycle at a time, measuring the flange's speed over each cycle from the
// simulation's own poses.
struct Probe {
  explicit Probe(scenarios::Rig& rig_) : rig(rig_), previous(rig_.flange()) {}
  double step() {
    rig.run(kDt);
    const ci::Pose now = rig.flange();
    const double speed = (now.position - previous.position).norm() / kDt;
    previous = now;
    return speed;
  }
  // The largest speed over `seconds`.
  double peak_speed(double seconds) {
    double peak = 0.0;
    for (int k = 0; k < static_cast<int>(std::lround(seconds / kDt)); ++k) {
      peak = std::max(peak, step());
    }
    return peak;
  }
  scenarios::Rig& rig;
  ci::Pose previous;
};

double penetration(const Eigen::Vector3d& position, const ci::WorkspaceParameters& box) {
  return (position - position.cwiseMax(box.min).cwiseMin(box.max)).norm();
}

}  // namespace

// ---- 1. A workspace box that excludes the flange ---------------------------------------------

struct BoxCase {
  const char* name;
  double outside;         // [m] how far past the box the flange is
  double wall_stiffness;  // [N/m]
  double speed_cap;       // [m/s]
  bool at_start;          // the configuration's box, not a run-time move
};

class BoxPastTheFlange : public ::testing::TestWithParam<BoxCase> {};

// Measured on the landed code with these cases: 0.85 m/s against a 0.25 m/s cap (0.15 m
// outside); 1.59 m/s at 0.30 m; 1.71 m/s with a 100,000 N/m wall (and a fault: 10 rad/s at a
// joint); 1.07 m/s under panda.yaml's own 1 m/s cap; 0.85 m/s for the configured box. Now the box
// in force stops at the flange and closes in behind it as the spring brings it in at the cap; the
// flange ends at the box's face.
TEST_P(BoxPastTheFlange, TheFlangeComesInNoFasterThanTheCap) {
  const BoxCase& c = GetParam();
  const scenarios::RobotSetup robot = panda();
  ci::Parameters p = with_readme_caps(scenarios::base_parameters(robot));
  p.safety.max_speed.translation = c.speed_cap;
  const double start_x = 0.3069;  // the ready pose's flange (x, 0, 0.5903)
  ci::Parameters moved = p;
  moved.safety.workspace.max.x() = start_x - c.outside;
  moved.safety.workspace.stiffness = c.wall_stiffness;
  scenarios::Rig rig(robot, c.at_start ? moved : p);
  Probe probe(rig);
  if (!c.at_start) {
    probe.peak_speed(0.3);
    rig.loop().set_parameters(moved);
  }
  const double peak = probe.peak_speed(4.0);
  EXPECT_LE(peak, kSpeedMargin * c.speed_cap) << c.name;
  EXPECT_LE(penetration(rig.flange().position, moved.safety.workspace), 0.005)
      << c.name << ": the flange is brought into the box";
  EXPECT_EQ(rig.loop().state().controller.status, ci::Status::ok);
  ::testing::Test::RecordProperty("peak_speed", std::to_string(peak));
}

INSTANTIATE_TEST_SUITE_P(Panda, BoxPastTheFlange,
                         ::testing::Values(BoxCase{"moved_15cm", 0.15, 2000.0, 0.25, false},
                                           BoxCase{"moved_30cm", 0.30, 2000.0, 0.25, false},
                                           BoxCase{"moved_15cm_wall_1e5", 0.15, 1e5, 0.25, false},
                                           BoxCase{"moved_15cm_panda_yaml_cap", 0.15, 2000.0, 1.0,
                                                   false},
                                           BoxCase{"configured_15cm", 0.15, 2000.0, 0.25, true}),
                         [](const auto& info) { return std::string(info.param.name); });

// ---- 2. A declared payload that is not carried -----------------------------------------------

// A declared 3.5 kg that is not there and a commanded 30 N up; a ceiling 1 cm above a thin bar
// the flange carries 15-25 cm out in front of it (the ceiling then meets the bar, not the wrist
// above the flange). Landed: the compensation (34 N) was outside the cap and pressed on top of
// it, 47.6 N settled against the 40 N cap. Now the sum presses with at most the cap.
TEST(PayloadNotCarried, PressesACeilingWithAtMostTheCap) {
  const scenarios::RobotSetup robot = panda();
  ci::Parameters p = with_readme_caps(scenarios::base_parameters(robot));
  p.payload.mass = 3.5;
  ci::sim::SimulationOptions options;
  options.armature = p.dynamics.armature;
  const ci::Pose flange =
      ci::sim::Simulation::from_mjcf_file(robot.mjcf, options).body_pose("panda_link8");
  const Eigen::Matrix3d to_flange = flange.orientation.toRotationMatrix().transpose();
  // A bar along the base's x (2 x 2 cm across, 10 g), from 1 to 25 cm ahead of the flange.
  ci::sim::AttachedBox bar;
  bar.name = "bar";
  bar.body = "panda_link8";
  bar.position = to_flange * Eigen::Vector3d(0.13, 0.0, 0.0);
  bar.orientation = flange.orientation.conjugate();
  bar.half_size = Eigen::Vector3d(0.12, 0.01, 0.01);
  bar.mass = 0.01;
  const ci::sim::Box ceiling{"ceiling", flange.position + Eigen::Vector3d(0.2, 0.0, 0.04),
                             Eigen::Vector3d(0.05, 0.05, 0.02)};
  ci::sim::Simulation sim = ci::sim::make_scene(robot.mjcf, {ceiling}, {bar}, options);
  const ci::RobotModel model =
      ci::RobotModel::from_urdf_file(robot.urdf, robot.base_link, robot.tip_link);
  ci::ControlLoop loop(model, p);
  ci::sim::ClosedLoopRunner runner(sim, loop);
  runner.start();
  loop.set_wrench((ci::Vector6d() << 0, 0, 30, 0, 0, 0).finished());
  runner.run_for(3.0);
  double settled = 0.0;
  runner.run_for(
      0.5, [&](std::int64_t) { settled += sim.contact_wrench("bar").head<3>().norm() / 500.0; });
  EXPECT_GT(settled, 20.0) << "the bar presses the ceiling";
  EXPECT_LE(settled, kForceMargin * 40.0);
  ::testing::Test::RecordProperty("settled_force", std::to_string(settled));
}

// In free space the same declaration lifts the flange until the spring holds the compensation;
// the rise is speed-capped, and once at rest the mismatch with the estimate (0 kg) is reported
// within a second.
TEST(PayloadNotCarried, RisesUnderTheCapAndIsReportedAtRest) {
  const scenarios::RobotSetup robot = panda();
  ci::Parameters p = with_readme_caps(scenarios::base_parameters(robot));
  p.stiffness.translation.setConstant(1000.0);
  p.payload.mass = 3.5;
  scenarios::Rig rig(robot, p);
  Probe probe(rig);
  double peak = 0.0, rest_since = -1.0, reported_at = -1.0;
  for (int k = 0; k < 4000 && reported_at < 0.0; ++k) {
    const double speed = probe.step();
    peak = std::max(peak, speed);
    if (speed > 0.005) rest_since = -1.0;
    if (speed <= 0.005 && rest_since < 0.0) rest_since = k * kDt;
    if (rig.loop().state().controller.safety.payload_mismatch) reported_at = k * kDt;
  }
  EXPECT_LE(peak, kSpeedMargin * 0.25);
  ASSERT_GE(reported_at, 0.0) << "the mismatch was never reported";
  ASSERT_GE(rest_since, 0.0);
  EXPECT_LE(reported_at - rest_since, 1.0);
  EXPECT_NEAR(rig.flange().position.z() - 0.5903, 3.5 * 9.81 / 1000.0, 0.01)
      << "the spring holds the compensation";
  EXPECT_LT(rig.loop().state().controller.safety.payload_estimate_mass, 0.5);
  ::testing::Test::RecordProperty("peak_speed", std::to_string(peak));
  ::testing::Test::RecordProperty("reported_after_rest", std::to_string(reported_at - rest_since));
}

// ---- 3. Teaching against a wall --------------------------------------------------------------

// Teaching (no stiffness), a 2000 N/m wall 1 cm away, a 40 N push into it for 1 s, released.
// Landed: the wall threw the flange back at 0.238 m/s against a 0.1 m/s cap; now the governor
// takes the wall's push along the motion too.
TEST(TeachingWall, ThrowsTheFlangeBackNoFasterThanTheCap) {
  const scenarios::RobotSetup robot = panda();
  ci::Parameters p = scenarios::base_parameters(robot);
  p.safety.max_speed.translation = 0.1;
  p.safety.max_force.force = 0.0;
  p.safety.workspace.max.x() = 0.3069 + 0.01;
  p.safety.workspace.stiffness = 2000.0;
  scenarios::Rig rig(robot, p);
  rig.loop().start_teaching();
  rig.run(0.5);
  rig.push(Eigen::Vector3d(40.0, 0.0, 0.0));
  Probe probe(rig);
  probe.peak_speed(1.0);
  const double deepest = rig.flange().position.x() - (0.3069 + 0.01);
  EXPECT_GT(deepest, 0.01) << "the push drove the flange into the wall";
  rig.release();
  const double peak = probe.peak_speed(2.0);
  EXPECT_LE(peak, kSpeedMargin * 0.1);
  EXPECT_GT(peak, 0.05) << "the wall pushed the flange back";
  ::testing::Test::RecordProperty("peak_speed_after_release", std::to_string(peak));
}

// ---- 4. A schedule of the pose-error clip ----------------------------------------------------

// The energy in the arm: kinetic (M(q) with the rotors), the clipped spring with the clips in
// force, and the tank. Gravity is the firmware's.
double stored_energy(scenarios::Rig& rig) {
  const ci::ControlLoop& loop = rig.loop();
  const ci::LoopState& state = loop.state();
  const ci::ControllerState& controller = state.controller;
  ci::ModelWorkspace workspace(rig.model());
  ci::Kinematics kinematics = workspace.make_kinematics();
  workspace.compute(state.q, state.dq, kinematics, ci::ModelTerms::mass);
  ci::JointMatrix mass = kinematics.mass;
  mass.diagonal() +=
      ci::per_joint(loop.controller().parameters().dynamics.armature, rig.model().num_joints());
  const double kinetic = 0.5 * state.dq.dot(mass * state.dq);
  const ci::Vector6d error = ci::pose_error(controller.pose, controller.filtered.pose);
  const ci::Vector6d k = controller.filtered.stiffness.diagonal();
  const auto clipped_spring = [](double length, double clip, double stiffness) {
    return length <= clip ? 0.5 * stiffness * length * length
                          : stiffness * clip * (length - 0.5 * clip);
  };
  const ci::SafetyState& safety = controller.safety;
  return kinetic +
         clipped_spring(error.head<3>().norm(), safety.pose_error_in_force.translation, k[0]) +
         clipped_spring(error.tail<3>().norm(), safety.pose_error_in_force.rotation, k[3]) +
         safety.tank_level;
}

struct ClipCase {
  const char* name;
  bool caps;
  bool tank;  // false: the tank off, where the schedule must pump (the check can fail)
};

class ClipSchedule : public ::testing::TestWithParam<ClipCase> {};

// The clip at 1 cm while the error grows and 10 m while it shrinks, 3000 N/m, unit-mass damping at
// zeta 0.1 and no minimum damping, no filters (with panda.yaml's damping the landed code did not
// pump; the issue reported 5 cm growing to 92 cm, the tank full throughout). Now a raise of the
// clip is paid from the tank: the energy never grows, and the error stays within what the energy at
// the start allows with the weakest spring, c / 2 + E_0 / (k c). With the tank off the same
// schedule pumps (measured: 66 cm and 710 J, and +-12 cm at 0.94 m/s with the caps), so the checks
// can fail.
TEST_P(ClipSchedule, PumpsNoEnergyIntoTheArm) {
  const ClipCase& c = GetParam();
  const scenarios::RobotSetup robot = panda();
  ci::Parameters p = scenarios::base_parameters(robot);
  if (!c.caps) {
    p.safety.max_speed = {0.0, 0.0};
    p.safety.max_force = {0.0, 0.0};
  }
  p.stiffness.translation.setConstant(3000.0);
  p.damping_ratio.translation.setConstant(0.1);
  p.dynamics.inertia_shaped_damping = false;
  p.minimum_damping.translation = 0.0;
  p.filter.pose.time = p.filter.stiffness.time = p.filter.nullspace.time = 0.0;
  p.filter.wrench.time = 0.0;
  p.limits.pose_error.translation = 10.0;
  p.safety.energy_tank.enabled = c.tank;
  scenarios::Rig rig(robot, p);
  rig.run(0.2);
  ci::Pose reference = rig.flange();
  reference.position.x() -= 0.05;
  rig.loop().set_reference_pose(reference);
  rig.run(kDt);
  const double start_energy = stored_energy(rig);
  Probe probe(rig);
  double previous_error = 0.05, largest_error = 0.0, largest_growth = 0.0, last_second_peak = 0.0;
  double clip = 10.0;
  for (int k = 0; k < 5000; ++k) {
    const double speed = probe.step();
    if (k >= 4000) last_second_peak = std::max(last_second_peak, speed);
    const double error = (rig.flange().position - reference.position).norm();
    const double wanted = error > previous_error ? 0.01 : 10.0;
    if (wanted != clip) {
      ci::Parameters values = rig.loop().latest_parameters();
      values.limits.pose_error.translation = wanted;
      rig.loop().update_parameters(
          ci::ParameterUpdate::of(values, {"limits.pose_error.translation"}));
      clip = wanted;
    }
    previous_error = error;
    largest_error = std::max(largest_error, error);
    largest_growth = std::max(largest_growth, stored_energy(rig) - start_energy);
  }
  const double bound = 0.005 + (start_energy + 0.005) / (3000.0 * 0.01);
  if (!c.tank) {
    // The mutant: without the tank the schedule pumps.
    EXPECT_GT(c.caps ? last_second_peak : largest_error, c.caps ? 0.05 : bound) << c.name;
  } else if (c.caps) {
    // The speed cap ramps the reference in, and the force cap bounds the spring: the error stays
    // near the step (landed: +-11 cm), and the arm comes to rest.
    EXPECT_LE(largest_error, 0.06) << c.name;
    EXPECT_LE(last_second_peak, 0.05) << c.name << ": the arm comes to rest";
  } else {
    EXPECT_LE(largest_error, bound) << c.name;
    EXPECT_LE(largest_growth, 0.01 * start_energy + 0.005) << c.name;
    EXPECT_LE(last_second_peak, 0.05) << c.name << ": the arm comes to rest";
  }
  ::testing::Test::RecordProperty("largest_error", std::to_string(largest_error));
  ::testing::Test::RecordProperty("energy_growth", std::to_string(largest_growth));
}

INSTANTIATE_TEST_SUITE_P(Panda, ClipSchedule,
                         ::testing::Values(ClipCase{"caps_off", false, true},
                                           ClipCase{"panda_yaml_caps", true, true},
                                           ClipCase{"caps_off_no_tank", false, false},
                                           ClipCase{"panda_yaml_caps_no_tank", true, false}),
                         [](const auto& info) { return std::string(info.param.name); });

// ---- 5. The payload estimate under contact ---------------------------------------------------

// A reference 4 cm into a table at 1000 N/m: the flange presses with 40 N. Landed: the estimate
// read -2 to -4 kg and was valid. A press is no load: not valid, never negative.
TEST(PayloadEstimate, AReferenceInsideATableIsNoPayload) {
  const scenarios::RobotSetup robot = panda();
  ci::Parameters p = scenarios::base_parameters(robot);
  p.stiffness.translation.setConstant(1000.0);
  const ci::sim::Box table =
      ci::sim::Box::table(Eigen::Vector2d(0.3069, 0.0), Eigen::Vector2d(0.1, 0.1), 0.5903 - 0.03);
  scenarios::Rig rig(robot, p, {table});
  rig.run(0.2);
  ci::Pose reference = rig.flange();
  reference.position.z() -= 0.07;
  rig.loop().set_reference_pose(reference);
  rig.run(3.0);
  const ci::SafetyState& safety = rig.loop().state().controller.safety;
  EXPECT_GT(rig.contact_force().norm(), 30.0) << "the flange presses the table";
  EXPECT_FALSE(safety.payload_estimate_valid);
  EXPECT_TRUE(safety.static_wrench_unexplained);
  EXPECT_GE(safety.payload_estimate_mass, 0.0);
}
