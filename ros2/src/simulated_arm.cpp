#include "simulated_arm.hpp"

#include <cartesian_impedance/node/temporary_file.hpp>

#include "log.hpp"

namespace cartesian_impedance_ros2 {

namespace ci = cartesian_impedance;

namespace {

// The robot's file (the MJCF, else the URDF) and the boxes around it. The engines' URDF loaders
// read a file: urdf_path itself, or robot_description's text in a temporary one.
ci::sim::Simulation simulate_file(const Ros2Configuration& configuration,
                                  const ci::sim::SimulationOptions& options,
                                  const std::vector<ci::sim::Box>& boxes) {
  const auto simulate = [&](const std::string& path, bool urdf) {
    if (!boxes.empty()) return ci::sim::make_scene(path, boxes, options);
    return urdf ? ci::sim::Simulation::from_urdf_file(path, options)
                : ci::sim::Simulation::from_mjcf_file(path, options);
  };
  const std::string& mjcf = configuration.common.settings.mjcf_path;
  if (!mjcf.empty()) return simulate(mjcf, false);
  if (configuration.urdf_source != "robot_description") {
    return simulate(configuration.urdf_source, true);
  }
  const ci::node::TemporaryFile file(configuration.urdf, ".urdf");
  return simulate(file.path(), true);
}

}  // namespace

ci::sim::Simulation simulate_arm(const Ros2Configuration& configuration,
                                 const ci::RobotModel& model, const ci::sim::PlantOptions& plant,
                                 const std::vector<ci::sim::Box>& boxes) {
  const ci::node::NodeSettings& settings = configuration.common.settings;
  ci::sim::SimulationOptions options;
  options.timestep = 1.0 / settings.control_rate;  // one simulation step per control cycle
  options.joint_names = model.joint_names();
  // The simulated firmware compensates gravity like the real robots, unless the controller is
  // configured to do it itself (then it would be compensated twice).
  options.gravity_compensation = !configuration.common.parameters.dynamics.gravity_compensation;
  options.engine = settings.engine;
  options.plant = plant;
  const ci::node::SimulationStart start = ci::node::simulation_start(settings, model);
  options.start_q = start.q;
  if (!start.message.empty()) log(start.warning ? LogLevel::warn : LogLevel::info, start.message);
  return simulate_file(configuration, options, boxes);
}

}  // namespace cartesian_impedance_ros2
