#include "cartesian_impedance/controller.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <string>

#include "cartesian_impedance/error.hpp"
#include "checks.hpp"

namespace cartesian_impedance {
namespace {

bool clamp_each(Eigen::Ref<Eigen::VectorXd> values, const Range& range) {
  bool clamped = false;
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    const double value = std::clamp(values[i], range.min, range.max);
    clamped |= value != values[i];
    values[i] = value;
  }
  return clamped;
}

// Diagonal stiffness/damping from the [translation; rotation] halves of the parameters.
Vector6d stacked(const Eigen::Vector3d& translation, const Eigen::Vector3d& rotation) {
  Vector6d result;
  result << translation, rotation;
  return result;
}

inline void rotate_six(const Eigen::Matrix3d& rotation, const Vector6d& in, Vector6d& out) {
  out.head<3>().noalias() = rotation * in.head<3>();
  out.tail<3>().noalias() = rotation * in.tail<3>();
}

inline void rotate_six_inverse(const Eigen::Matrix3d& rotation, const Vector6d& in, Vector6d& out) {
  out.head<3>().noalias() = rotation.transpose() * in.head<3>();
  out.tail<3>().noalias() = rotation.transpose() * in.tail<3>();
}

}  // namespace

const char* to_string(Status status) noexcept {
  switch (status) {
    case Status::ok:
      return "ok";
    case Status::not_started:
      return "not_started";
    case Status::invalid_dt:
      return "invalid_dt";
    case Status::invalid_robot_state:
      return "invalid_robot_state";
    case Status::numerical_error:
      return "numerical_error";
    case Status::missing_dynamics:
      return "missing_dynamics";
    case Status::model_error:
      return "model_error";
  }
  return "unknown";
}

std::string to_string(const Fault& fault) {
  if (fault.input == nullptr || fault.input[0] == '\0') return "";
  std::string text = fault.input;
  if (fault.index >= 0) text += "[" + std::to_string(fault.index) + "]";
  text += std::string(" = ") + format_number(fault.value) + " " + fault.reason;
  if (fault.has_bound) text += " = " + format_number(fault.bound);
  return text;
}

namespace {
Matrix6d in_base(const Matrix6d& matrix, Frame frame, const Eigen::Quaterniond& orientation) {
  if (frame == Frame::base) return matrix;
  const Matrix6d rotation6 = block_rotation(orientation.toRotationMatrix());
  return rotation6 * matrix * rotation6.transpose();
}
}  // namespace

Matrix6d ControllerState::stiffness_base() const noexcept {
  return in_base(filtered.stiffness, stiffness_frame, pose.orientation);
}

Matrix6d ControllerState::damping_base() const noexcept {
  return in_base(damping, stiffness_frame, pose.orientation);
}

CartesianImpedanceController::CartesianImpedanceController(int num_joints,
                                                           const Parameters& parameters)
    : num_joints_(num_joints) {
  if (num_joints < 1 || num_joints > kMaxJoints) {
    throw Error("num_joints = " + std::to_string(num_joints) + " is outside [1, " +
                std::to_string(kMaxJoints) + "]");
  }
  const Eigen::Index n = num_joints;
  Targets& commanded = state_.commanded;
  commanded.stiffness.setZero();
  commanded.damping_ratio.setZero();
  commanded.nullspace_q = JointVector::Zero(n);
  commanded.nullspace_stiffness = JointVector::Zero(n);
  commanded.wrench.setZero();
  commanded.twist.setZero();
  commanded.nullspace_dq = JointVector::Zero(n);
  state_.filtered = commanded;
  state_.pose_error.setZero();
  state_.wrench_base.setZero();
  state_.tau_cartesian = JointVector::Zero(n);
  state_.tau_nullspace = JointVector::Zero(n);
  state_.tau_wrench = JointVector::Zero(n);
  state_.tau_gravity = JointVector::Zero(n);
  state_.tau = JointVector::Zero(n);
  state_.joint_torque_limit = JointVector::Zero(n);
  tau_previous_ = JointVector::Zero(n);
  max_step_ = JointVector::Zero(n);
  tau_0_ = JointVector::Zero(n);
  nullspace_damping_ = JointVector::Zero(n);
  scheduled_nullspace_damping_ = JointVector::Zero(n);
  scheduled_damping_.setZero();
  damping_frame_.setZero();
  state_.damping.setZero();
  damping_computed_for_stiffness_.setConstant(std::nan(""));
  damping_computed_for_ratio_.setConstant(std::nan(""));
  set_parameters(parameters);
}

void CartesianImpedanceController::apply_saturation(Targets& commanded, ActiveLimits& limits,
                                                    const Command& command) const noexcept {
  // Every commanded value is brought within the (possibly new) limits. A quantity's flag says
  // whether its last command was saturated: it is set afresh for the quantity just commanded
  // (all of them for new parameters) and otherwise only raised, never cleared by an unrelated
  // command.
  const LimitParameters& l = parameters_.limits;
  const bool all = std::holds_alternative<Parameters>(command);
  auto update = [all](bool& flag, bool saturated, bool commanded_now) {
    flag = (all || commanded_now) ? saturated : (flag || saturated);
  };
  update(limits.stiffness_saturated,
         saturate_stiffness(commanded.stiffness, l.stiffness.translation.min,
                            l.stiffness.translation.max, l.stiffness.rotation.min,
                            l.stiffness.rotation.max),
         std::holds_alternative<Stiffness>(command));
  Eigen::Matrix<double, 1, 1> nullspace_zeta(commanded.nullspace_damping_ratio);
  const bool cartesian_zeta = clamp_each(commanded.damping_ratio, l.damping_ratio);
  const bool nullspace_zeta_clamped = clamp_each(nullspace_zeta, l.damping_ratio);
  commanded.nullspace_damping_ratio = nullspace_zeta[0];
  update(limits.damping_ratio_saturated, cartesian_zeta || nullspace_zeta_clamped,
         std::holds_alternative<DampingRatio>(command) ||
             std::holds_alternative<NullspaceDampingRatio>(command));
  update(limits.nullspace_stiffness_saturated,
         clamp_each(commanded.nullspace_stiffness, l.nullspace_stiffness),
         std::holds_alternative<NullspaceStiffness>(command));
  const bool force_clipped = clip_norm(commanded.wrench.head<3>(), l.wrench.force);
  const bool torque_clipped = clip_norm(commanded.wrench.tail<3>(), l.wrench.torque);
  update(limits.wrench_saturated, force_clipped || torque_clipped,
         std::holds_alternative<Wrench>(command));
}

void CartesianImpedanceController::change_frames(Frame stiffness_frame,
                                                 Frame wrench_frame) noexcept {
  // The filtered values live in the frame they were commanded in; when the frame changes they
  // are re-expressed in the new one (with the last measured orientation) so the filter carries
  // on from where the robot is instead of jumping.
  if (!started_) return;
  const Eigen::Matrix3d rotation = state_.pose.orientation.toRotationMatrix();
  const Matrix6d rotation6 = block_rotation(rotation);
  Targets& filtered = state_.filtered;
  if (stiffness_frame != parameters_.stiffness.frame) {
    filtered.stiffness = stiffness_frame == Frame::base
                             ? Matrix6d(rotation6 * filtered.stiffness * rotation6.transpose())
                             : Matrix6d(rotation6.transpose() * filtered.stiffness * rotation6);
  }
  if (wrench_frame != parameters_.wrench.frame) {
    const Vector6d wrench = filtered.wrench;
    if (wrench_frame == Frame::base) {
      rotate_six(rotation, wrench, filtered.wrench);
    } else {
      rotate_six_inverse(rotation, wrench, filtered.wrench);
    }
  }
}

void CartesianImpedanceController::commit(const Parameters& parameters, const Command& command,
                                          Targets commanded) noexcept {
  // Callers have validated everything; from here on nothing can fail, so a rejected command
  // never leaves a half-applied change behind. A command of the impedance ends a schedule().
  scheduled_ = false;
  change_frames(parameters.stiffness.frame, parameters.wrench.frame);
  parameters_ = parameters;
  state_.stiffness_frame = parameters.stiffness.frame;
  state_.wrench_frame = parameters.wrench.frame;
  apply_saturation(commanded, state_.limits, command);
  state_.commanded = commanded;
  if (!started_) state_.filtered = state_.commanded;
  refresh_damping_mode();
  joint_torque_limit_ = per_joint(parameters.limits.joint_torque, num_joints_);
  joint_torque_rate_limit_ = per_joint(parameters.limits.joint_torque_rate, num_joints_);
  joint_velocity_bound_ = per_joint(parameters.plausibility.joint_velocity, num_joints_);
  // A raised bound holds at once (the rate limit keeps the torque continuous); a lowered one
  // ramps down from the torque being commanded (limit_torque()), so that neither the rate limit
  // nor the bound in force is ever exceeded.
  if (started_) {
    state_.joint_torque_limit =
        joint_torque_limit_.cwiseMax(state_.joint_torque_limit.cwiseMin(tau_previous_.cwiseAbs()));
  } else {
    state_.joint_torque_limit = joint_torque_limit_;
  }
  gains_.dt = -1.0;
}

void CartesianImpedanceController::refresh_damping_mode() noexcept {
  // The filter blends commanded and filtered K, so it stays diagonal while both are.
  stiffness_diagonal_ =
      is_diagonal(state_.commanded.stiffness) && is_diagonal(state_.filtered.stiffness);
  if (stiffness_diagonal_) damping_frame_.setZero();
  damping_computed_for_stiffness_.setConstant(std::nan(""));
}

void CartesianImpedanceController::check_robot_state(const RobotState& robot) const {
  checks::size("robot.q", robot.q.size(), num_joints_);
  checks::size("robot.dq", robot.dq.size(), num_joints_);
  checks::size("robot.jacobian columns", robot.jacobian.cols(), num_joints_);
  checks::finite_vector("robot.q", robot.q);
  checks::finite_vector("robot.dq", robot.dq);
  for (Eigen::Index i = 0; i < robot.jacobian.size(); ++i) {
    checks::finite(checks::indexed("robot.jacobian", i), robot.jacobian.data()[i]);
  }
  checks::pose("robot.pose", robot.pose);
  for (int i = 0; i < num_joints_; ++i) {
    if (std::abs(robot.dq[i]) > joint_velocity_bound_[i]) {
      throw Error(checks::indexed("robot.dq", i) + " = " + format_number(robot.dq[i]) +
                  " rad/s is beyond plausibility.joint_velocity = " +
                  format_number(joint_velocity_bound_[i]) + " rad/s");
    }
  }
}

namespace {

bool set_fault(Fault& fault, const char* input, int index, double value, const char* reason,
               double bound = 0.0, bool has_bound = false) noexcept {
  fault = Fault{input, index, value, reason, bound, has_bound};
  return true;
}

// First non-finite element of a vector or matrix, as a fault of `input`.
template <typename Derived>
bool find_non_finite(const Eigen::DenseBase<Derived>& values, const char* input,
                     Fault& fault) noexcept {
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    const double value = values.derived().data()[i];
    if (!std::isfinite(value)) {
      return set_fault(fault, input, static_cast<int>(i), value, "is not finite");
    }
  }
  return false;
}

}  // namespace

bool CartesianImpedanceController::find_fault(const RobotState& robot,
                                              Fault& fault) const noexcept {
  const int n = num_joints_;
  if (robot.q.size() != n) return set_fault(fault, "q", -1, robot.q.size(), "has the wrong size");
  if (robot.dq.size() != n) {
    return set_fault(fault, "dq", -1, robot.dq.size(), "has the wrong size");
  }
  if (robot.jacobian.cols() != n) {
    return set_fault(fault, "jacobian", -1, robot.jacobian.cols(), "has the wrong column count");
  }
  // One sum checks every value for the common case (a NaN or an infinity anywhere makes it NaN or
  // infinite); only a failing sum pays for finding the element.
  // The Jacobian column by column: fixed-size additions, where Eigen's sum() of the 6 x n
  // matrix runs a dynamic-size reduction.
  Vector6d column_sum = Vector6d::Zero();
  for (Eigen::Index i = 0; i < robot.jacobian.cols(); ++i) column_sum += robot.jacobian.col(i);
  const double sum = robot.q.sum() + robot.dq.sum() + column_sum.sum() + robot.pose.position.sum() +
                     robot.pose.orientation.coeffs().sum();
  if (!std::isfinite(sum)) {
    if (find_non_finite(robot.q, "q", fault) || find_non_finite(robot.dq, "dq", fault) ||
        find_non_finite(robot.jacobian, "jacobian", fault) ||
        find_non_finite(robot.pose.position, "pose.position", fault) ||
        find_non_finite(robot.pose.orientation.coeffs(), "pose.orientation", fault)) {
      return true;
    }
    return set_fault(fault, "robot state", -1, sum, "overflows");
  }
  const double norm = robot.pose.orientation.norm();
  if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
    return set_fault(fault, "pose.orientation", -1, norm, "has a norm away from 1");
  }
  for (int i = 0; i < n; ++i) {
    if (std::abs(robot.dq[i]) > joint_velocity_bound_[i]) {
      return set_fault(fault, "dq", i, robot.dq[i], "is beyond plausibility.joint_velocity",
                       joint_velocity_bound_[i], true);
    }
  }
  // Optional terms: absent (size 0) or complete and finite.
  if (robot.mass.size() != 0 && (robot.mass.rows() != n || robot.mass.cols() != n)) {
    return set_fault(fault, "mass", -1, robot.mass.rows(), "has the wrong size");
  }
  if (robot.gravity.size() != 0 && robot.gravity.size() != n) {
    return set_fault(fault, "gravity", -1, robot.gravity.size(), "has the wrong size");
  }
  if (robot.secondary_torque.size() != 0 && robot.secondary_torque.size() != n) {
    return set_fault(fault, "secondary_torque", -1, robot.secondary_torque.size(),
                     "has the wrong size");
  }
  const double optional_sum = robot.mass.sum() + robot.gravity.sum() + robot.secondary_torque.sum();
  if (!std::isfinite(optional_sum)) {
    if (find_non_finite(robot.mass, "mass", fault) ||
        find_non_finite(robot.gravity, "gravity", fault) ||
        find_non_finite(robot.secondary_torque, "secondary_torque", fault)) {
      return true;
    }
    return set_fault(fault, "robot state", -1, optional_sum, "overflows");
  }
  return false;
}

void CartesianImpedanceController::start(const RobotState& robot) {
  start(robot, Eigen::VectorXd::Zero(num_joints_));
}

void CartesianImpedanceController::start(const RobotState& robot,
                                         const Eigen::Ref<const Eigen::VectorXd>& tau_previous) {
  check_robot_state(robot);
  checks::size("tau_previous", tau_previous.size(), num_joints_);
  checks::finite_vector("tau_previous", tau_previous, "Nm");
  const Pose pose{robot.pose.position, robot.pose.orientation.normalized()};
  Targets& commanded = state_.commanded;
  commanded.pose = pose;
  commanded.nullspace_q = robot.q;
  commanded.twist.setZero();
  commanded.nullspace_dq.setZero();
  state_.filtered = commanded;
  state_.filtered.wrench.setZero();
  refresh_damping_mode();
  state_.pose = pose;
  state_.tau = tau_previous;
  tau_previous_ = tau_previous;
  state_.joint_torque_limit = joint_torque_limit_.cwiseMax(tau_previous_.cwiseAbs());
  state_.limits.joint_torque_limit_ramping =
      (state_.joint_torque_limit.array() > joint_torque_limit_.array()).any();
  state_.fault = Fault{};
  state_.tau_cartesian.setZero();
  state_.tau_nullspace.setZero();
  state_.tau_wrench.setZero();
  state_.status = Status::ok;
  const Range& plausible = parameters_.plausibility.dt;
  last_valid_dt_ = std::clamp(1e-3, plausible.min, plausible.max);
  gains_.dt = -1.0;
  started_ = true;
}

void CartesianImpedanceController::apply(const Command& command) {
  apply(validate_command(command, num_joints_));
}

bool CartesianImpedanceController::apply(const ValidCommand& valid) noexcept {
  if (valid.num_joints() != 0 && valid.num_joints() != num_joints_) return false;
  const Command& command = valid.command();
  // The reference pose and nullspace target are filtered toward directly; every other command
  // also changes the configuration (parameters() keeps what was commanded) and is saturated.
  if (const auto* reference = std::get_if<ReferencePose>(&command)) {
    state_.commanded.pose = reference->pose_base;
    return true;
  }
  if (const auto* target = std::get_if<NullspaceTarget>(&command)) {
    state_.commanded.nullspace_q = target->q_desired;
    return true;
  }
  Parameters parameters = parameters_;
  Targets commanded = state_.commanded;
  if (const auto* c = std::get_if<Stiffness>(&command)) {
    // parameters() keeps the diagonal; a full matrix lives in the commanded targets.
    parameters.stiffness.translation = c->stiffness.diagonal().head<3>();
    parameters.stiffness.rotation = c->stiffness.diagonal().tail<3>();
    parameters.stiffness.frame = c->frame.value_or(parameters_.stiffness.frame);
    commanded.stiffness = c->stiffness;
  } else if (const auto* c = std::get_if<DampingRatio>(&command)) {
    parameters.damping_ratio.translation = c->ratio.head<3>();
    parameters.damping_ratio.rotation = c->ratio.tail<3>();
    commanded.damping_ratio = c->ratio;
  } else if (const auto* c = std::get_if<NullspaceStiffness>(&command)) {
    parameters.nullspace.stiffness = c->stiffness;
    commanded.nullspace_stiffness = per_joint(c->stiffness, num_joints_);
  } else if (const auto* c = std::get_if<NullspaceDampingRatio>(&command)) {
    parameters.nullspace.damping_ratio = c->ratio;
    commanded.nullspace_damping_ratio = c->ratio;
  } else if (const auto* c = std::get_if<Wrench>(&command)) {
    parameters.wrench.force = c->wrench.head<3>();
    parameters.wrench.torque = c->wrench.tail<3>();
    parameters.wrench.frame = c->frame.value_or(parameters_.wrench.frame);
    commanded.wrench = c->wrench;
  } else if (const auto* c = std::get_if<Parameters>(&command)) {
    parameters = *c;
    commanded.stiffness =
        stacked(parameters.stiffness.translation, parameters.stiffness.rotation).asDiagonal();
    commanded.damping_ratio =
        stacked(parameters.damping_ratio.translation, parameters.damping_ratio.rotation);
    commanded.nullspace_stiffness = per_joint(parameters.nullspace.stiffness, num_joints_);
    commanded.nullspace_damping_ratio = parameters.nullspace.damping_ratio;
    commanded.wrench << parameters.wrench.force, parameters.wrench.torque;
  }
  commit(parameters, command, commanded);
  return true;
}

void CartesianImpedanceController::update_gains(double dt) noexcept {
  if (dt == gains_.dt) return;
  const FilterParameters& filter = parameters_.filter;
  gains_.dt = dt;
  gains_.pose = filter_gain(dt, filter.pose.time, filter.pose.fraction);
  gains_.stiffness = filter_gain(dt, filter.stiffness.time, filter.stiffness.fraction);
  gains_.nullspace = filter_gain(dt, filter.nullspace.time, filter.nullspace.fraction);
  gains_.wrench = filter_gain(dt, filter.wrench.time, filter.wrench.fraction);
}

void CartesianImpedanceController::filter_targets() noexcept {
  // a_{k+1} = (1 - a) a_k + a a_d, written in this form so that a = 1 lands exactly on a_d.
  const Targets& commanded = state_.commanded;
  Targets& filtered = state_.filtered;
  const double a_pose = gains_.pose;
  filtered.pose.position =
      (1.0 - a_pose) * filtered.pose.position + a_pose * commanded.pose.position;
  filtered.pose.orientation =
      filtered.pose.orientation.slerp(a_pose, commanded.pose.orientation).normalized();
  const double a_stiffness = gains_.stiffness;
  if (stiffness_diagonal_) {
    filtered.stiffness.diagonal() = (1.0 - a_stiffness) * filtered.stiffness.diagonal() +
                                    a_stiffness * commanded.stiffness.diagonal();
  } else {
    filtered.stiffness =
        (1.0 - a_stiffness) * filtered.stiffness + a_stiffness * commanded.stiffness;
  }
  filtered.damping_ratio =
      (1.0 - a_stiffness) * filtered.damping_ratio + a_stiffness * commanded.damping_ratio;
  const double a_nullspace = gains_.nullspace;
  filtered.nullspace_q =
      (1.0 - a_nullspace) * filtered.nullspace_q + a_nullspace * commanded.nullspace_q;
  filtered.nullspace_stiffness = (1.0 - a_nullspace) * filtered.nullspace_stiffness +
                                 a_nullspace * commanded.nullspace_stiffness;
  filtered.nullspace_damping_ratio = (1.0 - a_nullspace) * filtered.nullspace_damping_ratio +
                                     a_nullspace * commanded.nullspace_damping_ratio;
  filtered.twist = commanded.twist;
  filtered.nullspace_dq = commanded.nullspace_dq;
  const double a_wrench = gains_.wrench;
  filtered.wrench = (1.0 - a_wrench) * filtered.wrench + a_wrench * commanded.wrench;
}

void CartesianImpedanceController::compute_torque(const RobotState& robot) noexcept {
  const Targets& filtered = state_.filtered;
  const Jacobian& jacobian = robot.jacobian;
  state_.pose.position = robot.pose.position;
  state_.pose.orientation = robot.pose.orientation.normalized();
  const Eigen::Matrix3d rotation = state_.pose.orientation.toRotationMatrix();

  // Pose error, clipped so that a far reference pulls no harder than a near one.
  Vector6d& error = state_.pose_error;
  error = pose_error(state_.pose, filtered.pose);
  ActiveLimits& limits = state_.limits;
  limits.translation_error_clipped =
      clip_norm(error.head<3>(), parameters_.limits.pose_error.translation);
  limits.rotation_error_clipped =
      clip_norm(error.tail<3>(), parameters_.limits.pose_error.rotation);

  const bool in_base = parameters_.stiffness.frame == Frame::base;
  const DynamicsParameters& dynamics = parameters_.dynamics;
  // D = 2 Z^1/2 sqrt(K) Z^1/2 follows the filtered K. A diagonal K (the common case) needs six
  // square roots; a full one a 6x6 eigen-decomposition, done only while K or zeta move. Shaped
  // by the task-space inertia, it changes with q and is computed every cycle.
  bool damping_diagonal = stiffness_diagonal_;
  if (scheduled_) {
    damping_frame_ = scheduled_damping_;
    damping_diagonal = stiffness_diagonal_ && scheduled_damping_diagonal_;
  } else if (dynamics.inertia_shaped_damping) {
    if (!inertia_damping_.compute(jacobian, robot.mass,
                                  parameters_.nullspace.pseudo_inverse_damping,
                                  in_base ? nullptr : &rotation, filtered.stiffness,
                                  filtered.damping_ratio, damping_frame_)) {
      state_.tau.setConstant(std::nan(""));  // reported as a numerical error by update()
      return;
    }
    damping_computed_for_stiffness_.setConstant(std::nan(""));
    damping_diagonal = false;
  } else if (stiffness_diagonal_) {
    damping_frame_.diagonal() =
        2.0 * filtered.damping_ratio.cwiseProduct(filtered.stiffness.diagonal().cwiseSqrt());
  } else if (filtered.stiffness != damping_computed_for_stiffness_ ||
             filtered.damping_ratio != damping_computed_for_ratio_) {
    damping_frame_ = damping_from_stiffness(filtered.stiffness, filtered.damping_ratio);
    damping_computed_for_stiffness_ = filtered.stiffness;
    damping_computed_for_ratio_ = filtered.damping_ratio;
  }

  // The damping floor keeps a soft arm (teaching: K = 0, so D = 0) from coasting. Raising the
  // diagonal by a non-negative amount keeps D symmetric positive semi-definite.
  Matrix6d& damping = state_.damping;
  damping = damping_frame_;
  const MinimumDampingParameters& minimum = parameters_.minimum_damping;
  for (int i = 0; i < 6; ++i) {
    damping(i, i) = std::max(damping(i, i), i < 3 ? minimum.translation : minimum.rotation);
  }

  // The damper acts on the velocity relative to the reference's (zero unless tracking).
  Vector6d velocity;
  jacobian_times(jacobian, robot.dq, velocity);
  velocity -= filtered.twist;
  // Spring and damper in the stiffness frame; in the end-effector frame the error and velocity
  // are rotated in and the resulting wrench back out.
  Vector6d error_frame, velocity_frame, force_frame;
  if (in_base) {
    error_frame = error;
    velocity_frame = velocity;
  } else {
    rotate_six_inverse(rotation, error, error_frame);
    rotate_six_inverse(rotation, velocity, velocity_frame);
  }
  if (damping_diagonal) {
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
  jacobian_transpose_times(jacobian, force, state_.tau_cartesian);

  // Nullspace joint impedance, projected so that it does not disturb the end effector.
  const JointVector& stiffness_ns = filtered.nullspace_stiffness;
  if (scheduled_) {
    nullspace_damping_ = scheduled_nullspace_damping_;
  } else {
    nullspace_damping_ = (2.0 * filtered.nullspace_damping_ratio) * stiffness_ns.cwiseSqrt();
  }
  tau_0_ = -stiffness_ns.cwiseProduct(robot.q - filtered.nullspace_q) -
           nullspace_damping_.cwiseMax(parameters_.minimum_damping.nullspace)
               .cwiseProduct(robot.dq - filtered.nullspace_dq);
  if (robot.secondary_torque.size() == num_joints_) tau_0_ += robot.secondary_torque;
  const double lambda = parameters_.nullspace.pseudo_inverse_damping;
  if (dynamics.dynamically_consistent_nullspace) {
    if (!projector_.project_dynamic(jacobian, robot.mass, lambda, tau_0_, state_.tau_nullspace)) {
      state_.tau.setConstant(std::nan(""));
      return;
    }
  } else {
    projector_.project(jacobian, lambda, tau_0_, state_.tau_nullspace);
  }

  // Commanded wrench.
  if (parameters_.wrench.frame == Frame::base) {
    state_.wrench_base = filtered.wrench;
  } else {
    rotate_six(rotation, filtered.wrench, state_.wrench_base);
  }
  jacobian_transpose_times(jacobian, state_.wrench_base, state_.tau_wrench);

  if (dynamics.gravity_compensation) {
    state_.tau_gravity = robot.gravity;
  } else {
    state_.tau_gravity.setZero();
  }
  state_.tau = state_.tau_cartesian + state_.tau_nullspace + state_.tau_wrench + state_.tau_gravity;
}

void CartesianImpedanceController::track(const Pose& pose_base, const Vector6d& twist_base,
                                         const JointVector& q_desired,
                                         const JointVector& dq_desired) noexcept {
  for (Targets* targets : {&state_.commanded, &state_.filtered}) {
    targets->pose = pose_base;
    targets->twist = twist_base;
    targets->nullspace_q = q_desired;
    targets->nullspace_dq = dq_desired;
  }
}

void CartesianImpedanceController::schedule(const ScheduledImpedance& impedance) noexcept {
  for (Targets* targets : {&state_.commanded, &state_.filtered}) {
    targets->pose = impedance.reference;
    targets->stiffness = impedance.stiffness;
    targets->nullspace_q = impedance.nullspace_q;
    targets->nullspace_stiffness = impedance.nullspace_stiffness;
    targets->wrench = impedance.wrench;
  }
  scheduled_damping_ = impedance.damping;
  scheduled_damping_diagonal_ = is_diagonal(impedance.damping);
  scheduled_nullspace_damping_ = impedance.nullspace_damping;
  scheduled_ = true;
  refresh_damping_mode();
}

void CartesianImpedanceController::stop_tracking() noexcept {
  state_.commanded.twist.setZero();
  state_.commanded.nullspace_dq.setZero();
}

void CartesianImpedanceController::limit_torque(double dt) noexcept {
  // The bound in force ramps down toward limits.joint_torque at the rate limit (and never sits
  // below it), so a lowered limit is reached as fast as the rate limit allows. The torque is
  // clamped to that bound before and after the rate limit: the previous torque lies within the
  // previous bound, so the clamp after the rate limit moves each joint by at most rate * dt.
  JointVector& bound = state_.joint_torque_limit;
  max_step_ = joint_torque_rate_limit_ * dt;
  bound = (bound - max_step_).cwiseMax(joint_torque_limit_);
  state_.limits.joint_torque_limit_ramping = (bound.array() > joint_torque_limit_.array()).any();
  state_.limits.joint_torque_saturated = saturate_torque(bound, state_.tau);
  state_.limits.torque_rate_limited = limit_rate(tau_previous_, max_step_, state_.tau);
  saturate_torque(bound, state_.tau);
  tau_previous_ = state_.tau;
}

Status CartesianImpedanceController::fail_closed(Status status, const Fault& fault,
                                                 double dt) noexcept {
  // No trustworthy law output: ramp the last command as fast as the rate limit allows toward
  // zero, or toward the last gravity torque when the law compensates gravity (zero would drop
  // the arm).
  if (!started_) {
    state_.tau.setZero();
    state_.status = Status::not_started;
    return state_.status;
  }
  const Range& plausible = parameters_.plausibility.dt;
  if (!(dt >= plausible.min && dt <= plausible.max)) dt = last_valid_dt_;
  state_.tau = state_.tau_gravity;
  state_.tau_cartesian.setZero();
  state_.tau_nullspace.setZero();
  state_.tau_wrench.setZero();
  limit_torque(dt);
  state_.status = status;
  state_.fault = fault;
  return status;
}

Status CartesianImpedanceController::update(const RobotState& robot, double dt) noexcept {
  if (!started_) {
    state_.tau.setZero();
    state_.status = Status::not_started;
    return state_.status;
  }
  const Range& plausible = parameters_.plausibility.dt;
  if (!std::isfinite(dt)) {
    return fail_closed(Status::invalid_dt, Fault{"dt", -1, dt, "is not finite"}, dt);
  }
  if (dt < plausible.min) {
    return fail_closed(Status::invalid_dt,
                       Fault{"dt", -1, dt, "is below plausibility.dt.min", plausible.min, true},
                       dt);
  }
  if (dt > plausible.max) {
    return fail_closed(Status::invalid_dt,
                       Fault{"dt", -1, dt, "is above plausibility.dt.max", plausible.max, true},
                       dt);
  }
  Fault fault;
  if (find_fault(robot, fault)) return fail_closed(Status::invalid_robot_state, fault, dt);
  const DynamicsParameters& dynamics = parameters_.dynamics;
  if ((dynamics.inertia_shaped_damping || dynamics.dynamically_consistent_nullspace) &&
      robot.mass.rows() != num_joints_) {
    return fail_closed(Status::missing_dynamics,
                       Fault{"mass", -1, static_cast<double>(robot.mass.rows()),
                             "is missing (dynamics options need M(q))"},
                       dt);
  }
  if (dynamics.gravity_compensation && robot.gravity.size() != num_joints_) {
    return fail_closed(Status::missing_dynamics,
                       Fault{"gravity", -1, static_cast<double>(robot.gravity.size()),
                             "is missing (dynamics.gravity_compensation needs g(q))"},
                       dt);
  }
  last_valid_dt_ = dt;

  update_gains(dt);
  filter_targets();
  compute_torque(robot);
  if (!state_.tau.allFinite()) {
    Fault numerical;
    find_non_finite(state_.tau, "tau", numerical);
    return fail_closed(Status::numerical_error, numerical, dt);
  }
  limit_torque(dt);
  state_.status = Status::ok;
  state_.fault = Fault{};
  return state_.status;
}

}  // namespace cartesian_impedance
