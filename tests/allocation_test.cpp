// The control cycle allocates nothing: malloc and operator new are counted (support/
// allocation_counter) over 10,000 cycles with every feature on, and with every part of the
// safety layer acting.

#include <gtest/gtest.h>

#include <random>
#include <variant>

#include "cartesian_impedance/compat/cartesian_impedance_controller.hpp"
#include "cartesian_impedance/core/controller.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "support/allocation_counter.hpp"
#include "support/random_cases.hpp"
#include "support/safety_caps.hpp"

namespace ci = cartesian_impedance;
using namespace random_cases;

namespace {

// Every feature that costs something in the cycle: filters running, a full stiffness matrix in
// the end-effector frame (damping shaped by the task-space inertia, a matrix square root every
// cycle), a wrench in the end-effector frame, dynamically consistent nullspace projection,
// clipping, saturation and rate limiting.
ci::CartesianImpedanceController busy_controller(int n, std::mt19937& rng,
                                                 const ci::RobotState& robot) {
  ci::Parameters parameters;
  parameters.stiffness.frame = ci::Frame::end_effector;
  parameters.wrench.frame = ci::Frame::end_effector;
  parameters.filter.stiffness.time = 20.0;  // still moving after 10,000 cycles at 1 kHz
  parameters.filter.pose.time = 20.0;
  parameters.nullspace.pseudo_inverse_damping = 0.05;
  parameters.dynamics.dynamically_consistent_nullspace = true;
  parameters.limits.pose_error = {0.02, 0.05};
  parameters.limits.joint_torque = ci::JointVector::Constant(1, 5.0);
  parameters.limits.joint_torque_rate = ci::JointVector::Constant(1, 100.0);
  ci::CartesianImpedanceController controller(n, parameters);
  controller.start(robot);
  controller.set_stiffness_matrix(random_stiffness(rng));
  controller.set_wrench((ci::Vector6d() << 5, 0, -3, 0, 0.2, 0).finished());
  controller.set_reference_pose(
      {robot.pose.position + Eigen::Vector3d(0.1, 0, 0),
       Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY())) *
           robot.pose.orientation});
  controller.set_nullspace_target(robot.q + random_joints(n, rng, 0.2));
  return controller;
}

}  // namespace

// The counter itself must see each kind of allocation (volatile keeps the compiler from eliding
// the pairs, which the language allows).
TEST(Allocation, CounterSeesMallocAndNew) {
  allocation_counter::Scope scope;
  void* volatile block = std::malloc(16);
  std::free(block);
  int* volatile number = new int(3);
  delete number;
  Eigen::VectorXd dynamic(100);
  dynamic.setZero();
  EXPECT_EQ(scope.allocations(), 3);
}

class AllocationFree : public ::testing::TestWithParam<int> {};

TEST_P(AllocationFree, UpdateAllocatesNothingWithEveryFeatureOn) {
  const int n = GetParam();
  std::mt19937 rng(21);
  ci::RobotState robot = random_robot_state(n, rng);
  const ci::JointMatrix root = ci::JointMatrix::Random(n, n);
  robot.mass = root * root.transpose() + ci::JointMatrix::Identity(n, n);
  ci::CartesianImpedanceController controller = busy_controller(n, rng, robot);
  ci::JointVector dq_step = random_joints(n, rng, 1e-4);
  bool rate_limited = false, saturated = false, clipped = false;
  allocation_counter::Scope scope;
  for (int k = 0; k < 10000; ++k) {
    robot.q += dq_step;
    robot.dq = 1000.0 * dq_step;
    robot.pose.position.x() += 1e-6;
    const ci::Status status = controller.update(robot, k % 2 ? 0.001 : 0.0011);
    if (status != ci::Status::ok) FAIL() << "status " << ci::to_string(status);
    rate_limited |= controller.state().limits.torque_rate_limited;
    saturated |= controller.state().limits.joint_torque_saturated;
    clipped |= controller.state().limits.translation_error_clipped;
  }
  // Bad input takes the safe path, which must not allocate either.
  robot.q[0] = std::nan("");
  for (int k = 0; k < 100; ++k) controller.update(robot, 0.001);
  controller.update(robot, -1.0);
  EXPECT_EQ(scope.allocations(), 0);
  EXPECT_TRUE(rate_limited && saturated && clipped) << "every limit should have been exercised";
  EXPECT_NE(controller.state().filtered.stiffness, controller.state().commanded.stiffness)
      << "the stiffness filter should still be moving (matrix square root every cycle)";
}

INSTANTIATE_TEST_SUITE_P(Joints, AllocationFree, ::testing::Values(6, 7));

// The oscillation watch through all it does: a swing of the end effector (10 Hz, 0.2 m/s along
// x, and 1.2 rad/s about z) found and the stiffness halved eight times, the ninth failing closed,
// the halt, and the hold once the arm is at rest.
TEST(AllocationFree, TheOscillationWatchAllocatesNothingFromSwingToHold) {
  std::mt19937 rng(5);
  ci::RobotState robot = random_robot_state(7, rng);
  const ci::JointMatrix root = ci::JointMatrix::Random(7, 7);
  robot.mass = root * root.transpose() + ci::JointMatrix::Identity(7, 7);
  ci::CartesianImpedanceController controller(7);
  controller.start(robot);
  const Eigen::MatrixXd inverse = robot.jacobian.completeOrthogonalDecomposition().pseudoInverse();
  bool halted = false;
  allocation_counter::Scope scope;
  for (int k = 0; k < 6000; ++k) {
    const double swing = std::sin(2.0 * M_PI * 10.0 * k * 0.001);
    const ci::Vector6d twist = (ci::Vector6d() << 0.2 * swing, 0, 0, 0, 0, 1.2 * swing).finished();
    robot.dq.noalias() = inverse * twist;
    halted |= controller.update(robot, 0.001) == ci::Status::motion_halted;
  }
  robot.dq.setZero();
  for (int k = 0; k < 200; ++k) controller.update(robot, 0.001);
  EXPECT_EQ(scope.allocations(), 0);
  EXPECT_TRUE(halted) << controller.state().safety.oscillations << " oscillations";
  EXPECT_TRUE(controller.state().limits.holding);
}

// The passivity controller through all it does: on the Cartesian robot (J = I) an undamped spring
// 20 ms late under an imposed motion along x (1.5 mm at 5 Hz) generates energy whatever it is
// halved to; eight halvings, the ninth failing closed, the halt and the hold.
TEST(AllocationFree, ThePassivityControllerAllocatesNothingFromGenerationToHold) {
  ci::Parameters parameters;
  parameters.dynamics.inertia_shaped_damping = false;
  parameters.stiffness.translation.setConstant(3000.0);
  parameters.damping_ratio.translation.setZero();
  parameters.minimum_damping = {0.0, 0.0, 0.0};
  parameters.safety.passivity.delay = 0.02;
  parameters.safety.passivity.threshold = 1e-5;
  ci::RobotState robot = ci::make_robot_state(6);
  robot.jacobian = ci::Jacobian::Identity(6, 6);
  ci::CartesianImpedanceController controller(6, parameters);
  controller.start(robot);
  const Eigen::Vector3d start = robot.pose.position;
  bool halted = false;
  allocation_counter::Scope scope;
  for (int k = 1; k <= 6000 && !halted; ++k) {
    const double w = 2.0 * M_PI * 5.0;
    robot.pose.position.x() = start.x() + 0.0015 * std::sin(w * k * 0.001);
    robot.dq[0] = 0.0015 * w * std::cos(w * k * 0.001);
    halted = controller.update(robot, 0.001) == ci::Status::motion_halted;
  }
  robot.dq.setZero();
  for (int k = 0; k < 200; ++k) controller.update(robot, 0.001);
  EXPECT_EQ(scope.allocations(), 0);
  EXPECT_TRUE(halted);
  EXPECT_EQ(controller.state().safety.passivity_halvings, 9);
  EXPECT_TRUE(controller.state().limits.holding);
}

// The controller's safety layer with every part acting (support/safety_caps.hpp), on the Panda's
// model: the default diagonal stiffness in the base frame, and a full (coupled) stiffness raise
// in the end-effector frame, which the tank charges through the whole matrix and the rotated
// error. The joints move as commanded (q integrates dq), faster than the speed caps, the flange
// outside the workspace box and leaving it; then still, so the payload estimate runs.
class SafetyAllocationFree : public ::testing::TestWithParam<bool> {};

TEST_P(SafetyAllocationFree, UpdateAllocatesNothingWithEverySafetyCapActing) {
  const bool full_stiffness = GetParam();
  const ci::RobotModel model = ci::RobotModel::from_urdf_file(
      std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/panda/panda.urdf", "panda_link0",
      "panda_link8");
  ci::JointVector q(7);
  q << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4;
  ci::JointVector dq = ci::JointVector::Constant(7, 0.01);
  ci::Parameters parameters;
  if (full_stiffness) {
    parameters.stiffness.frame = ci::Frame::end_effector;
    parameters.wrench.frame = ci::Frame::end_effector;
  }
  const safety_caps::Scene scene = safety_caps::scene(model, q, dq, parameters);
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  ci::RobotState robot = ci::make_robot_state(7);
  const auto measure = [&] {
    ASSERT_TRUE(workspace.compute(q, dq, kinematics, ci::ModelTerms::mass));
    robot.q = q;
    robot.dq = dq;
    robot.pose = kinematics.pose;
    robot.jacobian = kinematics.jacobian;
    robot.mass = kinematics.mass;
  };
  const ci::JointVector q_moving = q;
  q = scene.start;
  measure();
  ci::CartesianImpedanceController controller(7, scene.parameters);
  controller.start(robot);
  q = q_moving;
  for (const ci::Command& command : scene.commands) {
    // The scene's wrench is in the base frame: say so when the configured frame is another.
    if (const auto* wrench = std::get_if<ci::Wrench>(&command)) {
      controller.apply(ci::Wrench(wrench->wrench, ci::Frame::base));
    } else {
      controller.apply(command);
    }
  }
  if (full_stiffness) {
    // A raise over the scene's soft start (200 N/m, 10 Nm/rad) along every axis, coupled.
    const Eigen::Matrix3d axes =
        Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    ci::Matrix6d stiffness = ci::Matrix6d::Zero();
    stiffness.topLeftCorner<3, 3>() =
        axes * Eigen::Vector3d(1000, 600, 300).asDiagonal() * axes.transpose();
    stiffness.bottomRightCorner<3, 3>() =
        axes * Eigen::Vector3d(50, 30, 20).asDiagonal() * axes.transpose();
    controller.apply(ci::Stiffness(stiffness));
  }

  safety_caps::Acted moving, still;
  long allocations = 0;
  int failed = 0;
  const auto cycle = [&](safety_caps::Acted& acted) {
    measure();
    allocation_counter::Scope scope;
    const ci::Status status = controller.update(robot, 0.001);
    allocations += scope.allocations();
    if (status != ci::Status::ok) ++failed;
    acted.record(controller.state().safety);
    q += 0.001 * dq;
  };
  for (int k = 0; k < 2000; ++k) cycle(moving);
  dq.setZero();
  for (int k = 0; k < 700; ++k) cycle(still);  // kPayloadSettleTime (0.5 s) and more

  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(failed, 0) << ci::to_string(controller.state().fault);
  EXPECT_EQ(moving.missing(false), "") << "these parts of the safety layer never acted";
  EXPECT_TRUE(still.payload_estimate) << "the payload estimate never became valid";
}

INSTANTIATE_TEST_SUITE_P(Stiffness, SafetyAllocationFree, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& info) {
                           return info.param ? "FullInEndEffectorFrame" : "DiagonalInBaseFrame";
                         });

// The compatibility API: its own overload allocates nothing per call, filters and rate limit
// running, bad measurements included; the published signature allocates exactly its returned
// vector.
TEST(CompatAllocations, TheWritingOverloadAllocatesNothingThePublishedOneItsResult) {
  const int n = 7;
  std::mt19937 rng(5);
  const ci::RobotState robot = random_robot_state(n, rng);
  cartesian_impedance_controller::CartesianImpedanceController compat;
  compat.setFiltering(1000.0, 0.5, 0.5, 0.5, 0.5);
  compat.setMaxTorqueDelta(0.05);
  compat.initNullspaceConfig(Eigen::VectorXd(robot.q));
  compat.setReferencePose(robot.pose.position + Eigen::Vector3d(0.05, 0, 0),
                          robot.pose.orientation);
  // The caller's data, as Eigen::VectorXd / MatrixXd, allocated before counting.
  Eigen::VectorXd q = robot.q, dq = robot.dq, tau = Eigen::VectorXd::Zero(n);
  const Eigen::MatrixXd jacobian = robot.jacobian;
  const Eigen::Vector3d position = robot.pose.position;
  const Eigen::Quaterniond orientation = robot.pose.orientation;
  {
    allocation_counter::Scope scope;
    for (int k = 0; k < 2000; ++k) {
      q[k % n] += 1e-5;
      compat.calculateCommandedTorques(q, dq, position, orientation, jacobian, tau);
      if (k == 1000) compat.setStiffness(800.0, 800.0, 800.0, 60.0, 60.0, 60.0, 10.0);
    }
    q[2] = std::nan("");
    compat.calculateCommandedTorques(q, dq, position, orientation, jacobian, tau);
    EXPECT_EQ(compat.status(), ci::Status::invalid_robot_state);
    q[2] = 0.0;
    EXPECT_EQ(scope.allocations(), 0);
  }
  allocation_counter::Scope scope;
  for (int k = 0; k < 100; ++k) {
    compat.calculateCommandedTorques(q, dq, position, orientation, jacobian);
  }
  EXPECT_EQ(scope.allocations(), 100);
  EXPECT_GT(tau.cwiseAbs().maxCoeff(), 0.5);  // the cycles did work
}
