// Scripted motion of a free rigid body under Cartesian impedance control.
//
// The "robot" is a body of 1 kg and 1 kg m^2 whose six joints are its translation and its
// rotation about the base axes, so J = I and each joint torque is a component of the wrench on
// the body. Its mass matrix M = I goes to the controller with the state, which makes zeta = 1
// critical damping of this body (D = 2 zeta sqrt(m K) with m = 1), so the numbers below can be
// checked by hand: a spring of K N/m under F N settles at F/K.
//
// Usage: scripted_motion [--quiet]

#include <cartesian_impedance/core/controller.hpp>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace ci = cartesian_impedance;

namespace {

constexpr double kDt = 0.001;          // [s] 1 kHz
constexpr double kBodyFriction = 5.0;  // [N s/m], [Nm s/rad] viscous, like joint friction

struct Body {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();

  ci::RobotState state() const {
    ci::RobotState robot = ci::make_robot_state(6);
    robot.q.head<3>() = position;
    robot.q.tail<3>() =
        Eigen::AngleAxisd(orientation).angle() * Eigen::AngleAxisd(orientation).axis();
    robot.dq << velocity, angular_velocity;
    robot.pose = ci::Pose{position, orientation};
    robot.jacobian = ci::Jacobian::Identity(6, 6);
    robot.mass = ci::JointMatrix::Identity(6, 6);  // 1 kg, 1 kg m^2
    return robot;
  }

  // Semi-implicit Euler with unit mass and inertia.
  void step(const ci::Vector6d& wrench, double dt) {
    velocity += (wrench.head<3>() - kBodyFriction * velocity) * dt;
    angular_velocity += (wrench.tail<3>() - kBodyFriction * angular_velocity) * dt;
    position += velocity * dt;
    const Eigen::Vector3d rotation = angular_velocity * dt;
    if (rotation.norm() > 0.0) {
      orientation = Eigen::Quaterniond(Eigen::AngleAxisd(rotation.norm(), rotation.normalized())) *
                    orientation;
    }
    orientation.normalize();
  }
};

struct Row {
  std::string scenario;
  std::string expected;
  std::string measured;
};

}  // namespace

int main(int argc, char** argv) {
  const bool quiet = argc > 1 && std::strcmp(argv[1], "--quiet") == 0;

  ci::Parameters parameters;
  parameters.stiffness.translation.setConstant(500.0);        // N/m
  parameters.stiffness.rotation.setConstant(50.0);            // Nm/rad
  parameters.limits.joint_torque_rate.setConstant(1, 200.0);  // N/s here, since J = I
  ci::CartesianImpedanceController controller(6, parameters);

  Body body;
  controller.start(body.state());
  double time = 0.0;
  double max_rate = 0.0;
  ci::Vector6d external = ci::Vector6d::Zero();

  auto run = [&](const char* phase, double duration) {
    if (!quiet)
      std::printf("\n%s\n   t [s]    x [mm]    y [mm]    z [mm]   Fx [N]   Fy [N]   Fz [N]\n",
                  phase);
    const int steps = static_cast<int>(std::lround(duration / kDt));
    for (int k = 0; k < steps; ++k) {
      const ci::JointVector previous = controller.torque();
      controller.update(body.state(), kDt);
      const ci::JointVector& tau = controller.torque();
      max_rate = std::max(max_rate, (tau - previous).cwiseAbs().maxCoeff() / kDt);
      body.step(tau + external, kDt);
      time += kDt;
      if (!quiet && (k + 1) % 250 == 0) {
        std::printf("%8.3f %9.2f %9.2f %9.2f %8.2f %8.2f %8.2f\n", time, 1e3 * body.position.x(),
                    1e3 * body.position.y(), 1e3 * body.position.z(), tau[0], tau[1], tau[2]);
      }
    }
  };

  std::vector<Row> rows;
  char text[128];
  char expected[128];

  // 1. Reference step of 10 cm: filtered, so the pull grows smoothly instead of jumping.
  controller.set_reference_pose(ci::Pose{Eigen::Vector3d(0.1, 0.0, 0.0), body.orientation});
  run("1. reference step of 100 mm along x", 3.0);
  std::snprintf(text, sizeof(text), "%.2f mm", 1e3 * body.position.x());
  rows.push_back({"reference step to x = 100 mm", "100.00 mm", text});

  // 2. A 10 N push along y against 500 N/m settles at F / K = 20 mm.
  const double y0 = body.position.y();
  external[1] = 10.0;
  run("2. push of 10 N along y at 500 N/m", 3.0);
  std::snprintf(text, sizeof(text), "%.2f mm", 1e3 * (body.position.y() - y0));
  rows.push_back({"10 N push at 500 N/m", "20.00 mm", text});

  // 3. Doubling the stiffness online halves the displacement under the same push.
  controller.set_stiffness((ci::Vector6d() << 500, 1000, 500, 50, 50, 50).finished());
  run("3. stiffness along y doubled to 1000 N/m, push continues", 3.0);
  std::snprintf(text, sizeof(text), "%.2f mm", 1e3 * (body.position.y() - y0));
  rows.push_back({"same push at 1000 N/m", "10.00 mm", text});
  external.setZero();

  // 4. A commanded wrench of 5 N along z against 500 N/m moves the body by 10 mm.
  const double z0 = body.position.z();
  controller.set_wrench((ci::Vector6d() << 0, 0, 5, 0, 0, 0).finished());
  run("4. commanded force of 5 N along z", 3.0);
  std::snprintf(text, sizeof(text), "%.2f mm", 1e3 * (body.position.z() - z0));
  rows.push_back({"commanded 5 N at 500 N/m", "10.00 mm", text});
  controller.set_wrench(ci::Vector6d::Zero());

  // 5. Teaching: zero stiffness; a short push moves the body and it stays where it was left.
  controller.set_stiffness(ci::Vector6d::Zero());
  run("5. zero stiffness (teaching mode): settle", 2.0);
  const double x_before = body.position.x();
  // With only viscous damping b acting (the body's friction plus the controller's minimum
  // damping, which keeps a soft arm from coasting), a push of F for T seconds moves the body by
  // F T / b in all.
  const double damping = kBodyFriction + parameters.minimum_damping.translation;
  external[0] = 2.0;
  run("   push 2 N along x for 0.3 s", 0.3);
  external.setZero();
  run("   released", 3.0);
  const double x_moved = body.position.x() - x_before;
  std::snprintf(text, sizeof(text), "%.1f mm, at rest (%.3f mm/s)", 1e3 * x_moved,
                1e3 * body.velocity.x());
  std::snprintf(expected, sizeof(expected), "%.1f mm, no spring back", 1e3 * 2.0 * 0.3 / damping);
  rows.push_back({"teaching: 2 N push for 0.3 s", expected, text});

  std::snprintf(text, sizeof(text), "%.1f N/s", max_rate);
  rows.push_back({"largest torque rate", "<= 200.0 N/s", text});

  std::printf("\n%-32s %-28s %s\n", "scenario", "theory", "measured");
  for (const Row& row : rows) {
    std::printf("%-32s %-28s %s\n", row.scenario.c_str(), row.expected.c_str(),
                row.measured.c_str());
  }
  return 0;
}
