#include "simulated_arm.hpp"

#include <cartesian_impedance/node/simulated_arm.hpp>

#include "log.hpp"

namespace cartesian_impedance_ros2 {

namespace ci = cartesian_impedance;

ci::sim::Simulation simulate_arm(const Ros2Configuration& configuration,
                                 const ci::RobotModel& model, const ci::sim::PlantOptions& plant,
                                 const std::vector<ci::sim::Box>& boxes) {
  const std::string path =
      configuration.urdf_source == "robot_description" ? "" : configuration.urdf_source;
  return ci::node::simulate_arm(
      configuration.common, model, configuration.urdf, path,
      [](const ci::node::SimulationStart& start) {
        log(start.warning ? LogLevel::warn : LogLevel::info, start.message);
      },
      plant, boxes);
}

}  // namespace cartesian_impedance_ros2
