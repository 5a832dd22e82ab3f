// Closed-loop behaviour in the MuJoCo simulation, on the Panda and the iiwa14: every line a
// scenario reports (theory next to measurement, with a tolerance derived from physics in the
// scenario) must hold.

#include <gtest/gtest.h>

#include "scenarios.hpp"

namespace ci = cartesian_impedance;
namespace scenarios = cartesian_impedance::scenarios;

namespace {

void expect_all_pass(const scenarios::Outcome& outcome) {
  ASSERT_FALSE(outcome.results.empty());
  for (const scenarios::Result& result : outcome.results) {
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

class Behaviour : public ::testing::TestWithParam<std::tuple<std::string, std::string>> {};

TEST_P(Behaviour, MatchesTheory) {
  const auto& [robot, scenario] = GetParam();
  expect_all_pass(scenarios::run_scenario(
      scenario, scenarios::builtin_robot(robot, CARTESIAN_IMPEDANCE_SOURCE_DIR)));
}

std::string name(const ::testing::TestParamInfo<Behaviour::ParamType>& info) {
  return std::get<0>(info.param) + "_" + std::get<1>(info.param);
}

}  // namespace

INSTANTIATE_TEST_SUITE_P(
    Panda, Behaviour,
    ::testing::Combine(::testing::Values("panda"),
                       ::testing::Values("hold", "compliance", "reference_step", "wrench",
                                         "nullspace", "teaching", "trajectory", "stability_grid")),
    name);
INSTANTIATE_TEST_SUITE_P(
    Iiwa14, Behaviour,
    ::testing::Combine(::testing::Values("iiwa14"),
                       ::testing::Values("hold", "compliance", "reference_step", "wrench",
                                         "nullspace", "teaching", "trajectory", "stability_grid")),
    name);
// The two-arm scene always holds a Panda and an iiwa14.
INSTANTIATE_TEST_SUITE_P(Scene, Behaviour,
                         ::testing::Combine(::testing::Values("panda"),
                                            ::testing::Values("two_arms")),
                         name);
