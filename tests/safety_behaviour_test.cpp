// The safety layer in closed loop (the demo's `safety` scenario, apps/scenarios_safety.cpp): on
// the four shipped robots every line agrees with theory, on MuJoCo and (the Panda) on DART; the
// Panda meets issue 30's figures; and each check fails when its cap is removed (the scenario's
// parameter mutations), or when the controller is broken (zero torque, flipped sign).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "scenarios.hpp"

namespace ci = cartesian_impedance;
namespace scenarios = cartesian_impedance::scenarios;

namespace {

scenarios::RobotSetup robot_named(const std::string& name) {
  return scenarios::builtin_robot(name, CARTESIAN_IMPEDANCE_SOURCE_DIR);
}

bool dart_available(std::string& reason) {
  return ci::sim::engine_available(ci::sim::Engine::dart, &reason);
}

// The line whose quantity starts with `prefix` (exactly one must).
const scenarios::Result& line(const scenarios::Outcome& outcome, const std::string& prefix) {
  const scenarios::Result* found = nullptr;
  for (const scenarios::Result& result : outcome.results) {
    if (result.quantity.rfind(prefix, 0) != 0) continue;
    if (found != nullptr) throw ci::Error("two lines start with '" + prefix + "'");
    found = &result;
  }
  if (found == nullptr) throw ci::Error("no line starts with '" + prefix + "'");
  return *found;
}

// Every line that applies passes; the ones that do not say why. `expected_not_applicable`: how
// many lines may not apply (DART's rigid contact has no meaningful peak force).
void expect_all_pass(const scenarios::Outcome& outcome, std::size_t expected_not_applicable) {
  ASSERT_FALSE(outcome.results.empty());
  std::size_t not_applicable = 0;
  for (const scenarios::Result& result : outcome.results) {
    if (!result.applicable) {
      ++not_applicable;
      EXPECT_NE(result.note.find("not applicable: "), std::string::npos) << result.quantity;
      continue;
    }
    EXPECT_TRUE(result.passed) << result.quantity << ": expected " << (result.bound ? "<= " : "")
                               << result.expected << " +- " << result.tolerance << " "
                               << result.unit << ", measured " << result.measured << " "
                               << result.unit << " (" << result.note << ")";
    ::testing::Test::RecordProperty(result.quantity, std::to_string(result.measured));
  }
  EXPECT_EQ(not_applicable, expected_not_applicable);
}

// Each line that checks a cap, by a part of its quantity that only it has.
const std::vector<std::string> kSpeedChecks = {
    "table, reference jumps: impact speed, caps",
    "N/m: peak speed, cap",
    "trajectory: peak speed, cap",
    "no spring: peak speed, cap",
    "push while teaching: speed, cap",
};
const std::vector<std::string> kForceChecks = {
    "table, reference jumps: peak force, caps",
    "table, reference jumps: settled force, caps",
    "table, reference at 0.1 m/s: peak force, caps",
    "table, reference at 0.1 m/s: settled force, caps",
};
const std::vector<std::string> kWorkspaceChecks = {
    "push while teaching: deepest beyond the wall",
    "push while teaching: rest beyond the wall",
    "reference 10 cm outside: filtered reference outside",
    "reference 10 cm outside: flange at rest beyond the face",
};
const std::vector<std::string> kPayloadChecks = {"payload declared: |sag|"};

}  // namespace

class SafetyScenario : public ::testing::TestWithParam<std::string> {};

// Every line on MuJoCo: the table, the speed cap, the walls and the payload, on each robot (the
// planar arm cannot move along y, so its tests of motion run along x; nothing is skipped). And
// two of issue 30's figures, which every shipped robot meets: a 20 N push while teaching stops
// within F / K_wall + 5 mm of the wall (K_wall 2000 N/m in each configuration), and a declared
// 1 kg payload sags at most 1 mm.
TEST_P(SafetyScenario, MatchesTheoryOnMujoco) {
  const scenarios::Outcome outcome = scenarios::run_scenario("safety", robot_named(GetParam()));
  expect_all_pass(outcome, 0);
  EXPECT_LE(line(outcome, "20 N push while teaching: deepest beyond the wall").measured,
            1e3 * 20.0 / 2000.0 + 5.0);
  EXPECT_LE(line(outcome, "1 kg payload declared: |sag|").measured, 1.0);
}

INSTANTIATE_TEST_SUITE_P(Robots, SafetyScenario,
                         ::testing::Values("panda", "iiwa14", "ur5e", "planar3"));

// The force cap on DART, whose contact is rigid and whose joint friction is hard: the settled
// force, the impact speeds and every other line; the per-step peak force of a rigid impact is
// not the controller's (3 lines say so).
TEST(SafetyScenarioDart, PandaMatchesTheory) {
  std::string reason;
  if (!dart_available(reason)) GTEST_SKIP() << reason;
  expect_all_pass(scenarios::run_scenario("safety", scenarios::with_engine(robot_named("panda"),
                                                                           ci::sim::Engine::dart)),
                  3);
}

// Issue 30's figures on the Panda in MuJoCo with config/panda.yaml: without caps a reference
// 5 cm inside the table at 3000 N/m presses with over 250 N at the impact and over 130 N settled
// (issue: 268 and 155 N); with max_speed 0.1 m/s and max_force 40 N at most 60 N and 42 N; a
// 300 mm jump peaks near 0.67 m/s without the speed cap and at most 1.1 x a 0.25 m/s cap; the
// estimate of an undeclared 1 kg payload is within 5 %.
TEST(SafetyScenario, PandaMeetsTheIssuesFigures) {
  const scenarios::Outcome outcome = scenarios::run_scenario("safety", robot_named("panda"));
  EXPECT_GT(line(outcome, "table, reference jumps: peak force without caps").measured, 250.0);
  EXPECT_GT(line(outcome, "table, reference jumps: settled force without caps").measured, 130.0);
  for (const std::string what : {"table, reference jumps: ", "table, reference at 0.1 m/s: "}) {
    const scenarios::Result& peak = line(outcome, what + "peak force, caps");
    const scenarios::Result& settled = line(outcome, what + "settled force, caps");
    EXPECT_NE(peak.quantity.find("caps 0.1 m/s, 40 N"), std::string::npos) << peak.quantity;
    EXPECT_LE(peak.measured, 60.0) << what;
    EXPECT_LE(settled.measured, 42.0) << what;
  }
  const scenarios::Result& free_speed =
      line(outcome, "300 mm jump at 3000 N/m: peak speed without");
  EXPECT_NEAR(free_speed.measured, 0.67, 0.05);
  EXPECT_LE(line(outcome, "300 mm jump at 3000 N/m: peak speed, cap 0.25").measured, 0.275);
  EXPECT_NEAR(line(outcome, "1 kg payload not declared: estimated mass").measured, 1.0, 0.05);
}

// Each check fails when its cap is removed: the same scenario with one cap's parameters at 0
// (or, for the workspace, no box; for the payload, not declared).
class SafetyCapRemoved
    : public ::testing::TestWithParam<std::tuple<std::string, scenarios::Mutation>> {};

void expect_checks_fail(const scenarios::RobotSetup& robot, scenarios::Mutation mutation) {
  scenarios::RobotSetup mutated = robot;
  mutated.mutation = mutation;
  const scenarios::Outcome outcome = scenarios::run_scenario("safety", mutated);
  const std::vector<std::string>& checks =
      mutation == scenarios::Mutation::no_speed_cap   ? kSpeedChecks
      : mutation == scenarios::Mutation::no_force_cap ? kForceChecks
      : mutation == scenarios::Mutation::no_workspace ? kWorkspaceChecks
                                                      : kPayloadChecks;
  for (const std::string& part : checks) {
    int lines = 0;
    for (const scenarios::Result& result : outcome.results) {
      if (result.quantity.find(part) == std::string::npos) continue;
      ++lines;
      EXPECT_TRUE(result.applicable) << result.quantity << ": " << result.note;
      EXPECT_FALSE(result.passed) << result.quantity << " passed without its cap: measured "
                                  << result.measured << " " << result.unit;
      ::testing::Test::RecordProperty(result.quantity, std::to_string(result.measured));
    }
    EXPECT_EQ(lines, 1) << "lines with '" << part << "'";
  }
}

TEST_P(SafetyCapRemoved, ItsChecksFail) {
  const auto& [robot, mutation] = GetParam();
  expect_checks_fail(robot_named(robot), mutation);
}

std::string cap_name(const ::testing::TestParamInfo<SafetyCapRemoved::ParamType>& info) {
  const scenarios::Mutation mutation = std::get<1>(info.param);
  return std::get<0>(info.param) +
         (mutation == scenarios::Mutation::no_speed_cap   ? "_no_speed_cap"
          : mutation == scenarios::Mutation::no_force_cap ? "_no_force_cap"
          : mutation == scenarios::Mutation::no_workspace ? "_no_workspace"
                                                          : "_no_payload");
}

INSTANTIATE_TEST_SUITE_P(Robots, SafetyCapRemoved,
                         ::testing::Combine(::testing::Values("panda", "iiwa14", "ur5e", "planar3"),
                                            ::testing::Values(scenarios::Mutation::no_speed_cap,
                                                              scenarios::Mutation::no_force_cap,
                                                              scenarios::Mutation::no_workspace,
                                                              scenarios::Mutation::no_payload)),
                         cap_name);

// The force cap removed on DART: the settled force passes the cap there too.
TEST(SafetyCapRemovedDart, PandaForceChecksFail) {
  std::string reason;
  if (!dart_available(reason)) GTEST_SKIP() << reason;
  scenarios::RobotSetup robot = scenarios::with_engine(robot_named("panda"), ci::sim::Engine::dart);
  robot.mutation = scenarios::Mutation::no_force_cap;
  const scenarios::Outcome outcome = scenarios::run_scenario("safety", robot);
  for (const std::string what : {"table, reference jumps: ", "table, reference at 0.1 m/s: "}) {
    const scenarios::Result& settled = line(outcome, what + "settled force, caps");
    EXPECT_FALSE(settled.passed) << settled.quantity << ": " << settled.measured << " N";
  }
}

// A broken controller fails the scenario too: the estimate among its checks (a dead controller
// lets the payload pull the arm down, so it is never still; a flipped one throws it off).
class SafetyBrokenController
    : public ::testing::TestWithParam<std::tuple<std::string, scenarios::Mutation>> {};

TEST_P(SafetyBrokenController, FailsItsChecks) {
  const auto& [robot, mutation] = GetParam();
  scenarios::RobotSetup setup = robot_named(robot);
  setup.mutation = mutation;
  const scenarios::Outcome outcome = scenarios::run_scenario("safety", setup);
  int failed = 0;
  for (const scenarios::Result& result : outcome.results)
    failed += result.applicable && !result.passed;
  EXPECT_GT(failed, 0);
  EXPECT_FALSE(line(outcome, "1 kg payload not declared: estimated mass").passed);
  RecordProperty("failed_checks", failed);
}

INSTANTIATE_TEST_SUITE_P(Panda, SafetyBrokenController,
                         ::testing::Combine(::testing::Values("panda"),
                                            ::testing::Values(scenarios::Mutation::zero_torque,
                                                              scenarios::Mutation::flipped_sign)),
                         [](const auto& info) {
                           return std::get<0>(info.param) +
                                  (std::get<1>(info.param) == scenarios::Mutation::zero_torque
                                       ? std::string("_zero_torque")
                                       : std::string("_flipped_sign"));
                         });
