#pragma once
// A small rigid-body simulation of an arm from its own RobotModel (KDL dynamics): semi-implicit
// Euler on (M(q) + A) ddq = tau + tau_external - C(q, dq) dq - [g(q)] - b dq, where A is the
// reflected rotor inertia (armature) every real drive has. Without it the wrist links weigh so
// little that the controller's damping (D = 2 zeta sqrt(K), unit-mass convention) would make an
// explicit 1 kHz integration unstable, which no real arm is. Good enough to close the loop in unit
// tests of the control loop without MuJoCo; the MuJoCo simulation in sim/ is the independent
// check.

#include "cartesian_impedance/model/robot_model.hpp"

namespace model_simulation {

namespace ci = cartesian_impedance;

class Simulation {
  ci::ModelWorkspace workspace_;
  ci::Kinematics kinematics_;

 public:
  /// `firmware_gravity`: like Panda and iiwa, the robot adds g(q) to the commanded torque itself.
  Simulation(const ci::RobotModel& model, const ci::JointVector& q0, bool firmware_gravity = true,
             double joint_damping = 0.5, double armature = 0.1)
      : workspace_(model),
        kinematics_(workspace_.make_kinematics()),
        q(q0),
        dq(ci::JointVector::Zero(q0.size())),
        external(ci::JointVector::Zero(q0.size())),
        firmware_gravity_(firmware_gravity),
        joint_damping_(joint_damping),
        armature_(armature) {}

  void step(const ci::JointVector& tau, double dt) {
    workspace_.compute(q, dq, kinematics_, true);
    ci::JointVector force = tau + external - kinematics_.coriolis - joint_damping_ * dq;
    if (!firmware_gravity_) force -= kinematics_.gravity;
    ci::JointMatrix inertia = kinematics_.mass;
    inertia.diagonal().array() += armature_;
    const ci::JointVector ddq = inertia.llt().solve(force);
    // A link-side torque sensor: the drive's torque with the firmware's gravity, less what the
    // damping and the rotor took (gravity included, as Franka's tau_J).
    measured_torque = tau - joint_damping_ * dq - armature_ * ddq;
    if (firmware_gravity_) measured_torque += kinematics_.gravity;
    dq += ddq * dt;
    if (blocked_joint >= 0) dq[blocked_joint] = 0.0;
    q += dq * dt;
  }

  /// End-effector pose at the current q.
  ci::Pose pose() {
    workspace_.compute(q, dq, kinematics_, false);
    return kinematics_.pose;
  }
  ci::Jacobian jacobian() {
    workspace_.compute(q, dq, kinematics_, false);
    return kinematics_.jacobian;
  }

  ci::JointVector q, dq;
  ci::JointVector external;  ///< external joint torque [Nm], e.g. J^T F of a push
  /// What link-side joint torque sensors read in the last step [Nm] (zero before the first).
  ci::JointVector measured_torque = ci::JointVector::Zero(q.size());
  int blocked_joint = -1;  ///< a joint held still, as by an obstacle

 private:
  bool firmware_gravity_;
  double joint_damping_;
  double armature_;
};

}  // namespace model_simulation
