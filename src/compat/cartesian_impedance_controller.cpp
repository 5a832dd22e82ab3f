#include "cartesian_impedance/compat/cartesian_impedance_controller.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
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
constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
using Action = CartesianImpedanceController::InputReport::Action;

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

// Checking::strict: the update frequency within [kMinFrequency, kMaxFrequency].
void check_frequency(const char* caller, double update_frequency) {
  if (!(update_frequency >= kMinFrequency && update_frequency <= kMaxFrequency)) {
    throw ci::Error(std::string(caller) +
                    ": update_frequency = " + ci::format_number(update_frequency) +
                    " Hz is outside [" + ci::format_number(kMinFrequency) + ", " +
                    ci::format_number(kMaxFrequency) + "]");
  }
}

// Checking::strict: the torque delta finite and, at the frequency, within the rate range.
void check_torque_delta(const char* caller, double max_torque_delta, double update_frequency) {
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
}

const char* const kStiffnessNames[7] = {
    "setStiffness: t_x", "setStiffness: t_y", "setStiffness: t_z", "setStiffness: r_x",
    "setStiffness: r_y", "setStiffness: r_z", "setStiffness: n"};
const char* const kStiffnessRows[7] = {
    "stiffness.translation", "stiffness.translation", "stiffness.translation", "stiffness.rotation",
    "stiffness.rotation",    "stiffness.rotation",    "nullspace.stiffness"};
const char* const kDampingNames[7] = {"setDampingFactors: d_x", "setDampingFactors: d_y",
                                      "setDampingFactors: d_z", "setDampingFactors: d_a",
                                      "setDampingFactors: d_b", "setDampingFactors: d_c",
                                      "setDampingFactors: d_n"};
const char* const kWrenchNames[6] = {"applyWrench: f_x",   "applyWrench: f_y",
                                     "applyWrench: f_z",   "applyWrench: tau_x",
                                     "applyWrench: tau_y", "applyWrench: tau_z"};

// The native controller set up to evaluate exactly the published law: no filters (the
// compatibility class filters with the published semantics and schedules the result), no damping
// floor, lambda = 0.2, unit-mass damping, and the torque delta per call as a rate [Nm/s].
ci::Parameters native_parameters(double torque_rate) {
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
  parameters.limits.joint_torque_rate = ci::JointVector::Constant(1, torque_rate);
  parameters.plausibility.dt = ci::Range{1.0 / kMaxFrequency, 1.0 / kMinFrequency};
  parameters.plausibility.joint_velocity =
      ci::JointVector::Constant(1, ci::parameter_info("plausibility.joint_velocity").max);
  return parameters;
}

}  // namespace

// Nothing here calls the public setters that are inline in the header: they carry the published
// assertions, which must follow the NDEBUG of the caller's code, and a copy instantiated here
// would carry this library's.

CartesianImpedanceController::CartesianImpedanceController(Checking checking)
    : checking_(checking), controller_(7, native_parameters(1e5)) {
  setNumberOfJoints(7);
  set_stiffness(
      (Eigen::Matrix<double, 7, 1>() << 200.0, 200.0, 200.0, 20.0, 20.0, 20.0, 0.0).finished(),
      true);
  // As published, only the Cartesian stiffness and damping start at their targets.
  filtered_.stiffness = targets_.stiffness;
  filtered_.damping = targets_.damping;
}

void CartesianImpedanceController::setNumberOfJoints(size_t n_joints) {
  if (n_joints < 1 || n_joints > static_cast<size_t>(ci::kMaxJoints)) {
    // A negative count passed as size_t arrives as a huge number; say what it was.
    const auto as_signed = static_cast<long long>(n_joints);
    throw ci::Error("setNumberOfJoints: n_joints = " + std::to_string(as_signed) +
                    " is outside [1, " + std::to_string(ci::kMaxJoints) + "]");
  }
  const int n = static_cast<int>(n_joints);
  ci::CartesianImpedanceController controller(n, native_parameters(torque_rate_));
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

void CartesianImpedanceController::set_stiffness(const Eigen::Matrix<double, 7, 1>& stiffness,
                                                 bool auto_damping) {
  static const char* const names[7] = {"t_x", "t_y", "t_z", "r_x", "r_y", "r_z", "n"};
  if (checking_ == Checking::strict) {
    for (int i = 0; i < 7; ++i)
      check_row(kStiffnessRows[i], "setStiffness", names[i], stiffness[i]);
  }
  begin_call();
  for (int i = 0; i < 7; ++i) {
    const ci::ParameterInfo& row = ci::parameter_info(kStiffnessRows[i]);
    double& target = i < 6 ? targets_.stiffness(i, i) : targets_.nullspace_stiffness;
    target = accept(kStiffnessNames[i], i < 3 ? "N/m" : "Nm/rad", stiffness[i], target, 0.0,
                    row.min, row.max);
  }
  if (auto_damping) apply_damping_rule();
}

void CartesianImpedanceController::set_damping_factors(const Eigen::Matrix<double, 7, 1>& factors) {
  static const char* const names[7] = {"d_x", "d_y", "d_z", "d_a", "d_b", "d_c", "d_n"};
  if (checking_ == Checking::strict) {
    for (int i = 0; i < 7; ++i) {
      check_row("damping_ratio.translation", "setDampingFactors", names[i], factors[i]);
    }
  }
  begin_call();
  const ci::ParameterInfo& row = ci::parameter_info("damping_ratio.translation");
  for (int i = 0; i < 7; ++i) {
    damping_factors_[i] =
        accept(kDampingNames[i], "", factors[i], damping_factors_[i], 0.0, row.min, row.max);
  }
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

void CartesianImpedanceController::initDesiredPose(const Eigen::Vector3d& position_d_target,
                                                   const Eigen::Quaterniond& orientation_d_target) {
  set_reference_pose(position_d_target, orientation_d_target);
  filtered_.position_d = targets_.position_d;
  filtered_.orientation_d = targets_.orientation_d;
}

void CartesianImpedanceController::setReferencePose(const Eigen::Vector3d& position_d,
                                                    const Eigen::Quaterniond& orientation_d) {
  set_reference_pose(position_d, orientation_d);
}

void CartesianImpedanceController::set_reference_pose(const Eigen::Vector3d& position_d,
                                                      const Eigen::Quaterniond& orientation_d) {
  if (checking_ == Checking::strict) {
    const ci::Pose pose = ci::checks::pose("setReferencePose", ci::Pose{position_d, orientation_d});
    begin_call();
    targets_.position_d = pose.position;
    targets_.orientation_d = pose.orientation;
    return;
  }
  begin_call();
  static const char* const kPosition = "setReferencePose: position_d";
  static const char* const kOrientation = "setReferencePose: orientation_d";
  // A pose that is not a number, or a zero quaternion, says nothing: the last pose stays whole.
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(position_d[i])) {
      report(Action::kept,
             ci::Fault{kPosition, i, position_d[i], "is not finite", 0.0, false, "m",
                       ci::Fault::Form::element},
             targets_.position_d[i]);
      return;
    }
  }
  const double norm = orientation_d.coeffs().norm();
  if (!std::isfinite(norm) || norm < ci::kQuaternionNormTolerance) {
    report(Action::kept,
           ci::Fault{kOrientation, -1, norm, "", ci::kQuaternionNormTolerance, true, "",
                     ci::Fault::Form::norm},
           kNaN);
    return;
  }
  // As published, any other quaternion is normalised; one far from unit norm is reported.
  if (std::abs(norm - 1.0) > ci::kQuaternionNormTolerance) {
    report(Action::clamped,
           ci::Fault{kOrientation, -1, norm, "", ci::kQuaternionNormTolerance, true, "",
                     ci::Fault::Form::norm},
           1.0);
  }
  for (int i = 0; i < 3; ++i) {
    targets_.position_d[i] =
        accept(kPosition, "m", position_d[i], targets_.position_d[i], -kInfinity,
               -ci::checks::kMaxPosition, ci::checks::kMaxPosition);
  }
  targets_.orientation_d = orientation_d.normalized();
}

void CartesianImpedanceController::set_nullspace_config(const Eigen::VectorXd& q_d_nullspace_target,
                                                        bool init) {
  static const char* const kName = "setNullspaceConfig: q_d_nullspace_target";
  if (checking_ == Checking::strict) {
    ci::checks::size("setNullspaceConfig: q_d_nullspace_target", q_d_nullspace_target.size(),
                     n_joints_);
    ci::checks::bounded_vector("setNullspaceConfig: q_d_nullspace_target", q_d_nullspace_target,
                               ci::checks::kMaxJointPosition, "rad");
  }
  begin_call();
  // A wrongly sized or not finite configuration is kept whole: joints taken from two
  // configurations would be a third one nobody asked for.
  if (q_d_nullspace_target.size() != n_joints_) {
    report(Action::kept,
           ci::Fault{kName, -1, static_cast<double>(q_d_nullspace_target.size()), "",
                     static_cast<double>(n_joints_), true, "values", ci::Fault::Form::size},
           kNaN);
  } else if (!q_d_nullspace_target.allFinite()) {
    int i = 0;
    while (std::isfinite(q_d_nullspace_target[i])) ++i;
    report(Action::kept,
           ci::Fault{kName, i, q_d_nullspace_target[i], "is not finite", 0.0, false, "rad"},
           targets_.q_d_nullspace[i]);
  } else {
    for (int i = 0; i < n_joints_; ++i) {
      targets_.q_d_nullspace[i] =
          accept(kName, "rad", q_d_nullspace_target[i], 0.0, -kInfinity,
                 -ci::checks::kMaxJointPosition, ci::checks::kMaxJointPosition);
    }
  }
  if (init) filtered_.q_d_nullspace = targets_.q_d_nullspace;
}

void CartesianImpedanceController::set_filtering(double update_frequency, double filter_nullspace,
                                                 double filter_stiffness, double filter_pose,
                                                 double filter_wrench) {
  if (checking_ == Checking::strict) {
    check_filter_fraction("filter_params_nullspace_config", filter_nullspace);
    check_filter_fraction("filter_params_stiffness", filter_stiffness);
    check_filter_fraction("filter_params_pose", filter_pose);
    check_filter_fraction("filter_params_wrench", filter_wrench);
    check_frequency("setFiltering", update_frequency);
    check_torque_delta("setFiltering", requested_torque_delta_, update_frequency);
  }
  begin_call();
  static const char* const names[4] = {
      "setFiltering: filter_params_nullspace_config", "setFiltering: filter_params_stiffness",
      "setFiltering: filter_params_pose", "setFiltering: filter_params_wrench"};
  const double given[4] = {filter_nullspace, filter_stiffness, filter_pose, filter_wrench};
  double* const kept[4] = {&filter_nullspace_, &filter_stiffness_, &filter_pose_, &filter_wrench_};
  for (int i = 0; i < 4; ++i) {
    if (given[i] > 0.0 && given[i] <= 1.0) {
      // As published, fractions below 1e-7 count as 1e-7.
      *kept[i] = std::max(given[i], 1e-7);
    } else {
      report(
          Action::kept,
          ci::Fault{names[i], -1, given[i],
                    std::isnan(given[i]) ? "is not finite" : "is outside (0, 1]", 0.0, false, ""},
          *kept[i]);
    }
  }
  reconfigure("torque delta (setMaxTorqueDelta: d)", requested_torque_delta_,
              accept("setFiltering: update_frequency", "Hz", update_frequency, update_frequency_,
                     0.0, kMinFrequency, kMaxFrequency));
  update_filter_steps();
}

void CartesianImpedanceController::set_max_torque_delta(double d, double update_frequency,
                                                        bool frequency_given) {
  if (checking_ == Checking::strict) {
    check_frequency("setMaxTorqueDelta", update_frequency);
    check_torque_delta("setMaxTorqueDelta", d, update_frequency);
  }
  begin_call();
  // Any delta from 0 up is the published domain, infinity included (no limit); the rate range
  // is applied with the frequency.
  const double requested =
      accept("setMaxTorqueDelta: d", "Nm", d, requested_torque_delta_, 0.0, 0.0, kInfinity);
  const double frequency =
      frequency_given ? accept("setMaxTorqueDelta: update_frequency", "Hz", update_frequency,
                               update_frequency_, 0.0, kMinFrequency, kMaxFrequency)
                      : update_frequency_;
  reconfigure("setMaxTorqueDelta: d", requested, frequency);
  if (frequency_given) update_filter_steps();
}

void CartesianImpedanceController::update_filter_steps() {
  step_nullspace_ = published_filter_step(update_frequency_, filter_nullspace_);
  step_stiffness_ = published_filter_step(update_frequency_, filter_stiffness_);
  step_pose_ = published_filter_step(update_frequency_, filter_pose_);
  step_wrench_ = published_filter_step(update_frequency_, filter_wrench_);
}

void CartesianImpedanceController::reconfigure(const char* input, double requested,
                                               double update_frequency) {
  // The delta is kept as asked for, so that a later frequency scales what the caller meant; the
  // rate in effect is that delta at the frequency, within the library's rate range.
  const ci::ParameterInfo& range = ci::parameter_info("limits.joint_torque_rate");
  const double asked = requested * update_frequency;
  const double rate = std::clamp(asked, range.min, range.max);
  if (rate != asked) {
    report(Action::clamped,
           ci::Fault{input, -1, requested,
                     asked > range.max ? "is above the largest torque delta at this frequency"
                                       : "is below the smallest torque delta at this frequency",
                     rate / update_frequency, true, "Nm"},
           rate / update_frequency);
  }
  controller_.set_parameters(native_parameters(rate));
  torque_rate_ = rate;
  max_torque_delta_ = rate / update_frequency;
  requested_torque_delta_ = requested;
  update_frequency_ = update_frequency;
}

void CartesianImpedanceController::applyWrench(const Eigen::Matrix<double, 6, 1>& wrench) {
  static const char* const names[6] = {"f_x", "f_y", "f_z", "tau_x", "tau_y", "tau_z"};
  if (checking_ == Checking::strict) {
    for (int i = 0; i < 6; ++i) {
      check_row(i < 3 ? "wrench.force" : "wrench.torque", "applyWrench", names[i], wrench[i]);
    }
  }
  begin_call();
  // A wrench that is not a number is kept whole, like a pose.
  for (int i = 0; i < 6; ++i) {
    if (std::isnan(wrench[i])) {
      report(Action::kept,
             ci::Fault{kWrenchNames[i], -1, wrench[i], "is not finite", 0.0, false,
                       i < 3 ? "N" : "Nm"},
             targets_.wrench[i]);
      return;
    }
  }
  for (int i = 0; i < 6; ++i) {
    const ci::ParameterInfo& row = ci::parameter_info(i < 3 ? "wrench.force" : "wrench.torque");
    targets_.wrench[i] =
        accept(kWrenchNames[i], i < 3 ? "N" : "Nm", wrench[i], 0.0, -kInfinity, row.min, row.max);
  }
}

void CartesianImpedanceController::setWarningInterval(double seconds) {
  if (!(seconds >= 0.0)) {
    throw ci::Error("setWarningInterval: seconds = " + ci::format_number(seconds) +
                    " s is outside [0, inf]");
  }
  warning_interval_ = seconds;
}

void CartesianImpedanceController::begin_call() noexcept {
  report_ = InputReport{};
}

double CartesianImpedanceController::accept(const char* input, const char* unit, double value,
                                            double last, double published_min, double min,
                                            double max) {
  if (std::isnan(value) || value < published_min) {
    report(Action::kept,
           ci::Fault{input, -1, value,
                     std::isnan(value) ? "is not finite" : "is below the published minimum",
                     published_min, !std::isnan(value), unit},
           last);
    return last;
  }
  if (value < min || value > max) {
    const double bound = value < min ? min : max;
    report(Action::clamped,
           ci::Fault{
               input, -1, value,
               value < min ? "is below this library's minimum" : "is above this library's maximum",
               bound, true, unit},
           bound);
    return bound;
  }
  return value;
}

void CartesianImpedanceController::report(InputReport::Action action, const ci::Fault& fault,
                                          double applied) {
  ++adjustment_count_;
  if (report_.adjusted++ == 0) {
    report_.action = action;
    report_.fault = fault;
    report_.applied = applied;
  }
  // One line per interval at most: a program that sets a bad value every cycle at 1 kHz gets a
  // line a second, not a thousand, and the next line counts those left out.
  const auto now = std::chrono::steady_clock::now();
  if (warned_ &&
      !(std::chrono::duration<double>(now - last_warning_).count() >= warning_interval_)) {
    ++warnings_left_out_;
    return;
  }
  std::string line = "cartesian_impedance_controller: " + ci::to_string(fault);
  if (action == Action::clamped) {
    line += "; " + ci::format_number(applied) + (fault.unit[0] != '\0' ? " " : "") + fault.unit +
            " is in effect";
  } else {
    line += "; the last valid value stays in effect";
  }
  if (warnings_left_out_ > 0) {
    line += " (" + std::to_string(warnings_left_out_) + " more adjustments since the last line)";
  }
  line += "\n";
  std::fputs(line.c_str(), stderr);
  warned_ = true;
  last_warning_ = now;
  warnings_left_out_ = 0;
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
