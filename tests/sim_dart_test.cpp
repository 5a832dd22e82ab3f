// The simulation's two engines on the same URDF files: DART (Engine::dart) must give the
// response the model predicts, exactly where the physics is exact (one step from rest under a
// torque or a push: dt (M + A + dt D)^-1 f, with the armature A that DART 6.12 lacks and the
// engine adds), and within the physics' bounds where it is not (friction, contact). Every check
// runs on MuJoCo too, so the two engines are held to the same numbers.

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "src/sim/simulation_impl.hpp"
#include "support/sim_reference.hpp"

namespace ci = cartesian_impedance;
namespace sim = cartesian_impedance::sim;
using ci::JointVector;
using ci::Vector6d;
using namespace sim_test;

namespace {

struct UrdfRobot {
  std::string name, urdf, base, tip;
  JointVector start;
};

// A copy of `robot`'s URDF without joint friction, in the test's temporary directory: one step
// from rest is then exactly dt (M + A + dt D)^-1 f on either engine, not only within the
// friction band.
UrdfRobot frictionless(UrdfRobot robot) {
  std::ifstream file(robot.urdf);
  std::stringstream content;
  content << file.rdbuf();
  std::string text = content.str();
  for (std::size_t at = text.find("friction=\""); at != std::string::npos;
       at = text.find("friction=\"", at + 1)) {
    const std::size_t end = text.find('"', at + 10);
    text.replace(at + 10, end - at - 10, "0");
  }
  // The process id in the name: ctest runs the two engines' cases at the same time.
  robot.urdf = ::testing::TempDir() + "sim_dart_test_frictionless_" + robot.name + "_" +
               std::to_string(getpid()) + ".urdf";
  std::ofstream(robot.urdf) << text;
  return robot;
}

std::vector<UrdfRobot> urdf_robots() {
  return {{"panda", kPandaUrdf, "panda_link0", "panda_link8", panda_ready()},
          {"iiwa14", kIiwaUrdf, "iiwa_link_0", "iiwa_link_ee", iiwa_ready()},
          {"ur5e", kUr5eUrdf, "base_link", "tool0",
           joints({kPi, -kPi / 2, kPi / 2, -kPi / 2, -kPi / 2, 0})},
          {"planar3", kPlanar3Urdf, "base_link", "tool0", joints({0.5, 1.5, kPi - 2.0})}};
}

sim::SimulationOptions options_for(sim::Engine engine, const UrdfRobot& robot) {
  sim::SimulationOptions options;
  options.engine = engine;
  options.start_q = robot.start;
  return options;
}

// One step from rest at the start under generalized force f: dt (M + A + dt D)^-1 f, with the
// library's M(q) (KDL: it agrees with DART's own to 1e-15, dart_tests), the import's armature
// A = 0.1 kg m^2 and the URDF's damping D. Also the tip's Jacobian, for pushes.
struct Oracle {
  Eigen::MatrixXd step_response;  // dt (M + A + dt D)^-1
  ci::Jacobian jacobian;
};
Oracle oracle_for(const UrdfRobot& robot) {
  const ci::RobotModel model = ci::RobotModel::from_urdf_file(robot.urdf, robot.base, robot.tip);
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  const int n = model.num_joints();
  EXPECT_TRUE(workspace.compute(robot.start, JointVector::Zero(n), kinematics, true));
  // The import's MJCF carries the URDF's damping values unchanged (short decimals).
  const std::string file = ::testing::TempDir() + "sim_dart_test_" + robot.name + "_" +
                           std::to_string(getpid()) + ".xml";
  std::ofstream(file) << sim::detail::mjcf_from_urdf(robot.urdf, {0.1, 0.5});
  const Reference reference(file);
  std::remove(file.c_str());
  const double dt = 0.001;
  const ci::JointMatrix a =
      kinematics.mass + 0.1 * ci::JointMatrix::Identity(n, n) + dt * reference.damping();
  return {dt * a.inverse(), kinematics.jacobian};
}

// DART takes the URDF's numbers as they are: agreement to round-off. MuJoCo simulates the MJCF
// its URDF import wrote: bodies and inertials to the last digit (urdf_import.cpp writes them
// again), joints with MuJoCo's 6 significant digits (measured agreement about 1e-7; 1e-5 before
// the inertials were written again, when a mass of 4.970684 kg became 4.97068): 1e-5.
double relative_tolerance(sim::Engine engine) {
  return engine == sim::Engine::dart ? 1e-9 : 1e-5;
}

std::string engine_label(const ::testing::TestParamInfo<sim::Engine>& info) {
  return sim::engine_name(info.param);
}

class BothEngines : public ::testing::TestWithParam<sim::Engine> {
 protected:
  void SetUp() override {
    std::string reason;
    if (!sim::engine_available(GetParam(), &reason)) GTEST_SKIP() << reason;
  }
};

class Dart : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string reason;
    if (!sim::engine_available(sim::Engine::dart, &reason)) GTEST_SKIP() << reason;
  }
};

}  // namespace

INSTANTIATE_TEST_SUITE_P(Engines, BothEngines,
                         ::testing::Values(sim::Engine::mujoco, sim::Engine::dart), engine_label);

// One step from rest under a joint torque: dt (M + A + dt D)^-1 tau, M, A and D those of the
// MuJoCo import (M agrees with DART's own to 1e-15, dart_tests). Without DART's added armature
// (0.1 kg m^2 against link inertias of 0.001 to 1 kg m^2) the distal joints would accelerate
// several times faster than predicted.
TEST_P(BothEngines, OneStepFromRestIsTheInverseMassMatrixWithArmature) {
  for (const UrdfRobot& original : urdf_robots()) {
    const UrdfRobot robot = frictionless(original);
    SCOPED_TRACE(robot.name);
    const Oracle oracle = oracle_for(robot);
    const int n = static_cast<int>(robot.start.size());
    for (int k = 0; k < n; ++k) {
      sim::Simulation s =
          sim::Simulation::from_urdf_file(robot.urdf, options_for(GetParam(), robot));
      ASSERT_EQ(s.engine(), GetParam());
      JointVector tau = JointVector::Zero(n);
      tau[k] = 5.0;
      s.set_torque(tau);
      s.step();
      const JointVector predicted = oracle.step_response * tau;
      EXPECT_LT((s.dq() - predicted).norm(), relative_tolerance(GetParam()) * predicted.norm())
          << "joint " << k + 1 << ": dq " << s.dq().transpose() << "\npredicted "
          << predicted.transpose();
    }
  }
}

// A plant's model error (SimulationOptions::plant) is one arm on both engines: drawn once into
// the MuJoCo model and copied to DART's links. One step from rest under a torque agrees between
// the engines as closely as for the nominal arm (1e-5, MuJoCo's joints), and differs from the
// nominal arm's by more than 5 % for some joint (the error reached the dynamics).
TEST_F(Dart, APlantsModelErrorIsTheSameArmOnBothEngines) {
  sim::PlantOptions plant;
  plant.seed = 7;
  plant.inertia = {0.7, 1.3};
  plant.center_of_mass_offset = 0.01;
  plant.damping = {0.8, 1.2};
  plant.armature = {0.8, 1.2};
  for (const UrdfRobot& original : urdf_robots()) {
    const UrdfRobot robot = frictionless(original);
    SCOPED_TRACE(robot.name);
    const Oracle nominal = oracle_for(robot);
    const int n = static_cast<int>(robot.start.size());
    double largest_change = 0.0;
    for (int k = 0; k < n; ++k) {
      JointVector tau = JointVector::Zero(n);
      tau[k] = 5.0;
      std::vector<JointVector> responses;
      for (const sim::Engine engine : {sim::Engine::mujoco, sim::Engine::dart}) {
        sim::SimulationOptions options = options_for(engine, robot);
        options.plant = plant;
        sim::Simulation s = sim::Simulation::from_urdf_file(robot.urdf, options);
        s.set_torque(tau);
        s.step();
        responses.push_back(s.dq());
      }
      EXPECT_LT((responses[1] - responses[0]).norm(), 1e-5 * responses[0].norm())
          << "joint " << k + 1 << ": MuJoCo " << responses[0].transpose() << "\nDART "
          << responses[1].transpose();
      const JointVector predicted = nominal.step_response * tau;
      largest_change =
          std::max(largest_change, (responses[0] - predicted).norm() / predicted.norm());
    }
    EXPECT_GT(largest_change, 0.05);
  }
}

// A push at the tip acts through the Jacobian transpose of that body's origin.
TEST_P(BothEngines, PushOnTheTipActsThroughTheJacobianTranspose) {
  for (const UrdfRobot& original : urdf_robots()) {
    const UrdfRobot robot = frictionless(original);
    SCOPED_TRACE(robot.name);
    const Oracle oracle = oracle_for(robot);
    const Vector6d wrench = (Vector6d() << 30, -20, -40, 1, 2, -1).finished();
    sim::Simulation s = sim::Simulation::from_urdf_file(robot.urdf, options_for(GetParam(), robot));
    s.push(robot.tip, wrench, 1.0);
    s.step();
    const JointVector predicted = oracle.step_response * oracle.jacobian.transpose() * wrench;
    EXPECT_LT((s.dq() - predicted).norm(), relative_tolerance(GetParam()) * predicted.norm())
        << "dq " << s.dq().transpose() << "\npredicted " << predicted.transpose();
  }
}

// The firmware's gravity compensation holds every arm still; without it each arm falls.
TEST_P(BothEngines, GravityCompensationHoldsTheArmAndWithoutItTheArmFalls) {
  for (const UrdfRobot& robot : urdf_robots()) {
    SCOPED_TRACE(robot.name);
    sim::SimulationOptions options = options_for(GetParam(), robot);
    sim::Simulation held = sim::Simulation::from_urdf_file(robot.urdf, options);
    options.gravity_compensation = false;
    sim::Simulation falling = sim::Simulation::from_urdf_file(robot.urdf, options);
    for (int k = 0; k < 1000; ++k) {
      held.step();
      falling.step();
    }
    EXPECT_NEAR(held.time(), 1.0, 1e-9);
    // g(q) is exact to round-off and friction holds the residue.
    EXPECT_LT((held.q() - robot.start).cwiseAbs().maxCoeff(), 1e-6);
    EXPECT_GT((falling.q() - robot.start).cwiseAbs().maxCoeff(), 0.1);
  }
}

// Poses come from the engine; they must be MuJoCo's kinematics of the same joint positions.
TEST_P(BothEngines, BodyPosesAreTheKinematicsOfTheSimulatedJoints) {
  const UrdfRobot robot = urdf_robots()[0];
  sim::Simulation s = sim::Simulation::from_urdf_file(robot.urdf, options_for(GetParam(), robot));
  s.set_torque(joints({3, -3, 2, 2, 1, -1, 0.5}));
  for (int k = 0; k < 300; ++k) s.step();
  ASSERT_GT((s.q() - robot.start).norm(), 0.1);
  sim::Simulation kinematics = sim::Simulation::from_urdf_file(robot.urdf);
  kinematics.set_state(s.q(), JointVector::Zero(7));
  for (const char* body : {"panda_link3", "panda_link6", "panda_link8"}) {
    SCOPED_TRACE(body);
    const ci::Pose engine = s.body_pose(body), mujoco = kinematics.body_pose(body);
    EXPECT_LT((engine.position - mujoco.position).norm(), 1e-12);
    EXPECT_LT(engine.orientation.angularDistance(mujoco.orientation), 1e-12);
  }
}

// A table 4 cm below the flange; a 20 N downward push lowers the arm onto it. At rest the table
// pushes back with 20 N: J^T (F + F_contact) = tau_friction, |tau_friction| <= 0.1 Nm against
// levers >= 0.3 m, so within 0.4 N; DART's contact is hard (no penetration beyond its 1 mm error
// allowance), MuJoCo's soft (sub-millimetre). Bound 1 N, and 2 mm on the height.
TEST_P(BothEngines, FlangePressedOnATableFeelsThePressingForce) {
  const UrdfRobot robot = urdf_robots()[0];
  const double top = 0.55;
  sim::Simulation s =
      sim::make_scene(robot.urdf, {sim::Box::table({0.45, 0.0}, {0.25, 0.4}, top, "table")},
                      options_for(GetParam(), robot));
  const Vector6d push = (Vector6d() << 0, 0, -20, 0, 0, 0).finished();
  s.push("panda_link8", push, std::numeric_limits<double>::infinity());
  for (int k = 0; k < 2500; ++k) s.step();
  for (int k = 0; k < 500; ++k) {
    s.step();
    const Vector6d wrench = s.contact_wrench("panda_link8");
    ASSERT_NEAR(wrench[2], 20.0, 1.0) << "step " << k << ": " << wrench.transpose();
    ASSERT_LT(wrench.head<2>().norm(), 1.0) << "step " << k << ": " << wrench.transpose();
  }
  EXPECT_NEAR(s.body_pose("panda_link8").position.z(), top, 2e-3);
  EXPECT_EQ(s.contact_wrench("panda_link7").head<3>(), s.contact_wrench("panda_link8").head<3>());
  EXPECT_EQ(s.contact_wrench("panda_link3"), Vector6d::Zero());
  s.set_state(s.q(), JointVector::Zero(7));
  if (GetParam() == sim::Engine::dart) {
    EXPECT_EQ(s.contact_wrench("panda_link8"), Vector6d::Zero());  // solved only by a step
  }
}

// A joint driven into its limit comes to rest there (MuJoCo: soft limit; DART: hard constraint).
TEST_P(BothEngines, JointLimitStopsTheJoint) {
  const UrdfRobot robot = urdf_robots()[0];
  sim::Simulation s = sim::Simulation::from_urdf_file(robot.urdf, options_for(GetParam(), robot));
  s.set_torque(joints({0, 0, 0, 5, 0, 0, 0}));  // joint 4 toward its upper limit -0.0698
  for (int k = 0; k < 3000; ++k) s.step();
  // Measured: MuJoCo rests 0.6 mrad inside its soft limit, DART at it to 1e-9 rad.
  EXPECT_NEAR(s.q()[3], -0.0698, 2e-3);
  EXPECT_LT(std::abs(s.dq()[3]), 1e-3);
}

// Two copies of one arm: pushing one leaves the other where it is, on both engines.
TEST_P(BothEngines, RobotsOfOneSceneMoveIndependently) {
  const UrdfRobot robot = urdf_robots()[2];
  sim::SimulationOptions options;
  options.engine = GetParam();
  options.start_q.resize(12);
  options.start_q << robot.start, robot.start;
  sim::Simulation s = sim::make_robots_scene({{robot.urdf, "left_", Eigen::Vector3d(0, 0.6, 0)},
                                              {robot.urdf, "right_", Eigen::Vector3d(0, -0.6, 0)}},
                                             options);
  const ci::Pose left = s.body_pose("left_tool0"), right = s.body_pose("right_tool0");
  EXPECT_NEAR(left.position.y() - right.position.y(), 1.2, 1e-12);
  s.push("left_tool0", (Vector6d() << 0, 20, 0, 0, 0, 0).finished(), 0.5);
  for (int k = 0; k < 500; ++k) s.step();
  EXPECT_GT((s.body_pose("left_tool0").position - left.position).norm(), 0.01);
  EXPECT_LT((s.q().tail(6) - robot.start).cwiseAbs().maxCoeff(), 1e-9);
}

// ---------------------------------------------------------------------------------------------
// DART only

TEST_F(Dart, RendersDartsState) {
  std::string reason;
  if (!sim::offscreen_rendering_available(&reason)) {
    GTEST_SKIP() << "offscreen rendering unavailable here: " << reason;
  }
  const UrdfRobot robot = urdf_robots()[0];
  sim::Simulation s =
      sim::Simulation::from_urdf_file(robot.urdf, options_for(sim::Engine::dart, robot));
  const std::string before = ::testing::TempDir() + "sim_dart_before.png";
  const std::string after = ::testing::TempDir() + "sim_dart_after.png";
  s.render_png(before, 64, 48);
  s.push("panda_link8", (Vector6d() << 0, 60, 0, 0, 0, 0).finished(), 0.3);
  for (int k = 0; k < 300; ++k) s.step();
  s.render_png(after, 64, 48);
  auto read = [](const std::string& path) {
    std::ifstream file(path, std::ios::binary);
    std::stringstream content;
    content << file.rdbuf();
    return content.str();
  };
  EXPECT_GT(read(before).size(), 100u);
  EXPECT_NE(read(before), read(after));  // the picture follows DART's motion
  std::remove(before.c_str());
  std::remove(after.c_str());
}

TEST_F(Dart, ErrorsNameTheEngine) {
  EXPECT_ERROR([] { sim::engine_from_name("bullet"); }, {"'bullet'", "mujoco", "dart"});
  EXPECT_EQ(sim::engine_from_name("dart"), sim::Engine::dart);
  EXPECT_STREQ(sim::engine_name(sim::Engine::mujoco), "mujoco");
  sim::SimulationOptions options;
  options.engine = sim::Engine::dart;
  EXPECT_ERROR([&] { sim::Simulation::from_mjcf_file(kPandaXml, options); },
               {"engine 'dart'", "panda.xml", "URDF"});
  EXPECT_ERROR([&] { sim::make_scene(kPandaXml, {}, options); }, {"engine 'dart'", "URDF"});
  // The bad-options checks come first and are the same for both engines.
  options.start_q = joints({0, 0, 0, 0, 0, 0, 0});
  EXPECT_ERROR([&] { sim::Simulation::from_urdf_file(kPandaUrdf, options); },
               {"start_q[3]", "panda_joint4"});
}
