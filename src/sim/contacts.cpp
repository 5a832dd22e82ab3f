// Contact wrenches on a body of the simulation, as a wrist force-torque sensor would measure them
// (contact_wrench_beyond) or on the body and what is welded to it alone (contact_wrench), and
// their mean over steps.

#include <mujoco/mujoco.h>

#include <string>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "simulation_impl.hpp"

namespace cartesian_impedance::sim {

Vector6d Simulation::contact_wrench(const std::string& body) const {
  return impl_->contact_wrench(impl_->find_body(body));
}

Vector6d Simulation::contact_wrench_beyond(const std::string& body) const {
  return impl_->contact_wrench(impl_->find_body(body), true);
}

void Simulation::track_contact_wrench(const std::string& body) {
  Impl& s = *impl_;
  s.tracked_body = body.empty() ? -1 : s.find_body(body);
  s.tracked_sum.setZero();
  s.tracked_steps = 0;
}

Vector6d Simulation::take_mean_contact_wrench() {
  Impl& s = *impl_;
  if (s.tracked_body < 0) {
    throw Error("take_mean_contact_wrench: no body is tracked (call track_contact_wrench first)");
  }
  const Vector6d mean =
      s.tracked_steps > 0 ? Vector6d(s.tracked_sum / double(s.tracked_steps)) : Vector6d::Zero();
  s.tracked_sum.setZero();
  s.tracked_steps = 0;
  return mean;
}

Vector6d Simulation::Impl::contact_wrench(int id, bool beyond) const noexcept {
  const mjModel* m = model.get();
  const mjData* d = data.get();
  const int weld = m->body_weldid[id];
  if (physics) return physics->contact_wrench(weld, physics->body_pose(id).position, beyond);
  const auto on = [&](int geom) {
    for (int body = m->geom_bodyid[geom]; body > 0; body = m->body_parentid[body]) {
      if (m->body_weldid[body] == weld) return true;
      if (!beyond) return false;
    }
    return false;
  };
  update_kinematics();
  const Eigen::Vector3d origin = Eigen::Map<const Eigen::Vector3d>(d->xpos + 3 * id);

  Vector6d wrench = Vector6d::Zero();
  for (int c = 0; c < d->ncon; ++c) {
    const mjContact& contact = d->contact[c];
    if (contact.efc_address < 0) continue;  // excluded from the constraint problem: no force
    const bool on_first = on(contact.geom1);
    const bool on_second = on(contact.geom2);
    if (on_first == on_second) continue;  // not touching this body, or internal to it
    // mj_contactForce: the force geom1 exerts on geom2, in the contact frame (rows of `frame`
    // are the frame's axes in world coordinates, the first one the normal from geom1 to geom2).
    mjtNum local[6];
    mj_contactForce(m, d, c, local);
    const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> frame(contact.frame);
    Eigen::Vector3d force = frame.transpose() * Eigen::Vector3d(local[0], local[1], local[2]);
    Eigen::Vector3d torque = frame.transpose() * Eigen::Vector3d(local[3], local[4], local[5]);
    if (on_first) {
      force = -force;
      torque = -torque;
    }
    const Eigen::Vector3d point(contact.pos[0], contact.pos[1], contact.pos[2]);
    wrench.head<3>() += force;
    wrench.tail<3>() += torque + (point - origin).cross(force);
  }
  return wrench;
}

}  // namespace cartesian_impedance::sim
