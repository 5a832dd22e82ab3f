#include "cartesian_impedance/core/command.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "cartesian_impedance/core/checks.hpp"
#include "cartesian_impedance/core/math.hpp"

namespace cartesian_impedance {

namespace {

// A diagonal stiffness is checked axis by axis against its parameter rows (the messages a user
// of set_stiffness() expects); a full one element by element, then for symmetry and
// positive semi-definiteness.
void check_stiffness(Stiffness& command) {
  Matrix6d& stiffness = command.stiffness;
  if (is_diagonal(stiffness)) {
    checks::axes(parameter_info("stiffness.translation"), stiffness.diagonal().head<3>());
    checks::axes(parameter_info("stiffness.rotation"), stiffness.diagonal().tail<3>());
    return;
  }
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
  stiffness = 0.5 * (stiffness + stiffness.transpose()).eval();
  const double smallest = Eigen::SelfAdjointEigenSolver<Matrix6d>(stiffness).eigenvalues()[0];
  if (smallest < -1e-9 * scale) {
    throw Error("stiffness is not positive semi-definite: smallest eigenvalue " +
                format_number(smallest) + " is below 0");
  }
}

// JointVector holds at most kMaxJoints values; more would overflow it.
JointVector joint_values(std::string_view name, const Eigen::Ref<const Eigen::VectorXd>& values) {
  if (values.size() > kMaxJoints) {
    throw Error(std::string(name) + " has " + std::to_string(values.size()) + " values; at most " +
                std::to_string(kMaxJoints) + " joints are supported");
  }
  return values;
}

}  // namespace

NullspaceTarget::NullspaceTarget(const Eigen::Ref<const Eigen::VectorXd>& q)
    : q_desired(joint_values("nullspace_target", q)) {}

NullspaceStiffness::NullspaceStiffness(const Eigen::Ref<const Eigen::VectorXd>& k)
    : stiffness(joint_values("nullspace.stiffness", k)) {}

ValidCommand validate_command(Command command, int num_joints) {
  // How many joints the command was checked for, where that matters.
  const int joints = std::visit(
      Overloaded{
          [](ReferencePose& c) {
            c.pose_base = checks::pose("reference_pose", c.pose_base);
            return 0;
          },
          [](Stiffness& c) {
            check_stiffness(c);
            return 0;
          },
          [](DampingRatio& c) {
            checks::axes(parameter_info("damping_ratio.translation"), c.ratio.head<3>());
            checks::axes(parameter_info("damping_ratio.rotation"), c.ratio.tail<3>());
            return 0;
          },
          [num_joints](NullspaceTarget& c) {
            checks::size("nullspace_target", c.q_desired.size(), num_joints);
            checks::bounded_vector("nullspace_target", c.q_desired, checks::kMaxJointPosition,
                                   "rad");
            return num_joints;
          },
          [num_joints](NullspaceStiffness& c) {
            checks::one_or_per_joint("nullspace.stiffness", c.stiffness.size(), num_joints);
            const ParameterInfo& info = parameter_info("nullspace.stiffness");
            for (Eigen::Index i = 0; i < c.stiffness.size(); ++i) {
              info.check(checks::indexed(info.name, i), c.stiffness[i]);
            }
            return num_joints;
          },
          [](NullspaceDampingRatio& c) {
            parameter_info("nullspace.damping_ratio").check("nullspace.damping_ratio", c.ratio);
            return 0;
          },
          [](Wrench& c) {
            checks::axes(parameter_info("wrench.force"), c.wrench.head<3>());
            checks::axes(parameter_info("wrench.torque"), c.wrench.tail<3>());
            return 0;
          },
          [num_joints](Parameters& c) {
            validate(c, num_joints);
            return num_joints;
          },
          [num_joints](ParameterUpdate& c) {
            validate(c.values, num_joints);
            return num_joints;
          },
          [](Resume&) { return 0; },
      },
      command);
  return ValidCommand(std::move(command), joints);
}

const char* command_name(const Command& command) noexcept {
  return std::visit([](const auto& c) { return std::decay_t<decltype(c)>::kName; }, command);
}

}  // namespace cartesian_impedance
