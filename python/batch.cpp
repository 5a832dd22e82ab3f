// Python bindings of the batch runner: cartesian_impedance.sim.BatchRunner and run_many(), which
// advance many independent (Simulation, ControlLoop) pairs in C++ threads with the GIL released.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/sim/batch_runner.hpp"
#include "conversions.hpp"
#include "simulation.hpp"
#include "wrappers.hpp"

namespace cartesian_impedance::python {

// Argument types: a sequence of each, checked element by element below (named in the signature
// pybind11 writes, and so in the stubs).
class Simulations : public py::object {
 public:
  using py::object::object;
  static bool check_(py::handle) { return true; }
};
class ControlLoops : public py::object {
 public:
  using py::object::object;
  static bool check_(py::handle) { return true; }
};

}  // namespace cartesian_impedance::python

namespace pybind11::detail {
template <>
struct handle_type_name<cartesian_impedance::python::Simulations> {
  static constexpr auto name = const_name("Sequence[Simulation]");
};
template <>
struct handle_type_name<cartesian_impedance::python::ControlLoops> {
  static constexpr auto name = const_name("Sequence[cartesian_impedance.ControlLoop]");
};
}  // namespace pybind11::detail

namespace cartesian_impedance::python {

namespace {

// BatchRunner.run() takes the GIL back this often [s] to let Ctrl+C (KeyboardInterrupt) through.
constexpr double kSignalCheckInterval = 0.1;

// The elements of a list or tuple of T, each checked: TypeError naming `name[i]`.
template <typename T>
std::vector<py::object> elements(py::handle sequence, const char* name, const char* type_name) {
  if (!py::isinstance<py::list>(sequence) && !py::isinstance<py::tuple>(sequence)) {
    throw py::type_error(std::string(name) + " must be a list or tuple of " + type_name + ", got " +
                         std::string(py::str(py::type::of(sequence).attr("__name__"))));
  }
  std::vector<py::object> items;
  for (py::handle item : sequence) {
    if (!py::isinstance<T>(item)) {
      throw py::type_error(std::string(name) + "[" + std::to_string(items.size()) + "] must be a " +
                           type_name + ", got " +
                           std::string(py::str(py::type::of(item).attr("__name__"))));
    }
    items.push_back(py::reinterpret_borrow<py::object>(item));
  }
  return items;
}

py::tuple tuple_of(const std::vector<py::object>& items) {
  py::tuple tuple(items.size());
  for (std::size_t i = 0; i < items.size(); ++i) tuple[i] = items[i];
  return tuple;
}

/// The C++ BatchRunner plus the Python objects it runs (kept alive) and the claims of a run.
class Batch {
 public:
  Batch(py::handle simulations, py::handle loops, int threads, std::chrono::microseconds spin)
      : simulations_(elements<Sim>(simulations, "sims", "cartesian_impedance.sim.Simulation")),
        loops_(elements<Loop>(loops, "loops", "cartesian_impedance.ControlLoop")) {
    if (simulations_.size() != loops_.size()) {
      throw ci::Error("sims has " + std::to_string(simulations_.size()) +
                      " entries but loops has " + std::to_string(loops_.size()) +
                      "; give one control loop per simulation");
    }
    std::vector<ci::sim::BatchPair> pairs;
    for (std::size_t i = 0; i < simulations_.size(); ++i) {
      // Refused while another thread runs one of them (its joint names are read here).
      pairs.push_back({&simulations_[i].cast<Sim&>().get(), &loops_[i].cast<Loop&>().cycle()});
    }
    batch_ = std::make_unique<ci::sim::BatchRunner>(pairs, threads, spin);
  }

  Batch(const Batch&) = delete;
  Batch& operator=(const Batch&) = delete;

  ~Batch() {
    // A forked process holds a copy of this runner but none of its pool's threads (fork copies
    // only the calling thread): joining them would wait forever, and a pool thread may have
    // held the runner's mutex at the fork. The copy is left to the process's exit.
    if (::getpid() != process_) static_cast<void>(batch_.release());
  }

  py::array_t<std::int64_t> run(Real seconds_object) {
    if (::getpid() != process_) {
      throw ci::Error("this BatchRunner was made in process " + std::to_string(process_) +
                      " and its threads do not exist in this forked process " +
                      std::to_string(::getpid()) + ": make a new BatchRunner here");
    }
    const double seconds = read_scalar(seconds_object, "seconds");
    if (!(seconds >= 0.0) || !std::isfinite(seconds)) {
      throw ci::Error("seconds = " + ci::format_number(seconds) + " must be finite and >= 0");
    }
    Claim batch_claim(running_, "this BatchRunner");
    // Each simulation and loop is claimed for the run: another thread touching one gets a
    // RuntimeError instead of racing with the pool. A refusal releases what was claimed.
    std::vector<std::unique_ptr<Claim>> claims;
    for (std::size_t i = 0; i < simulations_.size(); ++i) {
      claims.push_back(std::make_unique<Claim>(simulations_[i].cast<Sim&>().running,
                                               "sims[" + std::to_string(i) + "]"));
      claims.push_back(std::make_unique<Claim>(loops_[i].cast<Loop&>().running,
                                               "loops[" + std::to_string(i) + "]"));
    }
    const std::vector<std::int64_t>* done = nullptr;
    {
      py::gil_scoped_release release;
      done = &batch_->run_for(
          seconds,
          [] {
            py::gil_scoped_acquire acquire;
            if (PyErr_CheckSignals() != 0) throw py::error_already_set();
          },
          kSignalCheckInterval);
    }
    py::array_t<std::int64_t> steps(static_cast<py::ssize_t>(done->size()));
    for (std::size_t i = 0; i < done->size(); ++i) {
      steps.mutable_at(static_cast<py::ssize_t>(i)) = (*done)[i];
    }
    return steps;
  }

  std::size_t size() const { return simulations_.size(); }
  int threads() const { return batch_->threads(); }
  std::chrono::microseconds spin() const { return batch_->spin(); }
  py::tuple simulations() const { return tuple_of(simulations_); }
  py::tuple loops() const { return tuple_of(loops_); }
  bool running() const { return running_.load() != nullptr; }

 private:
  std::vector<py::object> simulations_;
  std::vector<py::object> loops_;
  std::unique_ptr<ci::sim::BatchRunner> batch_;
  Holder running_{nullptr};
  const pid_t process_ = ::getpid();  // where the pool's threads run
};

}  // namespace

void bind_batch(py::module_& sim) {
  const char* pairs_doc =
      "sims: Simulation objects, loops: ControlLoop objects, one per simulation; pair i is "
      "(sims[i], loops[i]): the loop drives every joint of its simulation (model.joint_names = "
      "sim.joint_names, in that order). No simulation or loop may appear twice. threads: how many "
      "C++ threads run the pairs (the calling one among them), at most one per pair; 0 = one per "
      "core.";
  const char* run_doc =
      "Advances every pair by `seconds` of simulated time (round(seconds / timestep) steps of "
      "its own simulation), in C++ threads with the GIL released: each pair ends exactly "
      "(bit for bit) where sim.run(loop, seconds) would take it alone. Each loop must be "
      "started. Returns the steps each pair ran (int64 array, one per pair). Errors name the "
      "pair (e.g. 'pair 3: the control loop has not been started ...') and then nothing runs. "
      "Meanwhile the simulations and the loops' start/step/state raise RuntimeError in other "
      "threads; commands to the loops are fine from any thread. Ctrl+C stops every pair and "
      "raises KeyboardInterrupt (checked every 0.1 s). In a process forked after the runner was "
      "made (its threads stay in the parent) it raises Error: make a new one there.";

  py::class_<Batch>(sim, "BatchRunner",
                    (std::string("Many independent closed loops (Simulation, ControlLoop) run "
                                 "together on a pool of C++ threads that lives as long as the "
                                 "runner: for batches of rollouts or environments. ") +
                     pairs_doc)
                        .c_str())
      .def(py::init([](Simulations sims, ControlLoops loops, int threads, Real spin_object) {
             const double spin = read_scalar(spin_object, "spin");
             const double max_spin = 1e-6 * double(ci::sim::BatchRunner::kMaxSpin.count());
             if (!(spin >= 0.0 && spin <= max_spin)) {
               throw ci::Error("spin = " + ci::format_number(spin) + " s is outside [0, " +
                               ci::format_number(max_spin) + "] s");
             }
             return std::make_unique<Batch>(sims, loops, threads,
                                            std::chrono::microseconds(std::llround(spin * 1e6)));
           }),
           py::arg("sims"), py::arg("loops"), py::arg("threads") = 0,
           py::arg("spin") = 1e-6 * double(ci::sim::BatchRunner::kDefaultSpin.count()),
           "Raises Error naming the pair whose loop does not fit its simulation, or that repeats "
           "a simulation or loop; TypeError for an element that is not a Simulation or "
           "ControlLoop. spin [s]: after a run, each pool thread looks for the next one this "
           "long before it sleeps (yielding its core to anyone who wants it): a learning loop's "
           "next run then starts without a thread wake-up, which takes up to 0.5 ms on a VM; 0 "
           "sleeps at once and uses no CPU between runs (for processes that share their cores). "
           "At most 1 s.")
      .def_property_readonly(
          "spin", [](const Batch& batch) { return 1e-6 * double(batch.spin().count()); },
          "[s] how long a pool thread spins after a run before it sleeps.")
      .def("run", &Batch::run, py::arg("seconds"), run_doc)
      .def_property_readonly(
          "threads", &Batch::threads,
          "Threads that run the pairs: the caller's and threads - 1 of the pool.")
      .def_property_readonly("sims", &Batch::simulations, "The simulations, in the pairs' order.")
      .def_property_readonly("loops", &Batch::loops, "The control loops, in the pairs' order.")
      .def("__len__", &Batch::size, "Number of pairs.")
      .def("__repr__", [](const Batch& batch) {
        return "BatchRunner(" + std::to_string(batch.size()) + " pairs, " +
               std::to_string(batch.threads()) + " threads" +
               (batch.running() ? ", running)" : ")");
      });

  sim.def(
      "run_many",
      [](Simulations sims, ControlLoops loops, Real seconds, int threads) {
        // The pool's threads spin from their start, so they take this run without a wake-up.
        Batch batch(sims, loops, threads, ci::sim::BatchRunner::kDefaultSpin);
        return batch.run(seconds);
      },
      py::arg("sims"), py::arg("loops"), py::arg("seconds"), py::arg("threads") = 0,
      (std::string("BatchRunner(sims, loops, threads).run(seconds) in one call: its threads are "
                   "started and ended by this call (a BatchRunner kept for many runs saves "
                   "that). ") +
       pairs_doc + " " + run_doc)
          .c_str());
}

}  // namespace cartesian_impedance::python
