// The collision monitor in closed loop with MuJoCo: the momentum observer against an external
// torque computed without it (a known push on a known link, J_link^T F from a model of the chain
// up to that link), detection and isolation of a contact, each reaction against the contact
// force without it, and no false alarm in free motion on the realistic plant.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>
#include <limits>
#include <map>
#include <string>

#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/sim/closed_loop_runner.hpp"
#include "cartesian_impedance/sim/engine.hpp"
#include "cartesian_impedance/sim/simulation.hpp"

namespace ci = cartesian_impedance;

namespace {

const std::string kSource = CARTESIAN_IMPEDANCE_SOURCE_DIR;

const ci::RobotModel& panda_model() {
  static const ci::RobotModel model = ci::RobotModel::from_urdf_file(
      kSource + "/models/panda/panda.urdf", "panda_link0", "panda_link8");
  return model;
}

ci::sim::Simulation panda_simulation(const ci::sim::PlantOptions& plant = {},
                                     const std::vector<ci::sim::Box>& boxes = {}) {
  ci::sim::SimulationOptions options;
  options.joint_names = panda_model().joint_names();
  options.plant = plant;
  return ci::sim::make_scene(kSource + "/models/panda/panda.xml", boxes, options);
}

// The Panda's ready pose; DART loads the URDF (MuJoCo the MJCF, whose keyframe is this pose).
ci::sim::Simulation panda_on(ci::sim::Engine engine, const ci::sim::PlantOptions& plant = {},
                             const std::vector<ci::sim::Box>& boxes = {}) {
  ci::sim::SimulationOptions options;
  options.joint_names = panda_model().joint_names();
  options.plant = plant;
  options.engine = engine;
  options.start_q =
      (ci::JointVector(7) << 0, -M_PI / 4, 0, -3 * M_PI / 4, 0, M_PI / 2, M_PI / 4).finished();
  return ci::sim::make_scene(
      kSource + (engine == ci::sim::Engine::dart ? "/models/panda/panda.urdf"
                                                 : "/models/panda/panda.xml"),
      boxes, options);
}

// The controller's model as the simulation's: the rotors' inertia from the robot file.
ci::Parameters parameters_for(const ci::sim::Simulation& sim) {
  ci::Parameters p;
  p.dynamics.armature = sim.model_armature();
  return p;
}

// The external torque of a push held on `body` at its origin, [force; torque] in the world (the
// base frame): J^T w, J the Jacobian of the chain up to that body, zero on the joints after it.
ci::JointVector push_torque(const ci::JointVector& q, const std::string& body,
                            const ci::Vector6d& push) {
  static std::map<std::string, ci::RobotModel> chains;
  if (chains.count(body) == 0) {
    chains.emplace(body, ci::RobotModel::from_urdf_file(kSource + "/models/panda/panda.urdf",
                                                        "panda_link0", body));
  }
  const ci::RobotModel& chain = chains.at(body);
  ci::ModelWorkspace workspace(chain);
  ci::Kinematics k = workspace.make_kinematics();
  const int n = chain.num_joints();
  EXPECT_TRUE(workspace.compute(q.head(n), ci::JointVector::Zero(n), k, false));
  ci::JointVector torque = ci::JointVector::Zero(q.size());
  torque.head(n) = k.jacobian.transpose() * push;
  return torque;
}

}  // namespace

// A push of 15 N and 1 Nm held on link 4 from t = 0.5 s. The observer's estimate follows the
// external torque through its first-order filter: once 5/K_O have passed (e^-5 = 0.7 % of the
// step left), on every joint and at every step, within what the model does not know of the
// simulated joints: their Coulomb friction and viscous damping (the robot file's 0.1 Nm and
// 0.5 Nm s/rad), 1 % of |tau_ext| for the filter and 0.02 Nm for the integration of a
// 1 ms step. A wrong sign, joint or lever is of the order of the torque itself (up to 3 Nm).
TEST(MomentumObserver, MatchesAKnownPushOnAKnownLink) {
  ci::sim::Simulation sim = panda_simulation();
  const ci::Parameters p = parameters_for(sim);
  ci::ControlLoop loop(panda_model(), p);
  ci::sim::ClosedLoopRunner runner(sim, loop);
  runner.start();
  runner.run_for(0.5);
  EXPECT_LE(loop.state().controller.collision.residual.cwiseAbs().maxCoeff(), 0.15)
      << "no push, no external torque but the joints' friction";
  ci::Vector6d push;
  push << 9.0, -12.0, 0.0, 0.6, 0.0, 0.8;
  sim.push("panda_link4", push, std::numeric_limits<double>::infinity());
  const ci::JointVector friction = sim.friction_loss(), damping = sim.joint_damping();
  const double settle = 5.0 / p.collision.observer_gain;
  double worst = 0.0, largest = 0.0;
  runner.run_for(1.5, [&](std::int64_t steps) {
    if (static_cast<double>(steps) * sim.timestep() < settle) return;
    const ci::JointVector expected = push_torque(sim.true_q(), "panda_link4", push);
    const ci::JointVector& r = loop.state().controller.collision.residual;
    const ci::JointVector bound =
        (friction + damping.cwiseProduct(sim.true_dq().cwiseAbs())).array() +
        0.01 * expected.norm() + 0.02;
    worst = std::max(worst, ((r - expected).cwiseAbs().array() / bound.array()).maxCoeff());
    largest = std::max(largest, expected.cwiseAbs().maxCoeff());
  });
  EXPECT_LE(worst, 1.0) << "the estimate left its bound";
  EXPECT_GE(largest, 2.0) << "the push must load the joints";
  EXPECT_FALSE(loop.state().controller.collision.detected) << "below the 5 Nm threshold";
}

// A push that loads joint k and none after it (it acts on link k) is a collision on link k: a
// moment of 12 Nm about the joint's axis, on the nominal Panda at rest, is found and named.
TEST(MomentumObserver, NamesThePushedLink) {
  for (const int joint : {1, 3, 5}) {
    SCOPED_TRACE("link " + std::to_string(joint + 1));
    ci::sim::Simulation sim = panda_simulation();
    ci::ControlLoop loop(panda_model(), parameters_for(sim));
    ci::sim::ClosedLoopRunner runner(sim, loop);
    runner.start();
    runner.run_for(0.2);
    const std::string body = "panda_link" + std::to_string(joint + 1);
    Eigen::Vector3d axis;
    for (int i = 0; i < 3; ++i) {
      axis[i] = push_torque(sim.true_q(), body, ci::Vector6d::Unit(3 + i))[joint];
    }
    ci::Vector6d push = ci::Vector6d::Zero();
    push.tail<3>() = 12.0 * axis.normalized();
    sim.push(body, push, 0.3);
    runner.run_for(0.3);
    const ci::CollisionState& collision = loop.state().controller.collision;
    EXPECT_TRUE(collision.detected);
    EXPECT_EQ(collision.collisions, 1);
    EXPECT_EQ(collision.joint, joint);
    EXPECT_EQ(collision.reaction, ci::CollisionReaction::report);
  }
}

// The observer on the joint torque sensors (collision.measured_torque), on both engines. The
// joints' Coulomb friction and viscous damping, and the rotors' inertia, act on the drive's side
// of a link-side sensor, so they leave the estimate; what is left is the integration of a 1 ms
// step. Free motion along a 25 cm move at the 0.25 m/s cap (nominal plant, the robot file's
// 0.1 Nm of friction and 0.5 Nm s/rad of damping per joint): the torque sent leaves the friction
// and damping in the residual (at least 0.1 Nm), the measurement at most 0.03 Nm. Then the
// push of MatchesAKnownPushOnAKnownLink is matched within 1 % and 0.02 Nm: no friction term.
class MeasuredTorqueOn : public ::testing::TestWithParam<ci::sim::Engine> {};

TEST_P(MeasuredTorqueOn, TheObserverLeavesOutTheJointsFrictionAndMatchesAKnownPush) {
  const ci::sim::Engine engine = GetParam();
  std::string reason;
  if (!ci::sim::engine_available(engine, &reason)) GTEST_SKIP() << reason;
  double free_motion[2] = {0.0, 0.0};  // largest |r| in free motion: sent, measured
  for (const bool measured : {false, true}) {
    SCOPED_TRACE(measured ? "measured" : "sent");
    ci::sim::Simulation sim = panda_on(engine);
    ci::Parameters p = parameters_for(sim);
    p.safety.max_speed.translation = 0.25;
    p.collision.measured_torque = measured;
    ci::ControlLoop loop(panda_model(), p);
    ci::sim::ClosedLoopRunner runner(sim, loop);
    runner.start();
    ci::Pose target = loop.state().controller.pose;
    target.position.y() += 0.25;
    loop.set_reference_pose(target);
    double& largest = free_motion[measured ? 1 : 0];
    runner.run_for(1.5, [&](std::int64_t steps) {
      if (steps < 10) return;  // the observer's first cycles start from rest
      largest = std::max(largest, loop.state().controller.collision.residual.cwiseAbs().maxCoeff());
    });
    ASSERT_LE((loop.state().controller.pose.position - target.position).norm(), 0.01)
        << "the move must be made";
    if (!measured) continue;
    ci::Vector6d push;
    push << 9.0, -12.0, 0.0, 0.6, 0.0, 0.8;
    sim.push("panda_link4", push, std::numeric_limits<double>::infinity());
    const double settle = 5.0 / p.collision.observer_gain;
    double worst = 0.0;
    runner.run_for(1.5, [&](std::int64_t steps) {
      if (static_cast<double>(steps) * sim.timestep() < settle) return;
      const ci::JointVector expected = push_torque(sim.true_q(), "panda_link4", push);
      const ci::JointVector& r = loop.state().controller.collision.residual;
      worst =
          std::max(worst, (r - expected).cwiseAbs().maxCoeff() / (0.01 * expected.norm() + 0.02));
    });
    EXPECT_LE(worst, 1.0) << "the estimate left its bound";
    EXPECT_EQ(loop.state().controller.status, ci::Status::ok);
  }
  std::printf("%s free motion, largest |r|: %.3f Nm (torque sent), %.3f Nm (measured)\n",
              ci::sim::engine_name(engine), free_motion[0], free_motion[1]);
  EXPECT_GE(free_motion[0], 0.1) << "friction and damping, with the torque sent";
  EXPECT_LE(free_motion[1], 0.03);
}

INSTANTIATE_TEST_SUITE_P(Engines, MeasuredTorqueOn,
                         ::testing::Values(ci::sim::Engine::mujoco, ci::sim::Engine::dart),
                         [](const auto& info) {
                           return std::string(ci::sim::engine_name(info.param));
                         });

namespace {

// The forearm swung into a fixed box: the Panda's end effector sent 30 cm sideways at the speed
// cap of 0.25 m/s (1000 N/m, the realistic plant), which sweeps link 5 into a box beside it at
// 0.26 m/s. Measured from the first step with a contact force on the arm.
struct Swing {
  std::int64_t contact = -1;   // step of first contact
  std::int64_t detected = -1;  // step the monitor found it
  double impact = 0.0;         // [N] largest force on the arm within 10 ms of the contact
  double clamping = 0.0;       // [N] largest force from 100 ms after the contact on
  double impulse = 0.0;        // [N s] over the 1.5 s after the contact
  ci::CollisionState state;
  ci::TrajectoryState trajectory = ci::TrajectoryState::idle;
};

// What a test does with the scene after the swing.
using AfterSwing =
    std::function<void(ci::sim::Simulation&, ci::ControlLoop&, ci::sim::ClosedLoopRunner&)>;

Swing swing_into_box(ci::CollisionReaction reaction, ci::sim::Engine engine,
                     const AfterSwing& after = {}, bool measured_torque = false) {
  ci::sim::Box box;
  box.center = Eigen::Vector3d(0.05, 0.15, 0.66);
  box.half_size = Eigen::Vector3d(0.05, 0.04, 0.06);
  ci::sim::Simulation sim = panda_on(engine, ci::sim::PlantOptions::realistic(3), {box});
  ci::Parameters p = parameters_for(sim);
  p.safety.max_speed.translation = 0.25;
  p.stiffness.translation.setConstant(1000);
  p.stiffness.rotation.setConstant(100);
  p.collision.reaction = reaction;
  p.collision.measured_torque = measured_torque;
  ci::ControlLoop loop(panda_model(), p);
  ci::sim::ClosedLoopRunner runner(sim, loop);
  runner.start();
  ci::Pose target = loop.state().controller.pose;
  target.position.y() += 0.3;
  loop.set_reference_pose(target);
  Swing swing;
  const std::int64_t steps_10ms = static_cast<std::int64_t>(0.01 / sim.timestep() + 0.5);
  runner.run_for(2.0, [&](std::int64_t steps) {
    Eigen::Vector3d force = Eigen::Vector3d::Zero();
    for (int k = 1; k <= 8; ++k) {
      force += sim.contact_wrench("panda_link" + std::to_string(k)).head<3>();
    }
    if (swing.contact < 0 && force.norm() > 0.0) swing.contact = steps;
    if (swing.detected < 0 && loop.state().controller.collision.detected) swing.detected = steps;
    if (swing.contact < 0) return;
    const std::int64_t since = steps - swing.contact;
    if (since <= steps_10ms) swing.impact = std::max(swing.impact, force.norm());
    if (since >= 10 * steps_10ms) swing.clamping = std::max(swing.clamping, force.norm());
    swing.impulse += force.norm() * sim.timestep();
  });
  swing.state = loop.state().controller.collision;
  if (after) after(sim, loop, runner);
  return swing;
}

}  // namespace

// On both engines: found within 10 ms of the first contact (measured: 4 ms on MuJoCo, 2 ms on
// DART), on the forearm: the last joint that feels a sideways push on link 5 is joint 3 (joints
// 4 and 5 turn about axes the push runs along or through), so the monitor names link 3, 4 or 5.
// Without a reaction the controller goes on pressing toward its reference (the clamping force
// grows past 100 N: 139 N on MuJoCo, 269 N on DART); each reaction ends it, to a tenth at most
// from 100 ms on (0-0.9 N, and 23 N for DART's reflex, whose hard contact keeps the complying
// arm on the box), and the impulse to under half (1 N s against 190). The impact itself (the
// arm's momentum meeting a rigid box in the first milliseconds: 98 N on MuJoCo's soft
// contact, 994 N on DART's hard one) is what no reaction after the contact can change: the
// speed limit is for that.
class CollisionReactionOn : public ::testing::TestWithParam<ci::sim::Engine> {};

TEST_P(CollisionReactionOn, EachReactionEndsTheClampingForce) {
  const ci::sim::Engine engine = GetParam();
  std::string reason;
  if (!ci::sim::engine_available(engine, &reason)) GTEST_SKIP() << reason;
  const Swing report = swing_into_box(ci::CollisionReaction::report, engine);
  ASSERT_GE(report.contact, 0) << "the forearm must reach the box";
  ASSERT_GE(report.detected, report.contact) << "found only once it touched";
  EXPECT_LE(report.detected - report.contact, 10);
  EXPECT_GE(report.state.joint, 2);
  EXPECT_LE(report.state.joint, 4);
  EXPECT_EQ(report.state.reaction, ci::CollisionReaction::report);
  EXPECT_GE(report.clamping, 100.0);
  std::printf(
      "%s report : found %lld ms after contact at joint %d, impact %.0f N, clamping %.0f N, "
      "impulse %.1f N s\n",
      ci::sim::engine_name(engine), static_cast<long long>(report.detected - report.contact),
      report.state.joint + 1, report.impact, report.clamping, report.impulse);
  // The same swing with the joint torque sensors read: found as soon, named alike.
  const Swing sensed = swing_into_box(ci::CollisionReaction::report, engine, {}, true);
  ASSERT_GE(sensed.detected, sensed.contact);
  EXPECT_LE(sensed.detected - sensed.contact, report.detected - report.contact);
  EXPECT_GE(sensed.state.joint, 2);
  EXPECT_LE(sensed.state.joint, 4);
  std::printf("%s report, measured torque: found %lld ms after contact at joint %d\n",
              ci::sim::engine_name(engine),
              static_cast<long long>(sensed.detected - sensed.contact), sensed.state.joint + 1);
  for (const ci::CollisionReaction reaction :
       {ci::CollisionReaction::stop, ci::CollisionReaction::reflex,
        ci::CollisionReaction::retract}) {
    SCOPED_TRACE(std::string(ci::reaction_name(reaction)));
    const Swing swing = swing_into_box(reaction, engine);
    EXPECT_LE(swing.detected - swing.contact, 10);
    EXPECT_TRUE(swing.state.detected) << "latched until resume";
    EXPECT_EQ(swing.state.reaction, reaction);
    EXPECT_LE(swing.clamping, 0.1 * report.clamping);
    EXPECT_LE(swing.impulse, 0.5 * report.impulse);
    std::printf("%s %-7s: clamping %.1f N, impulse %.2f N s\n", ci::sim::engine_name(engine),
                std::string(ci::reaction_name(reaction)).c_str(), swing.clamping, swing.impulse);
  }
}

// Free motion at the speed cap on the nominal plant and on three draws of the realistic one
// (model error, friction, noise, delays), both shipped arms: moves of 25 cm back and forth, up
// and down, for 12 s each. No collision; the largest share of a threshold reached is printed
// (measured: 0.04-0.08 nominal, 0.39-0.61 realistic; before the threshold counted the velocity
// noise, 1.2-1.5 on the iiwa14).
TEST(CollisionMonitor, NoFalseAlarmInFreeMotionAtTheSpeedCap) {
  struct Arm {
    const char* name;
    std::string urdf, mjcf, base, tip;
  };
  const Arm arms[] = {{"panda", kSource + "/models/panda/panda.urdf",
                       kSource + "/models/panda/panda.xml", "panda_link0", "panda_link8"},
                      {"iiwa14", kSource + "/models/iiwa14/iiwa14.urdf",
                       kSource + "/models/iiwa14/iiwa14.xml", "iiwa_link_0", "iiwa_link_ee"}};
  for (const Arm& arm : arms) {
    const ci::RobotModel model = ci::RobotModel::from_urdf_file(arm.urdf, arm.base, arm.tip);
    // The observer reading the torque sent, then the joint torque sensors.
    for (const bool measured : {false, true}) {
      for (const std::uint64_t seed : {0, 1, 2, 3}) {
        SCOPED_TRACE(std::string(arm.name) + " seed " + std::to_string(seed) +
                     (measured ? ", measured" : ""));
        ci::sim::SimulationOptions options;
        options.joint_names = model.joint_names();
        if (seed > 0) options.plant = ci::sim::PlantOptions::realistic(seed);
        ci::sim::Simulation sim = ci::sim::Simulation::from_mjcf_file(arm.mjcf, options);
        ci::Parameters p = parameters_for(sim);
        p.safety.max_speed.translation = 0.25;
        p.safety.max_speed.rotation = 1.0;
        p.stiffness.translation.setConstant(1000);
        p.stiffness.rotation.setConstant(100);
        p.collision.measured_torque = measured;
        ci::ControlLoop loop(model, p);
        ci::sim::ClosedLoopRunner runner(sim, loop);
        runner.start();
        const ci::Pose start = loop.state().controller.pose;
        const Eigen::Vector3d moves[] = {
            {0, 0.25, 0}, {0, -0.25, 0}, {0.1, 0, -0.2}, {-0.1, 0.1, 0.1}};
        double share = 0.0;

        for (int move = 0; move < 8; ++move) {
          ci::Pose target = start;
          target.position += moves[move % 4];
          loop.set_reference_pose(target);
          runner.run_for(1.5, [&](std::int64_t) {
            const ci::CollisionState& c = loop.state().controller.collision;
            share =
                std::max(share, (c.unexpected.cwiseAbs().array() / c.threshold.array()).maxCoeff());
          });
        }
        EXPECT_EQ(loop.state().controller.collision.collisions, 0);
        EXPECT_EQ(loop.state().controller.status, ci::Status::ok);
        std::printf("%s seed %llu, %s: largest share of a threshold %.2f\n", arm.name,
                    static_cast<unsigned long long>(seed), measured ? "measured" : "sent", share);
      }
    }
  }
}

// A reaction holds the arm until Resume: a reference sent meanwhile is counted, not followed;
// after Resume the arm holds where it is and follows the next reference.
INSTANTIATE_TEST_SUITE_P(Engines, CollisionReactionOn,
                         ::testing::Values(ci::sim::Engine::mujoco, ci::sim::Engine::dart),
                         [](const auto& info) {
                           return std::string(ci::sim::engine_name(info.param));
                         });

TEST(CollisionReaction, HoldsUntilResume) {
  swing_into_box(
      ci::CollisionReaction::stop, ci::sim::Engine::mujoco,
      [](ci::sim::Simulation& sim, ci::ControlLoop& loop, ci::sim::ClosedLoopRunner& runner) {
        const Eigen::Vector3d stopped = loop.state().controller.pose.position;
        ci::Pose back = loop.state().controller.pose;
        back.position.y() -= 0.15;
        loop.set_reference_pose(back);
        runner.run_for(0.5);
        EXPECT_EQ(loop.state().controller.collision.commands_held, 1);
        EXPECT_LE((loop.state().controller.pose.position - stopped).norm(), 0.005);
        loop.send(ci::Resume{});
        runner.run_for(0.2);
        EXPECT_FALSE(loop.state().controller.collision.detected);
        EXPECT_LE((loop.state().controller.pose.position - stopped).norm(), 0.005)
            << "resume alone moves nothing";
        loop.set_reference_pose(back);
        runner.run_for(1.5);
        EXPECT_LE((loop.state().controller.pose.position - back.position).norm(), 0.01);
        EXPECT_EQ(loop.state().controller.collision.collisions, 1) << "no contact on the way back";
        EXPECT_EQ(loop.state().controller.status, ci::Status::ok);
        (void)sim;
      });
}

// A commanded wrench pressing on a table is not a collision: the flange is let down onto a table
// by -30 N (no vertical stiffness, 5 cm/s), and presses on it. The residual then holds the
// table's reaction, well past the threshold (the test asserts it: without the commanded
// wrench's band it would be a collision), and the monitor finds nothing.
TEST(CollisionMonitor, ACommandedWrenchOnATableIsNoCollision) {
  ci::sim::Simulation sim = panda_simulation(
      {}, {ci::sim::Box::table(Eigen::Vector2d(0.4, 0.0), Eigen::Vector2d(0.3, 0.3), 0.35)});
  ci::Parameters p = parameters_for(sim);
  p.safety.max_speed.translation = 0.05;
  p.stiffness.translation = Eigen::Vector3d(1000, 1000, 0);
  p.stiffness.rotation.setConstant(100);
  ci::ControlLoop loop(panda_model(), p);
  ci::sim::ClosedLoopRunner runner(sim, loop);
  runner.start();
  loop.set_wrench((ci::Vector6d() << 0, 0, -30, 0, 0, 0).finished());
  double share = 0.0, seen = 0.0;
  runner.run_for(8.0, [&](std::int64_t) {
    const ci::CollisionState& c = loop.state().controller.collision;
    share = std::max(share, (c.unexpected.cwiseAbs().array() / c.threshold.array()).maxCoeff());
    seen = std::max(seen, (c.residual.cwiseAbs().array() / c.threshold.array()).maxCoeff());
  });
  const Eigen::Vector3d pressed = sim.contact_wrench_beyond("panda_link7").head<3>();
  EXPECT_NEAR(pressed.z(), 30.0, 3.0) << "the hand must press on the table";
  EXPECT_GE(seen, 1.2);
  EXPECT_EQ(loop.state().controller.collision.collisions, 0) << "largest share " << share;
}

// Power and force limiting on the Panda (MuJoCo, nominal plant): a 30 cm reference jump at
// 3000 N/m with the skull as the body region. Every cycle the flange stays within 1.1 x the speed
// limit in force (the governor aims at 95 % of it, as for any speed cap), which follows the arm's
// effective mass along the motion; without the region the flange passes 0.6 m/s.
TEST(PowerAndForceLimiting, TheFlangeKeepsTheSpeedItsEffectiveMassAllows) {
  const auto run = [](ci::BodyRegion region, double& peak, double& worst_share, double& lowest,
                      double& highest) {
    ci::sim::Simulation sim = panda_simulation();
    ci::Parameters p = parameters_for(sim);
    p.stiffness.translation.setConstant(3000);
    p.stiffness.rotation.setConstant(300);
    p.safety.pfl.body_region = region;
    ci::ControlLoop loop(panda_model(), p);
    ci::sim::ClosedLoopRunner runner(sim, loop);
    runner.start();
    ci::Pose target = loop.state().controller.pose;
    target.position += Eigen::Vector3d(-0.1, 0.25, -0.15);
    loop.set_reference_pose(target);
    peak = worst_share = 0.0;
    lowest = std::numeric_limits<double>::infinity();
    highest = 0.0;
    ci::Pose before = loop.state().controller.pose;
    runner.run_for(3.0, [&](std::int64_t) {
      const ci::Pose now = loop.state().controller.pose;
      const double speed = (now.position - before.position).norm() / sim.timestep();
      before = now;
      peak = std::max(peak, speed);
      const double limit = loop.state().controller.safety.pfl_speed_limit;
      if (limit > 0.0) {
        worst_share = std::max(worst_share, speed / limit);
        lowest = std::min(lowest, limit);
        highest = std::max(highest, limit);
      }
    });
    EXPECT_LE((loop.state().controller.pose.position - target.position).norm(), 0.01);
  };
  double peak = 0, share = 0, lowest = 0, highest = 0;
  run(ci::BodyRegion::skull, peak, share, lowest, highest);
  std::printf("skull: flange peak %.3f m/s, limit %.3f-%.3f m/s, worst %.2f x the limit\n", peak,
              lowest, highest, share);
  EXPECT_LE(share, 1.1);
  EXPECT_GT(highest - lowest, 0.01) << "the limit follows the configuration and direction";
  double free_peak = 0, unused = 0;
  run(ci::BodyRegion::none, free_peak, unused, unused, unused);
  std::printf("off: flange peak %.3f m/s\n", free_peak);
  EXPECT_GE(free_peak, 1.5 * highest);
}
