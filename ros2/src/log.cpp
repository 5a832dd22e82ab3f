#include "log.hpp"

#include <unistd.h>

#include <chrono>
#include <cstdio>

namespace cartesian_impedance_ros2 {
namespace {

std::string logger = "cartesian_impedance_controller";

}  // namespace

void set_logger_name(const std::string& fully_qualified_node_name) {
  logger = fully_qualified_node_name.substr(fully_qualified_node_name.find_first_not_of('/'));
  for (char& c : logger) {
    if (c == '/') c = '.';
  }
}

void log(LogLevel level, std::string_view message) {
  static const char* const kNames[] = {"INFO", "WARN", "ERROR", "FATAL"};
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  const long long ns = std::chrono::duration_cast<std::chrono::nanoseconds>(now).count();
  std::string line = std::string("[") + kNames[static_cast<int>(level)] + "] [";
  char stamp[32];
  std::snprintf(stamp, sizeof stamp, "%lld.%09lld", ns / 1000000000, ns % 1000000000);
  line += stamp;
  line += "] [" + logger + "]: ";
  line.append(message.data(), message.size());
  line += '\n';
  // One write(2): whole lines even when several threads log at once.
  const ssize_t written = ::write(STDERR_FILENO, line.data(), line.size());
  (void)written;
}

}  // namespace cartesian_impedance_ros2
