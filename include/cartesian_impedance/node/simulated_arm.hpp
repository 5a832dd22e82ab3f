#pragma once
/// @file
/// The simulated arm of a node's sim mode and of the simulated robots its topics mode drives
/// (cartesian_impedance_sim_robot, cartesian_impedance_ros2_sim_robot), made the same way from
/// the same settings. Header-only: it needs the simulation library, which the node kit does not
/// link (a build without the simulation has the node kit all the same).

#include <string>
#include <vector>

#include "cartesian_impedance/model/robot_model.hpp"
#include "cartesian_impedance/node/node_settings.hpp"
#include "cartesian_impedance/node/temporary_file.hpp"
#include "cartesian_impedance/sim/plant.hpp"
#include "cartesian_impedance/sim/simulation.hpp"

namespace cartesian_impedance::node {

/// The arm of `configuration`: its MJCF (mjcf_path), else its URDF simulated by `engine` (the
/// file `urdf_path`, or the text `urdf` in a temporary file if the path is empty, as the engines'
/// loaders read files); one step per control cycle (1 / control_rate); the model's joints in its
/// order; from simulation_start() (start_q, the model's own start, or one chosen away from
/// singularities for a URDF), whose message, if any, goes to `report`; the firmware's gravity
/// compensation unless the controller compensates gravity itself (it would be compensated
/// twice); `plant`; `boxes` to touch (a table).
/// @throws Error if the MJCF or URDF does not load or does not match `model`.
template <typename Report>
sim::Simulation simulate_arm(const NodeConfiguration& configuration, const RobotModel& model,
                             const std::string& urdf, const std::string& urdf_path, Report&& report,
                             const sim::PlantOptions& plant = {},
                             const std::vector<sim::Box>& boxes = {}) {
  const NodeSettings& settings = configuration.settings;
  sim::SimulationOptions options;
  options.timestep = 1.0 / settings.control_rate;
  options.joint_names = model.joint_names();
  options.gravity_compensation = !configuration.parameters.dynamics.gravity_compensation;
  options.engine = settings.engine;
  options.plant = plant;
  const SimulationStart start = simulation_start(settings, model);
  options.start_q = start.q;
  if (!start.message.empty()) report(start);
  const auto simulate = [&](const std::string& path, bool is_urdf) {
    if (!boxes.empty()) return sim::make_scene(path, boxes, options);
    return is_urdf ? sim::Simulation::from_urdf_file(path, options)
                   : sim::Simulation::from_mjcf_file(path, options);
  };
  if (!settings.mjcf_path.empty()) return simulate(settings.mjcf_path, false);
  if (!urdf_path.empty()) return simulate(urdf_path, true);
  const TemporaryFile file(urdf, ".urdf");
  return simulate(file.path(), true);
}

}  // namespace cartesian_impedance::node
