// The control law of CartesianImpedanceController, one function per term (the formulas are in
// controller.hpp and math.hpp), and the limits that follow it.

#include <algorithm>
#include <cmath>
#include <limits>

#include "law.hpp"

namespace cartesian_impedance {

namespace {

inline void rotate_six(const Eigen::Matrix3d& rotation, const Vector6d& in, Vector6d& out) {
  out.head<3>().noalias() = rotation * in.head<3>();
  out.tail<3>().noalias() = rotation * in.tail<3>();
}

inline void rotate_six_inverse(const Eigen::Matrix3d& rotation, const Vector6d& in, Vector6d& out) {
  out.head<3>().noalias() = rotation.transpose() * in.head<3>();
  out.tail<3>().noalias() = rotation.transpose() * in.tail<3>();
}

// The first element of a torque term that is not finite, as a fault naming the term.
bool find_non_finite(const JointVector& term, const char* name, Fault& fault) noexcept {
  for (Eigen::Index i = 0; i < term.size(); ++i) {
    if (!std::isfinite(term[i])) {
      fault = Fault{name, static_cast<int>(i), term[i], "is not finite"};
      return true;
    }
  }
  return false;
}

}  // namespace

CartesianImpedanceController::Law::Law(int num_joints)
    : damping_frame(Matrix6d::Zero()),
      damping_computed_for_ratio(Vector6d::Constant(std::numeric_limits<double>::quiet_NaN())),
      nullspace_damping(JointVector::Zero(num_joints)),
      tau_0(JointVector::Zero(num_joints)),
      max_step(JointVector::Zero(num_joints)) {
  forget_damping();
}

bool CartesianImpedanceController::evaluate_law(const RobotState& robot, Fault& fault) noexcept {
  measure_pose(robot);
  if (!compute_damping(robot, fault)) return false;
  spring_damper(robot);
  if (!nullspace(robot, fault)) return false;
  commanded_wrench(robot);
  gravity(robot);
  state_.tau = state_.tau_cartesian + state_.tau_nullspace + state_.tau_wrench + state_.tau_gravity;
  if (state_.tau.allFinite()) return true;
  // Name the term that overflowed or became NaN.
  if (find_non_finite(state_.tau_cartesian, "tau_cartesian", fault) ||
      find_non_finite(state_.tau_nullspace, "tau_nullspace", fault) ||
      find_non_finite(state_.tau_wrench, "tau_wrench", fault) ||
      find_non_finite(state_.tau_gravity, "tau_gravity", fault)) {
    return false;
  }
  find_non_finite(state_.tau, "tau", fault);  // finite terms whose sum overflows
  return false;
}

// Status::motion_halted: no spring, the minimum damping alone (Cartesian and nullspace, in the
// base frame), the gravity torque as usual: a passive law whose torque changes slowly enough for
// any rate limit, which brings a moving arm to rest.
bool CartesianImpedanceController::evaluate_halt(const RobotState& robot, Fault& fault) noexcept {
  measure_pose(robot);
  const MinimumDampingParameters& minimum = parameters_.minimum_damping;
  Vector6d damping;
  damping << Eigen::Vector3d::Constant(minimum.translation),
      Eigen::Vector3d::Constant(minimum.rotation);
  state_.damping = damping.asDiagonal();
  Vector6d velocity;
  jacobian_times(robot.jacobian, robot.dq, velocity);
  const Vector6d force = -damping.cwiseProduct(velocity);
  jacobian_transpose_times(robot.jacobian, force, state_.tau_cartesian);
  law_->tau_0 = -minimum.nullspace * robot.dq;
  law_->projector.project(robot.jacobian, parameters_.nullspace.pseudo_inverse_damping, law_->tau_0,
                          state_.tau_nullspace);
  state_.tau_wrench.setZero();
  gravity(robot);
  state_.tau = state_.tau_cartesian + state_.tau_nullspace + state_.tau_gravity;
  if (state_.tau.allFinite()) return true;
  find_non_finite(state_.tau, "tau", fault);
  return false;
}

// e = [p - p_d; log(R R_d^T)], clipped so that a far reference pulls no harder than a near one.
void CartesianImpedanceController::measure_pose(const RobotState& robot) noexcept {
  state_.pose.position = robot.pose.position;
  state_.pose.orientation = robot.pose.orientation.normalized();
  law_->rotation = state_.pose.orientation.toRotationMatrix();
  Vector6d& error = state_.pose_error;
  error = pose_error(state_.pose, state_.filtered.pose);
  ActiveLimits& limits = state_.limits;
  limits.translation_error_clipped =
      clip_norm(error.head<3>(), parameters_.limits.pose_error.translation);
  limits.rotation_error_clipped =
      clip_norm(error.tail<3>(), parameters_.limits.pose_error.rotation);
}

// D in the stiffness frame, never below the minimum damping. It follows the filtered K: a
// diagonal K (the common case) needs six square roots; a full one a 6x6 eigen-decomposition,
// done only while K or zeta move. Shaped by the task-space inertia (the default), it changes with
// q and is computed every cycle. A schedule() gives D directly.
bool CartesianImpedanceController::compute_damping(const RobotState& robot, Fault& fault) noexcept {
  Law& law = *law_;
  const Targets& filtered = state_.filtered;
  law.damping_diagonal = stiffness_diagonal_;
  if (scheduled_) {
    law.damping_frame = scheduled_damping_;
    law.damping_diagonal = stiffness_diagonal_ && scheduled_damping_diagonal_;
  } else if (parameters_.dynamics.inertia_shaped_damping) {
    const bool in_base = parameters_.stiffness.frame == Frame::base;
    if (!law.inertia_damping.compute(robot.jacobian, robot.mass,
                                     parameters_.nullspace.pseudo_inverse_damping,
                                     in_base ? nullptr : &law.rotation, filtered.stiffness,
                                     filtered.damping_ratio, law.damping_frame)) {
      fault = Fault{"damping",
                    -1,
                    0.0,
                    "cannot be shaped by the task-space inertia: M(q) or J M^-1 J^T is not "
                    "positive definite, or D is not finite (dynamics.inertia_shaped_damping)",
                    0.0,
                    false,
                    "",
                    Fault::Form::statement};
      return false;
    }
    law.forget_damping();
    law.damping_diagonal = false;
  } else if (stiffness_diagonal_) {
    law.damping_frame.diagonal() =
        2.0 * filtered.damping_ratio.cwiseProduct(filtered.stiffness.diagonal().cwiseSqrt());
  } else if (filtered.stiffness != law.damping_computed_for_stiffness ||
             filtered.damping_ratio != law.damping_computed_for_ratio) {
    law.damping_frame = damping_from_stiffness(filtered.stiffness, filtered.damping_ratio);
    law.damping_computed_for_stiffness = filtered.stiffness;
    law.damping_computed_for_ratio = filtered.damping_ratio;
  }
  // The damping floor keeps a soft arm (teaching: K = 0, so D = 0) from coasting. Raising the
  // diagonal by a non-negative amount keeps D symmetric positive semi-definite.
  Matrix6d& damping = state_.damping;
  damping = law.damping_frame;
  const MinimumDampingParameters& minimum = parameters_.minimum_damping;
  for (int i = 0; i < 6; ++i) {
    damping(i, i) = std::max(damping(i, i), i < 3 ? minimum.translation : minimum.rotation);
  }
  return true;
}

// tau_cartesian = J^T (-K e - D (J dq - v_ref)): spring and damper in the stiffness frame; in the
// end-effector frame the error and velocity are rotated in and the wrench back out. The damper
// acts on the velocity relative to the reference's (zero unless tracking).
void CartesianImpedanceController::spring_damper(const RobotState& robot) noexcept {
  const Targets& filtered = state_.filtered;
  const Eigen::Matrix3d& rotation = law_->rotation;
  const bool in_base = parameters_.stiffness.frame == Frame::base;
  Vector6d velocity;
  jacobian_times(robot.jacobian, robot.dq, velocity);
  velocity -= filtered.twist;
  Vector6d error_frame, velocity_frame, force_frame;
  if (in_base) {
    error_frame = state_.pose_error;
    velocity_frame = velocity;
  } else {
    rotate_six_inverse(rotation, state_.pose_error, error_frame);
    rotate_six_inverse(rotation, velocity, velocity_frame);
  }
  const Matrix6d& damping = state_.damping;
  if (law_->damping_diagonal) {
    force_frame = -filtered.stiffness.diagonal().cwiseProduct(error_frame) -
                  damping.diagonal().cwiseProduct(velocity_frame);
  } else {
    force_frame.noalias() = -filtered.stiffness * error_frame;
    force_frame.noalias() -= damping * velocity_frame;
  }
  Vector6d force;
  if (in_base) {
    force = force_frame;
  } else {
    rotate_six(rotation, force_frame, force);
  }
  jacobian_transpose_times(robot.jacobian, force, state_.tau_cartesian);
}

// tau_nullspace = N tau_0, tau_0 = -K_ns (q - q_d) - D_ns (dq - dq_d) + a secondary task's torque:
// joint impedance projected so that it does not disturb the end effector.
bool CartesianImpedanceController::nullspace(const RobotState& robot, Fault& fault) noexcept {
  Law& law = *law_;
  const Targets& filtered = state_.filtered;
  const JointVector& stiffness_ns = filtered.nullspace_stiffness;
  if (scheduled_) {
    law.nullspace_damping = scheduled_nullspace_damping_;
  } else {
    law.nullspace_damping = (2.0 * filtered.nullspace_damping_ratio) * stiffness_ns.cwiseSqrt();
  }
  law.tau_0 = -stiffness_ns.cwiseProduct(robot.q - filtered.nullspace_q) -
              law.nullspace_damping.cwiseMax(parameters_.minimum_damping.nullspace)
                  .cwiseProduct(robot.dq - filtered.nullspace_dq);
  if (robot.secondary_torque.size() == num_joints_) law.tau_0 += robot.secondary_torque;
  const double lambda = parameters_.nullspace.pseudo_inverse_damping;
  if (parameters_.dynamics.dynamically_consistent_nullspace) {
    if (!law.projector.project_dynamic(robot.jacobian, robot.mass, lambda, law.tau_0,
                                       state_.tau_nullspace)) {
      fault = Fault{"nullspace",
                    -1,
                    0.0,
                    "cannot be projected dynamically consistently: M(q) is not positive definite "
                    "(dynamics.dynamically_consistent_nullspace)",
                    0.0,
                    false,
                    "",
                    Fault::Form::statement};
      return false;
    }
  } else {
    law.projector.project(robot.jacobian, lambda, law.tau_0, state_.tau_nullspace);
  }
  return true;
}

// tau_wrench = J^T F, with F rotated into the base frame when it is given in the end effector's.
void CartesianImpedanceController::commanded_wrench(const RobotState& robot) noexcept {
  if (parameters_.wrench.frame == Frame::base) {
    state_.wrench_base = state_.filtered.wrench;
  } else {
    rotate_six(law_->rotation, state_.filtered.wrench, state_.wrench_base);
  }
  jacobian_transpose_times(robot.jacobian, state_.wrench_base, state_.tau_wrench);
}

// tau_gravity = g(q) when the law compensates gravity, else zero.
void CartesianImpedanceController::gravity(const RobotState& robot) noexcept {
  if (parameters_.dynamics.gravity_compensation) {
    state_.tau_gravity = robot.gravity;
  } else {
    state_.tau_gravity.setZero();
  }
}

void CartesianImpedanceController::limit_torque(double dt) noexcept {
  // The bound in force ramps down toward limits.joint_torque at the rate limit (and never sits
  // below it), so a lowered limit is reached as fast as the rate limit allows. The torque is
  // clamped to that bound before and after the rate limit: the previous torque lies within the
  // previous bound, so the clamp after the rate limit moves each joint by at most rate * dt.
  JointVector& bound = state_.joint_torque_limit;
  JointVector& max_step = law_->max_step;
  max_step = joint_torque_rate_limit_ * dt;
  bound = (bound - max_step).cwiseMax(joint_torque_limit_);
  state_.limits.joint_torque_limit_ramping = (bound.array() > joint_torque_limit_.array()).any();
  state_.limits.joint_torque_saturated = saturate_torque(bound, state_.tau);
  state_.limits.torque_rate_limited = limit_rate(tau_previous_, max_step, state_.tau);
  saturate_torque(bound, state_.tau);
  tau_previous_ = state_.tau;
}

}  // namespace cartesian_impedance
