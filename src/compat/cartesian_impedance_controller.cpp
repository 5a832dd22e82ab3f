#include "cartesian_impedance/compat/cartesian_impedance_controller.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "cartesian_impedance/core/checks.hpp"
#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance_controller {
namespace ci = cartesian_impedance;

namespace {

// The update frequency's range follows from plausibility.dt, which the native controller checks
// every cycle against dt = 1 / f.
constexpr double kMinFrequency = 1.0;  // [Hz]
constexpr double kMaxFrequency = 1e6;  // [Hz]

// Per-call step of the published filter: the continuous first-order lag that closes `fraction`
// of the gap in one second (time constant kappa = -1 / ln(1 - fraction)), discretised by
// backward Euler at `frequency`. The published code caps the fraction at 0.999999.
double published_filter_step(double frequency, double fraction) {
  const double kappa = -1.0 / std::log(1.0 - std::min(fraction, 0.999999));
  return 1.0 / (kappa * frequency + 1.0);
}

template <typename T>
T blend(const T& current, const T& target, double step) {
  return (1.0 - step) * current + step * target;
}

// Checks `value` against a row of the parameter table; the message names the published argument
// ("setStiffness: t_x"). The name is only built for a message, so a valid call allocates nothing.
void check_row(const char* row, const char* function, const char* argument, double value) {
  const ci::ParameterInfo& info = ci::parameter_info(row);
  const bool above_min = info.min_exclusive ? value > info.min : value >= info.min;
  if (std::isfinite(value) && above_min && value <= info.max) return;
  info.check(std::string(function) + ": " + argument, value);
}

void check_filter_fraction(const char* name, double value) {
  if (!(value > 0.0 && value <= 1.0)) {
    throw ci::Error(
        std::string("setFiltering: ") + name + " = " + ci::format_number(value) +
        (std::isfinite(value) ? " is outside (0, 1]" : " is not finite (valid: (0, 1])"));
  }
}

// The native controller set up to evaluate exactly the published law: no filters (the
// compatibility class filters with the published semantics and schedules the result), no damping
// floor, lambda = 0.2, unit-mass damping, and the torque delta per call as a rate.
ci::Parameters native_parameters(double max_torque_delta, double update_frequency) {
  ci::Parameters parameters;
  for (ci::FilterSettings* filter : {&parameters.filter.pose, &parameters.filter.stiffness,
                                     &parameters.filter.nullspace, &parameters.filter.wrench}) {
    filter->time = 0.0;
  }
  parameters.minimum_damping = ci::MinimumDampingParameters{0.0, 0.0, 0.0};
  parameters.nullspace.pseudo_inverse_damping = 0.2;
  parameters.dynamics.inertia_shaped_damping = false;
  parameters.joint_limit_avoidance.stiffness = 0.0;
  // The published library has no safety layer: its caps are off by default, and its tank is
  // switched off here (schedule() bypasses it too), so the law stays the published one.
  parameters.safety.energy_tank.enabled = false;
  // The published library has no such limits; these are the widest the library allows.
  parameters.limits.pose_error =
      ci::PoseErrorLimits{ci::parameter_info("limits.pose_error.translation").max,
                          ci::parameter_info("limits.pose_error.rotation").max};
  parameters.limits.joint_torque =
      ci::JointVector::Constant(1, ci::parameter_info("limits.joint_torque").max);
  parameters.limits.joint_torque_rate =
      ci::JointVector::Constant(1, max_torque_delta * update_frequency);
  parameters.plausibility.dt = ci::Range{1.0 / kMaxFrequency, 1.0 / kMinFrequency};
  parameters.plausibility.joint_velocity =
      ci::JointVector::Constant(1, ci::parameter_info("plausibility.joint_velocity").max);
  return parameters;
}

}  // namespace

CartesianImpedanceController::CartesianImpedanceController()
    : controller_(7, native_parameters(100.0, 1000.0)) {
  setNumberOfJoints(7);
  setStiffness(200.0, 200.0, 200.0, 20.0, 20.0, 20.0, 0.0);
  // As published, only the Cartesian stiffness and damping start at their targets.
  filtered_.stiffness = targets_.stiffness;
  filtered_.damping = targets_.damping;
}

void CartesianImpedanceController::initDesiredPose(const Eigen::Vector3d& position_d_target,
                                                   const Eigen::Quaterniond& orientation_d_target) {
  setReferencePose(position_d_target, orientation_d_target);
  filtered_.position_d = targets_.position_d;
  filtered_.orientation_d = targets_.orientation_d;
}

void CartesianImpedanceController::initNullspaceConfig(
    const Eigen::VectorXd& q_d_nullspace_target) {
  setNullspaceConfig(q_d_nullspace_target);
  filtered_.q_d_nullspace = targets_.q_d_nullspace;
}

void CartesianImpedanceController::setNumberOfJoints(size_t n_joints) {
  if (n_joints < 1 || n_joints > static_cast<size_t>(ci::kMaxJoints)) {
    // A negative count passed as size_t arrives as a huge number; say what it was.
    const auto as_signed = static_cast<long long>(n_joints);
    throw ci::Error("setNumberOfJoints: n_joints = " + std::to_string(as_signed) +
                    " is outside [1, " + std::to_string(ci::kMaxJoints) + "]");
  }
  const int n = static_cast<int>(n_joints);
  ci::CartesianImpedanceController controller(
      n, native_parameters(max_torque_delta_, update_frequency_));
  // With the same joint count the robot keeps receiving the last torque: the next call moves from
  // it by at most the torque delta, as every call does (a reset to zero would jump).
  if (n == n_joints_ && controller_.torque().size() == n) {
    controller.start(ci::make_robot_state(n), controller_.torque());
  } else {
    controller.start(ci::make_robot_state(n));
  }
  controller_ = controller;
  n_joints_ = n;
  const ci::Pose measured_pose = measured_.pose;
  measured_ = ci::make_robot_state(n);
  measured_.pose = measured_pose;
  filtered_.q_d_nullspace = ci::JointVector::Zero(n);
  targets_.q_d_nullspace = filtered_.q_d_nullspace;
  status_ = ci::Status::not_started;
  fault_ = ci::Fault{};
}

void CartesianImpedanceController::setStiffness(const Eigen::Matrix<double, 7, 1>& stiffness,
                                                bool auto_damping) {
  static const char* const names[7] = {"t_x", "t_y", "t_z", "r_x", "r_y", "r_z", "n"};
  static const char* const rows[7] = {"stiffness.translation", "stiffness.translation",
                                      "stiffness.translation", "stiffness.rotation",
                                      "stiffness.rotation",    "stiffness.rotation",
                                      "nullspace.stiffness"};
  for (int i = 0; i < 7; ++i) {
    check_row(rows[i], "setStiffness", names[i], stiffness[i]);
  }
  targets_.stiffness.setZero();
  targets_.stiffness.diagonal() = stiffness.head<6>();
  targets_.nullspace_stiffness = stiffness[6];
  if (auto_damping) apply_damping_rule();
}

void CartesianImpedanceController::setStiffness(double t_x, double t_y, double t_z, double r_x,
                                                double r_y, double r_z, double n,
                                                bool auto_damping) {
  Eigen::Matrix<double, 7, 1> stiffness;
  stiffness << t_x, t_y, t_z, r_x, r_y, r_z, n;
  setStiffness(stiffness, auto_damping);
}

void CartesianImpedanceController::setStiffness(double t_x, double t_y, double t_z, double r_x,
                                                double r_y, double r_z, bool auto_damping) {
  setStiffness(t_x, t_y, t_z, r_x, r_y, r_z, targets_.nullspace_stiffness, auto_damping);
}

void CartesianImpedanceController::setDampingFactors(double d_x, double d_y, double d_z, double d_a,
                                                     double d_b, double d_c, double d_n) {
  Eigen::Matrix<double, 7, 1> factors;
  factors << d_x, d_y, d_z, d_a, d_b, d_c, d_n;
  static const char* const names[7] = {"d_x", "d_y", "d_z", "d_a", "d_b", "d_c", "d_n"};
  for (int i = 0; i < 7; ++i) {
    check_row("damping_ratio.translation", "setDampingFactors", names[i], factors[i]);
  }
  damping_factors_ = factors;
  apply_damping_rule();
}

void CartesianImpedanceController::apply_damping_rule() {
  // The published "unit mass" rule: d = factor * 2 sqrt(k), per axis and for the nullspace.
  targets_.damping.setZero();
  for (int i = 0; i < 6; ++i) {
    targets_.damping(i, i) = damping_factors_[i] * (2.0 * std::sqrt(targets_.stiffness(i, i)));
  }
  targets_.nullspace_damping =
      damping_factors_[6] * (2.0 * std::sqrt(targets_.nullspace_stiffness));
}

void CartesianImpedanceController::setReferencePose(const Eigen::Vector3d& position_d,
                                                    const Eigen::Quaterniond& orientation_d) {
  const ci::Pose pose = ci::checks::pose("setReferencePose", ci::Pose{position_d, orientation_d});
  targets_.position_d = pose.position;
  targets_.orientation_d = pose.orientation;
}

void CartesianImpedanceController::setNullspaceConfig(const Eigen::VectorXd& q_d_nullspace_target) {
  ci::checks::size("setNullspaceConfig: q_d_nullspace_target", q_d_nullspace_target.size(),
                   n_joints_);
  ci::checks::bounded_vector("setNullspaceConfig: q_d_nullspace_target", q_d_nullspace_target,
                             ci::checks::kMaxJointPosition, "rad");
  targets_.q_d_nullspace = q_d_nullspace_target;
}

void CartesianImpedanceController::setFiltering(double update_frequency,
                                                double filter_params_nullspace_config,
                                                double filter_params_stiffness,
                                                double filter_params_pose,
                                                double filter_params_wrench) {
  check_filter_fraction("filter_params_nullspace_config", filter_params_nullspace_config);
  check_filter_fraction("filter_params_stiffness", filter_params_stiffness);
  check_filter_fraction("filter_params_pose", filter_params_pose);
  check_filter_fraction("filter_params_wrench", filter_params_wrench);
  reconfigure("setFiltering", max_torque_delta_, update_frequency);
  // As published, fractions below 1e-7 count as 1e-7.
  filter_nullspace_ = std::max(filter_params_nullspace_config, 1e-7);
  filter_stiffness_ = std::max(filter_params_stiffness, 1e-7);
  filter_pose_ = std::max(filter_params_pose, 1e-7);
  filter_wrench_ = std::max(filter_params_wrench, 1e-7);
  update_filter_steps();
}

void CartesianImpedanceController::setMaxTorqueDelta(double d) {
  reconfigure("setMaxTorqueDelta", d, update_frequency_);
}

void CartesianImpedanceController::setMaxTorqueDelta(double d, double update_frequency) {
  reconfigure("setMaxTorqueDelta", d, update_frequency);
  update_filter_steps();
}

void CartesianImpedanceController::update_filter_steps() {
  step_nullspace_ = published_filter_step(update_frequency_, filter_nullspace_);
  step_stiffness_ = published_filter_step(update_frequency_, filter_stiffness_);
  step_pose_ = published_filter_step(update_frequency_, filter_pose_);
  step_wrench_ = published_filter_step(update_frequency_, filter_wrench_);
}

void CartesianImpedanceController::reconfigure(const char* caller, double max_torque_delta,
                                               double update_frequency) {
  if (!(update_frequency >= kMinFrequency && update_frequency <= kMaxFrequency)) {
    throw ci::Error(std::string(caller) +
                    ": update_frequency = " + ci::format_number(update_frequency) +
                    " Hz is outside [" + ci::format_number(kMinFrequency) + ", " +
                    ci::format_number(kMaxFrequency) + "]");
  }
  ci::checks::finite(std::string(caller) + ": d", max_torque_delta, "Nm");
  const ci::ParameterInfo& rate = ci::parameter_info("limits.joint_torque_rate");
  const double rate_value = max_torque_delta * update_frequency;
  if (!(rate_value >= rate.min && rate_value <= rate.max)) {
    // Name what the caller gave: the frequency from setFiltering(), the delta (and perhaps the
    // frequency) from setMaxTorqueDelta().
    const std::string given =
        std::string(caller) == "setFiltering"
            ? "update_frequency = " + ci::format_number(update_frequency) +
                  " Hz with the torque delta of " + ci::format_number(max_torque_delta) +
                  " Nm per call (setMaxTorqueDelta)"
            : "d = " + ci::format_number(max_torque_delta) + " Nm per call at " +
                  ci::format_number(update_frequency) + " Hz";
    throw ci::Error(std::string(caller) + ": " + given + " is " + ci::format_number(rate_value) +
                    " Nm/s, outside limits.joint_torque_rate " + rate.range_text());
  }
  controller_.set_parameters(native_parameters(max_torque_delta, update_frequency));
  max_torque_delta_ = max_torque_delta;
  update_frequency_ = update_frequency;
}

void CartesianImpedanceController::applyWrench(const Eigen::Matrix<double, 6, 1>& wrench) {
  static const char* const names[6] = {"f_x", "f_y", "f_z", "tau_x", "tau_y", "tau_z"};
  for (int i = 0; i < 6; ++i) {
    check_row(i < 3 ? "wrench.force" : "wrench.torque", "applyWrench", names[i], wrench[i]);
  }
  targets_.wrench = wrench;
}

void CartesianImpedanceController::filter_step(Impedance& next) const noexcept {
  // The published order and switches: a parameter of exactly 1 takes the target at once; an
  // unfiltered stiffness also snaps the nullspace configuration to its target.
  if (filter_nullspace_ == 1.0) {
    next.q_d_nullspace = targets_.q_d_nullspace;
  } else {
    next.q_d_nullspace = blend(next.q_d_nullspace, targets_.q_d_nullspace, step_nullspace_);
  }
  if (filter_stiffness_ == 1.0) {
    next.stiffness = targets_.stiffness;
    next.damping = targets_.damping;
    next.nullspace_stiffness = targets_.nullspace_stiffness;
    next.q_d_nullspace = targets_.q_d_nullspace;
    next.nullspace_damping = targets_.nullspace_damping;
  } else {
    next.stiffness = blend(next.stiffness, targets_.stiffness, step_stiffness_);
    next.damping = blend(next.damping, targets_.damping, step_stiffness_);
    next.nullspace_stiffness =
        blend(next.nullspace_stiffness, targets_.nullspace_stiffness, step_stiffness_);
    next.nullspace_damping =
        blend(next.nullspace_damping, targets_.nullspace_damping, step_stiffness_);
  }
  if (filter_pose_ == 1.0) {
    next.position_d = targets_.position_d;
    next.orientation_d = targets_.orientation_d;
  } else {
    next.position_d = blend(next.position_d, targets_.position_d, step_pose_);
    next.orientation_d = next.orientation_d.slerp(step_pose_, targets_.orientation_d);
  }
  if (filter_wrench_ == 1.0) {
    next.wrench = targets_.wrench;
  } else {
    next.wrench = blend(next.wrench, targets_.wrench, step_wrench_);
  }
}

ci::Status CartesianImpedanceController::step(const ci::RobotState& measured,
                                              bool measurement_checked) noexcept {
  // The filters advance only on a step the native controller accepts, so a rejected measurement
  // changes nothing but the torque (which steps toward zero).
  next_ = filtered_;
  filter_step(next_);
  schedule_.reference = ci::Pose{next_.position_d, next_.orientation_d};
  schedule_.stiffness = next_.stiffness;
  schedule_.damping = next_.damping;
  schedule_.nullspace_q = next_.q_d_nullspace;
  schedule_.nullspace_stiffness.setConstant(n_joints_, next_.nullspace_stiffness);
  schedule_.nullspace_damping.setConstant(n_joints_, next_.nullspace_damping);
  schedule_.wrench = next_.wrench;
  controller_.schedule(schedule_);
  status_ = measurement_checked ? controller_.update_measured(measured, 1.0 / update_frequency_)
                                : controller_.update(measured, 1.0 / update_frequency_);
  fault_ = controller_.state().fault;
  if (status_ == ci::Status::ok) {
    filtered_ = next_;
    if (&measured != &measured_) measured_ = measured;
  }
  return status_;
}

Eigen::VectorXd CartesianImpedanceController::calculateCommandedTorques() {
  step(measured_);
  return controller_.torque();
}

Eigen::VectorXd CartesianImpedanceController::calculateCommandedTorques(
    const Eigen::VectorXd& q, const Eigen::VectorXd& dq, const Eigen::Vector3d& position,
    Eigen::Quaterniond orientation, const Eigen::MatrixXd& jacobian) {
  Eigen::VectorXd tau(n_joints_);
  calculateCommandedTorques(q, dq, position, orientation, jacobian, tau);
  return tau;
}

ci::Status CartesianImpedanceController::calculateCommandedTorques(
    const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& dq,
    const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
    const Eigen::Ref<const Eigen::MatrixXd>& jacobian, Eigen::Ref<Eigen::VectorXd> tau) noexcept {
  const Eigen::Index n = n_joints_;
  if (const ci::Fault fault = ci::checks::count("tau", tau.size(), n)) {
    status_ = ci::Status::invalid_robot_state;
    fault_ = fault;
    return status_;
  }
  // The measurement is checked once, here (its sizes must be right before it is copied); the
  // native controller then checks only the rest.
  ci::checks::MeasurementBounds bounds;
  bounds.speed = &controller_.joint_velocity_bound();
  ci::Fault fault = ci::checks::measurement(q, dq, static_cast<int>(n), bounds);
  if (!fault) fault = ci::checks::count("jacobian", jacobian.rows(), 6, "rows");
  if (!fault) fault = ci::checks::count("jacobian", jacobian.cols(), n, "columns");
  if (fault) {
    status_ =
        controller_.fail_closed(ci::Status::invalid_robot_state, fault, 1.0 / update_frequency_);
    fault_ = fault;
  } else {
    input_.q = q;
    input_.dq = dq;
    input_.pose.position = position;
    input_.pose.orientation = orientation;
    input_.jacobian = jacobian;
    step(input_, true);
  }
  tau = controller_.torque();
  return status_;
}

void CartesianImpedanceController::getState(
    Eigen::VectorXd* q, Eigen::VectorXd* dq, Eigen::Vector3d* position,
    Eigen::Quaterniond* orientation, Eigen::Vector3d* position_d, Eigen::Quaterniond* orientation_d,
    Eigen::Matrix<double, 6, 6>* cartesian_stiffness, double* nullspace_stiffness,
    Eigen::VectorXd* q_d_nullspace, Eigen::Matrix<double, 6, 6>* cartesian_damping) const {
  if (q != nullptr) *q = measured_.q;
  if (dq != nullptr) *dq = measured_.dq;
  if (position != nullptr) *position = measured_.pose.position;
  if (orientation != nullptr) *orientation = measured_.pose.orientation;
  getState(position_d, orientation_d, cartesian_stiffness, nullspace_stiffness, q_d_nullspace,
           cartesian_damping);
}

void CartesianImpedanceController::getState(Eigen::Vector3d* position_d,
                                            Eigen::Quaterniond* orientation_d,
                                            Eigen::Matrix<double, 6, 6>* cartesian_stiffness,
                                            double* nullspace_stiffness,
                                            Eigen::VectorXd* q_d_nullspace,
                                            Eigen::Matrix<double, 6, 6>* cartesian_damping) const {
  if (position_d != nullptr) *position_d = filtered_.position_d;
  if (orientation_d != nullptr) *orientation_d = filtered_.orientation_d;
  if (cartesian_stiffness != nullptr) *cartesian_stiffness = filtered_.stiffness;
  if (nullspace_stiffness != nullptr) *nullspace_stiffness = filtered_.nullspace_stiffness;
  if (q_d_nullspace != nullptr) *q_d_nullspace = filtered_.q_d_nullspace;
  if (cartesian_damping != nullptr) *cartesian_damping = filtered_.damping;
}

Eigen::VectorXd CartesianImpedanceController::getLastCommands() const {
  return controller_.torque();
}

Eigen::Matrix<double, 6, 1> CartesianImpedanceController::getAppliedWrench() const {
  return filtered_.wrench;
}

Eigen::Matrix<double, 6, 1> CartesianImpedanceController::getPoseError() const {
  return controller_.state().pose_error;
}

}  // namespace cartesian_impedance_controller
