#pragma once
// Wrappers that own what Python needs beside the library object, shared by the binding files.

#include <pybind11/pybind11.h>

#include <atomic>
#include <stdexcept>
#include <string>
#include <utility>

#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/model/robot_model.hpp"

namespace cartesian_impedance::python {

namespace py = pybind11;
namespace ci = cartesian_impedance;

/// Who uses an object from another thread with the GIL released (a run, a control thread, a
/// simulated driver), as a refusal names it; null while nobody does.
using Holder = std::atomic<const char*>;

/// Marks an object as in use by a call that has released the GIL, or by a C++ thread; other
/// threads then get a RuntimeError naming the holder instead of racing with it.
class Claim {
 public:
  /// The holder of the simulation's runs (Simulation.run(), BatchRunner.run()).
  static constexpr const char* kRuns = "Simulation.run() or BatchRunner.run()";

  Claim(Holder& holder, const std::string& what, const char* by = kRuns) : holder_(holder) {
    const char* current = nullptr;
    if (!holder_.compare_exchange_strong(current, by))
      throw std::runtime_error(what + in_use(current));
  }
  ~Claim() { holder_.store(nullptr); }
  Claim(const Claim&) = delete;
  Claim& operator=(const Claim&) = delete;

  /// " is in use by <by> in another thread"
  static std::string in_use(const char* by) {
    return std::string(" is in use by ") + by + " in another thread";
  }

 private:
  Holder& holder_;
};

inline void check_free(const Holder& holder, const char* what) {
  if (const char* by = holder.load())
    throw std::runtime_error(std::string(what) + Claim::in_use(by));
}

/// RobotModel plus a workspace for compute() from Python.
struct Model {
  explicit Model(ci::RobotModel loaded) : model(std::move(loaded)), workspace(model) {}
  ci::RobotModel model;
  ci::ModelWorkspace workspace;
};

/// ControlLoop plus the Python model object it was made from and the run() claim.
class Loop {
 public:
  Loop(py::object model_object, const ci::Parameters& parameters, ci::LoopCapacity capacity)
      : model_object(std::move(model_object)),
        loop(this->model_object.cast<Model&>().model, parameters, capacity) {}

  /// The loop for cycle-thread calls (start, step, state): refused while run() uses it.
  ci::ControlLoop& cycle() {
    check_free(running, "this ControlLoop");
    return loop;
  }

  py::object model_object;
  ci::ControlLoop loop;
  Holder running{nullptr};
};

}  // namespace cartesian_impedance::python
