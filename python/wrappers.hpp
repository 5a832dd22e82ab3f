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

/// Marks an object as in use by a call that has released the GIL; other threads then get a
/// RuntimeError instead of racing with it.
class Claim {
 public:
  Claim(std::atomic<bool>& flag, const std::string& what) : flag_(flag) {
    if (flag_.exchange(true)) throw std::runtime_error(what + kInUse);
  }
  ~Claim() { flag_.store(false); }
  Claim(const Claim&) = delete;
  Claim& operator=(const Claim&) = delete;

  static constexpr const char* kInUse =
      " is in use by Simulation.run() or BatchRunner.run() in another thread";

 private:
  std::atomic<bool>& flag_;
};

inline void check_free(const std::atomic<bool>& flag, const char* what) {
  if (flag.load()) throw std::runtime_error(std::string(what) + Claim::kInUse);
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
  std::atomic<bool> running{false};
};

}  // namespace cartesian_impedance::python
