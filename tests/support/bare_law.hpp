#pragma once
// The law on analytic cases, shared by the controller's and the safety layer's tests: parameters
// that leave the bare formula (no model, no filters, limits out of the way) and a 6-joint
// "Cartesian" robot with J = I, so joint torques are the wrench components.

#include <cmath>

#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/core/types.hpp"

namespace bare_law {

namespace ci = cartesian_impedance;

// Default parameters for a controller without a model (no M(q)): the unit-mass damping.
inline ci::Parameters modelless_parameters() {
  ci::Parameters p;
  p.dynamics.inertia_shaped_damping = false;
  return p;
}

// Filters off, limits as far out of the way as their ranges allow: one update() evaluates the
// law on the commands.
inline ci::Parameters bare_parameters() {
  ci::Parameters p = modelless_parameters();
  p.filter.pose.time = p.filter.stiffness.time = p.filter.nullspace.time = p.filter.wrench.time =
      0.0;
  p.limits.pose_error = {10.0, M_PI};
  p.limits.wrench = {1e4, 1e3};
  p.limits.joint_torque = ci::JointVector::Constant(1, 1e4);
  p.limits.joint_torque_rate = ci::JointVector::Constant(1, 1e6);
  p.nullspace.stiffness = ci::JointVector::Constant(1, 0.0);
  p.nullspace.pseudo_inverse_damping = 0.0;
  p.minimum_damping = {0.0, 0.0, 0.0};
  // The law alone: a stiffness raised while a teleported pose is far from the reference would
  // wait for the energy tank (its own tests are in safety_test.cpp and energy_tank_test.cpp).
  p.safety.energy_tank.enabled = false;
  // Nor does the passivity controller halve anything: a teleported pose, or a fixed state with a
  // velocity, is not an arm moving under the torque, whose energy it balances (its own tests are
  // in passivity_test.cpp).
  p.safety.passivity.threshold = 0.0;
  return p;
}

inline ci::RobotState cartesian_robot() {
  ci::RobotState robot = ci::make_robot_state(6);
  robot.jacobian = ci::Jacobian::Identity(6, 6);
  robot.pose.position = Eigen::Vector3d(0.4, 0.0, 0.5);
  return robot;
}

}  // namespace bare_law
