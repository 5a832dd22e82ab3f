#pragma once
/// @file
/// What a node logs about its control thread, decided in one place for every shell: status
/// changes, measurements lost and back, and every few seconds while there are any, a summary of
/// the overruns. The shell calls update() from its publisher thread (never the control thread)
/// with the newest state and timing snapshot and logs the lines it returns with its own logger.

#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "cartesian_impedance/control_loop.hpp"
#include "cartesian_impedance/runtime/control_thread.hpp"

namespace cartesian_impedance::runtime {

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
  std::vector<ReportLine> update(const LoopState& state, const ControlThreadSnapshot& timing);

 private:
  double period_;
  double measurement_timeout_;
  std::string measurements_;
  std::chrono::steady_clock::duration interval_;
  Status status_ = Status::ok;
  bool stale_ = false;
  // The window of the next overrun summary: since when, and the thread's counts then (none
  // before the first: since the thread started).
  std::optional<std::chrono::steady_clock::time_point> window_began_;
  ControlThreadSnapshot window_start_;
};

}  // namespace cartesian_impedance::runtime
