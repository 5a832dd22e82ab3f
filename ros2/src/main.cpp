// cartesian_impedance_ros2: the Cartesian impedance controller on ROS 2 topics over DDS (see
// ros2/README.md). Exit codes, one rule: 0 after SIGINT or SIGTERM; 2 if what the node
// was given is wrong - the command line (a remap too), a parameter, a file it names (params file,
// parameters_file, urdf_path, mjcf_path) or robot_description, e.g. a URDF that does not load or
// an MJCF that does not match it - found before the control thread starts, with a message naming
// it; 1 if the node cannot run with what it was given: DDS cannot start, or the controller fails.

#include <malloc.h>

#include <csignal>
#include <exception>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <cartesian_impedance/core/error.hpp>

#include "arguments.hpp"
#include "log.hpp"
#include "node.hpp"
#include "parameters.hpp"

namespace {

std::atomic<bool> stop_requested{false};

extern "C" void on_signal(int) {
  stop_requested = true;
}

}  // namespace

int main(int argc, char** argv) {
  namespace ros2 = cartesian_impedance_ros2;
  // A peer decides how large a sample DDS receives (a parameter request of megabytes is refused,
  // but only after it arrived). glibc's default raises its mmap threshold to the largest block
  // freed, so after one such request the next ones come from the heap and stay resident; a fixed
  // threshold (which also fixes the trim threshold) gives every large block back when it is freed.
  // The control thread allocates nothing per cycle, so this costs it nothing.
  mallopt(M_MMAP_THRESHOLD, 1 << 20);
  ros2::RosArguments arguments;
  ros2::Ros2Configuration configuration;
  try {
    arguments = ros2::parse_arguments(std::vector<std::string>(argv + 1, argv + argc));
    if (arguments.help) {
      std::cout << ros2::usage();
      return 0;
    }
    ros2::set_logger_name(arguments.fully_qualified_name());
    configuration = ros2::read_configuration(arguments);
  } catch (const ros2::UsageError& error) {
    std::cerr << "cartesian_impedance_ros2: " << error.what() << "\n" << ros2::usage();
    return 2;
  } catch (const std::exception& error) {
    ros2::log(ros2::LogLevel::fatal, error.what());
    return 2;
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::optional<ros2::Node> node;
  try {
    node.emplace(std::move(arguments), std::move(configuration));
  } catch (const ros2::MiddlewareError& error) {
    ros2::log(ros2::LogLevel::fatal, error.what());
    return 1;
  } catch (const cartesian_impedance::Error& error) {
    // What only loading shows: a URDF or MJCF that does not load or does not match, a start_q
    // outside the chain's limits. As wrong as a bad parameter.
    ros2::log(ros2::LogLevel::fatal, error.what());
    return 2;
  } catch (const ros2::UsageError& error) {
    ros2::log(ros2::LogLevel::fatal, error.what());  // a topic name that is not valid
    return 2;
  } catch (const std::exception& error) {
    ros2::log(ros2::LogLevel::fatal, error.what());
    return 1;
  }
  try {
    return node->run(stop_requested);
  } catch (const std::exception& error) {
    ros2::log(ros2::LogLevel::fatal, error.what());
    return 1;
  }
}
