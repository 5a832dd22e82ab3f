#include "checks.hpp"

#include <cmath>

namespace cartesian_impedance::checks {

std::string indexed(std::string_view name, Eigen::Index i) {
  return std::string(name) + "[" + std::to_string(i) + "]";
}

void finite(std::string_view name, double value, std::string_view unit) {
  if (!std::isfinite(value)) {
    throw Error(std::string(name) + " = " + format_number(value) +
                (unit.empty() ? "" : " " + std::string(unit)) + " is not finite");
  }
}

void size(std::string_view name, Eigen::Index size, Eigen::Index expected) {
  if (size != expected) {
    throw Error(std::string(name) + " has " + std::to_string(size) + " values; expected " +
                std::to_string(expected));
  }
}

void one_or_per_joint(std::string_view name, Eigen::Index size, Eigen::Index num_joints) {
  if (size != 1 && size != num_joints) {
    throw Error(std::string(name) + " has " + std::to_string(size) +
                " values; expected 1 (all joints) or " + std::to_string(num_joints));
  }
}

void finite_vector(std::string_view name, const Eigen::Ref<const Eigen::VectorXd>& values,
                   std::string_view unit) {
  for (Eigen::Index i = 0; i < values.size(); ++i) finite(indexed(name, i), values[i], unit);
}

void bounded_vector(std::string_view name, const Eigen::Ref<const Eigen::VectorXd>& values,
                    double bound, std::string_view unit) {
  const std::string suffix = unit.empty() ? "" : " " + std::string(unit);
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    finite(indexed(name, i), values[i], unit);
    if (std::abs(values[i]) > bound) {
      throw Error(indexed(name, i) + " = " + format_number(values[i]) + suffix + " is outside [" +
                  format_number(-bound) + ", " + format_number(bound) + "]" + suffix);
    }
  }
}

Eigen::Quaterniond unit_quaternion(std::string_view name, const Eigen::Quaterniond& q) {
  static constexpr const char* kComponent[4] = {".x", ".y", ".z", ".w"};
  for (int i = 0; i < 4; ++i) finite(std::string(name) + kComponent[i], q.coeffs()[i]);
  const double norm = q.norm();
  if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
    throw Error(std::string(name) + " (x, y, z, w) = (" + format_number(q.x()) + ", " +
                format_number(q.y()) + ", " + format_number(q.z()) + ", " + format_number(q.w()) +
                ") has norm " + format_number(norm) + "; a unit quaternion is required (within " +
                format_number(kQuaternionNormTolerance) + ")");
  }
  return q.normalized();
}

Pose pose(std::string_view name, const Pose& pose) {
  static constexpr const char* kAxis[3] = {".x", ".y", ".z"};
  for (int i = 0; i < 3; ++i) {
    const std::string element = std::string(name) + ".position" + kAxis[i];
    finite(element, pose.position[i], "m");
    if (std::abs(pose.position[i]) > kMaxPosition) {
      throw Error(element + " = " + format_number(pose.position[i]) + " m is outside [" +
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
