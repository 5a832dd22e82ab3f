// The energy tank in closed loop (scenario energy_tank, apps/scenarios_energy_tank.cpp) on the
// Panda and the iiwa14, in MuJoCo and in DART: issue 30's stiffness schedule (200 N/m while the
// pose error grows, 3000 N/m while it shrinks, from a 10 mm offset) keeps the error within its
// initial value + 2 mm and the total energy (kinetic + spring + tank) from growing beyond what the
// sampled spring adds; a stiffness raise at rest keeps to the filter's schedule. Without the tank
// (the mutant) the same schedule pumps the error past the bound and the energy up.

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <tuple>

#include "scenarios.hpp"

namespace ci = cartesian_impedance;
namespace scenarios = cartesian_impedance::scenarios;

namespace {

const scenarios::Result& line(const scenarios::Outcome& outcome, const std::string& quantity) {
  const auto found =
      std::find_if(outcome.results.begin(), outcome.results.end(),
                   [&](const scenarios::Result& r) { return r.quantity.rfind(quantity, 0) == 0; });
  if (found == outcome.results.end()) throw std::runtime_error("no line '" + quantity + "'");
  return *found;
}

const std::string kBound = "largest pose error under the schedule, with the tank";
const std::string kPumped = "largest pose error under the schedule, without the tank";
const std::string kEnergy = "largest rise of kinetic + spring + tank energy, with the tank";
const std::string kRaise = "time a raise";

std::string describe(const scenarios::Result& r) {
  return r.quantity + ": " + (r.bound ? "at most " : "at least ") + std::to_string(r.expected) +
         " " + r.unit + ", measured " + std::to_string(r.measured) + " " + r.unit + " (" + r.note +
         ")";
}

class EnergyTankBehaviour
    : public ::testing::TestWithParam<std::tuple<std::string, ci::sim::Engine>> {
 protected:
  void SetUp() override {
    std::string reason;
    if (!ci::sim::engine_available(std::get<1>(GetParam()), &reason)) GTEST_SKIP() << reason;
  }
  scenarios::RobotSetup robot(scenarios::Mutation mutation = scenarios::Mutation::none) const {
    scenarios::RobotSetup setup = scenarios::with_engine(
        scenarios::builtin_robot(std::get<0>(GetParam()), CARTESIAN_IMPEDANCE_SOURCE_DIR),
        std::get<1>(GetParam()));
    setup.mutation = mutation;
    return setup;
  }
};

TEST_P(EnergyTankBehaviour, ScheduleStaysWithinTwoMillimetresAndTheEnergyDoesNotGrow) {
  const scenarios::Outcome outcome = scenarios::run_scenario("energy_tank", robot());
  for (const scenarios::Result& r : outcome.results) {
    EXPECT_TRUE(r.applicable && r.passed) << describe(r);
    ::testing::Test::RecordProperty(r.quantity, describe(r));
  }
  // The check is not vacuous: without the tank the schedule pumps the 10 mm offset up to the
  // issue's 0.1 m (measured 0.12-0.15 m in 4 s).
  EXPECT_GE(line(outcome, kPumped).measured, 100.0);
}

// The mutant: the tank disabled (safety.energy_tank.enabled = false) in the run that has it.
TEST_P(EnergyTankBehaviour, WithoutTheTankTheBoundAndTheEnergyCheckFail) {
  const scenarios::Outcome outcome =
      scenarios::run_scenario("energy_tank", robot(scenarios::Mutation::no_energy_tank));
  EXPECT_FALSE(line(outcome, kBound).passed) << describe(line(outcome, kBound));
  EXPECT_FALSE(line(outcome, kEnergy).passed) << describe(line(outcome, kEnergy));
  // The raise at rest does not need the tank: it passes either way.
  EXPECT_TRUE(line(outcome, kRaise).passed) << describe(line(outcome, kRaise));
}

std::string name(const ::testing::TestParamInfo<EnergyTankBehaviour::ParamType>& info) {
  return std::get<0>(info.param) + "_" + ci::sim::engine_name(std::get<1>(info.param));
}

INSTANTIATE_TEST_SUITE_P(Robots, EnergyTankBehaviour,
                         ::testing::Combine(::testing::Values("panda", "iiwa14"),
                                            ::testing::Values(ci::sim::Engine::mujoco,
                                                              ci::sim::Engine::dart)),
                         name);

// And like every scenario's checks, these fail for a dead controller (zero torque: the arm stays
// 50 mm off after the step, so the raise at rest never completes) and for the law's sign flipped
// (the arm runs off), here in MuJoCo.
TEST(EnergyTankMutants, ABrokenControllerFailsAtLeastOneCheck) {
  for (const std::string robot : {"panda", "iiwa14"}) {
    for (const scenarios::Mutation mutation :
         {scenarios::Mutation::zero_torque, scenarios::Mutation::flipped_sign}) {
      scenarios::RobotSetup setup = scenarios::builtin_robot(robot, CARTESIAN_IMPEDANCE_SOURCE_DIR);
      setup.mutation = mutation;
      const scenarios::Outcome outcome = scenarios::run_scenario("energy_tank", setup);
      EXPECT_TRUE(std::any_of(outcome.results.begin(), outcome.results.end(),
                              [](const scenarios::Result& r) { return r.applicable && !r.passed; }))
          << robot
          << (mutation == scenarios::Mutation::zero_torque ? ", zero torque" : ", flipped sign");
    }
  }
}

}  // namespace
