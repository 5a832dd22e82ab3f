// What the simulated robot's sensors read: the joints' positions and velocities, and the joint
// torque sensors on the link side of each drive, through the plant's delay and noise.

#include <mujoco/mujoco.h>

#include "cartesian_impedance/sim/simulation.hpp"
#include "simulation_impl.hpp"

namespace cartesian_impedance::sim {

void Simulation::Impl::read_state(bool restart, bool reseed) noexcept {
  const mjData* d = data.get();
  for (std::size_t i = 0; i < joint_ids.size(); ++i) {
    true_q[static_cast<Eigen::Index>(i)] = d->qpos[qpos_address[i]];
    true_dq[static_cast<Eigen::Index>(i)] = d->qvel[dof_address[i]];
  }
  if (restart) {
    // As if the arm had rested here, held by its drives: each joint's sensor carries what holds
    // its links, gravity's and the velocity's bias of the (true) model.
    for (std::size_t i = 0; i < joint_ids.size(); ++i) {
      true_torque[static_cast<Eigen::Index>(i)] = d->qfrc_bias[dof_address[i]];
    }
    plant.restart(true_q, true_dq, true_torque, reseed);
  }
  plant.measure(true_q, true_dq, true_torque, q, dq, measured_torque);
}

void Simulation::Impl::sense_torque(const JointVector& dq_before) noexcept {
  // The links' side of each joint took the drive's torque (actuator or applied, with the
  // firmware's compensation) and the passive forces (damping), less the Coulomb friction (a
  // constraint row of its own per joint) and what turned the rotor; a contact is felt through
  // the links' motion only, as a sensor feels it.
  const mjModel* m = model.get();
  const mjData* d = data.get();
  const double h = m->opt.timestep;
  for (std::size_t k = 0; k < joint_ids.size(); ++k) {
    const auto i = static_cast<Eigen::Index>(k);
    const int dof = dof_address[k];
    true_torque[i] = d->qfrc_applied[dof] + d->qfrc_actuator[dof] + d->qfrc_passive[dof] -
                     m->dof_armature[dof] * (d->qvel[dof] - dq_before[i]) / h;
  }
  // One pass over the constraint rows (a contact adds many): only the friction rows look up
  // their joint.
  for (int row = 0; row < d->nefc; ++row) {
    if (d->efc_type[row] != mjCNSTR_FRICTION_DOF) continue;
    for (std::size_t k = 0; k < joint_ids.size(); ++k) {
      if (dof_address[k] == d->efc_id[row])
        true_torque[static_cast<Eigen::Index>(k)] += d->efc_force[row];
    }
  }
}

const JointVector& Simulation::measured_torque() const noexcept {
  return impl_->measured_torque;
}

}  // namespace cartesian_impedance::sim
