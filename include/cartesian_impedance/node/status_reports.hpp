#pragma once
/// @file
/// A node's publisher thread, the same for every shell: at a fixed rate, the newest loop state,
/// measurement and timing snapshot go to the shell's publish function, and what the node logs
/// about its control thread is decided here (status changes with their fault, each oscillation
/// the controller's watch finds, measurements lost and back, and every few seconds while there
/// are any, a summary of the overruns) and handed to the shell's logger. Never the control
/// thread: it reads the loop's and the thread's lock-free outboxes.

#include <atomic>
#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/node/node_settings.hpp"
#include "cartesian_impedance/runtime/control_thread.hpp"
#include "cartesian_impedance/runtime/robot_io.hpp"

namespace cartesian_impedance::node {

struct ReportLine {
  enum class Level { info, warning };
  Level level;
  std::string text;
};

class StatusReporter {
 public:
  /// `period`: of the control cycle [s]; `measurement_timeout`: [s], named in the lost line;
  /// `measurements`: what the measurements are called ("joint_states").
  StatusReporter(double period, double measurement_timeout, std::string measurements,
                 std::chrono::steady_clock::duration summary_interval = std::chrono::seconds(5));

  /// The lines to log now (often none).
  std::vector<ReportLine> update(const LoopState& state,
                                 const runtime::ControlThreadSnapshot& timing);

 private:
  double period_;
  double measurement_timeout_;
  std::string measurements_;
  std::chrono::steady_clock::duration interval_;
  Status status_ = Status::ok;
  int oscillations_ = 0;        // SafetyState::oscillations at the last update
  int passivity_halvings_ = 0;  // SafetyState::passivity_halvings at the last update
  int collisions_ = 0;          // CollisionState::collisions at the last update
  bool stale_ = false;
  // The window of the next overrun summary: since when, and the thread's counts then (none
  // before the first: since the thread started).
  std::optional<std::chrono::steady_clock::time_point> window_began_;
  runtime::ControlThreadSnapshot window_start_;
};

/// What the publisher thread hands the shell each period.
struct PublisherSample {
  LoopState state;
  /// The newest measurement (topics mode), null without a measurement buffer (sim mode).
  const runtime::JointMeasurement* measured = nullptr;
  runtime::ControlThreadSnapshot timing;
};

struct PublisherOptions {
  double rate = 100.0;  ///< [Hz] publish() calls per second; missed periods are skipped
  /// Named in the log lines about lost measurements.
  double measurement_timeout = 0.1;
  std::string measurements = "joint_states";
};

/// A node's publisher as its settings configure it: publish_rate, joint_states_timeout.
PublisherOptions publisher_options(const NodeSettings& settings);

/// Runs until `stop` is true: every period while `thread` runs, reads a sample, calls
/// `publish(sample)` and passes each report line to `log`. `measurements` may be null.
void run_publisher(const PublisherOptions& options, const std::atomic<bool>& stop,
                   const runtime::ControlThread& thread, const ControlLoop& loop,
                   const runtime::MeasurementBuffer* measurements,
                   const std::function<void(const PublisherSample&)>& publish,
                   const std::function<void(const ReportLine&)>& log);

}  // namespace cartesian_impedance::node
