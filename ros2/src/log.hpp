#pragma once
/// @file
/// Log lines in ROS 2's console format (`[LEVEL] [seconds.nanoseconds] [node]: message`) on
/// stderr, one write per line so that threads do not interleave.

#include <string>
#include <string_view>

namespace cartesian_impedance_ros2 {

enum class LogLevel { info, warn, error, fatal };

/// Sets the logger name (the node's fully-qualified name without the leading '/', dots for
/// slashes, as rcl names loggers). Call once before threads start.
void set_logger_name(const std::string& fully_qualified_node_name);

void log(LogLevel level, std::string_view message);

}  // namespace cartesian_impedance_ros2
