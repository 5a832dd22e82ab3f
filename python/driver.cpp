// Python bindings of the simulated robot driver: SimulatedDriver and DriverState in the submodule
// cartesian_impedance.sim. The driver is a C++ thread that steps a Simulation in real time and
// exchanges joint states and torques with a runtime.ControlThread through a MeasurementBuffer and
// a TorqueOutbox, as a robot's driver does.
//
// Lifetimes: the C++ driver references the simulation, the buffer and the outbox from its
// construction; the Python SimulatedDriver holds references to their Python objects as long as it
// lives, and claims them (the simulation, the buffer's writing, the outbox's consuming) while it
// runs, so other threads get a RuntimeError instead of racing with it.

#include <pybind11/pybind11.h>

#include <memory>
#include <optional>
#include <string>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/runtime/control_thread.hpp"
#include "cartesian_impedance/sim/simulated_driver.hpp"
#include "conversions.hpp"
#include "runtime.hpp"
#include "simulation.hpp"
#include "wrappers.hpp"

namespace cartesian_impedance::python {

namespace {

// A simulated driver and what Python must keep alive and claim for it. Members are destroyed in
// reverse order: the driver is stopped first, then the claims released, then the references
// dropped.
class Driver {
 public:
  Driver(Sim& simulation, Measurements& measurements, Outbox& torques,
         const ci::sim::SimulatedDriverOptions& options)
      : simulation_object_(py::cast(&simulation, py::return_value_policy::reference)),
        measurements_object_(py::cast(&measurements, py::return_value_policy::reference)),
        torques_object_(py::cast(&torques, py::return_value_policy::reference)),
        simulation_(simulation),
        measurements_(measurements),
        torques_(torques),
        driver(simulation.get(), measurements.buffer, torques.outbox, options) {}

  void start() {
    if (driver.running())
      throw ci::Error("the simulated driver is already running: stop() it first");
    try {
      simulation_claim_.emplace(simulation_.running, "this Simulation", kSimulatedDriverHolder);
      writer_claim_.emplace(measurements_.writer, "this MeasurementBuffer", kSimulatedDriverHolder);
      consumer_claim_.emplace(torques_.consumer, "this TorqueOutbox", kSimulatedDriverHolder);
      driver.start();
    } catch (...) {
      release();
      throw;
    }
  }

  void stop() {
    {
      py::gil_scoped_release release;
      driver.stop();
    }
    release();
  }

 private:
  void release() {
    consumer_claim_.reset();
    writer_claim_.reset();
    simulation_claim_.reset();
  }

  py::object simulation_object_, measurements_object_, torques_object_;
  Sim& simulation_;
  Measurements& measurements_;
  Outbox& torques_;
  std::optional<Claim> simulation_claim_, writer_claim_, consumer_claim_;

 public:
  ci::sim::SimulatedDriver driver;  // last: stopped before the claims and references go
};

}  // namespace

void bind_simulated_driver(py::module_& sim) {
  using State = ci::sim::SimulatedDriverState;
  py::class_<State>(sim, "DriverState",
                    "The simulated arm and the driver's counters as of its latest tick.")
      .def_readonly("time", &State::time, "[s] simulated time")
      .def_property_readonly(
          "q", [](const State& s) { return vector_array(s.q); }, "Joint positions (n,) [rad].")
      .def_property_readonly(
          "dq", [](const State& s) { return vector_array(s.dq); }, "Joint velocities (n,) [rad/s].")
      .def_property_readonly(
          "tau", [](const State& s) { return vector_array(s.tau); },
          "The commanded torque applied in the tick (n,) [Nm], after the actuators' clipping and "
          "without the simulated firmware's gravity compensation; zero while held.")
      .def_readonly("held", &State::held,
                    "The arm is held (not stepped): before the first torque, and braked after a "
                    "torque timeout.")
      .def_readonly("ticks", &State::ticks, "ticks since start()")
      .def_readonly("late_ticks", &State::late_ticks,
                    "ticks that ended after the next tick's deadline")
      .def_readonly("steps", &State::steps, "simulation steps since start() (ticks not held)")
      .def_readonly("torques", &State::torques, "new torques taken from the outbox")
      .def_readonly("torque_cycle", &State::torque_cycle,
                    "the loop cycle of the newest torque taken")
      .def_readonly("torque_timeouts", &State::torque_timeouts,
                    "times the arm was braked because torques stopped")
      .def_readonly("rejected_torques", &State::rejected_torques,
                    "torques not applied: wrong size or not finite")
      .def_readonly("measurements", &State::measurements, "measurements published")
      .def_readonly("measurements_paused", &State::measurements_paused,
                    "the latest tick published no measurement (pause_measurements())")
      .def_property_readonly(
          "contact_wrench", [](const State& s) { return vector_array(s.contact_wrench); },
          "(6,) [N; Nm] what touches the driver's contact_body and the bodies beyond it, world "
          "frame, torque about the body's origin; zero without a contact body.")
      .def("__repr__", [](const State& s) {
        return "DriverState(time=" + ci::format_number(s.time) +
               " s, held=" + (s.held ? "True" : "False") + ", ticks=" + std::to_string(s.ticks) +
               ", late_ticks=" + std::to_string(s.late_ticks) +
               ", steps=" + std::to_string(s.steps) + ", torques=" + std::to_string(s.torques) +
               ", torque_timeouts=" + std::to_string(s.torque_timeouts) + ")";
      });

  const ci::sim::SimulatedDriverOptions defaults;
  py::class_<Driver>(
      sim, "SimulatedDriver",
      "A stand-in for a robot's driver: a C++ thread that steps the simulation in real time, one "
      "timestep per tick on absolute deadlines, applying the newest torque of a "
      "runtime.TorqueOutbox and publishing the measured q and dq to a runtime.MeasurementBuffer, "
      "for a runtime.ControlThread. Like a Panda on FCI, the arm is held (not stepped) until "
      "the first torque, a tick without a new torque applies the last one again, and after "
      "torque_timeout without one the arm is braked (velocity zeroed, not stepped) until torques "
      "return. While it runs the simulation is the driver's: read the arm with state(). A "
      "context manager: `with` stops it; so does dropping the last reference.")
      .def(py::init([](Sim& simulation, Measurements& measurements, Outbox& torques,
                       Real torque_timeout, int realtime_priority, std::string contact_body) {
             ci::sim::SimulatedDriverOptions options;
             options.torque_timeout = read_scalar(torque_timeout, "torque_timeout");
             options.realtime_priority = realtime_priority;
             options.contact_body = std::move(contact_body);
             return std::make_unique<Driver>(simulation, measurements, torques, options);
           }),
           py::arg("simulation"), py::arg("measurements"), py::arg("torques"),
           py::arg("torque_timeout") = defaults.torque_timeout,
           py::arg("realtime_priority") = defaults.realtime_priority,
           py::arg("contact_body") = defaults.contact_body,
           "simulation: the arm (the control loop's model must have its joints, in its order); "
           "measurements, torques: the hand-offs given to ControlThread.start(), of the "
           "simulation's joint count; torque_timeout [s] in (0, 1e6]: after this long without a "
           "new torque the arm is braked (0.02: FCI's 20 lost packets at 1 kHz); "
           "realtime_priority: SCHED_FIFO priority, 0 = normal scheduling; contact_body: a body "
           "whose contact wrench each tick reports (DriverState.contact_wrench), '' for none. "
           "Each measurement is stamped with when it was taken (Simulation.measurement_age "
           "before the tick). All three objects are kept alive as long as the driver. Raises "
           "Error if the joint counts differ, an option is out of range or the simulation has no "
           "such body.")
      .def("start", &Driver::start,
           "Starts the thread: it publishes the current state at once, then ticks every "
           "timestep. Claims the simulation, the buffer's writing and the outbox's consuming "
           "until stop(). Raises Error if it runs already.")
      .def("stop", &Driver::stop,
           "Ends the thread after its current tick and joins it (with the GIL released); the "
           "simulation is then the caller's again, as the last tick left it.")
      .def_property_readonly(
          "running", [](const Driver& self) { return self.driver.running(); },
          "True from start() until stop().")
      .def(
          "pause_measurements",
          [](Driver& self, Real seconds) {
            self.driver.pause_measurements(read_scalar(seconds, "seconds"));
          },
          py::arg("seconds"),
          "Publishes no measurement for the next `seconds` [s] of wall-clock time (within [0, "
          "1e6]; 0 ends a pause) while the arm goes on moving, as a driver that lost its "
          "connection: the control thread's measurements go stale and it fails closed, and "
          "resumes when they return.")
      .def(
          "state", [](const Driver& self) { return self.driver.state(); },
          "The DriverState as of the latest tick (any thread, also while running).")
      .def(
          "statistics", [](const Driver& self) { return self.driver.statistics(); },
          "The ticks' timing since start(), a runtime.ControlThreadStatistics: cycles are ticks, "
          "overruns late ticks.")
      .def_property_readonly(
          "period", [](const Driver& self) { return self.driver.period(); },
          "[s] between ticks: the simulation's timestep.")
      .def_property_readonly(
          "torque_timeout", [](const Driver& self) { return self.driver.options().torque_timeout; },
          "[s]")
      .def("__enter__", [](py::object self) { return self; })
      .def(
          "__exit__",
          [](Driver& self, py::object, py::object, py::object) {
            self.stop();
            return false;
          },
          py::arg("exc_type"), py::arg("exc_value"), py::arg("traceback"), "Stops the driver.")
      .def("__repr__", [](const Driver& self) {
        const ci::sim::SimulatedDriverState state = self.driver.state();
        return std::string("SimulatedDriver(") + (self.driver.running() ? "running" : "stopped") +
               ", t = " + ci::format_number(state.time) + " s, " + std::to_string(state.ticks) +
               " ticks, " + (state.held ? "held" : "driven") + ")";
      });
}

}  // namespace cartesian_impedance::python
