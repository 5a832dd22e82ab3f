#include "cartesian_impedance/core/checks.hpp"

#include <cmath>

namespace cartesian_impedance::checks {

namespace {

constexpr const char* kNotFinite = "is not finite";

Fault size_fault(const char* input, Eigen::Index size, Eigen::Index expected,
                 const char* counted = "values") noexcept {
  return Fault{input, -1,      static_cast<double>(size), "", static_cast<double>(expected),
               true,  counted, Fault::Form::size};
}

// The first element that is not finite, as a fault of `input` (with its index in `form`).
template <typename Derived>
Fault first_non_finite(const Eigen::DenseBase<Derived>& values, const char* input,
                       Fault::Form form = Fault::Form::element, const char* unit = "") noexcept {
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    const double value = values.derived().data()[i];
    if (!std::isfinite(value)) {
      return Fault{input, static_cast<int>(i), value, kNotFinite, 0.0, false, unit, form};
    }
  }
  return Fault{};
}

[[noreturn]] void fail(const Fault& fault, const std::string& message) {
  throw Error(fault, message);
}

}  // namespace

Fault count(const char* input, Eigen::Index size, Eigen::Index expected,
            const char* counted) noexcept {
  return size == expected ? Fault{} : size_fault(input, size, expected, counted);
}

namespace {

// measurement() for any vector type: the cycle's JointVector without the cost of a Ref.
template <typename Vector>
Fault check_measurement(const Vector& q, const Vector& dq, int num_joints,
                        const MeasurementBounds& bounds) noexcept {
  if (q.size() != num_joints) return size_fault("q", q.size(), num_joints);
  if (dq.size() != num_joints) return size_fault("dq", dq.size(), num_joints);
  // One sum checks finiteness in the common case; only a failing one looks for the element.
  if (!std::isfinite(q.sum() + dq.sum())) {
    for (int i = 0; i < num_joints; ++i) {
      if (!std::isfinite(q[i])) return Fault{"q", i, q[i], kNotFinite};
      if (!std::isfinite(dq[i])) return Fault{"dq", i, dq[i], kNotFinite};
    }
    return Fault{"robot state", -1, q.sum() + dq.sum(), "overflows"};
  }
  for (int i = 0; i < num_joints; ++i) {
    if (bounds.lower != nullptr && q[i] < (*bounds.lower)[i] - bounds.margin) {
      return Fault{"q",
                   i,
                   q[i],
                   "is outside the joint's limits: below the lower one minus "
                   "plausibility.joint_position_margin",
                   (*bounds.lower)[i] - bounds.margin,
                   true};
    }
    if (bounds.upper != nullptr && q[i] > (*bounds.upper)[i] + bounds.margin) {
      return Fault{"q",
                   i,
                   q[i],
                   "is outside the joint's limits: above the upper one plus "
                   "plausibility.joint_position_margin",
                   (*bounds.upper)[i] + bounds.margin,
                   true};
    }
    if (bounds.speed != nullptr && std::abs(dq[i]) > (*bounds.speed)[i]) {
      return Fault{"dq", i, dq[i], "is beyond plausibility.joint_velocity", (*bounds.speed)[i],
                   true};
    }
  }
  return Fault{};
}

}  // namespace

Fault measurement(const Eigen::Ref<const Eigen::VectorXd>& q,
                  const Eigen::Ref<const Eigen::VectorXd>& dq, int num_joints,
                  const MeasurementBounds& bounds) noexcept {
  return check_measurement(q, dq, num_joints, bounds);
}

Fault measurement(const JointVector& q, const JointVector& dq, int num_joints,
                  const MeasurementBounds& bounds) noexcept {
  return check_measurement(q, dq, num_joints, bounds);
}

Fault kinematics(const RobotState& robot, int num_joints) noexcept {
  const int n = num_joints;
  if (robot.jacobian.cols() != n) {
    return size_fault("jacobian", robot.jacobian.cols(), n, "columns");
  }
  // One sum checks every value for the common case (a NaN or an infinity anywhere makes it NaN or
  // infinite); only a failing sum pays for finding the element. The Jacobian column by column:
  // fixed-size additions, where Eigen's sum() of the 6 x n matrix runs a dynamic-size reduction.
  Vector6d column_sum = Vector6d::Zero();
  for (Eigen::Index i = 0; i < robot.jacobian.cols(); ++i) column_sum += robot.jacobian.col(i);
  const double sum =
      column_sum.sum() + robot.pose.position.sum() + robot.pose.orientation.coeffs().sum();
  if (!std::isfinite(sum)) {
    for (const Fault& fault :
         {first_non_finite(robot.jacobian, "jacobian"),
          first_non_finite(robot.pose.position, "pose.position", Fault::Form::axis, "m"),
          first_non_finite(robot.pose.orientation.coeffs(), "pose.orientation",
                           Fault::Form::axis)}) {
      if (fault) return fault;
    }
    return Fault{"robot state", -1, sum, "overflows"};
  }
  const double norm = robot.pose.orientation.norm();
  if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
    return Fault{"pose.orientation",       -1,   norm, "",
                 kQuaternionNormTolerance, true, "",   Fault::Form::norm};
  }
  // Optional terms: absent (size 0) or complete and finite.
  if (robot.mass.size() != 0 && (robot.mass.rows() != n || robot.mass.cols() != n)) {
    return size_fault("mass", robot.mass.rows(), n, "rows");
  }
  if (robot.gravity.size() != 0 && robot.gravity.size() != n) {
    return size_fault("gravity", robot.gravity.size(), n);
  }
  if (robot.secondary_torque.size() != 0 && robot.secondary_torque.size() != n) {
    return size_fault("secondary_torque", robot.secondary_torque.size(), n);
  }
  if (robot.measured_torque.size() != 0 && robot.measured_torque.size() != n) {
    return size_fault("measured_torque", robot.measured_torque.size(), n);
  }
  // The joint-limit bounds may be infinite (a free joint), never NaN.
  for (const auto& [bound, name] : {std::pair{&robot.joint_limit_ceiling, "joint_limit_ceiling"},
                                    std::pair{&robot.joint_limit_floor, "joint_limit_floor"}}) {
    if (bound->size() != 0 && bound->size() != n) return size_fault(name, bound->size(), n);
    for (int i = 0; i < bound->size(); ++i) {
      if (std::isnan((*bound)[i])) return Fault{name, i, (*bound)[i], "is not a number"};
    }
  }
  const double optional_sum = robot.mass.sum() + robot.gravity.sum() +
                              robot.secondary_torque.sum() + robot.measured_torque.sum();
  if (!std::isfinite(optional_sum)) {
    for (const Fault& fault :
         {first_non_finite(robot.mass, "mass"), first_non_finite(robot.gravity, "gravity"),
          first_non_finite(robot.secondary_torque, "secondary_torque"),
          first_non_finite(robot.measured_torque, "measured_torque")}) {
      if (fault) return fault;
    }
    return Fault{"robot state", -1, optional_sum, "overflows"};
  }
  return Fault{};
}

Fault robot_state(const RobotState& robot, int num_joints, const JointVector* speed) noexcept {
  MeasurementBounds bounds;
  bounds.speed = speed;
  if (const Fault fault = check_measurement(robot.q, robot.dq, num_joints, bounds)) return fault;
  return kinematics(robot, num_joints);
}

Fault time_step(double dt, const Range& plausible) noexcept {
  if (!std::isfinite(dt)) return Fault{"dt", -1, dt, kNotFinite};
  if (dt < plausible.min) {
    return Fault{"dt", -1, dt, "is below plausibility.dt.min", plausible.min, true};
  }
  if (dt > plausible.max) {
    return Fault{"dt", -1, dt, "is above plausibility.dt.max", plausible.max, true};
  }
  return Fault{};
}

void raise(const Fault& fault, std::string_view context) {
  if (fault) fail(fault, std::string(context) + to_string(fault));
}

std::string indexed(std::string_view name, Eigen::Index i) {
  return std::string(name) + "[" + std::to_string(i) + "]";
}

void finite(std::string_view name, double value, std::string_view unit) {
  if (!std::isfinite(value)) {
    const std::string input(name), unit_text(unit);
    raise(Fault{input.c_str(), -1, value, kNotFinite, 0.0, false, unit_text.c_str()});
  }
}

void size(std::string_view name, Eigen::Index size, Eigen::Index expected) {
  if (size != expected) {
    const std::string input(name);
    raise(size_fault(input.c_str(), size, expected));
  }
}

void one_or_per_joint(std::string_view name, Eigen::Index size, Eigen::Index num_joints) {
  if (size != 1 && size != num_joints) {
    const std::string input(name);
    fail(size_fault(input.c_str(), size, num_joints), input + " has " + std::to_string(size) +
                                                          " values; expected 1 (all joints) or " +
                                                          std::to_string(num_joints));
  }
}

void finite_vector(std::string_view name, const Eigen::Ref<const Eigen::VectorXd>& values,
                   std::string_view unit) {
  const std::string input(name), unit_text(unit);
  raise(first_non_finite(values, input.c_str(), Fault::Form::element, unit_text.c_str()));
}

void bounded_vector(std::string_view name, const Eigen::Ref<const Eigen::VectorXd>& values,
                    double bound, std::string_view unit) {
  finite_vector(name, values, unit);
  const std::string suffix = unit.empty() ? "" : " " + std::string(unit);
  const std::string input(name), unit_text(unit);
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    if (std::abs(values[i]) > bound) {
      fail(Fault{input.c_str(), static_cast<int>(i), values[i], "is outside", bound, true,
                 unit_text.c_str()},
           indexed(name, i) + " = " + format_number(values[i]) + suffix + " is outside [" +
               format_number(-bound) + ", " + format_number(bound) + "]" + suffix);
    }
  }
}

Eigen::Quaterniond unit_quaternion(std::string_view name, const Eigen::Quaterniond& q) {
  const std::string input(name);
  raise(first_non_finite(q.coeffs(), input.c_str(), Fault::Form::axis));
  const double norm = q.norm();
  if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
    fail(Fault{input.c_str(), -1, norm, "", kQuaternionNormTolerance, true, "", Fault::Form::norm},
         input + " (x, y, z, w) = (" + format_number(q.x()) + ", " + format_number(q.y()) + ", " +
             format_number(q.z()) + ", " + format_number(q.w()) + ") has norm " +
             format_number(norm) + "; a unit quaternion is required (within " +
             format_number(kQuaternionNormTolerance) + ")");
  }
  return q.normalized();
}

Pose pose(std::string_view name, const Pose& pose) {
  const std::string position = std::string(name) + ".position";
  raise(first_non_finite(pose.position, position.c_str(), Fault::Form::axis, "m"));
  static constexpr const char* kAxis[3] = {".x", ".y", ".z"};
  for (int i = 0; i < 3; ++i) {
    if (std::abs(pose.position[i]) > kMaxPosition) {
      fail(Fault{position.c_str(), i, pose.position[i], "is outside", kMaxPosition, true, "m",
                 Fault::Form::axis},
           position + kAxis[i] + " = " + format_number(pose.position[i]) + " m is outside [" +
               format_number(-kMaxPosition) + ", " + format_number(kMaxPosition) + "] m");
    }
  }
  return Pose{pose.position, unit_quaternion(std::string(name) + ".orientation", pose.orientation)};
}

void axes(const ParameterInfo& info, const Eigen::Ref<const Eigen::Vector3d>& values) {
  static constexpr const char* kAxis[3] = {".x", ".y", ".z"};
  for (int i = 0; i < 3; ++i) info.check(std::string(info.name) + kAxis[i], values[i]);
}

}  // namespace cartesian_impedance::checks
