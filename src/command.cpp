#include "cartesian_impedance/command.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "checks.hpp"

namespace cartesian_impedance {

Command Command::reference_pose(const Pose& pose_base) {
  Command command(Kind::reference_pose);
  command.pose_ = checks::pose("reference_pose", pose_base);
  return command;
}

Command Command::stiffness(const Vector6d& diagonal, std::optional<Frame> frame) {
  checks::axes(parameter_info("stiffness.translation"), diagonal.head<3>());
  checks::axes(parameter_info("stiffness.rotation"), diagonal.tail<3>());
  Command command(Kind::stiffness);
  command.matrix_ = diagonal.asDiagonal();
  command.frame_ = frame;
  return command;
}

Command Command::stiffness_matrix(const Matrix6d& stiffness, std::optional<Frame> frame) {
  // Entries are bounded like the diagonal stiffness parameters (the largest of their ranges), so
  // that the eigen-decompositions of saturation and damping stay far from overflow.
  const double bound = parameter_info("stiffness.translation").max;
  for (int row = 0; row < 6; ++row) {
    for (int col = 0; col < 6; ++col) {
      const std::string element =
          "stiffness(" + std::to_string(row) + ", " + std::to_string(col) + ")";
      checks::finite(element, stiffness(row, col));
      if (std::abs(stiffness(row, col)) > bound) {
        throw Error(element + " = " + format_number(stiffness(row, col)) + " is outside [" +
                    format_number(-bound) + ", " + format_number(bound) + "]");
      }
    }
  }
  const double scale = std::max(1.0, stiffness.cwiseAbs().maxCoeff());
  for (int row = 0; row < 6; ++row) {
    for (int col = row + 1; col < 6; ++col) {
      if (std::abs(stiffness(row, col) - stiffness(col, row)) > 1e-9 * scale) {
        throw Error("stiffness is not symmetric: stiffness(" + std::to_string(row) + ", " +
                    std::to_string(col) + ") = " + format_number(stiffness(row, col)) +
                    " but stiffness(" + std::to_string(col) + ", " + std::to_string(row) +
                    ") = " + format_number(stiffness(col, row)));
      }
    }
  }
  const Matrix6d symmetric = 0.5 * (stiffness + stiffness.transpose());
  const double smallest = Eigen::SelfAdjointEigenSolver<Matrix6d>(symmetric).eigenvalues()[0];
  if (smallest < -1e-9 * scale) {
    throw Error("stiffness is not positive semi-definite: smallest eigenvalue " +
                format_number(smallest) + " is below 0");
  }
  Command command(Kind::stiffness);
  command.matrix_ = symmetric;
  command.full_matrix_ = true;
  command.frame_ = frame;
  return command;
}

Command Command::damping_ratio(const Vector6d& damping_ratio) {
  checks::axes(parameter_info("damping_ratio.translation"), damping_ratio.head<3>());
  checks::axes(parameter_info("damping_ratio.rotation"), damping_ratio.tail<3>());
  Command command(Kind::damping_ratio);
  command.vector_ = damping_ratio;
  return command;
}

Command Command::nullspace_target(const Eigen::Ref<const Eigen::VectorXd>& q_desired,
                                  int num_joints) {
  checks::size("nullspace_target", q_desired.size(), num_joints);
  checks::bounded_vector("nullspace_target", q_desired, checks::kMaxJointPosition, "rad");
  Command command(Kind::nullspace_target);
  command.num_joints_ = num_joints;
  command.joints_ = q_desired;
  return command;
}

Command Command::nullspace_stiffness(const Eigen::Ref<const Eigen::VectorXd>& stiffness,
                                     int num_joints) {
  if (stiffness.size() != 1 && stiffness.size() != num_joints) {
    throw Error("nullspace.stiffness has " + std::to_string(stiffness.size()) +
                " values; expected 1 (all joints) or " + std::to_string(num_joints));
  }
  const ParameterInfo& info = parameter_info("nullspace.stiffness");
  for (Eigen::Index i = 0; i < stiffness.size(); ++i) {
    info.check(checks::indexed(info.name, i), stiffness[i]);
  }
  Command command(Kind::nullspace_stiffness);
  command.num_joints_ = num_joints;
  command.joints_ = stiffness;
  return command;
}

Command Command::nullspace_damping_ratio(double damping_ratio) {
  parameter_info("nullspace.damping_ratio").check("nullspace.damping_ratio", damping_ratio);
  Command command(Kind::nullspace_damping_ratio);
  command.scalar_ = damping_ratio;
  return command;
}

Command Command::wrench(const Vector6d& wrench, std::optional<Frame> frame) {
  checks::axes(parameter_info("wrench.force"), wrench.head<3>());
  checks::axes(parameter_info("wrench.torque"), wrench.tail<3>());
  Command command(Kind::wrench);
  command.vector_ = wrench;
  command.frame_ = frame;
  return command;
}

Command Command::parameters(const Parameters& parameters, int num_joints) {
  validate(parameters, num_joints);
  Command command(Kind::parameters);
  command.num_joints_ = num_joints;
  command.parameters_ = parameters;
  return command;
}

}  // namespace cartesian_impedance
