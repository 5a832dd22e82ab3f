// The simulated robot driver with the runtime's control thread, as on a robot: the driver's
// thread steps the simulated Panda in real time and publishes its joint state, the control
// thread steps the loop from those measurements and hands the torque back. The arm holds its
// start pose under gravity, and the check fails for a controller that commands nothing or the
// opposite torque; a driver that stops publishing makes the control thread fail closed and
// resume; the arm is held before the first torque and braked when torques stop.

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <iostream>
#include <limits>
#include <string>
#include <thread>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "cartesian_impedance/runtime/control_thread.hpp"
#include "cartesian_impedance/runtime/robot_io.hpp"
#include "cartesian_impedance/sim/simulated_driver.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "support/robots.hpp"

#ifdef CARTESIAN_IMPEDANCE_COUNT_ALLOCATIONS
#include "support/allocation_counter.hpp"
#endif

namespace ci = cartesian_impedance;
namespace rt = cartesian_impedance::runtime;
namespace sim = cartesian_impedance::sim;
using ci::JointVector;

namespace {

const std::string kPandaMjcf =
    std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.xml";
constexpr const char* kFlange = "panda_link8";

// The Panda's simulation in the model's joint order; without the simulated firmware's gravity
// compensation the controller must hold the arm's weight itself (dynamics.gravity_compensation).
sim::Simulation panda_simulation(const ci::RobotModel& model, bool firmware_gravity) {
  sim::SimulationOptions options;
  options.joint_names = model.joint_names();
  options.gravity_compensation = firmware_gravity;
  return sim::Simulation::from_mjcf_file(kPandaMjcf, options);
}

ci::Parameters holding_parameters(const sim::Simulation& simulation, bool gravity) {
  ci::Parameters parameters;
  parameters.dynamics.gravity_compensation = gravity;
  parameters.dynamics.armature = simulation.armature();  // the controller's M(q) = the simulated
  return parameters;
}

// Hands the control thread's torque to the outbox times `factor`: 1 is the controller as it is,
// 0 a controller that commands nothing, -1 one with its sign flipped.
class ScaledSink final : public rt::TorqueSink {
 public:
  ScaledSink(rt::TorqueSink& next, double factor) : next_(next), factor_(factor) {}
  void write(const JointVector& tau, std::uint64_t cycle) noexcept override {
    scaled_ = factor_ * tau;
    next_.write(scaled_, cycle);
  }

 private:
  rt::TorqueSink& next_;
  double factor_;
  JointVector scaled_;
};

// Waits (polling, at most `wall_seconds`) until the driver has simulated `seconds`.
bool simulate_for(const sim::SimulatedDriver& driver, double seconds, double wall_seconds = 20.0) {
  const auto give_up = std::chrono::steady_clock::now() +
                       std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                           std::chrono::duration<double>(wall_seconds));
  while (driver.state().time < seconds) {
    if (std::chrono::steady_clock::now() > give_up) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

// The largest force at the flange [N] that the joints' Coulomb friction can hold at q: a spring
// pulling with less may leave the arm standing off its rest. The least-norm wrench with
// J^T F = tau (what the Cartesian spring must supply; the nullspace torque has no component
// there), over the corners of the friction box.
double friction_band_force(const ci::RobotModel& model, const JointVector& q,
                           const JointVector& friction) {
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  EXPECT_TRUE(workspace.compute(q, JointVector::Zero(q.size()), kinematics));
  const Eigen::MatrixXd map =
      Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(kinematics.jacobian.transpose())
          .pseudoInverse();
  const int n = static_cast<int>(friction.size());
  double band = 0.0;
  for (long corner = 0; corner < (1L << n); ++corner) {
    Eigen::VectorXd tau(n);
    for (int i = 0; i < n; ++i) tau[i] = (corner >> i & 1) ? friction[i] : -friction[i];
    band = std::max(band, (map * tau).head<3>().norm());
  }
  return band;
}

struct Hold {
  double displacement = 0.0;  ///< [m] of the flange after 1 s of simulated time
  double tolerance = 0.0;     ///< [m] friction band / stiffness
  sim::SimulatedDriverState driver;
  rt::ControlThreadStatistics control;
  ci::Status status = ci::Status::not_started;
};

// The Panda without firmware gravity compensation, driven by the simulated driver, its loop on
// the control thread with the torque times `factor`, for 1 s of simulated time.
Hold hold_for_one_second(double factor) {
  const ci::RobotModel model = robots::panda();
  sim::Simulation simulation = panda_simulation(model, /*firmware_gravity=*/false);
  const ci::Parameters parameters = holding_parameters(simulation, true);
  ci::ControlLoop loop(model, parameters);
  rt::MeasurementBuffer measurements(model.num_joints());
  rt::TorqueOutbox torques(model.num_joints());
  ScaledSink sink(torques, factor);
  rt::ControlThread control({1000.0, 0.1, 0});
  sim::SimulatedDriver driver(simulation, measurements, torques);

  Hold hold;
  const Eigen::Vector3d start = simulation.body_pose(kFlange).position;
  hold.tolerance = friction_band_force(model, simulation.q(), simulation.friction_loss()) /
                   parameters.stiffness.translation.minCoeff();
  control.start(loop, measurements, &sink);
  driver.start();
  const bool simulated = simulate_for(driver, 1.0);
  driver.stop();
  control.stop();
  EXPECT_TRUE(simulated) << "the driver did not simulate 1 s within 20 s";
  hold.displacement = (simulation.body_pose(kFlange).position - start).norm();
  hold.driver = driver.state();
  hold.control = control.statistics();
  hold.status = loop.latest_state().controller.status;
  return hold;
}

}  // namespace

TEST(SimulatedDriver, WithTheControlThreadHoldsThePandaAtItsStartPoseUnderGravity) {
  const Hold hold = hold_for_one_second(1.0);
  // Released at rest where the spring is relaxed, the arm could settle off it only by what the
  // joints' friction holds against the spring (about 0.6 mm here); g(q) is the simulated one.
  EXPECT_LT(hold.displacement, hold.tolerance);
  EXPECT_EQ(hold.status, ci::Status::ok);
  // The arm was stepped by the driver and the torques came from the control thread's loop.
  EXPECT_GE(hold.driver.steps, 1000u);
  EXPECT_GE(hold.driver.ticks, hold.driver.steps);
  EXPECT_GT(hold.driver.torques, 0u);
  EXPECT_GT(hold.control.cycles, 0u);
  EXPECT_EQ(hold.driver.rejected_torques, 0u);
  EXPECT_FALSE(hold.driver.held);
  std::cout << "held within " << 1e3 * hold.displacement << " mm (tolerance "
            << 1e3 * hold.tolerance << " mm); driver: " << hold.driver.ticks << " ticks, "
            << hold.driver.late_ticks << " late, " << hold.driver.torques
            << " torques; control thread: " << hold.control.cycles << " cycles, "
            << hold.control.overruns << " overruns\n";
}

TEST(SimulatedDriver, TheHoldCheckFailsForAControllerThatCommandsNothingOrTheOppositeTorque) {
  for (double factor : {0.0, -1.0}) {
    SCOPED_TRACE("torque times " + std::to_string(factor));
    const Hold hold = hold_for_one_second(factor);
    // Unsupported, the arm falls by decimetres within the second.
    EXPECT_GT(hold.displacement, hold.tolerance);
    EXPECT_GT(hold.displacement, 0.05);
    std::cout << "torque times " << factor << ": the flange moved " << 1e3 * hold.displacement
              << " mm\n";
  }
}

TEST(SimulatedDriver, StoppedMeasurementsFailTheControlThreadClosedAndItResumes) {
  const ci::RobotModel model = robots::panda();
  sim::Simulation simulation = panda_simulation(model, /*firmware_gravity=*/true);
  ci::ControlLoop loop(model, holding_parameters(simulation, false));
  rt::MeasurementBuffer measurements(model.num_joints());
  rt::TorqueOutbox torques(model.num_joints());
  rt::ControlThread control({1000.0, /*measurement_timeout [s]*/ 0.02, 0});
  sim::SimulatedDriver driver(simulation, measurements, torques);
  control.start(loop, measurements, &torques);
  driver.start();
  ASSERT_TRUE(simulate_for(driver, 0.1));
  EXPECT_EQ(control.statistics().stale_episodes, 0u);

  driver.pause_measurements(0.3);
  // Within the pause, once the timeout has passed, the cycle runs on an invalid measurement.
  bool failed_closed = false;
  for (int i = 0; i < 200 && !failed_closed; ++i) {
    failed_closed = loop.latest_state().controller.status == ci::Status::invalid_robot_state;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_TRUE(failed_closed);
  EXPECT_TRUE(driver.state().measurements_paused);
  const double paused_at = driver.state().time;
  // The arm goes on moving (here: held by the firmware's gravity compensation) meanwhile.
  ASSERT_TRUE(simulate_for(driver, paused_at + 0.5));
  driver.stop();
  control.stop();

  EXPECT_EQ(control.statistics().stale_episodes, 1u);
  EXPECT_FALSE(control.statistics().stale);
  EXPECT_FALSE(driver.state().measurements_paused);
  EXPECT_EQ(loop.latest_state().controller.status, ci::Status::ok);
}

TEST(SimulatedDriver, HoldsTheArmBeforeTheFirstTorqueAndBrakesItWhenTorquesStop) {
  const ci::RobotModel model = robots::panda();
  // Without firmware gravity compensation: an arm that were stepped without torque would fall.
  sim::Simulation simulation = panda_simulation(model, /*firmware_gravity=*/false);
  const JointVector start = simulation.q();
  rt::MeasurementBuffer measurements(model.num_joints());
  rt::TorqueOutbox torques(model.num_joints());
  sim::SimulatedDriverOptions options;
  options.torque_timeout = 0.01;
  sim::SimulatedDriver driver(simulation, measurements, torques, options);
  driver.start();
  EXPECT_TRUE(driver.running());
  EXPECT_THROW(driver.start(), ci::Error);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  sim::SimulatedDriverState state = driver.state();
  EXPECT_TRUE(state.held);
  EXPECT_GT(state.ticks, 0u);
  EXPECT_EQ(state.steps, 0u);
  EXPECT_EQ(state.time, 0.0);
  EXPECT_EQ(state.q, start);
  rt::JointMeasurement measured;
  measurements.read(measured);
  EXPECT_GT(measured.sequence, 0u);  // published all the same, for the control thread to start
  EXPECT_EQ(measured.q, start);

  // One torque (zero: the arm starts to fall), then none: after the timeout the brakes hold it.
  torques.write(JointVector::Zero(7), 1);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  state = driver.state();
  EXPECT_TRUE(state.held);
  EXPECT_EQ(state.torques, 1u);
  EXPECT_EQ(state.torque_cycle, 1u);
  EXPECT_EQ(state.torque_timeouts, 1u);
  EXPECT_GT(state.steps, 0u);
  EXPECT_EQ(state.dq, JointVector::Zero(7));
  const std::uint64_t braked_at = state.steps;
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  EXPECT_EQ(driver.state().steps, braked_at);

  // A torque the drive refuses is not applied and does not release the brakes.
  torques.write(JointVector::Constant(7, std::numeric_limits<double>::quiet_NaN()), 2);
  std::this_thread::sleep_for(std::chrono::milliseconds(30));
  driver.stop();
  EXPECT_FALSE(driver.running());
  state = driver.state();
  EXPECT_EQ(state.rejected_torques, 1u);
  EXPECT_TRUE(state.held);
  EXPECT_EQ(state.steps, braked_at);
  EXPECT_EQ(simulation.q(), state.q);  // stopped: the simulation is the caller's again
}

// Each reading is stamped with when it was taken: the plant's sensing delay before the tick that
// published it. The flange's contact wrench is reported, zero in free space.
TEST(SimulatedDriver, StampsEachReadingWhenItWasTakenAndReportsTheFlangesContact) {
  const ci::RobotModel model = robots::panda();
  for (const bool realistic : {false, true}) {
    SCOPED_TRACE(realistic ? "realistic plant" : "nominal plant");
    sim::SimulationOptions options;
    options.joint_names = model.joint_names();
    if (realistic) options.plant = sim::PlantOptions::realistic();
    sim::Simulation simulation = sim::Simulation::from_mjcf_file(kPandaMjcf, options);
    EXPECT_EQ(simulation.measurement_age(), realistic ? 0.001 : 0.0);
    rt::MeasurementBuffer measurements(7);
    rt::TorqueOutbox torques(7);
    sim::SimulatedDriverOptions driver_options;
    driver_options.contact_body = kFlange;
    driver_options.torque_timeout = 10.0;  // one torque drives it for the whole test
    sim::SimulatedDriver driver(simulation, measurements, torques, driver_options);
    driver.start();
    torques.write(JointVector::Zero(7), 1);
    ASSERT_TRUE(simulate_for(driver, 0.02));
    rt::JointMeasurement measured;
    measurements.read(measured);
    const sim::SimulatedDriverState state = driver.state();
    driver.stop();
    // Published within the tick that read it: its age at publication is the sensing delay and
    // the tick's step (tens of microseconds; 5 ms for a loaded machine's preemption).
    const double age = std::chrono::duration<double>(measured.received - measured.sampled).count();
    EXPECT_GE(age, simulation.measurement_age());
    EXPECT_LT(age, simulation.measurement_age() + 0.005);
    EXPECT_EQ(state.contact_wrench, ci::Vector6d::Zero());
  }
  sim::Simulation simulation = panda_simulation(model, true);
  rt::MeasurementBuffer measurements(7);
  rt::TorqueOutbox torques(7);
  sim::SimulatedDriverOptions options;
  options.contact_body = "gripper";
  try {
    sim::SimulatedDriver driver(simulation, measurements, torques, options);
    FAIL() << "a contact body the simulation does not have was accepted";
  } catch (const ci::Error& error) {
    EXPECT_NE(std::string(error.what()).find("body 'gripper' not found"), std::string::npos)
        << error.what();
  }
}

TEST(SimulatedDriver, RejectsMismatchedJointCountsAndOptionsOutOfRange) {
  const ci::RobotModel model = robots::panda();
  sim::Simulation simulation = panda_simulation(model, true);
  rt::MeasurementBuffer measurements(7), six(6);
  rt::TorqueOutbox torques(7), six_torques(6);
  try {
    sim::SimulatedDriver driver(simulation, six, torques);
    FAIL() << "a buffer of 6 joints for 7 was accepted";
  } catch (const ci::Error& error) {
    EXPECT_NE(std::string(error.what())
                  .find("the simulation has 7 joints, the measurement buffer "
                        "6 and the torque outbox 7"),
              std::string::npos)
        << error.what();
  }
  EXPECT_THROW(sim::SimulatedDriver(simulation, measurements, six_torques), ci::Error);
  for (double timeout : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(), 2e6}) {
    sim::SimulatedDriverOptions options;
    options.torque_timeout = timeout;
    try {
      sim::SimulatedDriver driver(simulation, measurements, torques, options);
      FAIL() << "torque_timeout " << timeout << " was accepted";
    } catch (const ci::Error& error) {
      EXPECT_EQ(std::string(error.what()),
                "simulated driver: torque_timeout = " + ci::format_number(timeout) +
                    " s is outside (0, 1000000]");
      EXPECT_STREQ(error.fault().input, "torque_timeout");
    }
  }
  sim::SimulatedDriver driver(simulation, measurements, torques);
  EXPECT_THROW(driver.pause_measurements(-0.1), ci::Error);
  EXPECT_THROW(driver.pause_measurements(std::numeric_limits<double>::infinity()), ci::Error);
  driver.pause_measurements(0.0);
}

#ifdef CARTESIAN_IMPEDANCE_COUNT_ALLOCATIONS
TEST(SimulatedDriver, TicksAllocateNothingWhileDrivingPausedAndBraked) {
  const ci::RobotModel model = robots::panda();
  sim::Simulation simulation = panda_simulation(model, true);
  ci::ControlLoop loop(model, holding_parameters(simulation, false));
  rt::MeasurementBuffer measurements(model.num_joints());
  rt::TorqueOutbox torques(model.num_joints());
  rt::ControlThread control({1000.0, 0.02, 0});
  sim::SimulatedDriverOptions options;
  options.contact_body = kFlange;  // its contact wrench each tick, too
  sim::SimulatedDriver driver(simulation, measurements, torques, options);
  control.start(loop, measurements, &torques);
  driver.start();
  ASSERT_TRUE(simulate_for(driver, 0.05));
  long allocations = 0;
  sim::SimulatedDriverState state;
  {
    allocation_counter::Scope scope;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));  // driven
    driver.pause_measurements(0.1);  // the control thread fails closed, the driver goes on
    std::this_thread::sleep_for(std::chrono::milliseconds(150));
    control.stop();  // torques stop: the driver brakes
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    state = driver.state();
    allocations = scope.allocations();
  }
  driver.stop();
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(state.torque_timeouts, 1u);
  EXPECT_TRUE(state.held);
  EXPECT_GE(control.statistics().stale_episodes, 1u);
}
#endif
