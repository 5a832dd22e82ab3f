// Several URDF robots in one MuJoCo world (sim::make_robots_scene): each is the robot
// Simulation::from_urdf_file() simulates, moved to its base position, with its own names, and
// the arms move independently.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/sim/closed_loop_runner.hpp"
#include "cartesian_impedance/sim/simulation.hpp"

namespace {

using cartesian_impedance::Error;
using cartesian_impedance::JointVector;
using cartesian_impedance::Vector6d;
using namespace cartesian_impedance::sim;

const std::string kSource = CARTESIAN_IMPEDANCE_SOURCE_DIR;
const std::string kUr5e = kSource + "/models/ur5e/ur5e.urdf";
const std::string kPlanar3 = kSource + "/models/planar3/planar3.urdf";

JointVector ur5e_start() {
  return (JointVector(6) << M_PI, -M_PI / 2, M_PI / 2, -M_PI / 2, -M_PI / 2, 0.0).finished();
}

// Two UR5e 1.6 m apart along y, both at their start configuration.
Simulation two_ur5e() {
  SimulationOptions options;
  options.start_q.resize(12);
  options.start_q << ur5e_start(), ur5e_start();
  return make_robots_scene({{kUr5e, "left_", Eigen::Vector3d(0, 0.8, 0)},
                            {kUr5e, "right_", Eigen::Vector3d(0, -0.8, 0)}},
                           options);
}

TEST(RobotsScene, TwoCopiesOfOneUrdfStandWhereTheyArePlacedWithTheirOwnNames) {
  const Eigen::Vector3d left(0.0, 0.8, 0.0), right(0.2, -0.8, 0.1);
  SimulationOptions options;
  options.start_q.resize(12);
  options.start_q << ur5e_start(), ur5e_start();
  const Simulation scene =
      make_robots_scene({{kUr5e, "left_", left}, {kUr5e, "right_", right}}, options);
  ASSERT_EQ(scene.num_joints(), 12);
  EXPECT_EQ(scene.joint_names()[0], "left_shoulder_pan_joint");
  EXPECT_EQ(scene.joint_names()[11], "right_wrist_3_joint");

  SimulationOptions one_options;
  one_options.start_q = ur5e_start();
  const Simulation one = Simulation::from_urdf_file(kUr5e, one_options);
  // The same kinematics, shifted: the copies' tools are where the single arm's is, plus the base.
  const Eigen::Vector3d tool = one.body_pose("tool0").position;
  EXPECT_LT((scene.body_pose("left_tool0").position - (tool + left)).norm(), 1e-12);
  EXPECT_LT((scene.body_pose("right_tool0").position - (tool + right)).norm(), 1e-12);
  EXPECT_TRUE(scene.body_pose("right_tool0")
                  .orientation.isApprox(one.body_pose("tool0").orientation, 1e-12));
  // And the same completed model: the import's rotor inertia on every joint of both.
  EXPECT_TRUE(scene.armature().isApprox(JointVector::Constant(12, one.armature()[0])));
}

TEST(RobotsScene, PushingOneArmLeavesTheOtherWhereItWas) {
  Simulation scene = two_ur5e();
  const JointVector start = scene.q();
  Vector6d push = Vector6d::Zero();
  push[1] = 20.0;
  scene.push("right_tool0", push, 0.5);
  for (int k = 0; k < 500; ++k) scene.step();
  // Gravity is compensated and no torque is commanded: the left arm stays; the pushed one moves
  // (20 N on a 0.5 Nm s/rad joint damping makes it move centimetres in 0.5 s).
  EXPECT_LT((scene.q().head(6) - start.head(6)).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_GT((scene.q().tail(6) - start.tail(6)).cwiseAbs().maxCoeff(), 1e-2);
}

TEST(RobotsScene, EachCopyHasItsOwnControllerThroughThePrefixes) {
  Simulation scene = two_ur5e();
  const auto model = cartesian_impedance::RobotModel::from_urdf_file(kUr5e, "base_link", "tool0");
  cartesian_impedance::ControlLoop left(model), right(model);
  EXPECT_THROW(ClosedLoopRunner(scene, {&left, &right}), Error);  // the scene's names are prefixed
  EXPECT_THROW(ClosedLoopRunner(scene, {&left, &right}, {"left_"}), Error);
  EXPECT_THROW(ClosedLoopRunner(scene, {&left, &right}, {"right_", "left_"}), Error);
  ClosedLoopRunner runner(scene, {&left, &right}, {"left_", "right_"});
  runner.start();
  const Eigen::Vector3d left_start = scene.body_pose("left_tool0").position;
  const Eigen::Vector3d right_start = scene.body_pose("right_tool0").position;
  cartesian_impedance::Pose target = right.state().controller.pose;
  target.position.z() -= 0.02;
  right.set_reference_pose(target);
  runner.run_for(2.0);
  // The right arm follows its reference down 2 cm (to within what joint friction holds back at
  // the default stiffness); the left one, whose controller was not asked, stays.
  EXPECT_NEAR(scene.body_pose("right_tool0").position.z() - right_start.z(), -0.02, 0.002);
  EXPECT_LT((scene.body_pose("left_tool0").position - left_start).norm(), 1e-6);
}

TEST(RobotsScene, DifferentArmsTogether) {
  const Simulation scene = make_robots_scene(
      {{kUr5e, "a/", Eigen::Vector3d::Zero()}, {kPlanar3, "b/", Eigen::Vector3d(0, 1.5, 0)}});
  ASSERT_EQ(scene.num_joints(), 9);
  EXPECT_EQ(scene.joint_names()[6], "b/joint1");
  EXPECT_LT((scene.body_pose("b/base_link").position - Eigen::Vector3d(0, 1.5, 0)).norm(), 1e-12);
}

TEST(RobotsScene, BadRobotsAreNamed) {
  const auto message = [](const std::vector<SceneRobot>& robots) {
    try {
      make_robots_scene(robots);
    } catch (const Error& error) {
      return std::string(error.what());
    }
    return std::string("(no error)");
  };
  EXPECT_EQ(message({}), "make_robots_scene: no robots given");
  EXPECT_EQ(message({{kUr5e, "arm_", Eigen::Vector3d::Zero()},
                     {kPlanar3, "arm_", Eigen::Vector3d::Zero()}}),
            "robots[1].prefix = 'arm_' is used by another robot; each robot needs its own, or "
            "their names clash");
  EXPECT_EQ(message({{kUr5e, "a_", Eigen::Vector3d(0, NAN, 0)}}),
            "robots[0].base_position = (0 nan 0) m is not finite");
  EXPECT_EQ(message({{kUr5e, "a\"", Eigen::Vector3d::Zero()}}),
            "robots[0].prefix = 'a\"' contains a character that cannot appear in an XML attribute "
            "(\" < > &)");
  EXPECT_NE(message({{kUr5e, "a_", Eigen::Vector3d::Zero()},
                     {"/no/such.urdf", "b_", Eigen::Vector3d::Zero()}})
                .find("/no/such.urdf"),
            std::string::npos);
}

}  // namespace
