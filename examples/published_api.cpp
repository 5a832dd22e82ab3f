// A program written only against the published base library's API, as a user of it would: a
// planar 7-joint arm (unit joint inertia, light viscous friction) is moved 5 cm and 0.1 rad by
// the controller with its filters and torque delta on, then pushed with a commanded 5 N wrench.
// The one line that differs from a program built on the published library is the include.
//
// Link it with cartesian_impedance::compat. The tests build it twice, against the compatibility
// header and against the oracle of the published semantics (tests/support/published_reference.hpp,
// through a header of the same name), and compare both outputs to 1e-9
// (tests/compat/compare_outputs.sh). It checks what the physics says itself: the arm reaches the
// reference, and the wrench moves it by F / K; it exits with 1 otherwise.

#include <Eigen/Dense>
#include <cartesian_impedance/compat/cartesian_impedance_controller.hpp>
#include <cmath>
#include <cstdio>

namespace {

constexpr int kJoints = 7;
constexpr double kLink = 0.15;  // [m] every link

struct Kinematics {
  Eigen::Vector3d position;
  Eigen::Quaterniond orientation;
  Eigen::MatrixXd jacobian;
};

// Revolute joints about z in the x-y plane: the flange angle is the sum of the joint angles.
Kinematics forward(const Eigen::VectorXd& q) {
  Eigen::Vector3d joint_origin[kJoints + 1];
  double angle = 0.0;
  joint_origin[0].setZero();
  for (int i = 0; i < kJoints; ++i) {
    angle += q[i];
    joint_origin[i + 1] =
        joint_origin[i] + kLink * Eigen::Vector3d(std::cos(angle), std::sin(angle), 0.0);
  }
  Kinematics k;
  k.position = joint_origin[kJoints];
  k.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()));
  k.jacobian = Eigen::MatrixXd::Zero(6, kJoints);
  for (int i = 0; i < kJoints; ++i) {
    const Eigen::Vector3d lever = k.position - joint_origin[i];
    k.jacobian.col(i) << -lever.y(), lever.x(), 0.0, 0.0, 0.0, 1.0;
  }
  return k;
}

}  // namespace

int main() {
  const double frequency = 1000.0, dt = 1.0 / frequency;
  Eigen::VectorXd q(kJoints), dq = Eigen::VectorXd::Zero(kJoints);
  q << 0.3, 0.4, 0.3, -0.2, 0.5, 0.4, 0.2;
  const Kinematics start = forward(q);

  cartesian_impedance_controller::CartesianImpedanceController controller;
  controller.setNumberOfJoints(kJoints);
  controller.setFiltering(frequency, 0.5, 0.9, 0.95, 0.9);
  controller.setMaxTorqueDelta(0.1);
  controller.initDesiredPose(start.position, start.orientation);
  controller.initNullspaceConfig(q);
  const double stiffness = 300.0;  // [N/m]
  // No nullspace spring: with lambda = 0.2 the published projector lets part of it into the task
  // on an arm of 15 cm links; joint friction settles the redundant joints instead.
  controller.setStiffness(stiffness, stiffness, stiffness, 30.0, 30.0, 30.0, 0.0);
  controller.setDampingFactors(1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0);

  const Eigen::Vector3d target = start.position + Eigen::Vector3d(0.05, 0.0, 0.0);
  const Eigen::Quaterniond target_orientation =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ())) * start.orientation;
  controller.setReferencePose(target, target_orientation);

  const double force = 5.0;  // [N] along y, from 3 s
  double error_before_push = 0.0;
  for (int k = 0; k <= 8000; ++k) {
    if (k == 3000) {
      Eigen::Matrix<double, 6, 1> wrench;
      wrench << 0.0, force, 0.0, 0.0, 0.0, 0.0;
      controller.applyWrench(wrench);
    }
    const Kinematics now = forward(q);
    const Eigen::VectorXd tau =
        controller.calculateCommandedTorques(q, dq, now.position, now.orientation, now.jacobian);
    if (k % 250 == 0) {
      std::printf("%6.3f %.12e %.12e", k * dt, now.position.x(), now.position.y());
      for (int i = 0; i < kJoints; ++i) std::printf(" %.12e", tau[i]);
      std::printf("\n");
    }
    if (k == 2999) error_before_push = (now.position - target).norm();
    // Unit inertia per joint and 2 Nm s/rad of friction, semi-implicit Euler.
    dq += dt * (tau - 2.0 * dq);
    q += dt * dq;
  }
  const Kinematics end = forward(q);
  const double push = end.position.y() - target.y();
  std::printf("# error before the push %.4f m; pushed %.4f m along y (F/K = %.4f m)\n",
              error_before_push, push, force / stiffness);
  // Reached within 1 mm of 50 mm; the push within 5 % of F/K (friction still creeping, the damped
  // projector's leak).
  const bool reached = error_before_push < 0.001;
  const bool pushed = std::abs(push - force / stiffness) < 0.05 * force / stiffness;
  return reached && pushed ? 0 : 1;
}
