#pragma once
// Seeded random inputs shared by the tests and the benchmark.

#include <Eigen/Dense>
#include <random>

#include "cartesian_impedance/core/types.hpp"

namespace random_cases {

namespace ci = cartesian_impedance;

inline double uniform(std::mt19937& rng, double low, double high) {
  return std::uniform_real_distribution<double>(low, high)(rng);
}

inline Eigen::Vector3d random_unit_vector(std::mt19937& rng) {
  std::normal_distribution<double> normal;
  Eigen::Vector3d v(normal(rng), normal(rng), normal(rng));
  return v.normalized();
}

/// Uniformly distributed rotation.
inline Eigen::Quaterniond random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return q.normalized();
}

/// Random 6 x n Jacobian with entries like a real arm's (m/rad and 1) and rank min(6, n), with
/// 2-norm condition number below `max_condition`, so the numerical tolerances of the tests
/// (which grow with the condition number squared for normal equations) stay meaningful.
inline ci::Jacobian random_jacobian(int n, std::mt19937& rng, double max_condition = 100.0) {
  for (;;) {
    ci::Jacobian jacobian(6, n);
    for (Eigen::Index i = 0; i < jacobian.size(); ++i) jacobian.data()[i] = uniform(rng, -1, 1);
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd{Eigen::MatrixXd(jacobian)};
    const auto& s = svd.singularValues();
    if (s[0] / s[s.size() - 1] < max_condition) return jacobian;
  }
}

/// Random symmetric positive definite 6x6 stiffness with translational eigenvalues in
/// [k_low, k_high] N/m, rotational ones a tenth of that, and a translation-rotation coupling.
inline ci::Matrix6d random_stiffness(std::mt19937& rng, double k_low = 50, double k_high = 2000) {
  ci::Matrix6d a = ci::Matrix6d::Zero();
  for (Eigen::Index i = 0; i < a.size(); ++i) a.data()[i] = uniform(rng, -1, 1);
  const Eigen::HouseholderQR<ci::Matrix6d> qr(a);
  const ci::Matrix6d axes = qr.householderQ();
  ci::Vector6d values;
  for (int i = 0; i < 3; ++i) values[i] = uniform(rng, k_low, k_high);
  for (int i = 3; i < 6; ++i) values[i] = 0.1 * uniform(rng, k_low, k_high);
  ci::Matrix6d k = axes * values.asDiagonal() * axes.transpose();
  return 0.5 * (k + k.transpose());
}

inline ci::JointVector random_joints(int n, std::mt19937& rng, double magnitude) {
  ci::JointVector v(n);
  for (int i = 0; i < n; ++i) v[i] = uniform(rng, -magnitude, magnitude);
  return v;
}

/// A consistent-looking robot state (the pose and Jacobian need not come from real kinematics:
/// the law only combines them).
inline ci::RobotState random_robot_state(int n, std::mt19937& rng) {
  ci::RobotState robot = ci::make_robot_state(n);
  robot.q = random_joints(n, rng, 2.0);
  robot.dq = random_joints(n, rng, 0.5);
  robot.pose.position =
      Eigen::Vector3d(uniform(rng, -0.8, 0.8), uniform(rng, -0.8, 0.8), uniform(rng, 0.0, 1.0));
  robot.pose.orientation = random_rotation(rng);
  robot.jacobian = random_jacobian(n, rng);
  return robot;
}

}  // namespace random_cases
