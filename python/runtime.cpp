// Python bindings of the runtime: the submodule cartesian_impedance.runtime (ControlThread,
// ControlThreadState, ControlThreadStatistics, MeasurementBuffer, JointMeasurement,
// TorqueOutbox). The control thread is a C++ thread: it runs without the GIL and never calls
// Python, so a policy in Python (at 20 Hz, say) cannot delay the 1 kHz cycle.
//
// Lifetimes: the C++ thread references the loop, the measurement buffer and the torque outbox;
// the Python ControlThread holds references to their Python objects from start() to stop(), so
// the garbage collector cannot free them while the thread runs. Dropping the last reference to a
// running ControlThread stops it.

#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/types.hpp"
#include "cartesian_impedance/runtime/control_thread.hpp"
#include "cartesian_impedance/runtime/robot_io.hpp"
#include "conversions.hpp"
#include "module.hpp"
#include "runtime.hpp"
#include "wrappers.hpp"

namespace cartesian_impedance::python {

namespace {

namespace rt = cartesian_impedance::runtime;

double seconds_of(std::chrono::steady_clock::time_point time) {
  return std::chrono::duration<double>(time.time_since_epoch()).count();
}

const char* state_name(rt::ControlThread::State state) {
  switch (state) {
    case rt::ControlThread::State::idle:
      return "idle";
    case rt::ControlThread::State::preparing:
      return "preparing";
    case rt::ControlThread::State::running:
      return "running";
    case rt::ControlThread::State::failed:
      return "failed";
    case rt::ControlThread::State::stopped:
      return "stopped";
  }
  return "unknown";
}

// A control thread and what Python must keep alive and claimed while it runs. Members are
// destroyed in reverse order: the thread is stopped first, then the claims are released, then the
// references dropped.
class Thread {
 public:
  explicit Thread(const rt::ControlThreadOptions& options) : thread(options) {}

  void start(Loop& loop, Measurements& measurements, Outbox* torques) {
    const rt::ControlThread::State state = thread.state();
    if (state == rt::ControlThread::State::preparing ||
        state == rt::ControlThread::State::running) {
      throw ci::Error("the control thread is already running: stop() it first");
    }
    thread.stop();  // joins a run that failed (it has ended)
    release();      // what a stopped or failed run held
    if (torques != nullptr && torques->outbox.num_joints() != loop.loop.num_joints()) {
      throw ci::Error("control thread: the torque outbox has " +
                      std::to_string(torques->outbox.num_joints()) + " joints, the control loop " +
                      std::to_string(loop.loop.num_joints()));
    }
    loop_claim_.emplace(loop.running, "this ControlLoop", kControlThreadHolder);
    try {
      if (torques != nullptr) {
        torques_claim_.emplace(torques->writer, "this TorqueOutbox", kControlThreadHolder);
      }
      thread.start(loop.loop, measurements.buffer, torques != nullptr ? &torques->outbox : nullptr);
    } catch (...) {
      release();
      throw;
    }
    // The Python objects these are the C++ parts of (pybind11 finds the registered instance).
    loop_object_ = py::cast(&loop, py::return_value_policy::reference);
    measurements_object_ = py::cast(&measurements, py::return_value_policy::reference);
    if (torques != nullptr) {
      torques_object_ = py::cast(torques, py::return_value_policy::reference);
    }
  }

  void stop() {
    {
      py::gil_scoped_release release;
      thread.stop();
    }
    release();
  }

 private:
  void release() {
    torques_claim_.reset();
    loop_claim_.reset();
    torques_object_ = py::object();
    measurements_object_ = py::object();
    loop_object_ = py::object();
  }

  py::object loop_object_, measurements_object_, torques_object_;
  std::optional<Claim> loop_claim_, torques_claim_;

 public:
  rt::ControlThread thread;  // last: stopped before the claims and references go
};

std::string statistics_repr(const rt::ControlThreadStatistics& s) {
  return "ControlThreadStatistics(cycles=" + std::to_string(s.cycles) +
         ", overruns=" + std::to_string(s.overruns) +
         ", worst_lateness_us=" + ci::format_number(s.worst_lateness_us) +
         ", period_p50_us=" + ci::format_number(s.period_p50_us) +
         ", period_p99_us=" + ci::format_number(s.period_p99_us) +
         ", period_max_us=" + ci::format_number(s.period_max_us) +
         ", measurement_age_p99_us=" + ci::format_number(s.measurement_age_p99_us) +
         ", stale=" + (s.stale ? "True" : "False") +
         ", stale_episodes=" + std::to_string(s.stale_episodes) +
         ", realtime=" + (s.realtime ? "True" : "False") + ")";
}

// A timeout in seconds for a blocking call: finite, within [0, max].
double read_timeout(py::handle object, const char* name, double max) {
  const double value = read_scalar(object, name);
  if (!(value >= 0.0 && value <= max)) {
    throw ci::Error(std::string(name) + " = " + ci::format_number(value) + " s is outside [0, " +
                    ci::format_number(max) + "]");
  }
  return value;
}

}  // namespace

void bind_runtime(py::module_& m) {
  py::module_ runtime = m.def_submodule(
      "runtime",
      "The runtime of a robot: the control thread, which steps a ControlLoop at a fixed rate on "
      "absolute deadlines (a C++ thread, without the GIL) from the measurements a robot's driver "
      "publishes, and the hand-offs between them (MeasurementBuffer: driver -> control thread; "
      "TorqueOutbox: control thread -> driver). cartesian_impedance.sim.SimulatedDriver is a "
      "driver for a simulated arm.");
  // `import cartesian_impedance.runtime` works too.
  py::module_::import("sys").attr("modules")["cartesian_impedance.runtime"] = runtime;
  runtime.attr("MAX_RATE") = rt::kMaxRate;
  runtime.attr("MIN_RATE") = rt::kMinRate;

  // ---- measurements: driver -> control thread ----
  py::class_<rt::JointMeasurement>(runtime, "JointMeasurement",
                                   "A measured joint state as the driver published it.")
      .def_property_readonly(
          "q", [](const rt::JointMeasurement& m) { return vector_array(m.q); },
          "Joint positions (n,) [rad or m].")
      .def_property_readonly(
          "dq", [](const rt::JointMeasurement& m) { return vector_array(m.dq); },
          "Joint velocities (n,) [rad/s or m/s].")
      .def_property_readonly(
          "effort", [](const rt::JointMeasurement& m) { return optional_array(m.effort); },
          "Measured joint torques (n,) [Nm or N], or None if the driver published none.")
      .def_readonly("sequence", &rt::JointMeasurement::sequence,
                    "1, 2, ... in order of publication; 0: nothing published yet.")
      .def_property_readonly(
          "received", [](const rt::JointMeasurement& m) { return seconds_of(m.received); },
          "When it was published [s], on the clock of time.monotonic() (CLOCK_MONOTONIC).")
      .def_property_readonly(
          "sampled", [](const rt::JointMeasurement& m) { return seconds_of(m.sampled); },
          "When the robot measured it [s], same clock: the driver's stamp, else received.")
      .def("__repr__", [](const rt::JointMeasurement& m) {
        return "JointMeasurement(sequence=" + std::to_string(m.sequence) +
               ", q=" + numbers_text(m.q) + ", dq=" + numbers_text(m.dq) + ")";
      });

  py::class_<Measurements>(
      runtime, "MeasurementBuffer",
      "The newest measured joint state, from one writer (the driver) to any reader (the control "
      "thread). Lock-free: publishing never waits for a reader.")
      .def(py::init([](int num_joints) { return std::make_unique<Measurements>(num_joints); }),
           py::arg("num_joints"),
           "Starts with q = dq = 0 and nothing published (sequence 0). Raises Error if "
           "num_joints is not within [1, MAX_JOINTS].")
      .def_property_readonly("num_joints",
                             [](const Measurements& self) { return self.buffer.num_joints(); })
      .def(
          "publish",
          [](Measurements& self, ArrayLike q, ArrayLike dq, ArrayLike effort, py::object sampled) {
            check_free(self.writer, "this MeasurementBuffer");
            const int n = self.buffer.num_joints();
            rt::JointMeasurement measured;
            read_vector(q, "q", Length{n}, measured.q);
            read_vector(dq, "dq", Length{n}, measured.dq);
            if (effort.is_none()) {
              measured.effort.resize(0);
            } else {
              read_vector(effort, "effort", Length{n}, measured.effort);
            }
            if (!sampled.is_none()) {
              const double seconds = read_scalar(sampled, "sampled");
              if (!(seconds > 0.0)) {
                throw ci::Error("sampled = " + ci::format_number(seconds) +
                                " s is not a time of time.monotonic()'s clock");
              }
              measured.sampled = std::chrono::steady_clock::time_point(
                  std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                      std::chrono::duration<double>(seconds)));
            }
            self.buffer.publish(measured);
          },
          py::arg("q"), py::arg("dq"), py::arg("effort") = py::none(),
          py::arg("sampled") = py::none(),
          "Makes q (n,) [rad or m] and dq (n,) [rad/s or m/s] (and the measured joint torques "
          "effort (n,) [Nm or N], if any) the newest measurement, received now; `sampled` is when "
          "the robot measured it [s] on time.monotonic()'s clock (its stamp; default: now), from "
          "which the control thread reports the measurements' age. Values that are "
          "not finite are passed on as measured: the control cycle then fails closed at once "
          "(status invalid_robot_state), the safe reaction to a bad measurement. One writer: "
          "refused (RuntimeError) while a SimulatedDriver publishes to this buffer.")
      .def(
          "read",
          [](const Measurements& self) {
            rt::JointMeasurement measured;
            self.buffer.read(measured);
            return measured;
          },
          "The newest measurement (a JointMeasurement; sequence 0 before the first). Any "
          "thread.")
      .def("__repr__", [](const Measurements& self) {
        rt::JointMeasurement measured;
        self.buffer.read(measured);
        return "MeasurementBuffer(" + std::to_string(self.buffer.num_joints()) +
               " joints, sequence " + std::to_string(measured.sequence) + ")";
      });

  // ---- torques: control thread -> driver ----
  py::class_<Outbox>(
      runtime, "TorqueOutbox",
      "Each cycle's torque from the control thread to one consumer (the driver's sender): the "
      "newest, each once; a consumer slower than the cycle skips the ones in between.")
      .def(py::init([](int num_joints) { return std::make_unique<Outbox>(num_joints); }),
           py::arg("num_joints"), "Raises Error if num_joints is not within [1, MAX_JOINTS].")
      .def_property_readonly("num_joints",
                             [](const Outbox& self) { return self.outbox.num_joints(); })
      .def(
          "wait",
          [](Outbox& self, Real timeout_object) -> py::object {
            const double timeout = read_timeout(timeout_object, "timeout", 1e6);
            Claim claim(self.consumer, "this TorqueOutbox", "TorqueOutbox.wait()");
            rt::TorqueSample sample;
            bool got = false;
            {
              py::gil_scoped_release release;
              got = self.outbox.wait(timeout, sample);
            }
            if (!got) return py::none();
            return py::make_tuple(vector_array(sample.tau), sample.cycle);
          },
          py::arg("timeout"),
          "Waits up to timeout [s] (within [0, 1e6]) for a torque not returned before, with the "
          "GIL released. Returns (tau (n,) [Nm or N], cycle: the loop's cycle count), or None "
          "after the timeout or a wake(). One consumer: refused (RuntimeError) while a "
          "SimulatedDriver consumes this outbox or another thread waits.")
      .def(
          "wake", [](Outbox& self) { self.outbox.wake(); },
          "Ends a wait() in another thread early (for shutdown).")
      .def("__repr__", [](const Outbox& self) {
        return "TorqueOutbox(" + std::to_string(self.outbox.num_joints()) + " joints)";
      });

  // ---- the control thread ----
  py::enum_<rt::ControlThread::State>(runtime, "ControlThreadState",
                                      "Where a ControlThread stands.")
      .value("idle", rt::ControlThread::State::idle, "not started")
      .value("preparing", rt::ControlThread::State::preparing,
             "started; waiting for the first measurement the loop can start from")
      .value("running", rt::ControlThread::State::running, "cycling")
      .value("failed", rt::ControlThread::State::failed, "starting failed: see failure")
      .value("stopped", rt::ControlThread::State::stopped, "stop() ended it");

  py::class_<rt::ControlThreadStatistics>(
      runtime, "ControlThreadStatistics",
      "The control thread's counters since start(): each read atomically on its own.")
      .def_readonly("cycles", &rt::ControlThreadStatistics::cycles, "cycles run")
      .def_readonly("overruns", &rt::ControlThreadStatistics::overruns,
                    "cycles that ended after the next cycle's deadline")
      .def_readonly("latest_lateness_us", &rt::ControlThreadStatistics::latest_lateness_us,
                    "[us] how late the most recent overrun ended (0 before any)")
      .def_readonly("worst_lateness_us", &rt::ControlThreadStatistics::worst_lateness_us,
                    "[us] the largest such lateness (0 without overruns)")
      .def_readonly("stale", &rt::ControlThreadStatistics::stale,
                    "the latest cycle had no fresh measurement")
      .def_readonly("stale_episodes", &rt::ControlThreadStatistics::stale_episodes,
                    "transitions from fresh to stale measurements")
      .def_readonly("realtime", &rt::ControlThreadStatistics::realtime,
                    "the thread runs with SCHED_FIFO priority")
      .def_readonly("period_min_us", &rt::ControlThreadStatistics::period_min_us,
                    "[us] smallest measured period (time between cycle starts)")
      .def_readonly("period_p50_us", &rt::ControlThreadStatistics::period_p50_us,
                    "[us] median period, within max(0.5 us, 0.4 %)")
      .def_readonly("period_p99_us", &rt::ControlThreadStatistics::period_p99_us,
                    "[us] 99th percentile of the period, within max(0.5 us, 0.4 %)")
      .def_readonly("period_max_us", &rt::ControlThreadStatistics::period_max_us,
                    "[us] largest measured period")
      .def_readonly("measurement_age_p50_us", &rt::ControlThreadStatistics::measurement_age_p50_us,
                    "[us] median age of the measurement each cycle used, from the driver's stamp "
                    "(else its receipt) to the cycle's start")
      .def_readonly("measurement_age_p99_us", &rt::ControlThreadStatistics::measurement_age_p99_us,
                    "[us] 99th percentile of the measurements' age")
      .def_readonly("measurement_age_max_us", &rt::ControlThreadStatistics::measurement_age_max_us,
                    "[us] largest age of a measurement a cycle used")
      .def("__repr__", &statistics_repr);

  const rt::ControlThreadOptions defaults;
  py::class_<Thread>(
      runtime, "ControlThread",
      "The control thread of a robot (the one the ROS nodes run on): a C++ thread that steps a "
      "ControlLoop at a fixed rate on absolute deadlines from the newest measurement of a "
      "MeasurementBuffer and hands each torque to a TorqueOutbox. A measurement older than "
      "measurement_timeout steps the loop with an invalid one: the controller fails closed and "
      "resumes when measurements return. While it runs, the loop's cycle (start, step, state) is "
      "the thread's: Python reads loop.latest_state() and sends commands. A context manager: "
      "`with` stops it; so does dropping the last reference.")
      .def(py::init([](Real rate, Real measurement_timeout, int realtime_priority) {
             rt::ControlThreadOptions options;
             options.rate = read_scalar(rate, "rate");
             options.measurement_timeout = read_scalar(measurement_timeout, "measurement_timeout");
             options.realtime_priority = realtime_priority;
             return std::make_unique<Thread>(options);
           }),
           py::arg("rate") = defaults.rate,
           py::arg("measurement_timeout") = defaults.measurement_timeout,
           py::arg("realtime_priority") = defaults.realtime_priority,
           "rate [Hz] within [MIN_RATE, MAX_RATE]; measurement_timeout [s] > 0: a measurement "
           "older than this counts as lost; realtime_priority: SCHED_FIFO priority 1..99 (needs "
           "CAP_SYS_NICE or an rtprio limit, else normal scheduling and scheduling_error says "
           "why), 0 = normal scheduling. Raises Error naming the option out of range.")
      .def(
          "start",
          [](Thread& self, Loop& loop, Measurements& measurements, Outbox* torques) {
            self.start(loop, measurements, torques);
          },
          py::arg("loop"), py::arg("measurements"), py::arg("torques") = py::none(),
          "Starts the thread: it waits for the first measurement the loop can start from, "
          "starts the loop there (loop.start(q, dq); a measurement it cannot start from is "
          "counted in rejected_starts() and the next one tried), then steps it once per period "
          "(dt: the measured time since the previous cycle) and writes each torque to `torques` "
          "(if given). The loop, the buffer and the outbox are kept alive until stop(); the "
          "loop's cycle and the outbox's writing are claimed until then. Raises Error if the "
          "thread runs already or the joint counts differ.")
      .def("stop", &Thread::stop,
           "Ends the thread after the cycle in progress and joins it (with the GIL released); "
           "releases the loop, the buffer and the outbox. Nothing happens if none runs.")
      .def_property_readonly(
          "state", [](const Thread& self) { return self.thread.state(); },
          "A ControlThreadState: idle, preparing, running, failed or stopped.")
      .def_property_readonly(
          "running", [](const Thread& self) { return self.thread.running(); },
          "True from the first cycle until stop().")
      .def_property_readonly(
          "failure", [](const Thread& self) { return self.thread.failure(); },
          "Why starting failed (the exception's message) once state is failed; else ''.")
      .def(
          "rejected_starts",
          [](const Thread& self) {
            const rt::RejectedStarts rejected = self.thread.rejected_starts();
            py::object latest = py::none();
            if (rejected.latest) latest = py::str(rejected.latest->what());
            return py::make_tuple(rejected.count, latest);
          },
          "(count, newest message or None): the measurements the loop could not start from since "
          "start() (not finite, outside the joint limits, too fast), while state is preparing.")
      .def(
          "statistics", [](const Thread& self) { return self.thread.statistics(); },
          "ControlThreadStatistics since start(): cycles, overruns, lateness, the measured "
          "period's quantiles, stale measurements.")
      .def_property_readonly(
          "scheduling_error", [](const Thread& self) { return self.thread.scheduling_error(); },
          "The errno that refused the requested SCHED_FIFO priority; 0 if granted or none asked.")
      .def_property_readonly(
          "rate", [](const Thread& self) { return self.thread.options().rate; }, "[Hz]")
      .def_property_readonly(
          "measurement_timeout",
          [](const Thread& self) { return self.thread.options().measurement_timeout; }, "[s]")
      .def_property_readonly(
          "realtime_priority",
          [](const Thread& self) { return self.thread.options().realtime_priority; })
      .def_property_readonly(
          "period", [](const Thread& self) { return self.thread.period(); }, "[s] 1 / rate")
      .def("__enter__", [](py::object self) { return self; })
      .def(
          "__exit__",
          [](Thread& self, py::object, py::object, py::object) {
            self.stop();
            return false;
          },
          py::arg("exc_type"), py::arg("exc_value"), py::arg("traceback"), "Stops the thread.")
      .def("__repr__", [](const Thread& self) {
        return "ControlThread(rate=" + ci::format_number(self.thread.options().rate) + " Hz, " +
               state_name(self.thread.state()) + ", " +
               std::to_string(self.thread.statistics().cycles) + " cycles)";
      });
}

}  // namespace cartesian_impedance::python
