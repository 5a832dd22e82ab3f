#pragma once
/// @file
/// The plant a Simulation runs (SimulationOptions::plant): how the simulated arm differs from the
/// model its controller uses, and how its sensors and drives behave. A real arm's links differ
/// from its URDF by tens of percent, its joint states arrive late (about 1 ms through a robot's
/// own interface, several ms through topics) and noisy, its torques act late. The nominal plant
/// is the model itself, measured at once and exactly; PlantOptions::realistic() is a plant of the
/// kind users meet.

#include <cstdint>
#include <string>

namespace cartesian_impedance::sim {

/// A factor drawn uniformly from [low, high], once per link or joint. [1, 1]: exact.
struct Spread {
  double low = 1.0;
  double high = 1.0;
};

/// What makes the plant differ from the model. All draws come from `seed`: the model error once
/// at construction, the noise every step (reset() starts the noise over, so a run repeats).
struct PlantOptions {
  std::uint64_t seed = 1;

  // Model error, drawn once per moving link (a body below an exchanged joint) or joint.
  /// Each link's mass and rotational inertia scaled by one factor (its density), so that the
  /// inertia stays physical.
  Spread inertia;
  /// Each link's centre of mass moved by up to this [m], uniformly within a ball.
  double center_of_mass_offset = 0.0;
  /// Each joint's Coulomb friction, viscous damping and armature (reflected rotor inertia).
  Spread friction;
  Spread damping;
  Spread armature;

  // Sensing: what q() and dq() report.
  /// Age of each reading [s]; rounded to whole timesteps.
  double measurement_delay = 0.0;
  /// Standard deviation of white noise on each reading [rad or m; rad/s or m/s].
  double position_noise = 0.0;
  double velocity_noise = 0.0;
  /// The encoder's quantum [rad or m]: positions are read as whole multiples of it (0: none).
  double position_resolution = 0.0;

  // Actuation.
  /// Time from set_torque() until the torque acts [s]; rounded to whole timesteps.
  double actuation_delay = 0.0;
  /// Standard deviation of white noise on each applied torque [Nm or N], drawn every step.
  double torque_noise = 0.0;
  /// Standard deviation of white noise on each measured joint torque [Nm or N]
  /// (Simulation::measured_torque(), which is read with measurement_delay like q and dq).
  double torque_sensor_noise = 0.0;

  /// A plant of the kind users meet: link inertias x U(0.7, 1.3), centres of mass moved up to
  /// 1 cm, friction x U(0.5, 1.5), damping and armature x U(0.8, 1.2); readings 1 ms old with
  /// 1e-5 rad and 0.005 rad/s of noise and a 2^-19-turn encoder; torques acting 1 ms late with
  /// 0.05 Nm of noise; joint torque sensors with 0.05 Nm of noise.
  static PlantOptions realistic(std::uint64_t seed = 1);

  /// Nothing differs: the simulation is the model, read at once and exactly.
  bool nominal() const noexcept;
};

/// "nominal" (PlantOptions{}) or "realistic" (PlantOptions::realistic(seed)).
/// @throw Error naming the valid names.
PlantOptions plant_from_name(const std::string& name, std::uint64_t seed = 1);

}  // namespace cartesian_impedance::sim
