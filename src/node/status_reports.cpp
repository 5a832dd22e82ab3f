#include "cartesian_impedance/node/status_reports.hpp"

#include <thread>
#include <utility>

#include "cartesian_impedance/core/parameters.hpp"

namespace cartesian_impedance::node {

StatusReporter::StatusReporter(double period, double measurement_timeout, std::string measurements,
                               std::chrono::steady_clock::duration summary_interval)
    : period_(period),
      measurement_timeout_(measurement_timeout),
      measurements_(std::move(measurements)),
      interval_(summary_interval) {}

std::vector<ReportLine> StatusReporter::update(const LoopState& state,
                                               const runtime::ControlThreadSnapshot& timing) {
  using Level = ReportLine::Level;
  std::vector<ReportLine> lines;
  const Status status = state.controller.status;
  if (status != status_) {
    if (status == Status::ok) {
      lines.push_back({Level::info, "controller status: ok"});
    } else {
      lines.push_back({Level::warning, std::string("controller status: ") + to_string(status) +
                                           " (" + to_string(state.controller.fault) + ")"});
    }
    status_ = status;
  }
  // Each oscillation the watch finds lowers the stiffness for good (until a restart): say so.
  const SafetyState& safety = state.controller.safety;
  if (safety.oscillations > oscillations_) {
    lines.push_back(
        {Level::warning,
         "the closed loop oscillated (a delay or a resonance past the stiffness's margin): the "
         "stiffness is now " +
             format_number(safety.oscillation_scale) + " of the commanded (" +
             std::to_string(safety.oscillations) + " oscillation(s) since start)"});
  }
  oscillations_ = safety.oscillations;
  // So does each halving by the passivity controller, of the springs that generated energy.
  if (safety.passivity_halvings > passivity_halvings_) {
    const Eigen::Vector3d& scale = safety.passivity_scale;
    lines.push_back({Level::warning,
                     "the controller generated energy on its port to the arm (a delay past the "
                     "stiffness's margin): the springs that did are halved, now translation " +
                         format_number(scale[0]) + ", rotation " + format_number(scale[1]) +
                         ", nullspace " + format_number(scale[2]) + " of the commanded (" +
                         std::to_string(safety.passivity_halvings) + " halving(s) since start)"});
  }
  passivity_halvings_ = safety.passivity_halvings;
  // And each collision the monitor finds, with what the controller does about it.
  const CollisionState& collision = state.controller.collision;
  if (collision.collisions > collisions_ && collision.joint >= 0) {
    const bool holds = collision.reaction != CollisionReaction::report;
    lines.push_back({Level::warning, "collision: the external torque on joint " +
                                         std::to_string(collision.joint + 1) +
                                         " passed its threshold " + format_number(collision.ratio) +
                                         " times (the contact is on its link "
                                         "or a later one); reaction " +
                                         std::string(reaction_name(collision.reaction)) +
                                         (holds ? ", holding until resume" : "") + " (" +
                                         std::to_string(collision.collisions) +
                                         " collision(s) since start)"});
  }
  collisions_ = collision.collisions;
  if (timing.stale != stale_) {
    if (timing.stale) {
      lines.push_back({Level::warning, "no " + measurements_ + " for more than " +
                                           format_number(measurement_timeout_) +
                                           " s: torque ramps toward zero"});
    } else {
      lines.push_back({Level::info, measurements_ + " are back"});
    }
    stale_ = timing.stale;
  }
  // Overruns: one line per window with any, counted from the thread's snapshots.
  const auto now = std::chrono::steady_clock::now();
  if (!window_began_) window_began_ = now;  // the first window: since start
  if (now - *window_began_ < interval_) return lines;
  const runtime::ControlThreadStatistics window = timing.since(window_start_);
  if (window.overruns > 0) {
    const double seconds = std::chrono::duration<double>(now - *window_began_).count();
    lines.push_back({Level::warning, runtime::overrun_summary(window, period_, seconds)});
  }
  window_began_ = now;
  window_start_ = timing;
  return lines;
}

PublisherOptions publisher_options(const NodeSettings& settings) {
  PublisherOptions options;
  options.rate = settings.publish_rate;
  options.measurement_timeout = settings.joint_states_timeout;
  return options;
}

void run_publisher(const PublisherOptions& options, const std::atomic<bool>& stop,
                   const runtime::ControlThread& thread, const ControlLoop& loop,
                   const runtime::MeasurementBuffer* measurements,
                   const std::function<void(const PublisherSample&)>& publish,
                   const std::function<void(const ReportLine&)>& log) {
  using Clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(1.0 / options.rate));
  StatusReporter reporter(1.0 / thread.options().rate, options.measurement_timeout,
                          options.measurements);
  PublisherSample sample;
  runtime::JointMeasurement measured;
  Clock::time_point next = Clock::now();
  while (!stop) {
    next += period;
    if (thread.running()) {
      sample.state = loop.latest_state();
      sample.measured = nullptr;
      if (measurements != nullptr) {
        measurements->read(measured);
        sample.measured = &measured;
      }
      sample.timing = thread.snapshot();
      publish(sample);
      for (const ReportLine& line : reporter.update(sample.state, sample.timing)) log(line);
    }
    const Clock::time_point now = Clock::now();
    if (now - next > period) next = now;
    std::this_thread::sleep_until(next);
  }
}

}  // namespace cartesian_impedance::node
