// The plant of a simulation (SimulationOptions::plant): readings (the joint torque sensors' too)
// as old as the measurement delay,
// torques acting as late as the actuation delay, noise of the stated spread that repeats after
// reset(), positions on the encoder's grid, joint parameters drawn within their ranges, and every
// field out of range refused by name. The model error on both engines: sim_dart_test.cpp.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "support/sim_reference.hpp"
#ifdef CARTESIAN_IMPEDANCE_COUNT_ALLOCATIONS
#include "support/allocation_counter.hpp"
#endif

namespace ci = cartesian_impedance;
namespace sim = cartesian_impedance::sim;
using ci::JointVector;

namespace {

sim::Simulation panda_with(const sim::PlantOptions& plant) {
  sim::SimulationOptions options;
  options.plant = plant;
  return sim::Simulation::from_mjcf_file(sim_test::kPandaXml, options);
}

// A torque that moves every joint, changing each step.
JointVector wave(int step, int n) {
  JointVector tau(n);
  for (int i = 0; i < n; ++i) tau[i] = 2.0 * std::sin(0.01 * step + i);
  return tau;
}

}  // namespace

TEST(Plant, TheNominalPlantReadsTheEngineAtOnce) {
  EXPECT_TRUE(sim::PlantOptions{}.nominal());
  EXPECT_FALSE(sim::PlantOptions::realistic().nominal());
  sim::Simulation s = panda_with({});
  for (int k = 0; k < 200; ++k) {
    s.set_torque(wave(k, 7));
    ASSERT_EQ(s.torque(), wave(k, 7));  // at once, within the Panda's limits
    s.step();
    ASSERT_EQ(s.q(), s.true_q());
    ASSERT_EQ(s.dq(), s.true_dq());
  }
}

// After every step the reading is the state of `delay` steps before, bit for bit; before the
// first steps, the state the arm started in.
TEST(Plant, ReadingsAreAsOldAsTheMeasurementDelay) {
  sim::PlantOptions plant;
  plant.measurement_delay = 0.005;
  sim::Simulation s = panda_with(plant);
  std::vector<JointVector> q_history{s.true_q()}, dq_history{s.true_dq()};
  EXPECT_EQ(s.q(), s.true_q());
  for (int k = 1; k <= 300; ++k) {
    s.set_torque(wave(k, 7));
    s.step();
    q_history.push_back(s.true_q());
    dq_history.push_back(s.true_dq());
    const std::size_t seen = static_cast<std::size_t>(std::max(0, k - 5));
    ASSERT_EQ(s.q(), q_history[seen]) << "step " << k;
    ASSERT_EQ(s.dq(), dq_history[seen]) << "step " << k;
  }
  EXPECT_GT((s.q() - s.true_q()).norm(), 1e-4);  // the arm moved meanwhile
  // set_state(): the arm has rested there; every reading is the new state.
  s.set_state(sim_test::panda_ready(), JointVector::Zero(7));
  EXPECT_EQ(s.q(), sim_test::panda_ready());
  s.step();
  EXPECT_EQ(s.q(), sim_test::panda_ready());
}

// A torque set at step k acts from step k + delay: the delayed arm follows, bit for bit, the
// nominal arm given the same torques `delay` steps later.
TEST(Plant, TorquesActAfterTheActuationDelay) {
  sim::PlantOptions plant;
  plant.actuation_delay = 0.003;
  sim::Simulation delayed = panda_with(plant);
  sim::Simulation nominal = panda_with({});
  const int n = 7;
  for (int k = 0; k < 400; ++k) {
    delayed.set_torque(wave(k, n));
    nominal.set_torque(k < 3 ? JointVector::Zero(n) : wave(k - 3, n));
    delayed.step();
    nominal.step();
    ASSERT_EQ(delayed.torque(), nominal.torque()) << "step " << k;
    ASSERT_EQ(delayed.true_q(), nominal.true_q()) << "step " << k;
  }
  EXPECT_GT((delayed.true_q() - sim_test::panda_ready()).norm(), 1e-3);
}

// White noise of the stated standard deviation on each reading and torque (a sample of 7 x 3000
// draws: its standard deviation within 4 % and its mean within 5 standard errors), positions on
// the encoder's grid, and the same noise again after reset().
TEST(Plant, NoiseHasItsSpreadAndRepeatsAfterReset) {
  sim::PlantOptions plant;
  plant.position_noise = 2e-4;
  plant.velocity_noise = 0.005;
  plant.torque_noise = 0.05;
  sim::Simulation s = panda_with(plant);
  const JointVector command = JointVector::Constant(7, 0.5);
  auto run = [&](std::vector<double>& q_errors, std::vector<double>& dq_errors,
                 std::vector<double>& tau_errors) {
    for (int k = 0; k < 3000; ++k) {
      s.set_torque(command);
      s.step();
      for (int i = 0; i < 7; ++i) {
        q_errors.push_back(s.q()[i] - s.true_q()[i]);
        dq_errors.push_back(s.dq()[i] - s.true_dq()[i]);
        tau_errors.push_back(s.torque()[i] - command[i]);
      }
    }
  };
  std::vector<double> q_errors, dq_errors, tau_errors;
  run(q_errors, dq_errors, tau_errors);
  auto expect_spread = [](const std::vector<double>& errors, double sigma, const char* what) {
    double sum = 0.0, squares = 0.0;
    for (const double e : errors) sum += e;
    const double mean = sum / static_cast<double>(errors.size());
    for (const double e : errors) squares += (e - mean) * (e - mean);
    const double deviation = std::sqrt(squares / static_cast<double>(errors.size() - 1));
    EXPECT_NEAR(deviation, sigma, 0.04 * sigma) << what;
    EXPECT_LT(std::abs(mean), 5.0 * sigma / std::sqrt(static_cast<double>(errors.size()))) << what;
  };
  expect_spread(q_errors, 2e-4, "position");
  expect_spread(dq_errors, 0.005, "velocity");
  expect_spread(tau_errors, 0.05, "torque");

  s.reset();
  std::vector<double> q_again, dq_again, tau_again;
  run(q_again, dq_again, tau_again);
  EXPECT_EQ(q_again, q_errors);
  EXPECT_EQ(dq_again, dq_errors);
  EXPECT_EQ(tau_again, tau_errors);

  plant = sim::PlantOptions{};
  plant.position_resolution = 1e-4;
  sim::Simulation encoder = panda_with(plant);
  for (int k = 0; k < 100; ++k) {
    encoder.set_torque(wave(k, 7));
    encoder.step();
    for (int i = 0; i < 7; ++i) {
      const double counts = encoder.q()[i] / 1e-4;
      ASSERT_LT(std::abs(counts - std::round(counts)), 1e-6);
      ASSERT_LE(std::abs(encoder.q()[i] - encoder.true_q()[i]), 0.5e-4 * (1 + 1e-9));
    }
  }
}

// The joint torque sensors (Simulation::measured_torque()) are read like the joints: as old as
// the measurement delay, bit for bit the nominal twin's reading of that many steps before, with
// white noise of torque_sensor_noise (7 x 3000 draws: standard deviation within 4 %, mean within
// 5 standard errors) from a generator of their own, which leaves the other readings' noise as it
// was.
TEST(Plant, TheJointTorqueSensorsAreReadLikeTheJoints) {
  sim::PlantOptions late;
  late.measurement_delay = 0.003;
  sim::Simulation delayed = panda_with(late);
  sim::Simulation nominal = panda_with({});
  std::vector<JointVector> history{nominal.measured_torque()};
  EXPECT_EQ(delayed.measured_torque(), nominal.measured_torque());
  for (int k = 1; k <= 300; ++k) {
    delayed.set_torque(wave(k, 7));
    nominal.set_torque(wave(k, 7));
    delayed.step();
    nominal.step();
    history.push_back(nominal.measured_torque());
    ASSERT_EQ(delayed.measured_torque(), history[static_cast<std::size_t>(std::max(0, k - 3))])
        << "step " << k;
  }
  EXPECT_GT((history.back() - history[history.size() - 4]).norm(), 1e-3);  // it changed

  sim::PlantOptions noisy;
  noisy.velocity_noise = 0.005;
  sim::PlantOptions sensed = noisy;
  sensed.torque_sensor_noise = 0.05;
  sim::Simulation quiet = panda_with(noisy);
  sim::Simulation loud = panda_with(sensed);
  double sum = 0.0, squares = 0.0;
  std::vector<double> errors;
  for (int k = 0; k < 3000; ++k) {
    quiet.set_torque(wave(k, 7));
    loud.set_torque(wave(k, 7));
    quiet.step();
    loud.step();
    ASSERT_EQ(loud.dq(), quiet.dq()) << "step " << k;
    for (int i = 0; i < 7; ++i) {
      errors.push_back(loud.measured_torque()[i] - quiet.measured_torque()[i]);
      sum += errors.back();
    }
  }
  const double count = static_cast<double>(errors.size());
  const double mean = sum / count;
  for (const double e : errors) squares += (e - mean) * (e - mean);
  EXPECT_NEAR(std::sqrt(squares / (count - 1.0)), 0.05, 0.04 * 0.05);
  EXPECT_LT(std::abs(mean), 5.0 * 0.05 / std::sqrt(count));
}

// Each joint's friction, damping and armature scaled by a factor within its range, drawn from
// the seed (another seed, other factors).
TEST(Plant, JointParametersAreDrawnWithinTheirRanges) {
  const sim::Simulation nominal = panda_with({});
  sim::PlantOptions plant = sim::PlantOptions::realistic(3);
  const sim::Simulation drawn = panda_with(plant);
  plant.seed = 4;
  const sim::Simulation other = panda_with(plant);
  auto expect_within = [](const JointVector& value, const JointVector& reference,
                          const sim::Spread& spread, const char* what) {
    const JointVector ratio = value.cwiseQuotient(reference);
    EXPECT_GE(ratio.minCoeff(), spread.low) << what;
    EXPECT_LE(ratio.maxCoeff(), spread.high) << what;
    EXPECT_GT(ratio.maxCoeff() - ratio.minCoeff(), 0.01 * (spread.high - spread.low)) << what;
  };
  expect_within(drawn.armature(), nominal.armature(), plant.armature, "armature");
  expect_within(drawn.joint_damping(), nominal.joint_damping(), plant.damping, "damping");
  expect_within(drawn.friction_loss(), nominal.friction_loss(), plant.friction, "friction");
  EXPECT_NE(drawn.armature(), other.armature());
}

TEST(Plant, AFieldOutOfRangeIsRefusedNamingItAndTheValue) {
  struct Case {
    void (*change)(sim::PlantOptions&);
    std::string expected;
  };
  const std::vector<Case> cases = {
      {[](sim::PlantOptions& p) {
         p.inertia = {1.2, 0.8};
       },
       "SimulationOptions.plant.inertia = [1.2, 0.8] is not a range within [0.1, 10]"},
      {[](sim::PlantOptions& p) {
         p.armature = {0.0, 1.0};
       },
       "SimulationOptions.plant.armature = [0, 1]"},
      {[](sim::PlantOptions& p) { p.measurement_delay = -0.001; },
       "SimulationOptions.plant.measurement_delay = -0.001 s is not within [0, 1]"},
      {[](sim::PlantOptions& p) { p.torque_noise = std::numeric_limits<double>::quiet_NaN(); },
       "SimulationOptions.plant.torque_noise = nan Nm"},
      {[](sim::PlantOptions& p) { p.torque_sensor_noise = -0.1; },
       "SimulationOptions.plant.torque_sensor_noise = -0.1 Nm is not within [0, 100]"},
      {[](sim::PlantOptions& p) { p.center_of_mass_offset = 0.5; },
       "SimulationOptions.plant.center_of_mass_offset = 0.5 m is not within [0, 0.1]"},
  };
  for (const Case& c : cases) {
    sim::PlantOptions plant;
    c.change(plant);
    try {
      panda_with(plant);
      ADD_FAILURE() << "accepted: " << c.expected;
    } catch (const ci::Error& error) {
      EXPECT_NE(std::string(error.what()).find(c.expected), std::string::npos) << error.what();
    }
  }
  try {
    sim::plant_from_name("noisy");
    ADD_FAILURE() << "plant 'noisy' accepted";
  } catch (const ci::Error& error) {
    EXPECT_EQ(std::string(error.what()), "plant 'noisy' is not known (valid: nominal, realistic)");
  }
}

#ifdef CARTESIAN_IMPEDANCE_COUNT_ALLOCATIONS
TEST(Plant, AStepOfTheRealisticPlantAllocatesNothing) {
  sim::Simulation s = panda_with(sim::PlantOptions::realistic());
  for (int k = 0; k < 10; ++k) s.step();
  allocation_counter::Scope scope;
  for (int k = 0; k < 2000; ++k) {
    s.set_torque(wave(k, 7));
    s.step();
  }
  EXPECT_EQ(scope.allocations(), 0);
  EXPECT_NE(s.q(), s.true_q());
}
#endif
