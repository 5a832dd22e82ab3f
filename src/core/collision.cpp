// The collision monitor: a generalized momentum observer (De Luca and Mattone 2005; Haddadin,
// De Luca and Albu-Schaeffer, "Robot Collisions: A Survey on Detection, Isolation, and
// Identification", 2017), detection against thresholds that grow with the torque the drives
// apply, isolation of the link, and the reactions of collision.reaction.
//
// The observer. The generalized momentum p = M(q) dq changes as dp/dt = tau - g + C^T dq +
// tau_ext (C^T dq, not C dq: dM/dt = C + C^T). With the drive's torque less gravity's part
// known, the rest of dp/dt is the external torque; the residual r follows it through a
// first-order filter of time constant 1/K_O, r' = K_O (tau_ext - r). It is written here in the
// filter's exact discrete form, r += (1 - e^(-K_O dt)) (dp/dt - tau + g - C^T dq - r), with dp/dt
// the momentum's change over the cycle: the classic form integrates the same difference, but
// with Euler's step it turns unstable past K_O dt = 2 (a 20 ms cycle at K_O = 100), and this
// form never does. No acceleration is measured and no joint velocity is differentiated alone.
//
// What acted. The torque sent last cycle acted since (a drive's own delay is part of the model's
// error). Gravity is compensated by the controller (dynamics.gravity_compensation, in
// tau_gravity) or by the robot's firmware, which adds the model's g(q) as the simulated firmware
// does; either way the drive's torque less tau_gravity is what moves the model beside gravity.
// tau_gravity also holds the declared payload's compensation: the payload's weight is then
// expected, and a payload declared wrongly shows as a contact on the last link.
//
// Or what was measured (collision.measured_torque): the joint torque sensors of the link side
// read, each cycle, what the drives passed to the links, gravity included. Less the model's g(q)
// and the payload's compensation, that is what moved the links; the drive's delay, its noise,
// the joints' friction and the rotors' inertia are then out of the residual, and only the
// model's error of the links is left in it.

#include <algorithm>
#include <cmath>

#include "cartesian_impedance/core/controller.hpp"
#include "law.hpp"

namespace cartesian_impedance {
namespace {

// Time constant of the end effector's velocity that says which way it was moving [s]: the
// retract reaction backs off along it where the contact is not on the last link.
constexpr double kMotionFilterTime = 0.05;
// Slower than this [m/s], the end effector was not moving anywhere to back off from.
constexpr double kMotionSpeed = 0.01;
// A report-only collision ends once every joint is below this share of its threshold.
constexpr double kClearShare = 0.5;

// How far `value` lies outside [low, high] less `allowance` (signed, zero within).
double beyond(double value, double low, double high, double allowance) noexcept {
  const double out = value > high ? value - high : (value < low ? value - low : 0.0);
  return std::copysign(std::max(0.0, std::abs(out) - allowance), out);
}

}  // namespace

bool CartesianImpedanceController::collision_latched() const noexcept {
  const CollisionState& collision = state_.collision;
  return collision.detected && collision.reaction != CollisionReaction::report;
}

void CartesianImpedanceController::forget_collision_observer() noexcept {
  observer_running_ = false;
}

void CartesianImpedanceController::observe_collision(const RobotState& robot, double dt) noexcept {
  CollisionState& collision = state_.collision;
  const CollisionParameters& parameters = parameters_.collision;
  const int n = num_joints_;
  if (resume_pending_) {
    resume_pending_ = false;
    if (collision_latched()) {
      hold_where_the_arm_is(robot);
      collision.detected = false;
    }
  }
  if (!parameters.detection || robot.mass.rows() != n || robot.coriolis_transposed.size() != n) {
    observer_running_ = false;
    collision.residual.setZero(n);
    collision.unexpected.setZero(n);
    collision.threshold.setZero(n);
    if (!collision_latched()) collision.detected = false;
    return;
  }
  // A measured torque is the link side's: the rotors' inertia (dynamics.armature, which the loop
  // adds to M) is behind the sensor, so the momentum it changes is the links' alone.
  const bool measured = parameters.measured_torque;
  JointVector momentum = robot.mass * robot.dq;
  JointVector applied;
  if (measured) {
    const JointVector& armature = parameters_.dynamics.armature;
    for (int i = 0; i < n; ++i) {
      momentum[i] -= armature[armature.size() == 1 ? 0 : i] * robot.dq[i];
    }
    applied = robot.measured_torque - robot.gravity - law_->tau_payload;
  } else {
    applied = state_.tau - state_.tau_gravity;
  }
  // The model's error grows with the torque it predicts the links take. With a measurement its
  // g(q) is part of that prediction (a firmware that compensates gravity keeps its own model's
  // error out of the torque sent, not out of a measured one), so the threshold scales with all
  // of it.
  const JointVector& predicted = measured ? robot.measured_torque : applied;
  if (measured != observer_measured_) {
    observer_measured_ = measured;
    observer_running_ = false;
  }
  // The filters' factors change only with dt and the gain: two exponentials saved per cycle.
  if (dt != observer_dt_ || parameters.observer_gain != observer_gain_) {
    observer_dt_ = dt;
    observer_gain_ = parameters.observer_gain;
    observer_follow_ = 1.0 - std::exp(-parameters.observer_gain * dt);
    motion_follow_ = 1.0 - std::exp(-dt / kMotionFilterTime);
  }
  const double follow = observer_follow_;
  if (!observer_running_) {
    // From rest at the first cycle, or after one that failed: the estimate starts at zero and the
    // thresholds at the torque applied now.
    observer_running_ = true;
    collision.residual.setZero(n);
    observer_applied_filtered_ = predicted.cwiseAbs();
    observer_wrench_filtered_ = -state_.tau_wrench;
    motion_direction_.setZero();
  } else {
    collision.residual += follow * ((momentum - observer_momentum_) / dt - applied -
                                    robot.coriolis_transposed - collision.residual);
    observer_applied_filtered_ += follow * (predicted.cwiseAbs() - observer_applied_filtered_);
    observer_wrench_filtered_ += follow * (-state_.tau_wrench - observer_wrench_filtered_);
  }
  observer_momentum_ = momentum;
  motion_direction_ +=
      motion_follow_ * (robot.jacobian.topRows<3>() * robot.dq - motion_direction_);

  // What is expected: the reaction to the commanded wrench (from none, before it meets anything,
  // to all of it, as the estimate follows it) and what a declared contact at the end effector
  // can press on each joint.
  const bool one_threshold = parameters.threshold.size() == 1;
  const bool declared_contact = parameters.contact_force > 0.0 || parameters.contact_torque > 0.0;
  const double noise = kCollisionNoiseSigmas * parameters.observer_gain * parameters.velocity_noise;
  int last = -1;
  bool clear = true;
  for (int i = 0; i < n; ++i) {
    const double wrench_now = -state_.tau_wrench[i];
    const double wrench_seen = observer_wrench_filtered_[i];
    const double allowance =
        declared_contact ? parameters.contact_force * robot.jacobian.col(i).head<3>().norm() +
                               parameters.contact_torque * robot.jacobian.col(i).tail<3>().norm()
                         : 0.0;
    collision.unexpected[i] =
        beyond(collision.residual[i], std::min({0.0, wrench_now, wrench_seen}),
               std::max({0.0, wrench_now, wrench_seen}), allowance);
    collision.threshold[i] = parameters.threshold[one_threshold ? 0 : i] +
                             parameters.threshold_fraction * observer_applied_filtered_[i] +
                             noise * robot.mass(i, i);
    const double share = std::abs(collision.unexpected[i]) / collision.threshold[i];
    if (share > 1.0) last = i;
    if (share >= kClearShare) clear = false;
  }
  if (!collision.detected && last >= 0) {
    collision.detected = true;
    collision.time = time_;
    collision.joint = last;
    collision.ratio = std::abs(collision.unexpected[last]) / collision.threshold[last];
    ++collision.collisions;
    // While teaching, a hand on the arm is what is expected: reported, not reacted to.
    const bool teaching = state_.commanded.stiffness.isZero(0.0);
    collision.reaction = teaching ? CollisionReaction::report : parameters.reaction;
    react_to_collision(robot);
  } else if (collision.detected && time_ - collision.time <= kCollisionIsolationTime &&
             last > collision.joint) {
    collision.joint = last;
  } else if (collision.detected && !collision_latched() && clear &&
             time_ - collision.time > kCollisionIsolationTime) {
    collision.detected = false;
  }
}

void CartesianImpedanceController::react_to_collision(const RobotState& robot) noexcept {
  // Every reaction holds where the arm is: the spring then brakes it with the damping instead of
  // pulling it on toward a reference beyond the contact. The retract's way out follows once the
  // contact's wrench is known (identify_contact()).
  if (state_.collision.reaction != CollisionReaction::report) hold_where_the_arm_is(robot);
}

void CartesianImpedanceController::identify_contact(const RobotState& robot) noexcept {
  CollisionState& collision = state_.collision;
  if (!collision.detected || time_ - collision.time > kCollisionIsolationTime) return;
  // The wrench at the end effector that explains r, (J J^T + lambda^2 I)^-1 J r, on the
  // projector's factorisation of this cycle: while the contact is isolated, not every cycle of a
  // long contact.
  law_->projector.task_force(robot.jacobian, parameters_.nullspace.pseudo_inverse_damping,
                             collision.residual, collision.contact_wrench);
  if (time_ != collision.time || collision.reaction != CollisionReaction::retract) return;
  // Away from the contact: along the force it presses with where it is on the last link (the
  // residual is then J^T of it), else back the way the end effector came.
  Eigen::Vector3d away = Eigen::Vector3d::Zero();
  const Eigen::Vector3d force = collision.contact_wrench.head<3>();
  if (collision.joint == num_joints_ - 1 && force.norm() > 1e-3) away = force.normalized();
  if (away.isZero(0.0) && motion_direction_.norm() > kMotionSpeed) {
    away = -motion_direction_.normalized();
  }
  // From the next cycle the filter and the speed caps take the reference there; the filtered one
  // stays at the arm.
  state_.commanded.pose.position += parameters_.collision.retract_distance * away;
}

}  // namespace cartesian_impedance
