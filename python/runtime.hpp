#pragma once
// What the runtime's binding files share (runtime.cpp: the submodule runtime; driver.cpp: the
// simulation's SimulatedDriver): the hand-offs between a driver and the control thread, with the
// claims of their one writer and one consumer.

#include "cartesian_impedance/runtime/robot_io.hpp"
#include "wrappers.hpp"

namespace cartesian_impedance::python {

/// The holders that the runtime's threads claim objects for.
inline constexpr const char* kControlThreadHolder = "a runtime.ControlThread";
inline constexpr const char* kSimulatedDriverHolder = "a sim.SimulatedDriver";

/// MeasurementBuffer plus the claim of its one writer while a SimulatedDriver runs (publish()
/// from Python is refused meanwhile).
struct Measurements {
  explicit Measurements(int num_joints) : buffer(num_joints) {}
  ci::runtime::MeasurementBuffer buffer;
  Holder writer{nullptr};
};

/// TorqueOutbox plus the claims of its one writer (a ControlThread while it runs) and its one
/// consumer (a SimulatedDriver while it runs, or a wait() in progress).
struct Outbox {
  explicit Outbox(int num_joints) : outbox(num_joints) {}
  ci::runtime::TorqueOutbox outbox;
  Holder writer{nullptr};
  Holder consumer{nullptr};
};

}  // namespace cartesian_impedance::python
