#include "cartesian_impedance/runtime/status_reports.hpp"

#include <utility>

#include "cartesian_impedance/parameters.hpp"

namespace cartesian_impedance::runtime {

StatusReporter::StatusReporter(double period, double measurement_timeout, std::string measurements,
                               std::chrono::steady_clock::duration summary_interval)
    : period_(period),
      measurement_timeout_(measurement_timeout),
      measurements_(std::move(measurements)),
      interval_(summary_interval) {}

std::vector<ReportLine> StatusReporter::update(const LoopState& state,
                                               const ControlThreadSnapshot& timing) {
  using Level = ReportLine::Level;
  std::vector<ReportLine> lines;
  const Status status = state.controller.status;
  if (status != status_) {
    if (status == Status::ok) {
      lines.push_back({Level::info, "controller status: ok"});
    } else {
      lines.push_back({Level::warning, std::string("controller status: ") + to_string(status)});
    }
    status_ = status;
  }
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
  const ControlThreadStatistics window = timing.since(window_start_);
  if (window.overruns > 0) {
    const double seconds = std::chrono::duration<double>(now - *window_began_).count();
    lines.push_back({Level::warning, overrun_summary(window, period_, seconds)});
  }
  window_began_ = now;
  window_start_ = timing;
  return lines;
}

}  // namespace cartesian_impedance::runtime
