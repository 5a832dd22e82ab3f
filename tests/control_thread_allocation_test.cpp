// The control thread allocates nothing per cycle: counted across every thread while it runs the
// robot cycle at 1 kHz (measurements arriving, then lost, then back; torques handed to an outbox),
// and while it runs a cycle of its own. Reading its timing statistics allocates nothing either.

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/runtime/control_thread.hpp"
#include "support/allocation_counter.hpp"
#include "support/robots.hpp"

namespace ci = cartesian_impedance;
namespace rt = cartesian_impedance::runtime;

TEST(ControlThreadAllocation, RobotCycleAllocatesNothing) {
  const ci::RobotModel model = robots::panda();
  ci::ControlLoop loop(model);
  rt::MeasurementBuffer measurements(7);
  rt::TorqueOutbox torques(7);
  rt::JointMeasurement measured;
  measured.q = robots::panda_ready();
  measured.dq = ci::JointVector::Zero(7);
  measurements.publish(measured);
  rt::ControlThreadOptions options;
  options.measurement_timeout = 0.02;
  rt::ControlThread thread(options);
  thread.start(loop, measurements, &torques);
  while (thread.statistics().cycles < 10) std::this_thread::sleep_for(std::chrono::milliseconds(1));

  // This thread plays the robot; sleeping and publishing allocate nothing either, nor does
  // reading the timing statistics.
  long allocations = 0;
  rt::ControlThreadStatistics window;
  rt::ControlThreadStatistics so_far;
  {
    allocation_counter::Scope scope;
    const rt::ControlThreadSnapshot begin = thread.snapshot();
    for (int k = 0; k < 300; ++k) {
      if (k < 100 || k >= 200) measurements.publish(measured);  // lost in between
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    window = thread.snapshot().since(begin);
    so_far = thread.statistics();
    allocations = scope.allocations();
  }
  thread.stop();
  const rt::ControlThreadStatistics statistics = thread.statistics();
  EXPECT_EQ(allocations, 0);
  // Cycles ran in the window that counted allocations (how many depends on the machine's load).
  EXPECT_GT(window.cycles, 0u);
  EXPECT_LE(window.cycles, so_far.cycles);
  EXPECT_GE(statistics.stale_episodes, 1u);  // the stale path was counted too
}
