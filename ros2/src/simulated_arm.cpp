#include "simulated_arm.hpp"

#include <cartesian_impedance/node/temporary_file.hpp>

#include "log.hpp"

namespace cartesian_impedance_ros2 {

namespace ci = cartesian_impedance;

namespace {

// The engines' URDF loaders read a file: urdf_path itself, or robot_description's text in a
// temporary one.
ci::sim::Simulation simulate_urdf(const Ros2Configuration& configuration,
                                  const ci::sim::SimulationOptions& options) {
  if (configuration.urdf_source != "robot_description") {
    return ci::sim::Simulation::from_urdf_file(configuration.urdf_source, options);
  }
  const ci::node::TemporaryFile file(configuration.urdf, ".urdf");
  return ci::sim::Simulation::from_urdf_file(file.path(), options);
}

}  // namespace

ci::sim::Simulation simulate_arm(const Ros2Configuration& configuration,
                                 const ci::RobotModel& model, const ci::sim::PlantOptions& plant) {
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
  // Without an MJCF, the engine simulates the URDF itself.
  return settings.mjcf_path.empty()
             ? simulate_urdf(configuration, options)
             : ci::sim::Simulation::from_mjcf_file(settings.mjcf_path, options);
}

}  // namespace cartesian_impedance_ros2
