#pragma once
// A plainly written implementation of the same control law, the way it is often written: dynamic
// Eigen matrices, an SVD for the pseudo-inverse and for the square root of the stiffness, the
// filter gain recomputed with pow() every cycle. It shares nothing with the library's maths
// beyond Eigen, so the tests use it as an independent reference and the benchmark as a baseline.

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "cartesian_impedance/core/parameters.hpp"

namespace reference {

namespace ci = cartesian_impedance;

struct Torques {
  Eigen::VectorXd cartesian, nullspace, wrench, total;
  Eigen::VectorXd spring;  // the spring's part of `cartesian`, J^T (-K e)
};

struct Targets {
  Eigen::Vector3d position;
  Eigen::Quaterniond orientation;
  Eigen::MatrixXd stiffness;      // 6x6 in the stiffness frame
  Eigen::VectorXd damping_ratio;  // 6
  Eigen::VectorXd nullspace_q;
  Eigen::VectorXd nullspace_stiffness;
  double nullspace_damping_ratio = 1.0;
  Eigen::VectorXd wrench;  // 6 in the wrench frame
};

// Damped pseudo-inverse of A (m x k) from its SVD: V diag(s / (s^2 + lambda^2)) U^T.
inline Eigen::MatrixXd damped_pseudo_inverse(const Eigen::MatrixXd& a, double lambda) {
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd& s = svd.singularValues();
  Eigen::VectorXd inverse(s.size());
  for (Eigen::Index i = 0; i < s.size(); ++i) {
    const double denominator = s[i] * s[i] + lambda * lambda;
    inverse[i] = denominator > 1e-300 ? s[i] / denominator : 0.0;
  }
  return svd.matrixV() * inverse.asDiagonal() * svd.matrixU().transpose();
}

// Square root of a symmetric positive semi-definite matrix from its SVD (U = V for such matrices).
inline Eigen::MatrixXd sqrt_psd(const Eigen::MatrixXd& a) {
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * svd.singularValues().cwiseSqrt().asDiagonal() * svd.matrixU().transpose();
}

inline Eigen::MatrixXd rotation6(const Eigen::Matrix3d& rotation) {
  Eigen::MatrixXd result = Eigen::MatrixXd::Zero(6, 6);
  result.topLeftCorner(3, 3) = rotation;
  result.bottomRightCorner(3, 3) = rotation;
  return result;
}

// tau = J^T (-K e - D J dq) + (I - J^T J^T+) tau_0 + J^T F, with no clipping or limits.
inline Torques law(const Eigen::VectorXd& q, const Eigen::VectorXd& dq,
                   const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                   const Eigen::MatrixXd& jacobian, const Targets& targets,
                   const ci::Parameters& parameters) {
  const Eigen::Index n = q.size();
  // Pose error: translation difference and the angle-axis of R R_d^T, by a route independent of
  // the library's (rotation matrices and Eigen's AngleAxis).
  const Eigen::Matrix3d rotation = orientation.toRotationMatrix();
  const Eigen::Matrix3d relative = rotation * targets.orientation.toRotationMatrix().transpose();
  const Eigen::AngleAxisd angle_axis(relative);
  Eigen::VectorXd error(6);
  error << position - targets.position, angle_axis.angle() * angle_axis.axis();

  const Eigen::MatrixXd frame = parameters.stiffness.frame == ci::Frame::base
                                    ? Eigen::MatrixXd::Identity(6, 6)
                                    : rotation6(rotation);
  const Eigen::MatrixXd stiffness = frame * targets.stiffness * frame.transpose();
  const Eigen::MatrixXd zeta_root = targets.damping_ratio.cwiseSqrt().asDiagonal();
  const Eigen::MatrixXd damping =
      frame * (2.0 * zeta_root * sqrt_psd(targets.stiffness) * zeta_root) * frame.transpose();

  Torques torques;
  torques.spring = jacobian.transpose() * (-stiffness * error);
  torques.cartesian = torques.spring - jacobian.transpose() * (damping * (jacobian * dq));

  const Eigen::VectorXd nullspace_damping =
      2.0 * targets.nullspace_damping_ratio * targets.nullspace_stiffness.cwiseSqrt();
  const Eigen::VectorXd tau_0 = -targets.nullspace_stiffness.cwiseProduct(q - targets.nullspace_q) -
                                nullspace_damping.cwiseProduct(dq);
  const Eigen::MatrixXd jacobian_transpose = jacobian.transpose();
  const Eigen::MatrixXd projector =
      Eigen::MatrixXd::Identity(n, n) -
      jacobian_transpose *
          damped_pseudo_inverse(jacobian_transpose, parameters.nullspace.pseudo_inverse_damping);
  torques.nullspace = projector * tau_0;

  const Eigen::MatrixXd wrench_frame = parameters.wrench.frame == ci::Frame::base
                                           ? Eigen::MatrixXd::Identity(6, 6)
                                           : rotation6(rotation);
  torques.wrench = jacobian.transpose() * (wrench_frame * targets.wrench);
  torques.total = torques.cartesian + torques.nullspace + torques.wrench;
  return torques;
}

// The whole cycle: filters (gain from pow() each cycle), law, pose-error clipping is left out
// (tests compare with wide limits), torque saturation and the rate limit of each joint.
class Controller {
 public:
  // How a torque beyond limits.joint_torque is limited: shaped in task space as the library does
  // (the cross-checks), or clipped joint by joint as a plain implementation of the published law
  // with a torque bound would (the benchmark's baseline).
  enum class Shaping { task_space, per_joint };

  Controller(int num_joints, const ci::Parameters& parameters,
             Shaping shaping = Shaping::task_space)
      : n_(num_joints), parameters_(parameters), shaping_(shaping) {
    commanded_.stiffness = Eigen::MatrixXd::Zero(6, 6);
    commanded_.stiffness.diagonal() << parameters.stiffness.translation,
        parameters.stiffness.rotation;
    commanded_.damping_ratio = Eigen::VectorXd(6);
    commanded_.damping_ratio << parameters.damping_ratio.translation,
        parameters.damping_ratio.rotation;
    commanded_.nullspace_stiffness =
        Eigen::VectorXd::Constant(n_, parameters.nullspace.stiffness[0]);
    commanded_.nullspace_damping_ratio = parameters.nullspace.damping_ratio;
    commanded_.wrench = Eigen::VectorXd(6);
    commanded_.wrench << parameters.wrench.force, parameters.wrench.torque;
    tau_previous_ = Eigen::VectorXd::Zero(n_);
  }

  Targets& commanded() { return commanded_; }
  const Targets& filtered() const { return filtered_; }

  void start(const Eigen::VectorXd& q, const Eigen::Vector3d& position,
             const Eigen::Quaterniond& orientation) {
    commanded_.position = position;
    commanded_.orientation = orientation;
    commanded_.nullspace_q = q;
    filtered_ = commanded_;
    filtered_.wrench = Eigen::VectorXd::Zero(6);
  }

  Eigen::VectorXd update(const Eigen::VectorXd& q, const Eigen::VectorXd& dq,
                         const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                         const Eigen::MatrixXd& jacobian, double dt) {
    const ci::FilterParameters& filter = parameters_.filter;
    const auto gain = [dt](const ci::FilterSettings& settings) {
      return settings.time > 0.0 ? 1.0 - std::pow(1.0 - settings.fraction, dt / settings.time)
                                 : 1.0;
    };
    const double a_pose = gain(filter.pose);
    const double a_stiffness = gain(filter.stiffness);
    const double a_nullspace = gain(filter.nullspace);
    const double a_wrench = gain(filter.wrench);
    filtered_.position = (1 - a_pose) * filtered_.position + a_pose * commanded_.position;
    filtered_.orientation = filtered_.orientation.slerp(a_pose, commanded_.orientation);
    filtered_.stiffness =
        (1 - a_stiffness) * filtered_.stiffness + a_stiffness * commanded_.stiffness;
    filtered_.damping_ratio =
        (1 - a_stiffness) * filtered_.damping_ratio + a_stiffness * commanded_.damping_ratio;
    filtered_.nullspace_q =
        (1 - a_nullspace) * filtered_.nullspace_q + a_nullspace * commanded_.nullspace_q;
    filtered_.nullspace_stiffness = (1 - a_nullspace) * filtered_.nullspace_stiffness +
                                    a_nullspace * commanded_.nullspace_stiffness;
    filtered_.nullspace_damping_ratio = (1 - a_nullspace) * filtered_.nullspace_damping_ratio +
                                        a_nullspace * commanded_.nullspace_damping_ratio;
    filtered_.wrench = (1 - a_wrench) * filtered_.wrench + a_wrench * commanded_.wrench;

    const Torques torques = law(q, dq, position, orientation, jacobian, filtered_, parameters_);
    const double torque_limit = parameters_.limits.joint_torque[0];
    Eigen::VectorXd tau = shaping_ == Shaping::task_space
                              ? shape(torques, torques.spring, torque_limit)
                              : torques.total;
    const double max_step = parameters_.limits.joint_torque_rate[0] * dt;
    for (Eigen::Index i = 0; i < n_; ++i) {
      tau[i] = std::clamp(tau[i], -torque_limit, torque_limit);
      tau[i] = tau_previous_[i] + std::clamp(tau[i] - tau_previous_[i], -max_step, max_step);
    }
    tau_previous_ = tau;
    return tau;
  }

  // The task-space shaping of a torque beyond the bound, written as its definition: the terms
  // give way in the order nullspace, spring, wrench, damping, each scaled by the largest factor
  // (found by bisection) that makes the sum fit.
  static Eigen::VectorXd shape(const Torques& torques, const Eigen::VectorXd& spring,
                               double limit) {
    const auto fits = [limit](const Eigen::VectorXd& tau) {
      return tau.cwiseAbs().maxCoeff() <= limit * (1.0 + 1e-12);
    };
    if (fits(torques.total)) return torques.total;
    const Eigen::VectorXd damping = torques.cartesian - spring;
    const Eigen::VectorXd parts[] = {torques.nullspace, spring, torques.wrench, damping};
    for (int giving_way = 0; giving_way < 4; ++giving_way) {
      Eigen::VectorXd kept = Eigen::VectorXd::Zero(spring.size());
      for (int k = giving_way + 1; k < 4; ++k) kept += parts[k];
      if (!fits(kept)) continue;
      double low = 0.0, high = 1.0;
      if (fits(kept + parts[giving_way])) return kept + parts[giving_way];
      for (int step = 0; step < 60; ++step) {
        const double middle = 0.5 * (low + high);
        (fits(kept + middle * parts[giving_way]) ? low : high) = middle;
      }
      return kept + low * parts[giving_way];
    }
    return Eigen::VectorXd::Zero(spring.size());
  }

 private:
  int n_;
  ci::Parameters parameters_;
  Shaping shaping_;
  Targets commanded_, filtered_;
  Eigen::VectorXd tau_previous_;
};

}  // namespace reference
