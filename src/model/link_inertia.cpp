#include "cartesian_impedance/model/link_inertia.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance {
namespace {

// 1000 t: more than any arm with its payload (the heaviest industrial robots lift 2.3 t).
constexpr double kMaxMass = 1e6;  // [kg]
// The largest mass 1 m from its centre of mass; the links of industrial arms have below 1e3.
constexpr double kMaxInertia = 1e6;  // [kg m^2] every entry of an inertia tensor
// Rounding in a file, relative to the trace: a zero moment written slightly negative, or moments
// written on the triangle limit (a flat plate). Beyond it, a violation is the file's and is
// reported.
constexpr double kRounding = 1e-9;
// What an eigen-decomposition's rounding may move moments that lie on the limit: a tensor within
// it is the file's own, used exactly as written.
constexpr double kEigenRounding = 1e-12;

std::string moments(const Eigen::Vector3d& m) {
  std::ostringstream text;
  text.precision(6);
  text << "(" << m[0] << ", " << m[1] << ", " << m[2] << ")";
  return text.str();
}

}  // namespace

LinkInertia physical_link_inertia(const std::string& link, double mass,
                                  const Eigen::Matrix3d& inertia) {
  const std::string name = "link '" + link + "'";
  if (!(mass >= 0.0 && mass <= kMaxMass)) {
    std::ostringstream message;
    message << name << " has mass = " << mass
            << " kg; expected a finite value >= 0 kg and <= " << kMaxMass << " kg";
    throw Error(message.str());
  }
  const char* entries[3][3] = {{"ixx", "ixy", "ixz"}, {"ixy", "iyy", "iyz"}, {"ixz", "iyz", "izz"}};
  for (int r = 0; r < 3; ++r) {
    for (int c = r; c < 3; ++c) {
      if (!(std::abs(inertia(r, c)) <= kMaxInertia)) {
        std::ostringstream message;
        message << name << " has inertia " << entries[r][c] << " = " << inertia(r, c)
                << " kg m^2; expected finite entries within +-" << kMaxInertia << " kg m^2";
        throw Error(message.str());
      }
    }
  }
  LinkInertia result;
  result.mass = mass;
  result.inertia = inertia;
  const double trace = inertia.trace();
  if (trace == 0.0 && inertia.isZero(0.0)) return result;  // a massless frame
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(inertia);
  Eigen::Vector3d moment = solver.eigenvalues();  // ascending
  const double slack = kRounding * std::max(std::abs(trace), 1e-300);
  if (moment[0] < -slack) {
    std::ostringstream message;
    message << name << " has an inertia tensor that is not positive semi-definite (principal "
            << "moments " << moments(moment) << " kg m^2, smallest " << moment[0]
            << "; expected >= 0)";
    throw Error(message.str());
  }
  const bool rounded_negative = moment[0] < 0.0;
  moment = moment.cwiseMax(0.0);
  const double excess = moment[2] - moment[0] - moment[1];  // > 0: A + B < C
  if (excess <= kEigenRounding * std::abs(trace)) {
    if (rounded_negative) {
      result.inertia =
          solver.eigenvectors() * moment.asDiagonal() * solver.eigenvectors().transpose();
    }
    return result;
  }
  // The nearest moments with A + B - C = slack and the same sum: a step along (1, 1, -2). The
  // sum is twice the body's polar moment (the integral of |r|^2 dm), which the repair keeps; so a
  // repaired tensor is its own repair. The other two inequalities still hold for sorted moments:
  // A' + C' - B' = (3A + C - B - slack) / 2. The slack keeps an engine's own eigen-decomposition
  // of the repaired tensor inside the limit.
  const Eigen::Vector3d before = moment;
  const double shift = (excess + slack) / 4.0;
  moment += Eigen::Vector3d(shift, shift, -2.0 * shift);
  result.inertia = solver.eigenvectors() * moment.asDiagonal() * solver.eigenvectors().transpose();
  if (excess > slack) {
    std::ostringstream text;
    text << name << ": principal moments " << moments(before)
         << " kg m^2 break the triangle inequality A + B >= C by " << excess
         << " kg m^2 (no rigid body has them); repaired to " << moments(moment)
         << " kg m^2, the nearest physical moments with the same sum and axes";
    result.repair = text.str();
  }
  return result;
}

}  // namespace cartesian_impedance
