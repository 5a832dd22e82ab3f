#pragma once
/// @file
/// The simulated arm of the node's sim mode and of the simulated robot
/// (cartesian_impedance_ros2_sim_robot), made the same way from the same settings.

#include <vector>

#include <cartesian_impedance/model/robot_model.hpp>
#include <cartesian_impedance/sim/plant.hpp>
#include <cartesian_impedance/sim/simulation.hpp>

#include "parameters.hpp"

namespace cartesian_impedance_ros2 {

/// The arm of `configuration`: its MJCF (mjcf_path), else its URDF (urdf_path or
/// robot_description) simulated by `engine`; one step per control cycle (1 / control_rate); the
/// model's joints in its order; from start_q (or the model's start, or a start chosen away from
/// singularities for a URDF, logged); the firmware's gravity compensation unless the controller
/// compensates gravity itself; `plant` (default: the model itself, read at once); `boxes` to
/// touch (a table).
/// @throws cartesian_impedance::Error if the MJCF or URDF does not load or does not match `model`.
cartesian_impedance::sim::Simulation simulate_arm(
    const Ros2Configuration& configuration, const cartesian_impedance::RobotModel& model,
    const cartesian_impedance::sim::PlantOptions& plant = {},
    const std::vector<cartesian_impedance::sim::Box>& boxes = {});

}  // namespace cartesian_impedance_ros2
