// Geometry fixed to a robot body (sim::AttachedBox) and the peg-in-hole scene built from it, on
// both engines: the box moves with its body, collides with the scene, weighs on the arm (the
// simulated firmware does not compensate it), the hole has the clearance asked for, and the
// impedance controller puts a peg into it, or jams it when the hole is 3 mm off.

#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>

#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "cartesian_impedance/sim/closed_loop_runner.hpp"
#include "cartesian_impedance/sim/peg_in_hole.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "support/sim_reference.hpp"

#ifdef CARTESIAN_IMPEDANCE_COUNT_ALLOCATIONS
#include "support/allocation_counter.hpp"
#endif

namespace ci = cartesian_impedance;
namespace sim = cartesian_impedance::sim;
using ci::JointVector;
using ci::Vector6d;
using namespace sim_test;

namespace {

constexpr double kGravity = 9.81;  // MuJoCo's default, and the one DART takes from it

// A 25 mm square peg, 10 cm long, of 0.4 kg, below the Panda's flange.
sim::AttachedBox peg(double mass = 0.4) {
  sim::AttachedBox box;
  box.name = "peg";
  box.body = "panda_link8";
  box.position = Eigen::Vector3d(0, 0, 0.05);
  box.half_size = Eigen::Vector3d(0.0125, 0.0125, 0.05);
  box.mass = mass;
  return box;
}

sim::SimulationOptions options_for(sim::Engine engine) {
  sim::SimulationOptions options;
  options.engine = engine;
  options.start_q = panda_ready();
  return options;
}

// The world pose of `local` in the frame of `frame`.
ci::Pose compose(const ci::Pose& frame, const Eigen::Vector3d& position,
                 const Eigen::Quaterniond& orientation) {
  ci::Pose pose;
  pose.position = frame.position + frame.orientation * position;
  pose.orientation = frame.orientation * orientation;
  return pose;
}

// The joint torque that holds a load of `mass` at `center` (world) against gravity on the
// Panda at q: J_c^T m g up, J_c the Jacobian of the point `center`, from the library's model.
JointVector holding_torque(const JointVector& q, const Eigen::Vector3d& center, double mass) {
  const ci::RobotModel model =
      ci::RobotModel::from_urdf_file(kPandaUrdf, "panda_link0", "panda_link8");
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  EXPECT_TRUE(workspace.compute(q, JointVector::Zero(7), kinematics, false));
  const Eigen::Vector3d lever = center - kinematics.pose.position;
  Eigen::Matrix3d cross;
  cross << 0, -lever.z(), lever.y(), lever.z(), 0, -lever.x(), -lever.y(), lever.x(), 0;
  const Eigen::MatrixXd linear =
      kinematics.jacobian.topRows(3) - cross * kinematics.jacobian.bottomRows(3);
  return linear.transpose() * Eigen::Vector3d(0, 0, mass * kGravity);
}

class Attached : public ::testing::TestWithParam<sim::Engine> {
 protected:
  void SetUp() override {
    std::string reason;
    if (!sim::engine_available(GetParam(), &reason)) GTEST_SKIP() << reason;
  }
};

std::string engine_label(const ::testing::TestParamInfo<sim::Engine>& info) {
  return sim::engine_name(info.param);
}

}  // namespace

INSTANTIATE_TEST_SUITE_P(Engines, Attached,
                         ::testing::Values(sim::Engine::mujoco, sim::Engine::dart), engine_label);

// The box is a body welded to the flange at its local pose, wherever the arm goes.
TEST_P(Attached, TheBoxFollowsTheFlange) {
  sim::AttachedBox box = peg();
  box.orientation =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));
  box.position = Eigen::Vector3d(0.01, -0.02, 0.05);
  sim::Simulation s = sim::make_scene(kPandaUrdf, {}, {box}, options_for(GetParam()));
  // Its weight, not compensated, and a push move the arm.
  s.push("panda_link8", (Vector6d() << 10, -10, 0, 0, 0, 0).finished(), 0.3);
  for (int step = 0; step <= 600; ++step) {
    if (step % 300 == 0) {
      SCOPED_TRACE(step);
      const ci::Pose expected = compose(s.body_pose("panda_link8"), box.position, box.orientation);
      const ci::Pose attached = s.body_pose("peg");
      EXPECT_LT((attached.position - expected.position).norm(), 1e-12);
      EXPECT_LT(attached.orientation.angularDistance(expected.orientation), 1e-9);
    }
    s.step();
  }
  EXPECT_GT((s.q() - panda_ready()).norm(), 0.05);
}

// The simulated firmware compensates the arm, not the box: with the box the arm sags, and the
// torque J^T m g that the library's model says holds the box holds it (to the joints' friction).
TEST_P(Attached, ItsWeightIsNotCompensatedAndJTransposeMgHoldsIt) {
  const double mass = 0.4;
  sim::Simulation s = sim::make_scene(kPandaUrdf, {}, {peg(mass)}, options_for(GetParam()));
  const Eigen::Vector3d center = s.body_pose("peg").position;
  sim::Simulation held = sim::make_scene(kPandaUrdf, {}, {peg(mass)}, options_for(GetParam()));
  held.set_torque(holding_torque(panda_ready(), center, mass));
  for (int k = 0; k < 1000; ++k) {
    s.step();
    held.step();
  }
  // 0.4 kg at 0.45 m from joint 2: about 1.8 Nm, far above its 0.1 Nm friction.
  EXPECT_GT((s.q() - panda_ready()).cwiseAbs().maxCoeff(), 0.05);
  // The import rounds to 6 digits, friction holds the rest.
  EXPECT_LT((held.q() - panda_ready()).cwiseAbs().maxCoeff(), 1e-4) << held.q().transpose();
}

// An MJCF whose compiler takes every inertia from the geoms still gets the box's mass: the arm
// (its inertias now those of its shapes, and compensated as such) holds the box with J^T m g.
TEST(AttachedBoxMjcf, AFileThatTakesInertiaFromGeomsGetsTheBoxsMass) {
  std::ifstream file(kPandaXml);
  std::stringstream content;
  content << file.rdbuf();
  std::string text = content.str();
  const std::string original = "inertiafromgeom=\"false\"";
  ASSERT_NE(text.find(original), std::string::npos);
  text.replace(text.find(original), original.size(), "inertiafromgeom=\"true\"");
  const std::string path =
      ::testing::TempDir() + "sim_attached_test_geom_inertia_" + std::to_string(getpid()) + ".xml";
  std::ofstream(path) << text;
  const double mass = 0.4;
  sim::Simulation s = sim::make_scene(path, {}, {peg(mass)}, {});
  std::remove(path.c_str());
  s.set_torque(holding_torque(panda_ready(), s.body_pose("peg").position, mass));
  for (int k = 0; k < 1000; ++k) s.step();
  EXPECT_LT((s.q() - panda_ready()).cwiseAbs().maxCoeff(), 1e-4) << s.q().transpose();
}

// A block 2 cm below the peg's tip; a 20 N push lowers the arm until the peg stands on it. At rest
// the block carries the push and the peg's weight (20 N + 0.4 kg g), within 1 N (the joints'
// friction, as FlangePressedOnATableFeelsThePressingForce); the peg's tip rests on the top
// within 2 mm; the flange never touches it.
TEST_P(Attached, ThePegStandsOnABlockAndFeelsTheForce) {
  const double mass = 0.4, top = 0.47;
  sim::Simulation s =
      sim::make_scene(kPandaUrdf, {sim::Box::table({0.31, 0.0}, {0.1, 0.1}, top, "block")},
                      {peg(mass)}, options_for(GetParam()));
  const double tip = s.body_pose("peg").position.z() - 0.05;
  ASSERT_NEAR(tip, 0.49, 1e-3);
  s.push("panda_link8", (Vector6d() << 0, 0, -20, 0, 0, 0).finished(),
         std::numeric_limits<double>::infinity());
  for (int k = 0; k < 2000; ++k) s.step();
  const Vector6d wrench = s.contact_wrench("peg");
  EXPECT_NEAR(wrench[2], 20.0 + mass * kGravity, 1.0) << wrench.transpose();
  EXPECT_LT(wrench.head<2>().norm(), 1.0) << wrench.transpose();
  EXPECT_NEAR(s.body_pose("peg").position.z() - 0.05, top, 2e-3);
  // Welded to the flange: its contacts are the flange's (and link 7's).
  EXPECT_EQ(s.contact_wrench("panda_link8").head<3>(), wrench.head<3>());
}

// track_contact_wrench averages the body's contact wrench over every step inside the engine's
// stepping (so a BatchRunner's run measures it too): the mean equals the one taken after each
// step by hand, bit for bit, and reads the push plus the peg's weight.
TEST_P(Attached, TrackedContactWrenchIsTheMeanOverTheSteps) {
  const double mass = 0.4;
  sim::Simulation s =
      sim::make_scene(kPandaUrdf, {sim::Box::table({0.31, 0.0}, {0.1, 0.1}, 0.47, "block")},
                      {peg(mass)}, options_for(GetParam()));
  s.push("panda_link8", (Vector6d() << 0, 0, -20, 0, 0, 0).finished(),
         std::numeric_limits<double>::infinity());
  for (int k = 0; k < 1500; ++k) s.step();
  s.track_contact_wrench("peg");
  Vector6d sum = Vector6d::Zero();
  for (int k = 0; k < 300; ++k) {
    s.step();
    sum += s.contact_wrench("peg");
  }
  const Vector6d mean = s.take_mean_contact_wrench();
  EXPECT_EQ(mean, Vector6d(sum / 300.0));
  EXPECT_NEAR(mean[2], 20.0 + mass * kGravity, 1.0) << mean.transpose();
  EXPECT_EQ(s.take_mean_contact_wrench(), Vector6d::Zero());  // no step since the take
  s.step();
  s.reset();  // drops the sum; the body stays tracked
  EXPECT_EQ(s.take_mean_contact_wrench(), Vector6d::Zero());
  EXPECT_ERROR([&] { s.track_contact_wrench("gripper"); }, {"body 'gripper'"});
  s.step();  // the failed call kept "peg" tracked
  EXPECT_NO_THROW(s.take_mean_contact_wrench());
  s.track_contact_wrench("");
  EXPECT_ERROR([&] { s.take_mean_contact_wrench(); }, {"no body is tracked"});
}

#ifdef CARTESIAN_IMPEDANCE_COUNT_ALLOCATIONS
// Leaving the attached weight out of the compensation costs no allocation (MuJoCo; DART's
// contact solver allocates anyway).
TEST(AttachedBoxRealTime, StepAllocatesNothingWithAnAttachedBoxInContact) {
  sim::Simulation s = sim::make_scene(
      kPandaXml, {sim::Box::table({0.31, 0.0}, {0.1, 0.1}, 0.47, "block")}, {peg()}, {});
  s.push("flange", (Vector6d() << 0, 0, -20, 0, 0, 0).finished(),
         std::numeric_limits<double>::infinity());
  for (int k = 0; k < 500; ++k) s.step();  // warm up: the peg lands on the block
  ASSERT_GT(s.contact_wrench("peg")[2], 10.0);
  s.track_contact_wrench("peg");  // every step then adds the peg's contact wrench
  allocation_counter::Scope scope;
  for (int k = 0; k < 1000; ++k) s.step();
  EXPECT_EQ(scope.allocations(), 0);
}
#endif

TEST(AttachedBoxErrors, NameTheFieldTheValueAndTheBodies) {
  sim::AttachedBox box = peg();
  box.body = "panda_link9";
  EXPECT_ERROR([&] { sim::make_scene(kPandaXml, {}, {box}, {}); },
               {"attached[0].body", "panda_link9", "panda_link8"});
  EXPECT_ERROR([&] { sim::make_scene(kPandaUrdf, {}, {box}, {}); },
               {"attached[0].body", "panda_link9", "panda_link7"});
  box = peg();
  box.half_size.y() = 0.0;
  EXPECT_ERROR([&] { sim::make_scene(kPandaXml, {}, {box}, {}); }, {"attached[0].half_size", "0"});
  box = peg();
  box.mass = -1.0;
  EXPECT_ERROR(
      [&] {
        sim::make_scene(kPandaXml, {}, {peg(), box}, {});
      },
      {"attached[1].mass", "-1", "kg"});
  box = peg();
  box.position.x() = std::nan("");
  EXPECT_ERROR([&] { sim::make_scene(kPandaXml, {}, {box}, {}); }, {"attached[0].position", "nan"});
  EXPECT_ERROR(
      [&] {
        sim::make_scene(kPandaXml, {}, {peg(), peg()}, {});
      },
      {"attached[1].name", "'peg'", "used"});
  box = peg();
  box.name = "a\"b";
  EXPECT_ERROR([&] { sim::make_scene(kPandaXml, {}, {box}, {}); }, {"attached[0].name", "XML"});
  sim::SceneRobot robot{kPandaUrdf, "left_", Eigen::Vector3d::Zero(), {peg()}};
  robot.attached[0].body = "tool0";
  EXPECT_ERROR([&] { sim::make_robots_scene({robot}); }, {"robots[0].attached[0].body", "tool0"});
}

// MJCF (MuJoCo) and a robots scene: the box is there, prefixed with its robot's names.
TEST(AttachedBoxScenes, MjcfAndRobotsScenesCarryTheBox) {
  sim::Simulation mjcf = sim::make_scene(kPandaXml, {}, {peg()}, {});
  const ci::Pose flange = mjcf.body_pose("panda_link8");
  EXPECT_LT(
      (mjcf.body_pose("peg").position - compose(flange, peg().position, peg().orientation).position)
          .norm(),
      1e-12);
  sim::SimulationOptions options;
  options.start_q.resize(14);
  options.start_q << panda_ready(), panda_ready();
  sim::Simulation two =
      sim::make_robots_scene({{kPandaUrdf, "left_", Eigen::Vector3d(0, 0.5, 0), {peg()}},
                              {kPandaUrdf, "right_", Eigen::Vector3d(0, -0.5, 0)}},
                             options);
  const ci::Pose left = two.body_pose("left_panda_link8");
  EXPECT_LT((two.body_pose("left_peg").position -
             compose(left, peg().position, peg().orientation).position)
                .norm(),
            1e-12);
  EXPECT_ERROR([&] { two.body_pose("right_peg"); }, {"right_peg"});
  // Only the left arm carries an uncompensated load.
  for (int k = 0; k < 500; ++k) two.step();
  EXPECT_GT((two.q().head(7) - panda_ready()).cwiseAbs().maxCoeff(), 0.01);
  EXPECT_LT((two.q().tail(7) - panda_ready()).cwiseAbs().maxCoeff(), 1e-6);
}

// ---------------------------------------------------------------------------------------------
// The hole

// Its inner faces are clearance / 2 from the peg's sides, in the hole's own frame however it is
// turned; the floor is at the depth.
TEST(SquareHole, InnerFacesAreHalfTheClearanceFromThePeg) {
  sim::SquareHole hole;
  hole.opening.position = Eigen::Vector3d(0.4, -0.1, 0.3);
  hole.opening.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()) *
                                                Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX()));
  hole.peg_half_width = 0.0125;
  hole.clearance = 0.0008;
  hole.depth = 0.03;
  const std::vector<sim::Box> boxes = sim::hole_boxes(hole);
  ASSERT_EQ(boxes.size(), 5u);
  const Eigen::Quaterniond inverse = hole.opening.orientation.conjugate();
  double inner[4];  // +x, -x, +y, -y: distance of each wall's inner face from the axis
  double bottom = 0.0, top = -1.0;
  for (const sim::Box& box : boxes) {
    EXPECT_TRUE(box.orientation.isApprox(hole.opening.orientation, 1e-15));
    const Eigen::Vector3d c = inverse * (box.center - hole.opening.position);
    top = std::max(top, c.z() + box.half_size.z());
    if (box.name == "hole_floor") {
      bottom = c.z() + box.half_size.z();
    } else if (box.name == "hole_wall_x_plus") {
      inner[0] = c.x() - box.half_size.x();
    } else if (box.name == "hole_wall_x_minus") {
      inner[1] = -(c.x() + box.half_size.x());
    } else if (box.name == "hole_wall_y_plus") {
      inner[2] = c.y() - box.half_size.y();
    } else {
      ASSERT_EQ(box.name, "hole_wall_y_minus");
      inner[3] = -(c.y() + box.half_size.y());
    }
  }
  for (const double face : inner) EXPECT_NEAR(face, 0.0125 + 0.0004, 1e-15);
  EXPECT_NEAR(top, 0.0, 1e-15);
  EXPECT_NEAR(bottom, -0.03, 1e-15);
  hole.floor = 0.0;
  EXPECT_EQ(sim::hole_boxes(hole).size(), 4u);
}

TEST(SquareHole, ErrorsNameTheField) {
  sim::SquareHole hole;
  hole.clearance = -0.001;
  EXPECT_ERROR([&] { sim::hole_boxes(hole); }, {"hole.clearance", "-0.001"});
  hole = sim::SquareHole{};
  hole.depth = 0.0;
  EXPECT_ERROR([&] { sim::hole_boxes(hole); }, {"hole.depth", "0"});
  hole = sim::SquareHole{};
  hole.opening.orientation = Eigen::Quaterniond(0.5, 0, 0, 0);
  EXPECT_ERROR([&] { sim::hole_boxes(hole); }, {"hole.opening.orientation"});
  sim::PegInHole scene;
  scene.robot = kPandaUrdf;
  scene.flange = "panda_link8";
  scene.peg_mass = 0.0;
  EXPECT_ERROR([&] { sim::make_peg_in_hole_scene(scene); }, {"peg_mass", "0"});
}

// ---------------------------------------------------------------------------------------------
// Insertion with the impedance controller

namespace {

struct Insertion {
  double depth = 0.0;           // of the peg's tip below the opening at the end [m]
  double force = 0.0;           // contact force on the peg along the hole's axis at the end [N]
  double time_to_depth = -1.0;  // first time the tip was within 1 mm of the floor [s]; -1 never
  double lateral = 0.0;         // largest contact force across the axis at the end [N]
};

constexpr double kHoleDepth = 0.03, kGap = 0.02, kPegLength = 0.1;
constexpr double kSpeed = 0.03;  // of the reference [m/s]

// The Panda at its ready pose holding a 25 mm square peg (0.2 kg, declared as the payload), a
// hole with 1 mm clearance whose opening is kGap below the tip, shifted by `offset` along x; the
// reference moved 1 cm beyond the hole's floor at 2000 N/m, 100 Nm/rad, for 3 s.
Insertion insert(sim::Engine engine, double offset) {
  const ci::RobotModel model =
      ci::RobotModel::from_urdf_file(kPandaUrdf, "panda_link0", "panda_link8");
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  EXPECT_TRUE(workspace.compute(panda_ready(), JointVector::Zero(7), kinematics, false));
  const ci::Pose flange = kinematics.pose;
  const Eigen::Vector3d tip =
      flange.position + flange.orientation * Eigen::Vector3d(0, 0, kPegLength);

  sim::PegInHole scene;
  scene.robot = kPandaUrdf;
  scene.flange = "panda_link8";
  scene.peg_length = kPegLength;
  scene.peg_mass = 0.2;
  scene.hole.peg_half_width = 0.0125;
  scene.hole.clearance = 0.001;
  scene.hole.depth = kHoleDepth;
  scene.hole.opening.position = tip + Eigen::Vector3d(offset, 0, -kGap);
  // The hole's z up, its sides along the peg's (the flange's x and y).
  scene.hole.opening.orientation =
      flange.orientation * Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  sim::Simulation s = sim::make_peg_in_hole_scene(scene, options_for(engine));

  ci::Parameters parameters;
  parameters.stiffness.translation.setConstant(2000.0);
  parameters.stiffness.rotation.setConstant(100.0);
  parameters.payload.mass = scene.peg_mass;
  parameters.payload.center_of_mass = Eigen::Vector3d(0, 0, 0.5 * kPegLength);
  parameters.dynamics.armature = s.armature();
  ci::ControlLoop loop(model, parameters);
  sim::ClosedLoopRunner runner(s, loop);
  runner.start();
  // Straight down at kSpeed, as a script or a policy would move it: a step of the reference
  // would swing the tip by millimetres on the way.
  const double travel = kGap + kHoleDepth + 0.01;

  const double opening_z = scene.hole.opening.position.z();
  auto tip_depth = [&] {
    const ci::Pose body = s.body_pose("peg");
    return opening_z -
           (body.position + body.orientation * Eigen::Vector3d(0, 0, 0.5 * kPegLength)).z();
  };
  Insertion result;
  runner.run_for(3.0, [&](std::int64_t) {
    ci::Pose target = flange;
    target.position.z() -= std::min(travel, kSpeed * s.time());
    loop.set_reference_pose(target);
    if (result.time_to_depth < 0.0 && tip_depth() > kHoleDepth - 0.001)
      result.time_to_depth = s.time();
  });
  result.depth = tip_depth();
  const Vector6d wrench = s.contact_wrench("peg");
  result.force = wrench[2];
  result.lateral = wrench.head<2>().norm();
  return result;
}

}  // namespace

// Centred, the peg goes down to the hole's floor and presses on it with what the spring's
// remaining 1 cm gives (2000 N/m x 1 cm = 20 N, less the joints' friction: 2 N bound).
TEST_P(Attached, TheControllerInsertsAPegIntoAHoleWith1mmClearance) {
  const Insertion insertion = insert(GetParam(), 0.0);
  std::printf(
      "[ figures  ] %s: depth %.2f mm of %.0f mm after %.3f s, contact force %.2f N "
      "along the axis, %.2f N across\n",
      sim::engine_name(GetParam()), 1e3 * insertion.depth, 1e3 * kHoleDepth,
      insertion.time_to_depth, insertion.force, insertion.lateral);
  EXPECT_NEAR(insertion.depth, kHoleDepth, 1e-3);
  EXPECT_GT(insertion.time_to_depth, 0.0);
  EXPECT_NEAR(insertion.force, 20.0, 2.0);
}

// 3 mm off (more than the 0.5 mm per side), the same motion lands the peg on the block's top
// and the stiff spring keeps it there.
TEST_P(Attached, APegOffsetBy3mmJamsOnTheBlock) {
  const Insertion insertion = insert(GetParam(), 0.003);
  std::printf("[ figures  ] %s, 3 mm off: depth %.2f mm, contact force %.2f N\n",
              sim::engine_name(GetParam()), 1e3 * insertion.depth, insertion.force);
  EXPECT_LT(insertion.depth, 1e-3);
  EXPECT_LT(insertion.time_to_depth, 0.0);
  EXPECT_GT(insertion.force, 20.0);  // the spring's 4 cm short of its target: about 80 N
}
