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
  std::atomic<bool> running{false};
};

/// BatchRunner and run_many() in the submodule sim (batch.cpp); after Simulation.
void bind_batch(py::module_& sim);

}  // namespace cartesian_impedance::python
