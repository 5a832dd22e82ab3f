#pragma once
// What the simulation's binding files share (simulation.cpp: the submodule sim; batch.cpp: its
// BatchRunner and run_many).

#include <pybind11/pybind11.h>

#include <atomic>
#include <utility>

#include "cartesian_impedance/sim/simulation.hpp"
#include "wrappers.hpp"

namespace cartesian_impedance::python {

/// Simulation plus the claim of a run (Simulation.run(), BatchRunner.run()).
struct Sim {
  explicit Sim(ci::sim::Simulation loaded) : sim(std::move(loaded)) {}
  ci::sim::Simulation& get() {
    check_free(running, "this Simulation");
    return sim;
  }
  ci::sim::Simulation sim;
  Holder running{nullptr};
};

/// BatchRunner and run_many() in the submodule sim (batch.cpp); after Simulation.
void bind_batch(py::module_& sim);
/// SimulatedDriver and DriverState in the submodule sim (driver.cpp); after Simulation and the
/// submodule runtime.
void bind_simulated_driver(py::module_& sim);

}  // namespace cartesian_impedance::python
