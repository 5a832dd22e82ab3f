#pragma once
// Internal to the sim target: the plant between the engine and the controller (plant.hpp).

#include <mujoco/mujoco.h>

#include <cstddef>
#include <random>
#include <vector>

#include "cartesian_impedance/core/types.hpp"
#include "cartesian_impedance/sim/plant.hpp"

namespace cartesian_impedance::sim::detail {

/// @throw Error naming the field of `plant` that is out of its range, and the value.
void check_plant(const PlantOptions& plant);

/// Whether `plant` changes the arm itself (inertias, centres of mass, joint parameters), not only
/// how it is read and driven.
bool changes_model(const PlantOptions& plant) noexcept;

/// Writes the model error of `plant` into `m` (after its joints' armature, damping and friction
/// are final): each moving link below one of `joint_ids` (except `exact_bodies`) gets its mass
/// and inertia scaled and its centre of mass moved, each of those joints its friction, damping
/// and armature scaled. Returns the bodies changed, for an engine that copies them.
std::vector<int> perturb_model(mjModel* m, const std::vector<int>& joint_ids,
                               const std::vector<int>& exact_bodies, const PlantOptions& plant);

/// The sensors and drives: delay lines sized once by configure(), so that a step allocates
/// nothing.
class PlantState {
 public:
  void configure(const PlantOptions& plant, double timestep, int joints);
  /// Every delayed reading becomes (q, dq, sensed torque), no torque is pending; `reseed`
  /// restarts the noise.
  void restart(const JointVector& q, const JointVector& dq, const JointVector& sensed, bool reseed);
  /// Takes in the state after a step and the torque the joints' sensors saw in it; q, dq and
  /// torque receive the reading.
  void measure(const JointVector& true_q, const JointVector& true_dq,
               const JointVector& true_torque, JointVector& q, JointVector& dq,
               JointVector& torque) noexcept;
  /// Takes in this step's command; tau receives what acts in this step.
  void actuate(const JointVector& command, JointVector& tau) noexcept;
  /// Whether actuate() changes anything (else the command acts as it is, at once).
  bool actuates() const noexcept { return actuates_; }
  /// How many timesteps old a reading is.
  int measurement_steps() const noexcept { return measurement_steps_; }
  int actuation_steps() const noexcept { return actuation_steps_; }

 private:
  PlantOptions plant_;
  int measurement_steps_ = 0;
  int actuation_steps_ = 0;
  bool senses_ = false;
  bool actuates_ = false;
  std::vector<JointVector> q_ring_, dq_ring_, sensed_ring_, tau_ring_;
  std::size_t q_head_ = 0, tau_head_ = 0;
  std::mt19937_64 random_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  std::mt19937_64 sensor_random_;
  std::normal_distribution<double> sensor_normal_{0.0, 1.0};
};

}  // namespace cartesian_impedance::sim::detail
