// Power and force limiting after ISO/TS 15066 (safety.pfl): the caps in force each cycle.
//
// A transient contact with a body region of effective mass m_H and spring constant k, met by an
// arm of effective mass m_R at the relative speed v, stores the impact's energy 1/2 mu v^2
// (mu = m_H m_R / (m_H + m_R), the two-body reduced mass) in the region's spring, 1/2 F^2 / k:
// the force stays within the region's transient limit F_T while v <= F_T / sqrt(mu k) (the
// standard's Annex A, equation A.6 with A.4). The arm's effective mass is taken where the
// controller knows it, at the end effector along its motion: m_R = 1 / u^T J_v M^-1 J_v^T u.
// Links other than the end effector are not bounded by it.

#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "cartesian_impedance/core/controller.hpp"
#include "law.hpp"

namespace cartesian_impedance {
namespace {

// Below these the end effector has no direction of motion, nor a reference to move toward.
constexpr double kMovingSpeed = 1e-3;     // [m/s]
constexpr double kReferenceAhead = 1e-4;  // [m]

// The tighter of a cap (0: off) and a limit.
double tighter(double cap, double limit) noexcept {
  return cap > 0.0 ? std::min(cap, limit) : limit;
}

}  // namespace

void CartesianImpedanceController::update_caps_in_force(const RobotState& robot) noexcept {
  SafetyState& safety = state_.safety;
  const SafetyParameters& parameters = parameters_.safety;
  safety.max_speed_in_force = parameters.max_speed;
  safety.max_force_in_force = parameters.max_force;
  safety.pfl_speed_limit = 0.0;
  safety.pfl_effective_mass = 0.0;
  if (parameters.pfl.body_region == BodyRegion::none) return;
  const BodyRegionLimits region = body_region_limits(parameters.pfl.body_region);
  safety.max_force_in_force.force = tighter(parameters.max_force.force, region.quasi_static_force);
  // Without M(q) the arm counts as infinitely heavy: the region's own mass bounds the impact.
  double arm = std::numeric_limits<double>::infinity();
  TaskInertia& inertia = law_->pfl_inertia;
  if (robot.mass.rows() == num_joints_ &&
      inertia.compute(robot.jacobian, mass_with_payload(robot))) {
    const Eigen::Matrix3d mobility = inertia.inverse().topLeftCorner<3, 3>();
    const Eigen::Vector3d velocity = robot.jacobian.topRows<3>() * robot.dq;
    const Eigen::Vector3d ahead = state_.commanded.pose.position - robot.pose.position;
    const Eigen::Vector3d direction = velocity.norm() > kMovingSpeed   ? velocity
                                      : ahead.norm() > kReferenceAhead ? ahead
                                                                       : Eigen::Vector3d::Zero();
    double inverse_mass = 0.0;
    if (!direction.isZero(0.0)) {
      const Eigen::Vector3d u = direction.normalized();
      inverse_mass = u.dot(mobility * u);
    } else {
      // No direction yet: the heaviest the end effector is in any.
      inverse_mass =
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(mobility, Eigen::EigenvaluesOnly)
              .eigenvalues()
              .minCoeff();
    }
    if (inverse_mass > 0.0) arm = 1.0 / inverse_mass;
  }
  const double reduced = std::isfinite(arm) ? 1.0 / (1.0 / region.mass + 1.0 / arm) : region.mass;
  safety.pfl_effective_mass = arm;
  safety.pfl_speed_limit = region.transient_force / std::sqrt(reduced * region.spring_constant);
  safety.max_speed_in_force.translation =
      tighter(parameters.max_speed.translation, safety.pfl_speed_limit);
}

}  // namespace cartesian_impedance
