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
      max_step(JointVector::Zero(num_joints)),
      tau_spring(JointVector::Zero(num_joints)),
      tau_damping(JointVector::Zero(num_joints)),
      tau_kept(JointVector::Zero(num_joints)),
      joint_drive(JointVector::Zero(num_joints)),
      joint_wall_torque(JointVector::Zero(num_joints)),
      tau_payload(JointVector::Zero(num_joints)),
      nullspace_q_before(JointVector::Zero(num_joints)),
      nullspace_stiffness_before(JointVector::Zero(num_joints)),
      nullspace_damping_torque(JointVector::Zero(num_joints)),
      nullspace_damping_projected(JointVector::Zero(num_joints)),
      governor_joint(JointVector::Zero(num_joints)) {
  for (JointVector& torque : torque_sent) torque.setZero(num_joints);
  forget_damping();
}

bool CartesianImpedanceController::evaluate_law(const RobotState& robot, double dt,
                                                Fault& fault) noexcept {
  measure_pose(robot);
  charge_parameter_changes(robot);
  clip_pose_error();
  const JointMatrix& mass = mass_with_payload(robot);
  if (!compute_damping(robot, mass, fault)) return false;
  spring_damper(robot, dt);
  watch_oscillation(dt);
  if (!nullspace(robot, mass, fault)) return false;
  measure_nullspace_dissipation(robot, dt);
  commanded_wrench();
  safety_layer(robot, mass, dt);
  cartesian_torques(robot);
  gravity(robot);
  estimate_payload(dt);
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
  // Scaled as the law's damping is by the oscillation watch: on a light wrist a damper acting on
  // a late measurement pumps energy in as a spring does (measured: the full minimum damping
  // swung a Panda's wrist at 10 rad/s behind 50 ms of delay).
  const double scale = std::sqrt(state_.safety.oscillation_scale);
  Vector6d damping;
  damping << Eigen::Vector3d::Constant(scale * minimum.translation),
      Eigen::Vector3d::Constant(scale * minimum.rotation);
  state_.damping = damping.asDiagonal();
  Vector6d velocity;
  jacobian_times(robot.jacobian, robot.dq, velocity);
  const Vector6d force = -damping.cwiseProduct(velocity);
  jacobian_transpose_times(robot.jacobian, force, state_.tau_cartesian);
  law_->tau_0 = -(scale * minimum.nullspace) * robot.dq;
  law_->projector.project(robot.jacobian, parameters_.nullspace.pseudo_inverse_damping, law_->tau_0,
                          state_.tau_nullspace);
  state_.tau_wrench.setZero();
  law_->wall_force_sent.setZero();
  law_->wall_spring_sent.setZero();
  law_->wall_damper_sent.setZero();
  law_->expecting = false;
  gravity(robot);
  state_.tau = state_.tau_cartesian + state_.tau_nullspace + state_.tau_gravity;
  if (state_.tau.allFinite()) return true;
  find_non_finite(state_.tau, "tau", fault);
  return false;
}

// e = [p - p_d; log(R R_d^T)].
void CartesianImpedanceController::measure_pose(const RobotState& robot) noexcept {
  state_.pose.position = robot.pose.position;
  state_.pose.orientation = robot.pose.orientation.normalized();
  law_->rotation = state_.pose.orientation.toRotationMatrix();
  law_->unclipped_error = pose_error(state_.pose, state_.filtered.pose);
  state_.pose_error = law_->unclipped_error;
}

// The error clipped (with the limits in force, which the tank may hold back) so that a far
// reference pulls no harder than a near one.
void CartesianImpedanceController::clip_pose_error() noexcept {
  Vector6d& error = state_.pose_error;
  const PoseErrorLimits& clip = state_.safety.pose_error_in_force;
  ActiveLimits& limits = state_.limits;
  limits.translation_error_clipped = clip_norm(error.head<3>(), clip.translation);
  limits.rotation_error_clipped = clip_norm(error.tail<3>(), clip.rotation);
}

// D in the stiffness frame, never below the minimum damping. It follows the filtered K: a
// diagonal K (the common case) needs six square roots; a full one a 6x6 eigen-decomposition,
// done only while K or zeta move. Shaped by the task-space inertia (the default), it changes with
// q and is computed every cycle. A schedule() gives D directly.
bool CartesianImpedanceController::compute_damping(const RobotState& robot, const JointMatrix& mass,
                                                   Fault& fault) noexcept {
  Law& law = *law_;
  const Targets& filtered = state_.filtered;
  law.damping_diagonal = stiffness_diagonal_;
  law.inertia_damping.inertia().invalidate();  // computed anew by the inertia-shaped damping
  if (scheduled_) {
    // The oscillation watch's scale of the stiffness takes the damping down by its square root:
    // the damping ratio is kept, as a damping derived from ratios keeps it.
    law.damping_frame = law.oscillation_damping_scale * scheduled_damping_;
    law.damping_diagonal = stiffness_diagonal_ && scheduled_damping_diagonal_;
  } else if (parameters_.dynamics.inertia_shaped_damping) {
    const bool in_base = parameters_.stiffness.frame == Frame::base;
    if (!law.inertia_damping.compute(robot.jacobian, mass,
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
  // (Lowered with the stiffness by the oscillation watch, by the square root as the damping is.)
  const MinimumDampingParameters& minimum = parameters_.minimum_damping;
  const double scale = law.oscillation_damping_scale;
  const double floor_translation = scale * minimum.translation;
  const double floor_rotation = scale * minimum.rotation;
  for (int i = 0; i < 6; ++i) {
    damping(i, i) = std::max(damping(i, i), i < 3 ? floor_translation : floor_rotation);
  }
  return true;
}

// F = -K e - D (J dq - v_ref): spring and damper in the stiffness frame, kept apart (in the base
// frame) for the safety layer and the torque shaping; in the end-effector frame the error and
// velocity are rotated in and the forces back out. The damper acts on the velocity relative to
// the reference's (zero unless tracking). What the damper dissipates fills the energy tank.
void CartesianImpedanceController::spring_damper(const RobotState& robot, double dt) noexcept {
  Law& law = *law_;
  const Targets& filtered = state_.filtered;
  const Eigen::Matrix3d& rotation = law.rotation;
  const bool in_base = parameters_.stiffness.frame == Frame::base;
  jacobian_times(robot.jacobian, robot.dq, law.twist);
  const Vector6d velocity = law.twist - filtered.twist;
  Vector6d error_frame, velocity_frame;
  if (in_base) {
    error_frame = state_.pose_error;
    velocity_frame = velocity;
  } else {
    rotate_six_inverse(rotation, state_.pose_error, error_frame);
    rotate_six_inverse(rotation, velocity, velocity_frame);
  }
  const Matrix6d& damping = state_.damping;
  Vector6d spring_frame, damping_frame;
  if (law.damping_diagonal) {
    spring_frame = -filtered.stiffness.diagonal().cwiseProduct(error_frame);
    damping_frame = -damping.diagonal().cwiseProduct(velocity_frame);
  } else {
    spring_frame.noalias() = -filtered.stiffness * error_frame;
    damping_frame.noalias() = -damping * velocity_frame;
  }
  if (in_base) {
    law.spring_force = spring_frame;
    law.damping_force = damping_frame;
  } else {
    rotate_six(rotation, spring_frame, law.spring_force);
    rotate_six(rotation, damping_frame, law.damping_force);
  }
  law.dissipated_cartesian = -damping_frame.dot(velocity_frame) * dt;
  // What the damper takes out of the arm's own motion, -v^T D v (translation, rotation), for the
  // passivity observer: its force on the reference's velocity, D v_ref, drives the arm along a
  // moving reference as the spring's moving anchor does, and is no dissipation.
  Vector6d twist_frame;
  if (in_base) {
    twist_frame = law.twist;
  } else {
    rotate_six_inverse(rotation, law.twist, twist_frame);
  }
  Vector6d damped;
  if (law.damping_diagonal) {
    damped = damping.diagonal().cwiseProduct(twist_frame);
  } else {
    damped.noalias() = damping * twist_frame;
  }
  law.damper_power = {-damped.head<3>().dot(twist_frame.head<3>()),
                      -damped.tail<3>().dot(twist_frame.tail<3>())};
}

// tau_cartesian = J^T (spring + damping, walls and brake), after the safety layer, plus the
// joint-limit walls (in joint space, unprojected).
// (The safety envelope's correction of the joint-limit walls, what it took off their task-space
// force, is in the damping force.)
void CartesianImpedanceController::cartesian_torques(const RobotState& robot) noexcept {
  const Vector6d force = law_->spring_force + law_->damping_force;
  jacobian_transpose_times(robot.jacobian, force, state_.tau_cartesian);
  if (law_->joint_walls) state_.tau_cartesian += law_->joint_wall_torque;
  state_.safety.joint_limit_wall = law_->joint_walls;
  jacobian_transpose_times(robot.jacobian, state_.wrench_base, state_.tau_wrench);
}

// tau_nullspace = N tau_0, tau_0 = -K_ns (q - q_d) - D_ns (dq - dq_d) + a secondary task's torque:
// joint impedance projected so that it does not disturb the end effector.
bool CartesianImpedanceController::nullspace(const RobotState& robot, const JointMatrix& mass,
                                             Fault& fault) noexcept {
  Law& law = *law_;
  const Targets& filtered = state_.filtered;
  const JointVector& stiffness_ns = filtered.nullspace_stiffness;
  if (scheduled_) {
    law.nullspace_damping = law.oscillation_damping_scale * scheduled_nullspace_damping_;
  } else {
    law.nullspace_damping = (2.0 * filtered.nullspace_damping_ratio) * stiffness_ns.cwiseSqrt();
  }
  law.nullspace_damping_torque =
      -law.nullspace_damping
           .cwiseMax(law.oscillation_damping_scale * parameters_.minimum_damping.nullspace)
           .cwiseProduct(robot.dq - filtered.nullspace_dq);
  law.tau_0 =
      law.nullspace_damping_torque - stiffness_ns.cwiseProduct(robot.q - filtered.nullspace_q);
  if (robot.secondary_torque.size() == num_joints_) law.tau_0 += robot.secondary_torque;
  const double lambda = parameters_.nullspace.pseudo_inverse_damping;
  if (parameters_.dynamics.dynamically_consistent_nullspace) {
    if (!law.projector.project_dynamic(robot.jacobian, mass, lambda, law.tau_0,
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

// What the projected nullspace damping dissipates, (dq - dq_d)^T N D_ns (dq - dq_d) dt, fills the
// tank too (fill_tank()), so that a raise of the nullspace stiffness paid from it is paid back by
// the motion it causes. Only while the tank is not full (then nothing can be added): the extra
// projection reuses the cycle's factorisation.
void CartesianImpedanceController::measure_nullspace_dissipation(const RobotState& robot,
                                                                 double dt) noexcept {
  const EnergyTankParameters& tank = parameters_.safety.energy_tank;
  Law& law = *law_;
  law.dissipated_nullspace = 0.0;
  if (!tank.enabled || scheduled_ || !(state_.safety.tank_level < tank.capacity)) return;
  law.projector.project_again(robot.jacobian, law.nullspace_damping_torque,
                              law.nullspace_damping_projected);
  law.dissipated_nullspace =
      -(robot.dq - state_.filtered.nullspace_dq).dot(law.nullspace_damping_projected) * dt;
}

// F in the base frame, rotated there when it is given in the end effector's; tau_wrench = J^T F
// follows the safety layer (cartesian_torques).
void CartesianImpedanceController::commanded_wrench() noexcept {
  if (parameters_.wrench.frame == Frame::base) {
    state_.wrench_base = state_.filtered.wrench;
  } else {
    rotate_six(law_->rotation, state_.filtered.wrench, state_.wrench_base);
  }
}

// tau_gravity = g(q) when the law compensates gravity, else zero; plus J^T of the wrench that
// holds the payload up.
void CartesianImpedanceController::gravity(const RobotState& robot) noexcept {
  if (parameters_.dynamics.gravity_compensation) {
    state_.tau_gravity = robot.gravity;
  } else {
    state_.tau_gravity.setZero();
  }
  const SafetyState& safety = state_.safety;
  JointVector& tau_payload = law_->tau_payload;
  if (safety.payload_mass > 0.0) {
    jacobian_transpose_times(robot.jacobian, payload_holding_wrench(), tau_payload);
    state_.tau_gravity += tau_payload;
  } else {
    tau_payload.setZero(num_joints_);
  }
}

namespace {

// The largest a in [0, 1] for which kept + a part lies within [-bound, bound] on every joint, or
// -1 if `kept` alone does not (then `part` has to go, and what comes before it too).
double largest_fitting_scale(const JointVector& kept, const JointVector& part,
                             const JointVector& bound) noexcept {
  double scale = 1.0;
  for (Eigen::Index i = 0; i < kept.size(); ++i) {
    const double room_up = bound[i] - kept[i];
    const double room_down = -bound[i] - kept[i];
    // Rounding in the sums may put `kept` a few ulps outside a bound it touches.
    const double slack = 1e-12 * bound[i];
    if (room_up < -slack || room_down > slack) return -1.0;
    if (part[i] > 0.0) scale = std::min(scale, std::max(room_up, 0.0) / part[i]);
    if (part[i] < 0.0) scale = std::min(scale, std::min(room_down, 0.0) / part[i]);
  }
  return scale;
}

}  // namespace

// The bound in force ramps down toward limits.joint_torque at the rate limit (and never sits
// below it), so a lowered limit is reached as fast as the rate limit allows. The law's torque
// (`law_robot` given) is first shaped in task space to fit it; the halt's and a failed cycle's
// (damping and gravity only) are clamped per joint. The torque is clamped to the bound before and
// after the rate limit: the previous torque lies within the previous bound, so the clamp after
// the rate limit moves each joint by at most rate * dt.
void CartesianImpedanceController::limit_torque(double dt, const RobotState* law_robot) noexcept {
  JointVector& bound = state_.joint_torque_limit;
  ActiveLimits& limits = state_.limits;
  law_->max_step = joint_torque_rate_limit_ * dt;
  bound = (bound - law_->max_step).cwiseMax(joint_torque_limit_);
  limits.joint_torque_limit_ramping = (bound.array() > joint_torque_limit_.array()).any();
  limits.torque_shaping = TorqueShaping::none;
  limits.torque_shaping_scale = 1.0;
  if (law_robot != nullptr) shape_torque(*law_robot, bound);
  // After the shaping, the clamp acts only where gravity alone does not fit.
  const bool clamped = saturate_torque(bound, state_.tau);
  limits.joint_torque_saturated = clamped || limits.torque_shaping != TorqueShaping::none;
  limits.torque_rate_limited = limit_rate(tau_previous_, law_->max_step, state_.tau);
  saturate_torque(bound, state_.tau);
  tau_previous_ = state_.tau;
  law_->torque_clamped = clamped;
  if (law_robot != nullptr) fill_tank();
}

// Clipping each joint's torque on its own turns the Cartesian force into one of another direction:
// a stiff spring the joints cannot deliver then pushes the arm sideways, the error grows, and the
// clipped spring feeds a limit cycle. Instead the terms give way whole, in task space, in the
// order of what the arm can best do without: the nullspace torque first (it never moves the end
// effector), then the spring (scaled, it still pulls straight toward the reference, with less
// force: a softer spring while the error is large), then the commanded wrench, then a declared
// payload's compensation (which pushes the arm if the load is not there); the damping last,
// since it is what takes energy out of the motion; gravity is never scaled, only clipped. Each
// scale is the largest that fits, a continuous function of the state, so the torque stays
// continuous where the shaping starts and where it hands from one term to the next.
void CartesianImpedanceController::shape_torque(const RobotState& robot,
                                                const JointVector& bound) noexcept {
  ActiveLimits& limits = state_.limits;
  JointVector& tau = state_.tau;
  if ((tau.array().abs() <= bound.array()).all()) return;
  Law& law = *law_;
  // tau = gravity + damping + wrench + spring + nullspace: what is kept when a term gives way is
  // the law's torque less that term and those before it, so each stage costs one subtraction and
  // the spring's own torque is computed only if the nullspace alone cannot make room.
  JointVector& kept = law.tau_kept;
  const auto give_way = [&](const JointVector& part, TorqueShaping term) {
    const double scale = largest_fitting_scale(kept, part, bound);
    if (scale < 0.0) return false;
    tau = kept + scale * part;
    limits.torque_shaping = term;
    limits.torque_shaping_scale = scale;
    return true;
  };
  kept = tau - state_.tau_nullspace;
  if (give_way(state_.tau_nullspace, TorqueShaping::nullspace)) return;
  jacobian_transpose_times(robot.jacobian, law.spring_force, law.tau_spring);
  kept -= law.tau_spring;
  if (give_way(law.tau_spring, TorqueShaping::spring)) return;
  kept -= state_.tau_wrench;
  if (give_way(state_.tau_wrench, TorqueShaping::wrench)) return;
  // A declared payload's compensation before the damping: if it is not carried it pushes the arm,
  // and what brakes that is the damping.
  kept -= law.tau_payload;
  if (give_way(law.tau_payload, TorqueShaping::payload)) return;
  law.tau_damping = kept - (state_.tau_gravity - law.tau_payload);
  kept = state_.tau_gravity - law.tau_payload;
  if (give_way(law.tau_damping, TorqueShaping::damping)) return;
  tau = kept;
  limits.torque_shaping = TorqueShaping::gravity;
  limits.torque_shaping_scale = 0.0;
}

}  // namespace cartesian_impedance
