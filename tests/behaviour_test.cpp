// Closed-loop behaviour in simulation, on the Panda, the iiwa14, the UR5e and the planar 3-joint
// arm (the last two from their URDF alone), on MuJoCo and on DART: every line a scenario reports
// (theory next to measurement, with a tolerance derived from physics in the scenario) must hold
// on both engines. And the checks themselves can fail: each scenario, run with a dead
// controller (zero torque) or with the law's sign flipped, must report at least one failure.

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <random>
#include <sstream>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/sim/closed_loop_runner.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "scenario_support.hpp"
#include "scenarios.hpp"

namespace ci = cartesian_impedance;
namespace scenarios = cartesian_impedance::scenarios;

namespace {

// Every line that applies to the robot passes; a line that does not must say why. A robot for
// which `applicable` scenarios must apply fails if they are all reported not applicable.
void expect_all_pass(const scenarios::Outcome& outcome) {
  ASSERT_FALSE(outcome.results.empty());
  for (const scenarios::Result& result : outcome.results) {
    if (!result.applicable) {
      EXPECT_NE(result.note.find("not applicable: "), std::string::npos) << result.quantity;
      EXPECT_GT(result.note.size(), std::string("not applicable: ").size() + 20) << result.note;
      ::testing::Test::RecordProperty(result.scenario + ": " + result.quantity, "n/a");
      continue;
    }
    EXPECT_TRUE(result.passed) << result.scenario << ": " << result.quantity << ": expected "
                               << (result.bound ? "at most " : "") << result.expected
                               << (result.tolerance > 0 ? " +- " + std::to_string(result.tolerance)
                                                        : std::string())
                               << " " << result.unit << ", measured " << result.measured << " "
                               << result.unit << " " << result.note;
    ::testing::Test::RecordProperty(result.scenario + ": " + result.quantity,
                                    std::to_string(result.measured));
  }
}

// A stiffness the torque-rate limit cannot follow (30,000 N/m, inside the table's ranges) drives
// a 10 cm step into a limit cycle. At the Panda's 1000 Nm/s it did (45 % of cycles failed closed,
// joints at 11.6 rad/s after 6 s, the arm 0.4 m off) until the torque shaping kept the spring's
// direction; at 200 Nm/s it still does (7.5 rad/s for good, measured), so the halt is tested
// there, with the plausible joint speed at 4 rad/s (about the URDF-derived 2 x 2.175). The third
// episode of implausible motion within a second halts it: springs off and the minimum damping
// alone until the arm is at rest, then the controller holds where it stopped; the state says so,
// and the next reference ends the hold.
TEST(HaltAfterImplausibleMotion, AnOscillationTheRateLimitFeedsEndsAtRestAndHolds) {
  const std::string source = CARTESIAN_IMPEDANCE_SOURCE_DIR;
  const ci::RobotModel model = ci::RobotModel::from_urdf_file(source + "/models/panda/panda.urdf",
                                                              "panda_link0", "panda_link8");
  ci::Parameters p = ci::load_parameters(source + "/config/panda.yaml");
  p.limits.stiffness.translation.max = 40000.0;
  p.stiffness.translation.setConstant(30000.0);
  p.limits.joint_torque_rate = ci::JointVector::Constant(1, 200.0);
  p.plausibility.joint_velocity = ci::JointVector::Constant(1, 4.0);
  // The shipped caps (1 m/s, 100 N) keep this oscillation from starting; the halt is tested here.
  p.safety.max_speed = ci::MaxSpeedParameters{};
  p.safety.max_force = ci::MaxForceParameters{};
  ci::ControlLoop loop(model, p);
  ci::sim::SimulationOptions options;
  options.joint_names = model.joint_names();
  ci::sim::Simulation sim =
      ci::sim::Simulation::from_mjcf_file(source + "/models/panda/panda.xml", options);
  loop.start(sim.q(), sim.dq());
  ci::sim::ClosedLoopRunner runner(sim, loop);
  runner.run_for(0.5);
  ci::Pose target = loop.state().controller.pose;
  target.position.x() += 0.1;
  loop.set_reference_pose(target);
  int implausible = 0, halted = 0, not_ok_late = 0;
  double fastest_late = 0.0;
  runner.run_for(8.0, [&](std::int64_t step) {
    const ci::Status status = loop.state().controller.status;
    implausible += status == ci::Status::invalid_robot_state;
    halted += status == ci::Status::motion_halted;
    if (step > 6000) {
      not_ok_late += status != ci::Status::ok;
      fastest_late = std::max(fastest_late, sim.dq().cwiseAbs().maxCoeff());
    }
  });
  EXPECT_GT(implausible, 0) << "the stiffness should have driven a joint beyond the plausible";
  EXPECT_GT(halted, 0);
  EXPECT_EQ(not_ok_late, 0) << ci::to_string(loop.state().controller.fault);
  EXPECT_LT(fastest_late, 0.01) << "the arm should be at rest, held, in the last 2 s";
  EXPECT_TRUE(loop.state().controller.limits.holding);
  loop.set_reference_pose(loop.state().controller.pose);
  runner.run(1);
  EXPECT_FALSE(loop.state().controller.limits.holding);
}

// A spring the joints cannot deliver: the UR5e with its URDF's efforts (150 Nm, 28 Nm at the
// wrist) and the library's default torque-rate limit (1000 Nm/s), at the library's largest
// stiffness, 5000 N/m and 500 Nm/rad, which at the largest pose error asks for 500 N and 250 Nm
// at the flange, and a reference that steps (no filter). Clipped joint by joint, the spring's
// force turns into one of another direction, the rate limit distorts it further, and the arm
// oscillates until it is halted: measured, 4 of 40 such references settled (34 halted). Shaped in
// task space: 38 of 40 (the other two are the rate limit's, which check_rate_limit warns of at
// this stiffness; with the URDF-derived rate, effort / 0.05 s, all 40 settle).
TEST(TorqueShaping, AStiffnessTheJointsCannotDeliverStillSettles) {
  scenarios::RobotSetup robot = scenarios::builtin_robot("ur5e", CARTESIAN_IMPEDANCE_SOURCE_DIR);
  robot.parameters_file.clear();
  ci::Parameters p;  // limits.joint_torque: the URDF's
  p.stiffness.translation.setConstant(p.limits.stiffness.translation.max);
  p.stiffness.rotation.setConstant(p.limits.stiffness.rotation.max);
  p.filter.pose.time = 0.0;  // a true step: the whole error at once
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> offset(-0.3, 0.3);
  int settled = 0, shaped_runs = 0;
  for (int run = 0; run < 40; ++run) {
    scenarios::Rig rig(robot, p);
    ci::JointVector q_target = rig.sim().q();
    for (int i = 0; i < q_target.size(); ++i) q_target[i] += offset(rng);
    ci::ModelWorkspace workspace(rig.model());
    ci::Pose target;
    ASSERT_TRUE(workspace.compute_pose(q_target, target));
    rig.loop().set_reference_pose(target);
    rig.loop().set_nullspace_target(q_target);
    bool shaped = false;
    for (int k = 0; k < 800; ++k) {
      rig.run(0.01);
      shaped |= rig.loop().state().controller.limits.torque_shaping != ci::TorqueShaping::none;
    }
    shaped_runs += shaped;
    // At 5000 N/m the joints' friction (at most 0.2 Nm over levers of at least 0.1 m) holds the
    // flange within 0.4 mm; 2 mm and 0.01 rad are the convergence scenario's bands.
    settled += (rig.flange().position - target.position).norm() < 0.002 &&
               scenarios::detail::rotation_between(target, rig.flange()).norm() < 0.01 &&
               rig.sim().dq().cwiseAbs().maxCoeff() < 0.01;
  }
  EXPECT_GE(settled, 36);
  EXPECT_GE(shaped_runs, 30)
      << "the references should have needed more torque than the joints have";
}

// The law resolves the pose error locally, so a reference reachable with every joint inside its
// limits can still ask, from where the arm starts, for a configuration past one: here (a joint
// configuration drawn 0.2 rad inside the limits, at 3000 N/m and 300 Nm/rad with the shipped
// configuration) the wrist would have to turn the other way round. Measured on the landed code:
// joint 7 pressed 7 mrad past its limit (2.8973 rad) with its whole 12 Nm for as long as the
// reference stood, the rotation error clipped at 0.5 rad, status ok and nothing saying why; five
// of 20 such references pressed a joint past a limit (up to 15 mrad), where the Panda's own reflex
// stops the arm. Now the drive toward a limit is bounded inside the margin and a wall holds the
// joint from halfway on: the arm never reaches the limit, rests half the margin off it, and the
// state names the joint that holds it back; a nullspace target near the reference's
// configuration takes it around.
TEST(JointLimits, AReferencePastAJointLimitHoldsTheArmOffItAndSaysSo) {
  scenarios::RobotSetup robot = scenarios::builtin_robot("panda", CARTESIAN_IMPEDANCE_SOURCE_DIR);
  ci::Parameters p = scenarios::base_parameters(robot);
  p.stiffness.translation.setConstant(3000.0);
  p.stiffness.rotation.setConstant(300.0);
  ci::JointVector q_target(7);
  q_target << 1.1826, -1.5128, 1.3915, -1.5376, 2.3148, 0.4052, 1.8413;
  for (const bool around : {false, true}) {
    SCOPED_TRACE(around ? "with the reference's configuration as nullspace target" : "alone");
    scenarios::Rig rig(robot, p);
    const ci::JointLimits& limits = rig.model().limits();
    ci::ModelWorkspace workspace(rig.model());
    ci::Pose target;
    ASSERT_TRUE(workspace.compute_pose(q_target, target));
    rig.loop().set_reference_pose(target);
    if (around) rig.loop().set_nullspace_target(q_target);
    double closest = 1e9;  // to a limit [rad]; negative: past it
    int held = -1;
    for (int k = 0; k < 2500; ++k) {
      rig.run(0.01);
      const ci::JointVector& q = rig.sim().q();
      closest = std::min({closest, (limits.position_upper - q).minCoeff(),
                          (q - limits.position_lower).minCoeff()});
      const int joint = rig.loop().state().controller.limits.joint_limit_held;
      if (joint >= 0) held = joint;
    }
    const double translation = (rig.flange().position - target.position).norm();
    const double rotation = scenarios::detail::rotation_between(target, rig.flange()).norm();
    const ci::ControllerState& state = rig.loop().state().controller;
    EXPECT_EQ(state.status, ci::Status::ok);
    EXPECT_LT(rig.sim().dq().cwiseAbs().maxCoeff(), 0.01) << "at rest";
    if (!around) {
      // It may coast past half the margin (the bound takes the drive, not the damping, which the
      // speed caps count on) but never reaches the limit, and it comes to rest held half the
      // margin off it (within what the joints' friction holds against the wall's 1740 Nm/rad
      // and more: 0.1 mrad).
      EXPECT_GT(closest, 0.0);
      EXPECT_GE(held, 0) << "the joint that holds the arm back is named";
      const int joint = state.limits.joint_limit_held;
      ASSERT_GE(joint, 0) << "still held at rest";
      const double off = std::min(limits.position_upper[joint] - rig.sim().q()[joint],
                                  rig.sim().q()[joint] - limits.position_lower[joint]);
      EXPECT_NEAR(off, 0.5 * p.joint_limit_avoidance.margin, 0.001);
      EXPECT_GT(rotation, 0.1) << "the reference cannot be reached this way round";
    } else {
      // The shipped joints' friction and the damped projector leave at most a few mm near this
      // pose; 2 mm and 0.01 rad are the convergence scenario's bands.
      EXPECT_LT(translation, 0.002);
      EXPECT_LT(rotation, 0.01);
      EXPECT_GT(closest, 0.0);
      EXPECT_EQ(state.limits.joint_limit_held, -1);
    }
  }
}

class Behaviour : public ::testing::TestWithParam<std::tuple<std::string, std::string>> {};

TEST_P(Behaviour, MatchesTheory) {
  const auto& [robot, scenario] = GetParam();
  expect_all_pass(scenarios::run_scenario(
      scenario, scenarios::builtin_robot(robot, CARTESIAN_IMPEDANCE_SOURCE_DIR)));
}

std::string name(const ::testing::TestParamInfo<Behaviour::ParamType>& info) {
  return std::get<0>(info.param) + "_" + std::get<1>(info.param);
}

// The same scenarios with DART integrating (the robots with an MJCF simulated from their URDF).
class DartBehaviour : public Behaviour {
 protected:
  void SetUp() override {
    std::string reason;
    if (!ci::sim::engine_available(ci::sim::Engine::dart, &reason)) GTEST_SKIP() << reason;
  }
};

scenarios::RobotSetup on_dart(const std::string& robot) {
  return scenarios::with_engine(scenarios::builtin_robot(robot, CARTESIAN_IMPEDANCE_SOURCE_DIR),
                                ci::sim::Engine::dart);
}

TEST_P(DartBehaviour, MatchesTheory) {
  const auto& [robot, scenario] = GetParam();
  expect_all_pass(scenarios::run_scenario(scenario, on_dart(robot)));
}

class BrokenController
    : public ::testing::TestWithParam<std::tuple<std::string, std::string, scenarios::Mutation>> {};

void expect_some_failure(scenarios::RobotSetup setup, const std::string& robot,
                         const std::string& scenario, scenarios::Mutation mutation) {
  setup.mutation = mutation;
  const scenarios::Outcome outcome = scenarios::run_scenario(scenario, setup);
  ASSERT_FALSE(outcome.results.empty());
  if (std::none_of(outcome.results.begin(), outcome.results.end(),
                   [](const scenarios::Result& r) { return r.applicable; })) {
    GTEST_SKIP() << "'" << scenario << "' does not apply to " << robot << ": "
                 << outcome.results.front().note;
  }
  int failed = 0;
  std::string failures;
  for (const scenarios::Result& result : outcome.results) {
    if (result.passed || !result.applicable) continue;
    // A broken controller's torque is not what the loop sent, which the collision monitor sees
    // as an external torque: that line fails for any mutant, so it must not count here.
    if (result.quantity == "collisions found with nothing touching the arm") continue;
    ++failed;
    failures += "\n  " + result.quantity + ": measured " + std::to_string(result.measured);
  }
  EXPECT_GT(failed, 0) << "every check of '" << scenario << "' passed with a broken controller";
  ::testing::Test::RecordProperty("failed_checks", failed);
  ::testing::Test::RecordProperty("failures", failures);
}

TEST_P(BrokenController, FailsAtLeastOneCheck) {
  const auto& [robot, scenario, mutation] = GetParam();
  expect_some_failure(scenarios::builtin_robot(robot, CARTESIAN_IMPEDANCE_SOURCE_DIR), robot,
                      scenario, mutation);
}

class DartBrokenController : public BrokenController {
 protected:
  void SetUp() override {
    std::string reason;
    if (!ci::sim::engine_available(ci::sim::Engine::dart, &reason)) GTEST_SKIP() << reason;
  }
};

TEST_P(DartBrokenController, FailsAtLeastOneCheck) {
  const auto& [robot, scenario, mutation] = GetParam();
  expect_some_failure(on_dart(robot), robot, scenario, mutation);
}

std::string broken_name(const ::testing::TestParamInfo<BrokenController::ParamType>& info) {
  return std::get<0>(info.param) + "_" + std::get<1>(info.param) +
         (std::get<2>(info.param) == scenarios::Mutation::zero_torque ? "_zero_torque"
                                                                      : "_flipped_sign");
}

const auto kScenarios =
    ::testing::Values("hold", "compliance", "reference_step", "wrench", "nullspace", "teaching",
                      "trajectory", "stability_grid", "convergence", "collision");
const auto kMutations =
    ::testing::Values(scenarios::Mutation::zero_torque, scenarios::Mutation::flipped_sign);

}  // namespace

// What a chain cannot do is not applicable exactly where its Jacobian says so: the planar arm
// moves in x, z and about y only; the UR5e has no redundant joint; the 7-joint arms do all.
TEST(NotApplicable, ExactlyWhereTheArmCannot) {
  const auto not_applicable = [](const std::string& robot, const std::string& scenario) {
    std::vector<std::string> lines;
    for (const scenarios::Result& r :
         scenarios::run_scenario(scenario,
                                 scenarios::builtin_robot(robot, CARTESIAN_IMPEDANCE_SOURCE_DIR))
             .results) {
      if (!r.applicable) lines.push_back(r.quantity);
    }
    return lines;
  };
  EXPECT_EQ(not_applicable("planar3", "compliance"),
            (std::vector<std::string>{"force along y: 20 N at 500 N/m",
                                      "torque about x: 5 Nm at 50 Nm/rad",
                                      "torque about z: 5 Nm at 50 Nm/rad"}));
  EXPECT_EQ(not_applicable("planar3", "nullspace").size(), 1u);
  EXPECT_EQ(not_applicable("ur5e", "nullspace").size(), 1u);
  EXPECT_TRUE(not_applicable("ur5e", "compliance").empty());
  EXPECT_TRUE(not_applicable("iiwa14", "nullspace").empty());
  EXPECT_TRUE(not_applicable("panda", "compliance").empty());
}

// An arm nobody tuned the scenarios for: the planar arm with a quarter of its joint torques
// (limits.joint_torque 15, 10, 2.5 Nm). The tuned 20 N push along z and 10 N on the table are
// more than its joints hold there (about 5.5 N down); each scenario sizes its loads to at most
// 30 % of that, and every line that applies then agrees with theory. (Before the scenarios read
// the arm they pushed 20 N into saturated joints.)
TEST(FitsTheArm, WeakJointsGetLoadsTheyCanHold) {
  std::ifstream shipped(std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/config/planar3.yaml");
  std::stringstream text;
  text << shipped.rdbuf();
  const std::string tuned = "joint_torque: [60, 40, 10]";
  std::string weak = text.str();
  ASSERT_NE(weak.find(tuned), std::string::npos) << "config/planar3.yaml changed";
  weak.replace(weak.find(tuned), tuned.size(), "joint_torque: [15, 10, 2.5]");
  const std::string file = ::testing::TempDir() + "/weak_planar3.yaml";
  std::ofstream(file) << weak;
  scenarios::RobotSetup robot = scenarios::builtin_robot("planar3", CARTESIAN_IMPEDANCE_SOURCE_DIR);
  robot.parameters_file = file;
  for (const std::string scenario : {"hold", "compliance", "wrench", "teaching", "two_arms"}) {
    SCOPED_TRACE(scenario);
    expect_all_pass(scenarios::run_scenario(scenario, robot));
  }
  const auto quantities = [&](const std::string& scenario) {
    std::vector<std::string> lines;
    for (const scenarios::Result& r : scenarios::run_scenario(scenario, robot).results) {
      if (r.applicable) lines.push_back(r.quantity);
    }
    return lines;
  };
  const std::vector<std::string> compliance = quantities("compliance");
  EXPECT_NE(std::find(compliance.begin(), compliance.end(), "force along z: 1.64 N at 500 N/m"),
            compliance.end());
  EXPECT_EQ(quantities("wrench"),
            (std::vector<std::string>{"contact force under a commanded 1.64 N",
                                      "sustained oscillations of the closed loop",
                                      "collisions found with nothing touching the arm"}));
}

INSTANTIATE_TEST_SUITE_P(Panda, Behaviour,
                         ::testing::Combine(::testing::Values("panda"), kScenarios), name);
INSTANTIATE_TEST_SUITE_P(Iiwa14, Behaviour,
                         ::testing::Combine(::testing::Values("iiwa14"), kScenarios), name);
// Simulated from their URDF alone, with a fixed link (tool0) at the tip.
INSTANTIATE_TEST_SUITE_P(Ur5e, Behaviour, ::testing::Combine(::testing::Values("ur5e"), kScenarios),
                         name);
INSTANTIATE_TEST_SUITE_P(Planar3, Behaviour,
                         ::testing::Combine(::testing::Values("planar3"), kScenarios), name);
// Two arms: the Panda's and the iiwa14's scene (the same for either), or two copies of a robot
// simulated from its URDF.
INSTANTIATE_TEST_SUITE_P(Scene, Behaviour,
                         ::testing::Combine(::testing::Values("panda", "ur5e", "planar3"),
                                            ::testing::Values("two_arms")),
                         name);
INSTANTIATE_TEST_SUITE_P(Mutants, BrokenController,
                         ::testing::Combine(::testing::Values("panda", "iiwa14", "ur5e", "planar3"),
                                            kScenarios, kMutations),
                         broken_name);
INSTANTIATE_TEST_SUITE_P(SceneMutants, BrokenController,
                         ::testing::Combine(::testing::Values("panda", "planar3"),
                                            ::testing::Values("two_arms"), kMutations),
                         broken_name);

// Every scenario on DART, for every robot the project ships; the checks fail there too with a
// broken controller (the Panda's mutants: the other robots' run the same checks).
INSTANTIATE_TEST_SUITE_P(Panda, DartBehaviour,
                         ::testing::Combine(::testing::Values("panda"), kScenarios), name);
INSTANTIATE_TEST_SUITE_P(Iiwa14, DartBehaviour,
                         ::testing::Combine(::testing::Values("iiwa14"), kScenarios), name);
INSTANTIATE_TEST_SUITE_P(Ur5e, DartBehaviour,
                         ::testing::Combine(::testing::Values("ur5e"), kScenarios), name);
INSTANTIATE_TEST_SUITE_P(Planar3, DartBehaviour,
                         ::testing::Combine(::testing::Values("planar3"), kScenarios), name);
INSTANTIATE_TEST_SUITE_P(Scene, DartBehaviour,
                         ::testing::Combine(::testing::Values("panda", "ur5e"),
                                            ::testing::Values("two_arms")),
                         name);
INSTANTIATE_TEST_SUITE_P(Mutants, DartBrokenController,
                         ::testing::Combine(::testing::Values("panda"), kScenarios, kMutations),
                         broken_name);

// ---------------------------------------------------------------------------------------------
// Soak: a minute of random commands per robot - references in and out of reach, stiffness from
// zero to the limits, full 6 x 6 stiffness matrices, damping, wrenches, nullspace targets and
// stiffness, trajectories, teaching, parameter reloads that lower the torque and rate limits, and
// rejected bad commands - with the loop's invariants checked on every one of the 60,000 cycles:
// a finite torque, no joint faster than its rate limit, no joint above the torque bound in
// force, a bound that never rises above limits.joint_torque and never falls faster than the rate
// limit; and the safety layer's promises with the caps in force (the shipped ones, and tight
// ones on the Panda): the flange at most 1.1 x the speed cap, spring + commanded wrench at most
// the force cap, the energy tank within [0, capacity]. Every few seconds a reachable reference
// at a usable stiffness must be approached without the arm running away.

namespace {

// What the safety layer did over a soak, and the worst of each of its promises.
struct SafetyFigures {
  double worst_speed_fraction = 0.0;  // flange speed / safety.max_speed.translation
  double worst_force_excess = -1e9;   // |spring + wrench| - safety.max_force.force [N]
  long governed = 0, braked = 0, force_capped = 0, clipped = 0, walled = 0, tank_paid = 0,
       tank_short = 0;
  long last_wall_cycle = -1000000;  // the last cycle a wall (workspace or joint limit) acted
};

struct SoakFigures {
  SafetyFigures safety;
  long cycles = 0;
  long commands = 0;
  long rejected = 0;
  double largest_rate_fraction = 0.0;    // |dtau| / (rate dt), worst joint and cycle
  double largest_torque_fraction = 0.0;  // |tau| / bound in force
  double fastest_reachable = 0.0;        // largest |dq| in the reachable phases [rad/s]
  double worst_reachable_error = 0.0;    // [m] at their end
};

double uniform(std::mt19937& rng, double low, double high) {
  return std::uniform_real_distribution<double>(low, high)(rng);
}

ci::Vector6d random_six(std::mt19937& rng, double translation, double rotation, double low = 0.0) {
  ci::Vector6d values;
  for (int i = 0; i < 3; ++i) values[i] = uniform(rng, low * translation, translation);
  for (int i = 3; i < 6; ++i) values[i] = uniform(rng, low * rotation, rotation);
  return values;
}

ci::JointVector random_configuration(const scenarios::Rig& rig, const ci::JointVector& around,
                                     double spread, std::mt19937& rng) {
  const ci::JointLimits& limits = rig.model().limits();
  ci::JointVector q = around;
  for (int i = 0; i < q.size(); ++i) {
    q[i] = std::clamp(q[i] + uniform(rng, -spread, spread), limits.position_lower[i] + 0.1,
                      limits.position_upper[i] - 0.1);
  }
  return q;
}

// One random command of any kind; returns false if the loop rejected it (as it must for the bad
// ones, which are sent on purpose).
bool random_command(scenarios::Rig& rig, const ci::Parameters& base, std::mt19937& rng) {
  ci::ControlLoop& loop = rig.loop();
  const ci::LimitParameters& limits = base.limits;
  const double k_t = limits.stiffness.translation.max, k_r = limits.stiffness.rotation.max;
  ci::ModelWorkspace workspace(rig.model());
  try {
    switch (std::uniform_int_distribution<int>(0, 12)(rng)) {
      case 0: {  // a reachable reference
        ci::Pose target;
        workspace.compute_pose(random_configuration(rig, rig.sim().q(), 0.4, rng), target);
        loop.set_reference_pose(target);
        break;
      }
      case 1: {  // out of reach
        ci::Pose target = rig.flange();
        target.position += 2.0 * Eigen::Vector3d::Random().normalized();
        target.orientation = Eigen::Quaterniond::UnitRandom();
        loop.set_reference_pose(target);
        break;
      }
      case 2:
        loop.set_stiffness(random_six(rng, k_t, k_r));
        break;
      case 3: {
        const ci::Matrix6d root = ci::Matrix6d::Random();
        ci::Matrix6d k = root * root.transpose();
        k *= uniform(rng, 0.0, 1.0) * k_t / k.diagonal().maxCoeff();
        k.bottomRightCorner<3, 3>() *= k_r / k_t;
        k.topRightCorner<3, 3>() *= std::sqrt(k_r / k_t);
        k.bottomLeftCorner<3, 3>() *= std::sqrt(k_r / k_t);
        loop.set_stiffness_matrix(
            k, uniform(rng, 0, 1) < 0.5 ? ci::Frame::base : ci::Frame::end_effector);
        break;
      }
      case 4:
        loop.set_damping_ratio(random_six(rng, 2.0, 2.0));
        break;
      case 5: {
        ci::Vector6d wrench = random_six(rng, 2 * limits.wrench.force, 2 * limits.wrench.torque);
        wrench.array() -=
            ci::Vector6d(random_six(rng, limits.wrench.force, limits.wrench.torque)).array();
        loop.set_wrench(wrench);
        break;
      }
      case 6:
        loop.set_nullspace_target(random_configuration(rig, rig.sim().q(), 0.5, rng));
        break;
      case 7:
        loop.set_nullspace_stiffness(
            Eigen::VectorXd::Constant(1, uniform(rng, 0, limits.nullspace_stiffness.max)));
        break;
      case 8: {
        ci::JointTrajectory trajectory;
        trajectory.joint_names = rig.model().joint_names();
        ci::JointVector q = rig.sim().q();
        const int points = std::uniform_int_distribution<int>(1, 8)(rng);
        double time = 0.0;
        for (int k = 0; k < points; ++k) {
          q = random_configuration(rig, q, 0.15, rng);
          time += uniform(rng, 0.3, 1.0);
          trajectory.times.push_back(time);
          trajectory.positions.emplace_back(q.data(), q.data() + q.size());
        }
        loop.execute_trajectory(trajectory);
        break;
      }
      case 9: {  // a reload that lowers the torque and rate limits and changes the gains
        ci::Parameters parameters = base;
        parameters.limits.joint_torque =
            ci::per_joint(base.limits.joint_torque, rig.model().num_joints()) *
            uniform(rng, 0.1, 1.0);
        parameters.limits.joint_torque_rate =
            ci::per_joint(base.limits.joint_torque_rate, rig.model().num_joints()) *
            uniform(rng, 0.3, 1.0);
        parameters.stiffness.translation.setConstant(uniform(rng, 0, k_t));
        parameters.stiffness.rotation.setConstant(uniform(rng, 0, k_r));
        parameters.dynamics.inertia_shaped_damping = uniform(rng, 0, 1) < 0.7;
        parameters.dynamics.dynamically_consistent_nullspace = uniform(rng, 0, 1) < 0.3;
        loop.set_parameters(parameters);
        break;
      }
      case 10:
        if (uniform(rng, 0, 1) < 0.5) {
          loop.start_teaching(uniform(rng, 0, 1) < 0.5);
        } else {
          loop.cancel_trajectory();
        }
        break;
      case 11: {  // bad on purpose: must be rejected
        ci::Pose target = rig.flange();
        target.position.x() = std::nan("");
        loop.set_reference_pose(target);
        break;
      }
      default:
        loop.set_stiffness(random_six(rng, 1e6, 1e6, 0.5));  // beyond the valid range
        break;
    }
  } catch (const ci::Error&) {
    return false;
  }
  return true;
}

// The safety layer's promises on one cycle that ran the law (status ok), with the caps in force:
// the flange no faster than 1.1 x safety.max_speed.translation (ground truth: the simulation's
// flange over the cycle); the force the controller presses with (its Cartesian force, from
// tau_cartesian = J^T F, less the damping, the walls and the brake, plus the commanded wrench:
// the spring and the wrench the cap scaled) no larger than safety.max_force.force; the tank's
// level within [0, capacity].
void check_safety(scenarios::Rig& rig, double speed, SafetyFigures& figures, long cycle) {
  const ci::LoopState& loop = rig.loop().state();
  const ci::ControllerState& state = loop.controller;
  const ci::SafetyParameters& caps = rig.loop().controller().parameters().safety;
  const ci::SafetyState& safety = state.safety;
  if (state.status != ci::Status::ok) return;
  ASSERT_GE(safety.tank_level, 0.0) << "cycle " << cycle;
  ASSERT_LE(safety.tank_level, caps.energy_tank.capacity) << "cycle " << cycle;
  figures.governed += safety.translation_drive_scale < 1.0;
  figures.braked += safety.braking;
  figures.force_capped += safety.force_scale < 1.0;
  figures.clipped += safety.reference_clipped;
  figures.walled += !safety.wall_force.isZero(0.0);
  figures.tank_paid += safety.tank_draw > 0.0;
  figures.tank_short += safety.stiffness_change_scale < 1.0;
  // The walls are not speed-governed (README "Safety layer"): a flange pushed back by a
  // workspace wall, or a joint by its joint-limit wall while teaching, may pass the speed cap
  // until the brake has taken the excess out; the joint-space wall is also no J^T F, so the
  // pressed force cannot be read back from tau_cartesian while it acts. Those cycles, and the
  // 0.2 s after a wall (two time constants of the brake and the damping on the Panda's
  // task-space mass), are not checked.
  if (safety.joint_limit_wall || !safety.wall_force.isZero(0.0)) figures.last_wall_cycle = cycle;
  if (cycle - figures.last_wall_cycle <= 200) return;
  ci::ModelWorkspace workspace(rig.model());
  ci::Kinematics kinematics = workspace.make_kinematics();
  ASSERT_TRUE(workspace.compute(loop.q, loop.dq, kinematics));
  const Eigen::MatrixXd& jacobian = kinematics.jacobian;
  const ci::Vector6d twist = jacobian * loop.dq;
  if (caps.max_speed.translation > 0.0) {
    figures.worst_speed_fraction =
        std::max(figures.worst_speed_fraction, speed / caps.max_speed.translation);
    ASSERT_LE(speed, 1.1 * caps.max_speed.translation)
        << "cycle " << cycle << ": trajectory " << static_cast<int>(loop.trajectory.state)
        << ", drive scale " << safety.translation_drive_scale << ", braking " << safety.braking
        << ", wall force " << safety.wall_force.transpose() << ", K "
        << state.filtered.stiffness.diagonal().transpose() << ", wrench "
        << state.wrench_base.transpose() << ", torque shaping "
        << static_cast<int>(state.limits.torque_shaping) << ", reference twist "
        << state.filtered.twist.transpose() << ", penetration "
        << safety.workspace_penetration.transpose() << ", error " << state.pose_error.transpose()
        << ", twist " << twist.transpose();
  }
  // tau_cartesian = J^T (spring + damping + walls + brake), J of full row rank.
  const ci::Vector6d cartesian =
      (jacobian * jacobian.transpose()).ldlt().solve(jacobian * state.tau_cartesian);
  // Less the damping -D (v - v_ref), the walls and the brake's -D_b (|v| - c) v / |v|: the
  // spring and the commanded wrench, which the cap holds.
  ci::Vector6d others = -state.damping_base() * (twist - state.filtered.twist);
  others.head<3>() += safety.wall_force;
  if (safety.braking) {
    for (const auto& [start, cap] :
         {std::pair{0, caps.max_speed.translation}, {3, caps.max_speed.rotation}}) {
      const double speed_law = twist.segment<3>(start).norm();
      if (cap > 0.0 && speed_law > cap) {
        others.segment<3>(start) -= state.damping.diagonal().segment<3>(start).mean() *
                                    (speed_law - cap) * twist.segment<3>(start).normalized();
      }
    }
  }
  // And what the nullspace torque leaks to the end effector through the damped projector, which
  // the cap holds with the rest (SafetyState): (J J^T + lambda^2 I)^-1 J tau_nullspace, with the
  // lambda the controller's projector uses (at least 1e-3 where it builds the system itself).
  const ci::Parameters& in_force = rig.loop().controller().parameters();
  const double lambda = in_force.nullspace.pseudo_inverse_damping;
  const bool own_system = in_force.dynamics.dynamically_consistent_nullspace;
  ci::Matrix6d gram = jacobian * jacobian.transpose();
  gram.diagonal().array() += own_system ? std::max(lambda * lambda, 1e-6) : lambda * lambda;
  const ci::Vector6d leak = gram.ldlt().solve(jacobian * state.tau_nullspace);
  const ci::Vector6d pressed = cartesian - others + state.wrench_base + leak;
  if (caps.max_force.force > 0.0) {
    const double excess = pressed.head<3>().norm() - caps.max_force.force;
    figures.worst_force_excess = std::max(figures.worst_force_excess, excess);
    ASSERT_LE(excess, 1e-6 * (1.0 + cartesian.norm())) << "cycle " << cycle;
  }
}

// Steps one cycle and checks the invariants against the limits in force.
void checked_step(scenarios::Rig& rig, SoakFigures& figures) {
  const ci::JointVector previous = rig.loop().state().controller.tau;
  const ci::JointVector previous_bound = rig.loop().state().controller.joint_torque_limit;
  const Eigen::Vector3d flange_before = rig.flange().position;
  rig.run(0.001);
  check_safety(rig, (rig.flange().position - flange_before).norm() / 0.001, figures.safety,
               figures.cycles + 1);
  if (::testing::Test::HasFatalFailure()) return;
  const ci::ControllerState& state = rig.loop().state().controller;
  const ci::Parameters& parameters = rig.loop().controller().parameters();
  const int n = rig.model().num_joints();
  const ci::JointVector rate = ci::per_joint(parameters.limits.joint_torque_rate, n) * 0.001;
  const ci::JointVector limit = ci::per_joint(parameters.limits.joint_torque, n);
  ++figures.cycles;
  ASSERT_TRUE(state.tau.allFinite()) << "cycle " << figures.cycles;
  for (int i = 0; i < n; ++i) {
    const double slack = 1e-12 * std::max(1.0, std::abs(state.tau[i]));
    ASSERT_LE(std::abs(state.tau[i] - previous[i]), rate[i] + slack)
        << "joint " << i << ", cycle " << figures.cycles;
    ASSERT_LE(std::abs(state.tau[i]), state.joint_torque_limit[i] + slack)
        << "joint " << i << ", cycle " << figures.cycles;
    ASSERT_GE(state.joint_torque_limit[i], limit[i]) << "joint " << i;
    ASSERT_LE(state.joint_torque_limit[i], std::max(limit[i], previous_bound[i]) + slack)
        << "the bound rose above limits.joint_torque, joint " << i;
    ASSERT_GE(state.joint_torque_limit[i], std::min(limit[i], previous_bound[i] - rate[i]) - slack)
        << "the bound fell faster than the rate limit, joint " << i;
    figures.largest_rate_fraction =
        std::max(figures.largest_rate_fraction, std::abs(state.tau[i] - previous[i]) / rate[i]);
    figures.largest_torque_fraction = std::max(
        figures.largest_torque_fraction, std::abs(state.tau[i]) / state.joint_torque_limit[i]);
  }
}

}  // namespace

// "panda", or "panda_tight_caps": the safety layer's caps set where the random commands reach
// them often (0.25 m/s, 40 N, a box of +-0.25 m about the start with walls).
class Soak : public ::testing::TestWithParam<std::string> {};

TEST_P(Soak, RandomCommandsForAMinuteKeepEveryBound) {
  const std::string tight = "_tight_caps";
  const bool tight_caps =
      GetParam().size() > tight.size() &&
      GetParam().compare(GetParam().size() - tight.size(), tight.size(), tight) == 0;
  const std::string robot_name =
      tight_caps ? GetParam().substr(0, GetParam().size() - tight.size()) : GetParam();
  const scenarios::RobotSetup robot =
      scenarios::builtin_robot(robot_name, CARTESIAN_IMPEDANCE_SOURCE_DIR);
  ci::Parameters base = scenarios::base_parameters(robot);
  if (tight_caps) {
    ci::SafetyParameters& safety = base.safety;
    safety.max_speed = {0.25, 1.0};
    safety.max_force = {40.0, 8.0};
    const Eigen::Vector3d start = scenarios::Rig(robot, base).flange().position;
    safety.workspace.min = start - Eigen::Vector3d::Constant(0.25);
    safety.workspace.max = start + Eigen::Vector3d::Constant(0.25);
    safety.workspace.stiffness = 2000.0;
  }
  scenarios::Rig rig(robot, base);
  std::mt19937 rng(robot_name == "panda" ? 1 : 2);
  SoakFigures figures;
  const ci::JointVector home = rig.sim().q();
  while (figures.cycles < 60000) {
    // 5 s of chaos: a random command every 20 to 500 ms.
    for (double until = 5.0; until > 0.0;) {
      figures.rejected += random_command(rig, base, rng) ? 0 : 1;
      ++figures.commands;
      const double hold = uniform(rng, 0.02, 0.5);
      for (int k = 0; k < static_cast<int>(hold / 0.001) && !HasFatalFailure(); ++k) {
        checked_step(rig, figures);
      }
      if (HasFatalFailure()) return;
      until -= hold;
    }
    // Then a reachable reference near home with the configuration's own gains, nothing else:
    // the arm must get there without running away.
    rig.loop().cancel_trajectory();
    rig.loop().set_parameters(base);
    ci::Pose target;
    ci::ModelWorkspace workspace(rig.model());
    const ci::JointVector q_target = random_configuration(rig, home, 0.3, rng);
    workspace.compute_pose(q_target, target);
    rig.loop().set_reference_pose(target);
    rig.loop().set_nullspace_target(q_target);
    // Joint speed once what the chaos left behind has been damped out (0.5 s).
    double fastest = 0.0;
    for (int k = 0; k < 4000 && !HasFatalFailure(); ++k) {
      checked_step(rig, figures);
      if (k >= 500) fastest = std::max(fastest, rig.sim().dq().cwiseAbs().maxCoeff());
    }
    if (HasFatalFailure()) return;
    figures.fastest_reachable = std::max(figures.fastest_reachable, fastest);
    figures.worst_reachable_error =
        std::max(figures.worst_reachable_error, (rig.flange().position - target.position).norm());
  }
  // Rejected commands are the bad ones sent on purpose (2 of 13 kinds).
  EXPECT_GT(figures.rejected, 0);
  EXPECT_LT(figures.rejected, figures.commands / 3);
  // Going for a reachable reference the arm never runs away: no joint comes near the speed the
  // controller would take for a sensor fault (plausibility.joint_velocity). (It does exceed
  // the robots' own joint speed limits when a rotation error of 0.5 rad is clipped: the law
  // has no joint speed limit.)
  EXPECT_LE(figures.fastest_reachable,
            0.5 * ci::per_joint(base.plausibility.joint_velocity, 1).maxCoeff());
  EXPECT_GT(figures.largest_rate_fraction, 0.99) << "the rate limit was never reached";
  RecordProperty("cycles", static_cast<int>(figures.cycles));
  RecordProperty("commands", static_cast<int>(figures.commands));
  RecordProperty("fastest_reachable", std::to_string(figures.fastest_reachable));
  RecordProperty("worst_reachable_error", std::to_string(figures.worst_reachable_error));
  RecordProperty("largest_torque_fraction", std::to_string(figures.largest_torque_fraction));
  const SafetyFigures& safety = figures.safety;
  RecordProperty("worst_speed_fraction", std::to_string(safety.worst_speed_fraction));
  RecordProperty("worst_force_excess", std::to_string(safety.worst_force_excess));
  if (tight_caps) {
    // Every cap was reached, so every promise above was tested (cycles of 60,000).
    EXPECT_GT(safety.governed, 0);
    EXPECT_GT(safety.braked, 0);
    EXPECT_GT(safety.force_capped, 0);
    EXPECT_GT(safety.clipped, 0);
    EXPECT_GT(safety.walled, 0);
    EXPECT_GT(safety.tank_paid, 0);
    EXPECT_GT(safety.tank_short, 0);
    RecordProperty("governed", static_cast<int>(safety.governed));
    RecordProperty("braked", static_cast<int>(safety.braked));
    RecordProperty("force_capped", static_cast<int>(safety.force_capped));
    RecordProperty("clipped", static_cast<int>(safety.clipped));
    RecordProperty("walled", static_cast<int>(safety.walled));
    RecordProperty("tank_short", static_cast<int>(safety.tank_short));
  }
}

INSTANTIATE_TEST_SUITE_P(Robots, Soak, ::testing::Values("panda", "iiwa14", "panda_tight_caps"));
