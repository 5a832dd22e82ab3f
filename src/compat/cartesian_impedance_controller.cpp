#include "cartesian_impedance/compat/cartesian_impedance_controller.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <thread>
#include <utility>

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
// floor, lambda = 0.2, unit-mass damping. Its torque-rate limit is the widest the library allows:
// the published one, each joint's change clipped on its own to the torque delta per call, is
// applied by the compatibility class itself (limit_torque_change()), so that it stays the
// published one whatever the library's own rate limit does (it once shaped the change and the
// filtered, rate-limited torques drifted from the published ones by 0.13 Nm). The widest rate,
// 1e6 Nm/s, is at least the torque delta at any frequency (reconfigure() clamps the delta to it).
ci::Parameters native_parameters() {
  ci::Parameters parameters;
  for (ci::FilterSettings* filter : {&parameters.filter.pose, &parameters.filter.stiffness,
                                     &parameters.filter.nullspace, &parameters.filter.wrench}) {
    filter->time = 0.0;
  }
  parameters.minimum_damping = ci::MinimumDampingParameters{0.0, 0.0, 0.0};
  parameters.nullspace.pseudo_inverse_damping = 0.2;
  parameters.dynamics.inertia_shaped_damping = false;
  parameters.joint_limit_avoidance.stiffness = 0.0;
  // The published library has no safety layer: its caps are off by default, and its tank and
  // passivity controller are switched off here (schedule() bypasses the tank too), so the law
  // stays the published one.
  parameters.safety.energy_tank.enabled = false;
  parameters.safety.passivity.threshold = 0.0;
  // The published library has no such limits; these are the widest the library allows.
  parameters.limits.pose_error =
      ci::PoseErrorLimits{ci::parameter_info("limits.pose_error.translation").max,
                          ci::parameter_info("limits.pose_error.rotation").max};
  parameters.limits.joint_torque =
      ci::JointVector::Constant(1, ci::parameter_info("limits.joint_torque").max);
  parameters.limits.joint_torque_rate =
      ci::JointVector::Constant(1, ci::parameter_info("limits.joint_torque_rate").max);
  parameters.plausibility.dt = ci::Range{1.0 / kMaxFrequency, 1.0 / kMinFrequency};
  parameters.plausibility.joint_velocity =
      ci::JointVector::Constant(1, ci::parameter_info("plausibility.joint_velocity").max);
  return parameters;
}

}  // namespace

// Nothing here calls the public setters that are inline in the header: they carry the published
// assertions, which must follow the NDEBUG of the caller's code, and a copy instantiated here
// would carry this library's.

CartesianImpedanceController::CycleState::CycleState()
    : controller(7, native_parameters()),
      measured(ci::make_robot_state(7)),
      tau(ci::JointVector::Zero(7)) {
  controller.start(ci::make_robot_state(7));
  filtered.q_d_nullspace = ci::JointVector::Zero(7);
}

CartesianImpedanceController::CartesianImpedanceController(Checking checking) {
  set_.checking = checking;
  set_.settings.targets.q_d_nullspace = ci::JointVector::Zero(7);
  set_.settings.init_q_d_nullspace = set_.settings.targets.q_d_nullspace;
  set_stiffness(
      (Eigen::Matrix<double, 7, 1>() << 200.0, 200.0, 200.0, 20.0, 20.0, 20.0, 0.0).finished(),
      true);
  take_settings();
  // As published, only the Cartesian stiffness and damping start at their targets.
  cycle_.filtered.stiffness = cycle_.settings.targets.stiffness;
  cycle_.filtered.damping = cycle_.settings.targets.damping;
}

CartesianImpedanceController& CartesianImpedanceController::operator=(
    const CartesianImpedanceController& other) {
  if (this == &other) return *this;
  // A controller handed over and not yet taken up is taken up first, so the copy has it.
  other.take_settings();
  set_ = other.set_;
  cycle_ = other.cycle_;
  handoff_.reset();
  handoff_state_.store(kSetterOwns, std::memory_order_relaxed);
  settings_version_.store(cycle_.version, std::memory_order_relaxed);
  publish();
  take_settings();
  return *this;
}

void CartesianImpedanceController::setNumberOfJoints(size_t n_joints) {
  if (n_joints < 1 || n_joints > static_cast<size_t>(ci::kMaxJoints)) {
    // A negative count passed as size_t arrives as a huge number; say what it was.
    const auto as_signed = static_cast<long long>(n_joints);
    throw ci::Error("setNumberOfJoints: n_joints = " + std::to_string(as_signed) +
                    " is outside [1, " + std::to_string(ci::kMaxJoints) + "]");
  }
  const int n = static_cast<int>(n_joints);
  if (n != set_.n_joints) {
    // A new count needs a controller of that size. It is built here, on the setter's thread:
    // constructing it allocates, and the control thread must not (it only swaps it in).
    ci::CartesianImpedanceController controller(n, native_parameters());
    controller.start(ci::make_robot_state(n));
    // The hand-over slot is the setter's unless the cycle is swapping right now (a few moves),
    // or holds an earlier controller not yet taken up, which this one replaces.
    for (;;) {
      int state = handoff_state_.load(std::memory_order_acquire);
      if (state == kSetterOwns) break;
      if (state == kReady &&
          handoff_state_.compare_exchange_weak(state, kSetterOwns, std::memory_order_acquire)) {
        break;
      }
      std::this_thread::yield();
    }
    // Frees the controller the cycle left here, or the one replaced.
    handoff_ = std::move(controller);
    handoff_state_.store(kReady, std::memory_order_release);
  }
  Settings& settings = set_.settings;
  ++settings.joint_count_changes;
  set_.n_joints = n;
  settings.n_joints = n;
  settings.targets.q_d_nullspace = ci::JointVector::Zero(n);
  settings.init_q_d_nullspace = settings.targets.q_d_nullspace;
  ++settings.nullspace_inits;
  publish();
}

void CartesianImpedanceController::set_stiffness(const Eigen::Matrix<double, 7, 1>& stiffness,
                                                 bool auto_damping) {
  static const char* const names[7] = {"t_x", "t_y", "t_z", "r_x", "r_y", "r_z", "n"};
  if (set_.checking == Checking::strict) {
    for (int i = 0; i < 7; ++i)
      check_row(kStiffnessRows[i], "setStiffness", names[i], stiffness[i]);
  }
  begin_call();
  for (int i = 0; i < 7; ++i) {
    const ci::ParameterInfo& row = ci::parameter_info(kStiffnessRows[i]);
    Impedance& targets = set_.settings.targets;
    double& target = i < 6 ? targets.stiffness(i, i) : targets.nullspace_stiffness;
    target = accept(kStiffnessNames[i], i < 3 ? "N/m" : "Nm/rad", stiffness[i], target, 0.0,
                    row.min, row.max);
  }
  if (auto_damping) apply_damping_rule();
  publish();
}

void CartesianImpedanceController::set_damping_factors(const Eigen::Matrix<double, 7, 1>& factors) {
  static const char* const names[7] = {"d_x", "d_y", "d_z", "d_a", "d_b", "d_c", "d_n"};
  if (set_.checking == Checking::strict) {
    for (int i = 0; i < 7; ++i) {
      check_row("damping_ratio.translation", "setDampingFactors", names[i], factors[i]);
    }
  }
  begin_call();
  const ci::ParameterInfo& row = ci::parameter_info("damping_ratio.translation");
  for (int i = 0; i < 7; ++i) {
    set_.damping_factors[i] =
        accept(kDampingNames[i], "", factors[i], set_.damping_factors[i], 0.0, row.min, row.max);
  }
  apply_damping_rule();
  publish();
}

void CartesianImpedanceController::apply_damping_rule() {
  // The published "unit mass" rule: d = factor * 2 sqrt(k), per axis and for the nullspace.
  Impedance& targets = set_.settings.targets;
  const Eigen::Matrix<double, 7, 1>& factors = set_.damping_factors;
  targets.damping.setZero();
  for (int i = 0; i < 6; ++i) {
    targets.damping(i, i) = factors[i] * (2.0 * std::sqrt(targets.stiffness(i, i)));
  }
  targets.nullspace_damping = factors[6] * (2.0 * std::sqrt(targets.nullspace_stiffness));
}

void CartesianImpedanceController::initDesiredPose(const Eigen::Vector3d& position_d_target,
                                                   const Eigen::Quaterniond& orientation_d_target) {
  Settings& settings = set_.settings;
  set_reference_pose(position_d_target, orientation_d_target);
  // A pose kept whole (not a number, a zero quaternion) leaves the filtered one as it was too.
  if (set_.report.adjusted == 0 || set_.report.action != Action::kept) {
    settings.init_position_d = settings.targets.position_d;
    settings.init_orientation_d = settings.targets.orientation_d;
    ++settings.pose_inits;
  }
  publish();
}

void CartesianImpedanceController::setReferencePose(const Eigen::Vector3d& position_d,
                                                    const Eigen::Quaterniond& orientation_d) {
  set_reference_pose(position_d, orientation_d);
  publish();
}

void CartesianImpedanceController::set_reference_pose(const Eigen::Vector3d& position_d,
                                                      const Eigen::Quaterniond& orientation_d) {
  if (set_.checking == Checking::strict) {
    const ci::Pose pose = ci::checks::pose("setReferencePose", ci::Pose{position_d, orientation_d});
    begin_call();
    set_.settings.targets.position_d = pose.position;
    set_.settings.targets.orientation_d = pose.orientation;
    return;
  }
  Impedance& targets = set_.settings.targets;
  begin_call();
  static const char* const kPosition = "setReferencePose: position_d";
  static const char* const kOrientation = "setReferencePose: orientation_d";
  // A pose that is not a number, or a zero quaternion, says nothing: the last pose stays whole.
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(position_d[i])) {
      report(Action::kept,
             ci::Fault{kPosition, i, position_d[i], "is not finite", 0.0, false, "m",
                       ci::Fault::Form::element},
             targets.position_d[i]);
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
    targets.position_d[i] = accept(kPosition, "m", position_d[i], targets.position_d[i], -kInfinity,
                                   -ci::checks::kMaxPosition, ci::checks::kMaxPosition);
  }
  targets.orientation_d = orientation_d.normalized();
}

void CartesianImpedanceController::set_nullspace_config(const Eigen::VectorXd& q_d_nullspace_target,
                                                        bool init) {
  static const char* const kName = "setNullspaceConfig: q_d_nullspace_target";
  if (set_.checking == Checking::strict) {
    ci::checks::size("setNullspaceConfig: q_d_nullspace_target", q_d_nullspace_target.size(),
                     set_.n_joints);
    ci::checks::bounded_vector("setNullspaceConfig: q_d_nullspace_target", q_d_nullspace_target,
                               ci::checks::kMaxJointPosition, "rad");
  }
  begin_call();
  Settings& settings = set_.settings;
  const int n = set_.n_joints;
  // A wrongly sized or not finite configuration is kept whole: joints taken from two
  // configurations would be a third one nobody asked for.
  if (q_d_nullspace_target.size() != n) {
    report(Action::kept,
           ci::Fault{kName, -1, static_cast<double>(q_d_nullspace_target.size()), "",
                     static_cast<double>(n), true, "values", ci::Fault::Form::size},
           kNaN);
  } else if (!q_d_nullspace_target.allFinite()) {
    int i = 0;
    while (std::isfinite(q_d_nullspace_target[i])) ++i;
    report(Action::kept,
           ci::Fault{kName, i, q_d_nullspace_target[i], "is not finite", 0.0, false, "rad"},
           settings.targets.q_d_nullspace[i]);
  } else {
    for (int i = 0; i < n; ++i) {
      settings.targets.q_d_nullspace[i] =
          accept(kName, "rad", q_d_nullspace_target[i], 0.0, -kInfinity,
                 -ci::checks::kMaxJointPosition, ci::checks::kMaxJointPosition);
    }
    // A configuration kept whole leaves the filtered one as it was too.
    if (init) {
      settings.init_q_d_nullspace = settings.targets.q_d_nullspace;
      ++settings.nullspace_inits;
    }
  }
  publish();
}

void CartesianImpedanceController::set_filtering(double update_frequency, double filter_nullspace,
                                                 double filter_stiffness, double filter_pose,
                                                 double filter_wrench) {
  if (set_.checking == Checking::strict) {
    check_filter_fraction("filter_params_nullspace_config", filter_nullspace);
    check_filter_fraction("filter_params_stiffness", filter_stiffness);
    check_filter_fraction("filter_params_pose", filter_pose);
    check_filter_fraction("filter_params_wrench", filter_wrench);
    check_frequency("setFiltering", update_frequency);
    check_torque_delta("setFiltering", set_.requested_torque_delta, update_frequency);
  }
  begin_call();
  static const char* const names[4] = {
      "setFiltering: filter_params_nullspace_config", "setFiltering: filter_params_stiffness",
      "setFiltering: filter_params_pose", "setFiltering: filter_params_wrench"};
  const double given[4] = {filter_nullspace, filter_stiffness, filter_pose, filter_wrench};
  Settings& settings = set_.settings;
  double* const kept[4] = {&settings.filter_nullspace, &settings.filter_stiffness,
                           &settings.filter_pose, &settings.filter_wrench};
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
  reconfigure("torque delta (setMaxTorqueDelta: d)", set_.requested_torque_delta,
              accept("setFiltering: update_frequency", "Hz", update_frequency,
                     settings.update_frequency, 0.0, kMinFrequency, kMaxFrequency));
  update_filter_steps();
  publish();
}

void CartesianImpedanceController::set_max_torque_delta(double d, double update_frequency,
                                                        bool frequency_given) {
  if (set_.checking == Checking::strict) {
    check_frequency("setMaxTorqueDelta", update_frequency);
    check_torque_delta("setMaxTorqueDelta", d, update_frequency);
  }
  begin_call();
  // Any delta from 0 up is the published domain, infinity included (no limit); the rate range
  // is applied with the frequency.
  const double requested =
      accept("setMaxTorqueDelta: d", "Nm", d, set_.requested_torque_delta, 0.0, 0.0, kInfinity);
  const double frequency =
      frequency_given ? accept("setMaxTorqueDelta: update_frequency", "Hz", update_frequency,
                               set_.settings.update_frequency, 0.0, kMinFrequency, kMaxFrequency)
                      : set_.settings.update_frequency;
  reconfigure("setMaxTorqueDelta: d", requested, frequency);
  if (frequency_given) update_filter_steps();
  publish();
}

void CartesianImpedanceController::update_filter_steps() {
  Settings& s = set_.settings;
  s.step_nullspace = published_filter_step(s.update_frequency, s.filter_nullspace);
  s.step_stiffness = published_filter_step(s.update_frequency, s.filter_stiffness);
  s.step_pose = published_filter_step(s.update_frequency, s.filter_pose);
  s.step_wrench = published_filter_step(s.update_frequency, s.filter_wrench);
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
  set_.settings.max_torque_delta = rate / update_frequency;
  set_.settings.update_frequency = update_frequency;
  set_.requested_torque_delta = requested;
}

void CartesianImpedanceController::applyWrench(const Eigen::Matrix<double, 6, 1>& wrench) {
  static const char* const names[6] = {"f_x", "f_y", "f_z", "tau_x", "tau_y", "tau_z"};
  if (set_.checking == Checking::strict) {
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
             set_.settings.targets.wrench[i]);
      publish();
      return;
    }
  }
  for (int i = 0; i < 6; ++i) {
    const ci::ParameterInfo& row = ci::parameter_info(i < 3 ? "wrench.force" : "wrench.torque");
    set_.settings.targets.wrench[i] =
        accept(kWrenchNames[i], i < 3 ? "N" : "Nm", wrench[i], 0.0, -kInfinity, row.min, row.max);
  }
  publish();
}

void CartesianImpedanceController::setWarningInterval(double seconds) {
  if (!(seconds >= 0.0)) {
    throw ci::Error("setWarningInterval: seconds = " + ci::format_number(seconds) +
                    " s is outside [0, inf]");
  }
  set_.warning_interval = seconds;
}

void CartesianImpedanceController::begin_call() noexcept {
  set_.report = InputReport{};
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
  ++set_.adjustment_count;
  InputReport& last = set_.report;
  if (last.adjusted++ == 0) {
    last.action = action;
    last.fault = fault;
    last.applied = applied;
  }
  // One line per interval at most: a program that sets a bad value every cycle at 1 kHz gets a
  // line a second, not a thousand, and the next line counts those left out.
  const auto now = std::chrono::steady_clock::now();
  if (set_.warned &&
      !(std::chrono::duration<double>(now - set_.last_warning).count() >= set_.warning_interval)) {
    ++set_.warnings_left_out;
    return;
  }
  std::string line = "cartesian_impedance_controller: " + ci::to_string(fault);
  if (action == Action::clamped) {
    line += "; " + ci::format_number(applied) + (fault.unit[0] != '\0' ? " " : "") + fault.unit +
            " is in effect";
  } else {
    line += "; the last valid value stays in effect";
  }
  if (set_.warnings_left_out > 0) {
    line +=
        " (" + std::to_string(set_.warnings_left_out) + " more adjustments since the last line)";
  }
  line += "\n";
  std::fputs(line.c_str(), stderr);
  set_.warned = true;
  set_.last_warning = now;
  set_.warnings_left_out = 0;
}

void CartesianImpedanceController::publish() noexcept {
  // One setter thread: with three slots and one reader, a free slot always exists.
  settings_buffer_.publish(set_.settings);
  settings_version_.fetch_add(1, std::memory_order_release);
}

void CartesianImpedanceController::take_settings() const noexcept {
  CycleState& cycle = cycle_;
  const std::uint64_t version = settings_version_.load(std::memory_order_acquire);
  if (version == cycle.version) return;  // most calls: nothing changed
  Settings& incoming = cycle.incoming;
  settings_buffer_.read(incoming);
  if (incoming.joint_count_changes != cycle.joint_count_changes && !reset_joints(incoming)) {
    return;
  }
  // The buffer may hold settings newer than `version`: taking them up again is harmless, each
  // initialisation is applied once by its count.
  cycle.version = version;
  if (incoming.pose_inits != cycle.pose_inits) {
    cycle.filtered.position_d = incoming.init_position_d;
    cycle.filtered.orientation_d = incoming.init_orientation_d;
    cycle.pose_inits = incoming.pose_inits;
  }
  if (incoming.nullspace_inits != cycle.nullspace_inits) {
    cycle.filtered.q_d_nullspace = incoming.init_q_d_nullspace;
    cycle.nullspace_inits = incoming.nullspace_inits;
  }
  std::swap(cycle.settings, incoming);
}

bool CartesianImpedanceController::reset_joints(const Settings& incoming) const noexcept {
  CycleState& cycle = cycle_;
  const int n = incoming.n_joints;
  if (n == cycle.n_joints) {
    // The same count: the controller starts over in place, as a new one would (no allocation).
    const ci::JointVector zero = ci::JointVector::Zero(n);
    cycle.controller.start(ci::make_robot_state(n), zero);
  } else if (!take_controller(n)) {
    // Settings for another count go with the controller built for it, which the setter thread
    // hands over before it publishes them; until it is here the settings in force stay, whole.
    return false;
  } else {
    // A new count starts from zero torque, as published. (With the same count the robot keeps
    // receiving the last torque, and the next call moves from it by at most the torque delta,
    // as every call does: a reset to zero would jump.)
    cycle.tau = ci::JointVector::Zero(n);
    cycle.n_joints = n;
  }
  cycle.joint_count_changes = incoming.joint_count_changes;
  const ci::Pose measured_pose = cycle.measured.pose;
  cycle.measured = ci::make_robot_state(n);
  cycle.measured.pose = measured_pose;
  cycle.status = ci::Status::not_started;
  cycle.fault = ci::Fault{};
  return true;
}

bool CartesianImpedanceController::take_controller(int n) const noexcept {
  int state = kReady;
  if (!handoff_state_.compare_exchange_strong(state, kTaking, std::memory_order_acquire)) {
    return false;
  }
  // One built for an earlier or later count change waits for the settings that go with it.
  if (!handoff_.has_value() || handoff_->num_joints() != n) {
    handoff_state_.store(kReady, std::memory_order_release);
    return false;
  }
  // Moves only: the old controller stays in the slot, and the setter thread frees it.
  std::swap(cycle_.controller, *handoff_);
  handoff_state_.store(kSetterOwns, std::memory_order_release);
  return true;
}

void CartesianImpedanceController::filter_step(Impedance& next) const noexcept {
  // The published order and switches: a parameter of exactly 1 takes the target at once; an
  // unfiltered stiffness also snaps the nullspace configuration to its target.
  const Settings& s = cycle_.settings;
  const Impedance& targets = s.targets;
  if (s.filter_nullspace == 1.0) {
    next.q_d_nullspace = targets.q_d_nullspace;
  } else {
    next.q_d_nullspace = blend(next.q_d_nullspace, targets.q_d_nullspace, s.step_nullspace);
  }
  if (s.filter_stiffness == 1.0) {
    next.stiffness = targets.stiffness;
    next.damping = targets.damping;
    next.nullspace_stiffness = targets.nullspace_stiffness;
    next.q_d_nullspace = targets.q_d_nullspace;
    next.nullspace_damping = targets.nullspace_damping;
  } else {
    next.stiffness = blend(next.stiffness, targets.stiffness, s.step_stiffness);
    next.damping = blend(next.damping, targets.damping, s.step_stiffness);
    next.nullspace_stiffness =
        blend(next.nullspace_stiffness, targets.nullspace_stiffness, s.step_stiffness);
    next.nullspace_damping =
        blend(next.nullspace_damping, targets.nullspace_damping, s.step_stiffness);
  }
  if (s.filter_pose == 1.0) {
    next.position_d = targets.position_d;
    next.orientation_d = targets.orientation_d;
  } else {
    next.position_d = blend(next.position_d, targets.position_d, s.step_pose);
    next.orientation_d = next.orientation_d.slerp(s.step_pose, targets.orientation_d);
  }
  if (s.filter_wrench == 1.0) {
    next.wrench = targets.wrench;
  } else {
    next.wrench = blend(next.wrench, targets.wrench, s.step_wrench);
  }
}

void CartesianImpedanceController::limit_torque_change() noexcept {
  CycleState& cycle = cycle_;
  const ci::JointVector& law = cycle.controller.torque();
  const double delta = cycle.settings.max_torque_delta;
  for (int i = 0; i < cycle.n_joints; ++i) {
    cycle.tau[i] += std::clamp(law[i] - cycle.tau[i], -delta, delta);
  }
}

ci::Status CartesianImpedanceController::step(const ci::RobotState& measured,
                                              bool measurement_checked) noexcept {
  // The filters advance only on a step the native controller accepts, so a rejected measurement
  // changes nothing but the torque (which steps toward zero).
  CycleState& cycle = cycle_;
  const int n = cycle.n_joints;
  const double dt = 1.0 / cycle.settings.update_frequency;
  cycle.next = cycle.filtered;
  filter_step(cycle.next);
  const Impedance& next = cycle.next;
  ci::ScheduledImpedance& schedule = cycle.schedule;
  schedule.reference = ci::Pose{next.position_d, next.orientation_d};
  schedule.stiffness = next.stiffness;
  schedule.damping = next.damping;
  schedule.nullspace_q = next.q_d_nullspace;
  schedule.nullspace_stiffness.setConstant(n, next.nullspace_stiffness);
  schedule.nullspace_damping.setConstant(n, next.nullspace_damping);
  schedule.wrench = next.wrench;
  cycle.controller.schedule(schedule);
  cycle.status = measurement_checked ? cycle.controller.update_measured(measured, dt)
                                     : cycle.controller.update(measured, dt);
  cycle.fault = cycle.controller.state().fault;
  limit_torque_change();
  if (cycle.status == ci::Status::ok) {
    cycle.filtered = cycle.next;
    if (&measured != &cycle.measured) cycle.measured = measured;
  }
  return cycle.status;
}

Eigen::VectorXd CartesianImpedanceController::calculateCommandedTorques() {
  take_settings();
  step(cycle_.measured);
  return cycle_.tau;
}

Eigen::VectorXd CartesianImpedanceController::calculateCommandedTorques(
    const Eigen::VectorXd& q, const Eigen::VectorXd& dq, const Eigen::Vector3d& position,
    Eigen::Quaterniond orientation, const Eigen::MatrixXd& jacobian) {
  // The joint count is read once, after the settings are taken up: a setNumberOfJoints() on
  // another thread takes effect at the next call, not between sizing and computing.
  take_settings();
  Eigen::VectorXd tau(cycle_.n_joints);
  compute(q, dq, position, orientation, jacobian, tau);
  return tau;
}

ci::Status CartesianImpedanceController::calculateCommandedTorques(
    const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& dq,
    const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
    const Eigen::Ref<const Eigen::MatrixXd>& jacobian, Eigen::Ref<Eigen::VectorXd> tau) noexcept {
  take_settings();
  return compute(q, dq, position, orientation, jacobian, tau);
}

ci::Status CartesianImpedanceController::compute(const Eigen::Ref<const Eigen::VectorXd>& q,
                                                 const Eigen::Ref<const Eigen::VectorXd>& dq,
                                                 const Eigen::Vector3d& position,
                                                 const Eigen::Quaterniond& orientation,
                                                 const Eigen::Ref<const Eigen::MatrixXd>& jacobian,
                                                 Eigen::Ref<Eigen::VectorXd> tau) noexcept {
  CycleState& cycle = cycle_;
  const Eigen::Index n = cycle.n_joints;
  if (const ci::Fault fault = ci::checks::count("tau", tau.size(), n)) {
    cycle.status = ci::Status::invalid_robot_state;
    cycle.fault = fault;
    return cycle.status;
  }
  // The measurement is checked once, here (its sizes must be right before it is copied); the
  // native controller then checks only the rest.
  ci::checks::MeasurementBounds bounds;
  bounds.speed = &cycle.controller.joint_velocity_bound();
  ci::Fault fault = ci::checks::measurement(q, dq, static_cast<int>(n), bounds);
  if (!fault) fault = ci::checks::count("jacobian", jacobian.rows(), 6, "rows");
  if (!fault) fault = ci::checks::count("jacobian", jacobian.cols(), n, "columns");
  if (fault) {
    cycle.status = cycle.controller.fail_closed(ci::Status::invalid_robot_state, fault,
                                                1.0 / cycle.settings.update_frequency);
    cycle.fault = fault;
    limit_torque_change();
  } else {
    cycle.input.q = q;
    cycle.input.dq = dq;
    cycle.input.pose.position = position;
    cycle.input.pose.orientation = orientation;
    cycle.input.jacobian = jacobian;
    step(cycle.input, true);
  }
  tau = cycle.tau;
  return cycle.status;
}

void CartesianImpedanceController::getState(
    Eigen::VectorXd* q, Eigen::VectorXd* dq, Eigen::Vector3d* position,
    Eigen::Quaterniond* orientation, Eigen::Vector3d* position_d, Eigen::Quaterniond* orientation_d,
    Eigen::Matrix<double, 6, 6>* cartesian_stiffness, double* nullspace_stiffness,
    Eigen::VectorXd* q_d_nullspace, Eigen::Matrix<double, 6, 6>* cartesian_damping) const {
  take_settings();
  const ci::RobotState& measured = cycle_.measured;
  if (q != nullptr) *q = measured.q;
  if (dq != nullptr) *dq = measured.dq;
  if (position != nullptr) *position = measured.pose.position;
  if (orientation != nullptr) *orientation = measured.pose.orientation;
  getState(position_d, orientation_d, cartesian_stiffness, nullspace_stiffness, q_d_nullspace,
           cartesian_damping);
}

void CartesianImpedanceController::getState(Eigen::Vector3d* position_d,
                                            Eigen::Quaterniond* orientation_d,
                                            Eigen::Matrix<double, 6, 6>* cartesian_stiffness,
                                            double* nullspace_stiffness,
                                            Eigen::VectorXd* q_d_nullspace,
                                            Eigen::Matrix<double, 6, 6>* cartesian_damping) const {
  take_settings();
  const Impedance& filtered = cycle_.filtered;
  if (position_d != nullptr) *position_d = filtered.position_d;
  if (orientation_d != nullptr) *orientation_d = filtered.orientation_d;
  if (cartesian_stiffness != nullptr) *cartesian_stiffness = filtered.stiffness;
  if (nullspace_stiffness != nullptr) *nullspace_stiffness = filtered.nullspace_stiffness;
  if (q_d_nullspace != nullptr) *q_d_nullspace = filtered.q_d_nullspace;
  if (cartesian_damping != nullptr) *cartesian_damping = filtered.damping;
}

}  // namespace cartesian_impedance_controller
