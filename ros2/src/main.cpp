// cartesian_impedance_ros2: the Cartesian impedance controller on ROS 2 topics over DDS (see the
// README's "ROS 2" section). Exit codes: 0 after SIGINT or SIGTERM, 1 if the controller cannot
// start, 2 for a bad command line or bad parameters (the message names the argument or parameter
// and the value).

#include <csignal>
#include <exception>
#include <iostream>
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
  try {
    ros2::Node node(std::move(arguments), std::move(configuration));
    return node.run(stop_requested);
  } catch (const cartesian_impedance::ParameterError& error) {
    // A parameter that only the loaded model shows to be wrong (start_q): as any other.
    ros2::log(ros2::LogLevel::fatal, error.what());
    return 2;
  } catch (const std::exception& error) {
    ros2::log(ros2::LogLevel::fatal, error.what());
    return 1;
  }
}
