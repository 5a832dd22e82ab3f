// The MuJoCo simulation backend, checked against MuJoCo's own C API on an independent copy of the
// same model (mass matrix, Jacobians, bias forces) and against plain physics (a free arm held by
// gravity compensation stays put; a pressed flange feels the pressing force from the table).
//
// Tolerances, where they are not round-off:
// - One step from rest of a gravity-compensated arm under a generalized force f, with MuJoCo's
//   implicit integrator, gives dq = dt (M + dt D)^-1 (f + f_friction), D = diag(joint damping).
//   The joint friction force (frictionloss, a constraint) is bounded per joint by the frictionloss
//   value, so |dq - dt (M + dt D)^-1 f| <= dt ||(M + dt D)^-1||_2 ||frictionloss||_2, and the
//   tests choose f large enough that this bound is < 10 % of the expected dq.
// - Replays against raw MuJoCo differ only by how the gravity torque and the push wrench are
//   computed (subtree centre of mass vs. recursive Newton-Euler; xfrc_applied vs. J^T F), i.e. by
//   round-off of about 1e-14 Nm per step; after a few hundred steps that leaves < 1e-9.

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "cartesian_impedance/sim/engine.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "src/sim/simulation_impl.hpp"
#include "support/sim_reference.hpp"

#ifdef CARTESIAN_IMPEDANCE_COUNT_ALLOCATIONS
#include "support/allocation_counter.hpp"
#endif

namespace ci = cartesian_impedance;
namespace sim = cartesian_impedance::sim;
using ci::JointMatrix;
using ci::JointVector;
using ci::Vector6d;
using namespace sim_test;

namespace {

struct RobotCase {
  const char* label;
  std::string file;
  std::string joint_prefix;  // joint i is prefix + i (1-based)
  JointVector ready;
  JointVector torque_limit;
};

std::vector<RobotCase> robot_cases() {
  return {
      {"panda", kPandaXml, "panda_joint", panda_ready(), joints({87, 87, 87, 87, 12, 12, 12})},
      {"iiwa14", kIiwaXml, "iiwa_joint_", iiwa_ready(), joints({320, 320, 176, 176, 110, 40, 40})}};
}

void PrintTo(const RobotCase& robot, std::ostream* out) {
  *out << robot.label;
}

class RobotFiles : public ::testing::TestWithParam<RobotCase> {};

}  // namespace

INSTANTIATE_TEST_SUITE_P(Models, RobotFiles, ::testing::ValuesIn(robot_cases()),
                         [](const auto& info) { return std::string(info.param.label); });

// ---------------------------------------------------------------------------------------------
// Loading

TEST_P(RobotFiles, LoadsSevenNamedJointsAtTheReadyKeyframe) {
  const RobotCase& robot = GetParam();
  const sim::Simulation s = sim::Simulation::from_mjcf_file(robot.file);
  ASSERT_EQ(s.num_joints(), 7);
  for (int i = 0; i < 7; ++i) {
    EXPECT_EQ(s.joint_names()[i], robot.joint_prefix + std::to_string(i + 1));
  }
  EXPECT_EQ(s.timestep(), 0.001);
  EXPECT_EQ(s.time(), 0.0);
  // The keyframe stores the decimal expansions of the same angles: equal to round-off.
  EXPECT_LT((s.q() - robot.ready).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(s.dq(), JointVector::Zero(7));
  EXPECT_EQ(s.torque(), JointVector::Zero(7));
  EXPECT_EQ(s.torque_upper_limits(), robot.torque_limit);
  EXPECT_EQ(s.torque_lower_limits(), -robot.torque_limit);
}

TEST(Loading, TimestepOptionReplacesTheModels) {
  sim::SimulationOptions options;
  options.timestep = 0.002;
  const sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml, options);
  EXPECT_EQ(s.timestep(), 0.002);
}

TEST(Loading, WithoutKeyframeStartsAtTheDefaultPose) {
  sim::SimulationOptions options;
  options.keyframe = "";
  const sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml, options);
  EXPECT_EQ(s.q(), JointVector::Zero(7));
}

TEST(Loading, JointOrderFollowsJointNames) {
  sim::SimulationOptions options;
  for (int i = 7; i >= 1; --i) options.joint_names.push_back("panda_joint" + std::to_string(i));
  sim::Simulation reversed = sim::Simulation::from_mjcf_file(kPandaXml, options);
  sim::Simulation normal = sim::Simulation::from_mjcf_file(kPandaXml);
  EXPECT_EQ(reversed.joint_names(), options.joint_names);
  EXPECT_EQ(reversed.q(), normal.q().reverse().eval());

  const JointVector tau = joints({5, -3, 2, 4, 1, -1, 0.5});
  normal.set_torque(tau);
  reversed.set_torque(tau.reverse());
  for (int k = 0; k < 200; ++k) {
    normal.step();
    reversed.step();
  }
  EXPECT_GT(normal.dq().norm(), 0.1);  // it did move
  EXPECT_EQ(reversed.q(), normal.q().reverse().eval());
  EXPECT_EQ(reversed.dq(), normal.dq().reverse().eval());
}

TEST(Loading, ASubsetOfJointsLeavesTheOthersUndriven) {
  sim::SimulationOptions options;
  options.joint_names = {"panda_joint2", "panda_joint4"};
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml, options);
  EXPECT_EQ(s.num_joints(), 2);
  EXPECT_EQ(s.q(), joints({-kPi / 4, -3 * kPi / 4}));
  EXPECT_EQ(s.torque_upper_limits(), joints({87, 87}));
}

// ---------------------------------------------------------------------------------------------
// Gravity compensation

TEST_P(RobotFiles, GravityCompensatedArmHoldsStillForTwoSeconds) {
  const RobotCase& robot = GetParam();
  sim::Simulation s = sim::Simulation::from_mjcf_file(robot.file);
  double deviation = 0.0;
  for (int k = 0; k < 2000; ++k) {
    s.step();
    deviation = std::max(deviation, (s.q() - robot.ready).cwiseAbs().maxCoeff());
  }
  EXPECT_NEAR(s.time(), 2.0, 1e-9);
  // g(q) is exact to round-off (1e-14 Nm); joint friction (>= 0.05 Nm) holds such residues, so the
  // arm does not move at all. 1e-3 rad is the brief's bound; the measured value is ~1e-20.
  EXPECT_LT(deviation, 1e-3);
  EXPECT_LT(s.dq().cwiseAbs().maxCoeff(), 1e-6);
}

TEST_P(RobotFiles, ArmFallsWithoutGravityCompensation) {
  const RobotCase& robot = GetParam();
  sim::SimulationOptions options;
  options.gravity_compensation = false;
  sim::Simulation s = sim::Simulation::from_mjcf_file(robot.file, options);
  for (int k = 0; k < 500; ++k) s.step();
  // Measured with raw MuJoCo (models/README.md): about 1 rad after 0.5 s for both robots.
  EXPECT_GT((s.q() - robot.ready).cwiseAbs().maxCoeff(), 0.3);
}

// The gravity torque is MuJoCo's own bias force at zero velocity, also while the arm moves: a
// replay with raw MuJoCo (qfrc_applied = tau + qfrc_bias(q, 0)) follows the same trajectory.
TEST_P(RobotFiles, GravityCompensationAndTorquesMatchRawMujocoWhileMoving) {
  const RobotCase& robot = GetParam();
  sim::Simulation s = sim::Simulation::from_mjcf_file(robot.file);
  Reference reference(robot.file);
  double difference = 0.0;
  for (int k = 0; k < 500; ++k) {
    JointVector tau(7);
    for (int i = 0; i < 7; ++i) {
      tau[i] = 0.3 * robot.torque_limit[i] * std::sin(0.01 * k + i);
    }
    ASSERT_FALSE(s.set_torque(tau));
    const JointVector force = tau + reference.gravity();
    s.step();
    reference.step(force);
    difference = std::max(difference, (s.q() - reference.q()).cwiseAbs().maxCoeff());
    difference = std::max(difference, (s.dq() - reference.dq()).cwiseAbs().maxCoeff());
  }
  EXPECT_GT((s.q() - robot.ready).norm(), 0.1);  // it really moved
  EXPECT_LT(difference, 1e-9);
}

// ---------------------------------------------------------------------------------------------
// Commanded torque

// Joint k alone, half its torque limit: one step from rest gives dt (M + dt D)^-1 tau, so the
// torque reaches the joint unscaled (gear 1), with the right sign, in joint space.
TEST_P(RobotFiles, JointTorqueAcceleratesAsTheInverseMassMatrixSays) {
  const RobotCase& robot = GetParam();
  for (int k = 0; k < 7; ++k) {
    SCOPED_TRACE("joint " + std::to_string(k + 1));
    sim::Simulation s = sim::Simulation::from_mjcf_file(robot.file);
    Reference reference(robot.file);
    JointVector tau = JointVector::Zero(7);
    tau[k] = 0.5 * robot.torque_limit[k];
    ASSERT_FALSE(s.set_torque(tau));
    s.step();
    expect_one_step(s.dq(), predict_one_step(reference, tau));
    EXPECT_GT(s.dq()[k], 0.0);
  }
}

TEST(Torque, IsClippedToTheActuatorRangeAndReported) {
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  EXPECT_TRUE(s.set_torque(joints({100, -100, 50, 0, 13, -12.5, 5})));
  EXPECT_EQ(s.torque(), joints({87, -87, 50, 0, 12, -12, 5}));
  EXPECT_FALSE(s.set_torque(joints({87, -87, 1, 2, 12, -12, 0})));
  EXPECT_EQ(s.torque(), joints({87, -87, 1, 2, 12, -12, 0}));

  // What is applied is the clipped torque: a raw replay with the clipped values matches.
  Reference reference(kPandaXml);
  const JointVector clipped = joints({87, -87, 50, 0, 12, -12, 5});
  s.set_torque(joints({1000, -1000, 50, 0, 100, -100, 5}));
  for (int k = 0; k < 50; ++k) {
    const JointVector force = clipped + reference.gravity();
    s.step();
    reference.step(force);
  }
  EXPECT_LT((s.q() - reference.q()).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Torque, RejectsWrongSizeAndNonFiniteValuesAndKeepsThePrevious) {
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  const JointVector tau = joints({1, 2, 3, 4, 5, 6, 7});
  s.set_torque(tau);
  EXPECT_ERROR([&] { s.set_torque(JointVector::Zero(6)); }, {"tau", "6", "expected 7"});
  JointVector bad = tau;
  bad[2] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_ERROR([&] { s.set_torque(bad); }, {"tau[2]", "panda_joint3", "nan", "finite"});
  bad[2] = std::numeric_limits<double>::infinity();
  EXPECT_ERROR([&] { s.set_torque(bad); }, {"tau[2]", "inf"});
  EXPECT_EQ(s.torque(), tau);
}

TEST(State, SetStateMovesTheJointsAndRejectsBadInput) {
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  Reference reference(kPandaXml);
  const JointVector q = joints({0.3, -0.2, 0.1, -2.0, 0.4, 1.9, -0.5});
  const JointVector dq = joints({0.1, 0, 0, 0, 0, 0, -0.2});
  s.set_state(q, dq);
  EXPECT_EQ(s.q(), q);
  EXPECT_EQ(s.dq(), dq);
  reference.set_state(q, dq);
  EXPECT_LT((s.site_pose("flange").position - reference.site_position("flange")).norm(), 1e-15);

  EXPECT_ERROR([&] { s.set_state(JointVector::Zero(3), dq); }, {"q", "3", "expected 7"});
  JointVector bad = dq;
  bad[6] = std::nan("");
  EXPECT_ERROR([&] { s.set_state(q, bad); }, {"dq[6]", "panda_joint7"});
  EXPECT_EQ(s.q(), q);  // unchanged by the rejected call

  s.set_torque(joints({1, 1, 1, 1, 1, 1, 1}));
  s.push("flange", Vector6d::Ones(), 1.0);
  for (int k = 0; k < 10; ++k) s.step();
  s.reset();
  EXPECT_EQ(s.time(), 0.0);
  EXPECT_LT((s.q() - panda_ready()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(s.torque(), JointVector::Zero(7));
  for (int k = 0; k < 100; ++k) s.step();  // no torque, no push left: holds still
  EXPECT_LT((s.q() - panda_ready()).cwiseAbs().maxCoeff(), 1e-9);
}

// ---------------------------------------------------------------------------------------------
// Poses

TEST(Poses, FlangeAtTheReadyPoseAndFollowingTheJoints) {
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  const ci::Pose flange = s.site_pose("flange");
  // Published: (0.3069, 0, 0.5903) to 4 digits; MuJoCo computes (0.306891, 0, 0.590282).
  EXPECT_LT((flange.position - Eigen::Vector3d(0.306891, 0, 0.590282)).norm(), 1e-6);
  // Flange z axis points down at the ready pose.
  EXPECT_LT((flange.orientation * Eigen::Vector3d::UnitZ() - Eigen::Vector3d(0, 0, -1)).norm(),
            1e-12);
  const ci::Pose link8 = s.body_pose("panda_link8");
  EXPECT_LT((link8.position - flange.position).norm(), 1e-15);
  EXPECT_LT(link8.orientation.angularDistance(flange.orientation), 1e-12);

  // After steps the pose belongs to the current q (not to the start of the last step).
  s.set_torque(joints({10, 10, 10, 10, 3, 3, 3}));
  for (int k = 0; k < 100; ++k) s.step();
  Reference reference(kPandaXml);
  reference.set_state(s.q(), s.dq());
  EXPECT_LT((s.site_pose("flange").position - reference.site_position("flange")).norm(), 1e-15);
}

// ---------------------------------------------------------------------------------------------
// Pushes

// A force F at the flange site yields the generalized force J^T F (J from mj_jacSite): one step
// from rest gives dt (M + dt D)^-1 J^T F. A pure torque likewise gives J_angular^T tau.
TEST(Push, ForceAndTorqueOnTheFlangeActThroughTheJacobianTranspose) {
  Reference reference(kPandaXml);
  const Eigen::MatrixXd jacobian = reference.jacobian("flange");
  const std::vector<Vector6d> wrenches = {(Vector6d() << 60, -40, -100, 0, 0, 0).finished(),
                                          (Vector6d() << 0, 0, 0, 2, 8, 4).finished(),
                                          (Vector6d() << -80, 20, 40, 4, -4, 2).finished()};
  for (const Vector6d& wrench : wrenches) {
    SCOPED_TRACE(::testing::PrintToString(wrench.transpose()));
    sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
    s.push("flange", wrench, 1.0);
    s.step();
    expect_one_step(s.dq(), predict_one_step(reference, jacobian.transpose() * wrench));
  }
}

// On a body, the wrench acts at the body's origin (not its centre of mass).
TEST(Push, OnABodyActsAtItsOrigin) {
  Reference reference(kPandaXml);
  const Eigen::MatrixXd jacobian = reference.jacobian("panda_link5");
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  const Vector6d wrench = (Vector6d() << 0, 100, 0, 0, 0, 0).finished();
  s.push("panda_link5", wrench, 1.0);
  s.step();
  expect_one_step(s.dq(), predict_one_step(reference, jacobian.transpose() * wrench));
}

// A push lasts `duration` (20 steps here) at a point that moves with the flange, then stops:
// a raw replay with qfrc_applied = g + J(q)^T F for exactly 20 steps matches.
TEST(Push, LastsItsDurationAndFollowsTheSite) {
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  Reference reference(kPandaXml);
  const Vector6d wrench = (Vector6d() << 10, 20, -15, 0.5, 0, -0.5).finished();
  s.push("flange", wrench, 0.02);
  for (int k = 0; k < 100; ++k) {
    JointVector force = reference.gravity();
    if (k < 20) force += reference.jacobian("flange").transpose() * wrench;
    s.step();
    reference.step(force);
  }
  EXPECT_GT((s.q() - panda_ready()).norm(), 0.01);  // it moved
  EXPECT_LT((s.q() - reference.q()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((s.dq() - reference.dq()).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Push, ClearPushesEndsThem) {
  sim::Simulation pushed = sim::Simulation::from_mjcf_file(kPandaXml);
  sim::Simulation untouched = sim::Simulation::from_mjcf_file(kPandaXml);
  pushed.push("flange", Vector6d::Constant(10.0), std::numeric_limits<double>::infinity());
  pushed.push("panda_link3", Vector6d::Constant(5.0), 1.0);
  pushed.clear_pushes();
  for (int k = 0; k < 100; ++k) {
    pushed.step();
    untouched.step();
  }
  EXPECT_EQ(pushed.q(), untouched.q());
}

TEST(Push, RejectsUnknownNamesAndBadValues) {
  sim::Simulation s = sim::Simulation::from_mjcf_file(kPandaXml);
  EXPECT_ERROR([&] { s.push("gripper", Vector6d::Zero(), 1.0); },
               {"'gripper'", "flange", "panda_link7"});
  Vector6d bad = Vector6d::Zero();
  bad[4] = std::nan("");
  EXPECT_ERROR([&] { s.push("flange", bad, 1.0); }, {"wrench_world[4]", "nan"});
  EXPECT_ERROR([&] { s.push("flange", Vector6d::Zero(), 0.0); }, {"duration", "0"});
  EXPECT_ERROR([&] { s.push("flange", Vector6d::Zero(), std::nan("")); }, {"duration"});
  EXPECT_ERROR([&] { s.push("world", Vector6d::Zero(), 1.0); }, {"world"});
}

// ---------------------------------------------------------------------------------------------
// Scenes and contact

// A table 4 cm below the flange; a 20 N downward push lowers the gravity-compensated arm onto it.
// At rest the table must push back with 20 N: static equilibrium J^T (F + F_contact) =
// tau_friction, with |tau_friction| <= 0.1 Nm against a lever of >= 0.3 m, i.e. < 0.4 N = 2 %;
// the contact solver adds a small step-to-step ripple (measured 1.5 %). Bound: 5 %.
TEST(Scene, FlangePressedOnATableFeelsThePressingForce) {
  const double top = 0.55;
  sim::Simulation s =
      sim::make_scene(kPandaXml, {sim::Box::table({0.45, 0.0}, {0.25, 0.4}, top, "table")});
  EXPECT_EQ(s.num_joints(), 7);
  EXPECT_EQ(s.contact_wrench("panda_link8"), Vector6d::Zero());  // hovering 4 cm above

  const Eigen::Vector3d force(0, 0, -20);
  s.push("flange", (Vector6d() << force, 0, 0, 0).finished(),
         std::numeric_limits<double>::infinity());
  for (int k = 0; k < 2500; ++k) s.step();
  for (int k = 0; k < 500; ++k) {
    s.step();
    const Vector6d wrench = s.contact_wrench("panda_link8");
    ASSERT_NEAR(wrench[2], 20.0, 1.0) << "step " << k << ": " << wrench.transpose();
    ASSERT_LT(wrench.head<2>().norm(), 1.0) << "step " << k << ": " << wrench.transpose();
  }
  // The flange rests on the table (soft contact: sub-millimetre penetration).
  EXPECT_NEAR(s.site_pose("flange").position.z(), top, 1e-3);
  // panda_link8 has no geoms: its contacts are those of panda_link7, to which it is welded.
  EXPECT_EQ(s.contact_wrench("panda_link7").head<3>(), s.contact_wrench("panda_link8").head<3>());
  EXPECT_EQ(s.contact_wrench("panda_link3"), Vector6d::Zero());
}

// A soft box (Box::time_constant) holds the same 20 N as the rigid one, only deeper: MuJoCo's
// contact stiffness goes as 1 / time constant^2, so 0.05 s against the default 0.02 s sinks
// 6.25 times as deep, within what the impedance's ramp (solimp 0.9-0.95 over the first mm, where
// both rest) changes of it: 5 to 7.5 (measured 6.2). Softer than 0.05 s is refused: at 0.07 s the
// flange sank through the table.
TEST(Scene, ASoftBoxHoldsTheSameForceDeeper) {
  const double top = 0.55;
  const auto pressed = [&](double time_constant) {
    sim::Box table = sim::Box::table({0.45, 0.0}, {0.25, 0.4}, top, "table");
    table.time_constant = time_constant;
    sim::Simulation s = sim::make_scene(kPandaXml, {table});
    s.push("flange", (Vector6d() << 0, 0, -20, 0, 0, 0).finished(),
           std::numeric_limits<double>::infinity());
    for (int k = 0; k < 3000; ++k) s.step();
    EXPECT_NEAR(s.contact_wrench("panda_link8")[2], 20.0, 1.0) << time_constant;
    return top - s.site_pose("flange").position.z();
  };
  const double rigid = pressed(0.0), soft = pressed(0.05);
  EXPECT_GT(rigid, 0.0);
  EXPECT_GT(soft / rigid, 5.0) << rigid << " " << soft;
  EXPECT_LT(soft / rigid, 7.5) << rigid << " " << soft;

  sim::Box bad = sim::Box::table({0.45, 0.0}, {0.25, 0.4}, top);
  bad.time_constant = -0.1;
  EXPECT_ERROR([&] { sim::make_scene(kPandaXml, {bad}); }, {"boxes[0].time_constant", "-0.1"});
  bad.time_constant = 0.07;
  EXPECT_ERROR([&] { sim::make_scene(kPandaXml, {bad}); },
               {"boxes[0].time_constant", "0.07", "0.05", "sink"});
  std::string reason;
  if (sim::engine_available(sim::Engine::dart, &reason)) {
    bad.time_constant = 0.05;
    sim::SimulationOptions options;
    options.engine = sim::Engine::dart;
    EXPECT_ERROR([&] { sim::make_scene(kPandaUrdf, {bad}, options); },
                 {"boxes[0].time_constant", "DART", "rigid"});
  }
}

TEST(Scene, BoxesAreValidated) {
  sim::Box box = sim::Box::table({0.5, 0}, {0.2, 0.2}, 0.3);
  EXPECT_DOUBLE_EQ(box.center.z(), 0.15);
  EXPECT_DOUBLE_EQ(box.half_size.z(), 0.15);
  box.half_size.y() = 0.0;
  EXPECT_ERROR([&] { sim::make_scene(kPandaXml, {box}); }, {"boxes[0].half_size[1]", "> 0"});
  box.half_size.y() = 0.2;
  box.center.x() = std::nan("");
  EXPECT_ERROR([&] { sim::make_scene(kPandaXml, {box}); }, {"boxes[0].center[0]", "finite"});
  // A URDF is converted (the scene then is the URDF's robot); another XML file is neither.
  EXPECT_EQ(sim::make_scene(kPandaUrdf, {}).num_joints(), 7);
  const std::string sdf = ::testing::TempDir() + "sim_test_robot.sdf";
  std::ofstream(sdf) << "<sdf version=\"1.6\"><model name=\"arm\"/></sdf>\n";
  EXPECT_ERROR([&] { sim::make_scene(sdf, {}); }, {"not an MJCF file", "<sdf>"});
  std::remove(sdf.c_str());
  EXPECT_ERROR([&] { sim::make_scene("/nonexistent/robot.xml", {}); },
               {"/nonexistent/robot.xml", "does not exist"});
  sim::Box a = sim::Box::table({0.5, 0}, {0.2, 0.2}, 0.3, "same");
  EXPECT_ERROR([&] { sim::make_scene(kPandaXml, {a, a}); }, {"same"});
}

TEST(Scene, WorksForTheIiwaAndKeepsItsKeyframe) {
  sim::Simulation s =
      sim::make_scene(kIiwaXml, {{"wall", Eigen::Vector3d(0, 0.8, 0.5),
                                  Eigen::Vector3d(1, 0.05, 0.5), Eigen::Quaterniond::Identity()}});
  EXPECT_LT((s.q() - iiwa_ready()).cwiseAbs().maxCoeff(), 1e-15);
}

// ---------------------------------------------------------------------------------------------
// Real-time behaviour

#ifdef CARTESIAN_IMPEDANCE_COUNT_ALLOCATIONS
TEST(RealTime, StepAllocatesNothingWithTorquePushesAndContact) {
  sim::Simulation s =
      sim::make_scene(kPandaXml, {sim::Box::table({0.45, 0.0}, {0.25, 0.4}, 0.55, "table")});
  s.push("flange", (Vector6d() << 0, 0, -20, 0, 0, 0).finished(),
         std::numeric_limits<double>::infinity());
  s.push("panda_link5", (Vector6d() << 0, 1, 0, 0, 0, 0).finished(), 0.5);
  JointVector tau = JointVector::Zero(7);
  for (int k = 0; k < 200; ++k) s.step();  // warm up: contacts appear
  allocation_counter::Scope scope;
  for (int k = 0; k < 3000; ++k) {
    tau[0] = 0.1 * std::sin(0.01 * k);
    s.set_torque(tau);
    s.step();
  }
  EXPECT_EQ(scope.allocations(), 0);
  EXPECT_GT(s.contact_wrench("panda_link8")[2], 10.0);  // the contact was there throughout
}
#endif
