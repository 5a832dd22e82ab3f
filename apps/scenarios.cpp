#include "scenarios.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <sstream>

#include "cartesian_impedance/config.hpp"
#include "cartesian_impedance/error.hpp"

namespace cartesian_impedance::scenarios {
namespace {

constexpr double kDt = 0.001;
constexpr double kForever = std::numeric_limits<double>::infinity();

// Breaks the runner's controllers on purpose (for tests of the tests): the hook replaces the
// torque they computed with what a broken controller would apply.
void set_mutation(sim::ClosedLoopRunner& runner, Mutation mutation) {
  switch (mutation) {
    case Mutation::none:
      runner.set_torque_hook({});
      break;
    case Mutation::zero_torque:
      runner.set_torque_hook([](JointVector& tau) { tau.setZero(); });
      break;
    case Mutation::flipped_sign:
      runner.set_torque_hook([](JointVector& tau) { tau = -tau; });
      break;
  }
}

Vector6d six(double a, double b, double c, double d, double e, double f) {
  return (Vector6d() << a, b, c, d, e, f).finished();
}

Result compare(const std::string& scenario, const std::string& quantity, double expected,
               double measured, const std::string& unit, double tolerance,
               const std::string& note = "") {
  Result result{scenario, quantity, expected, measured, unit, tolerance, false, false, note};
  result.passed = std::abs(measured - expected) <= tolerance;
  return result;
}

Result at_most(const std::string& scenario, const std::string& quantity, double bound,
               double measured, const std::string& unit, const std::string& note = "") {
  Result result{scenario, quantity, bound, measured, unit, 0.0, true, false, note};
  result.passed = measured <= bound;
  return result;
}

Result at_least(const std::string& scenario, const std::string& quantity, double bound,
                double measured, const std::string& unit, const std::string& note = "") {
  Result result{scenario, quantity, bound, measured, unit, 0.0, false, false, note};
  result.passed = measured >= bound;
  result.note = note.empty() ? "at least" : note;
  return result;
}

Eigen::Vector3d rotation_between(const Pose& from, const Pose& to) {
  return orientation_error(to.orientation, from.orientation);
}

void notify(const MomentCallback& moment, const std::string& label, Rig& rig) {
  if (moment) moment(label, rig.sim());
}

// The largest force and torque at the flange that the joints' Coulomb friction can hold at q:
// a spring pulling with less may leave the arm standing short of its rest position. A friction
// torque tau_f (|tau_f,i| <= f_i) holds the flange wrench F = (J J^T)^-1 J tau_f; the largest
// norms are at corners of the box of friction torques.
struct FrictionBand {
  double force = 0.0;   // [N]
  double torque = 0.0;  // [Nm]
};

FrictionBand friction_band(Rig& rig) {
  ModelWorkspace workspace(rig.model());
  Kinematics kinematics = workspace.make_kinematics();
  workspace.compute(rig.sim().q(), rig.sim().dq(), kinematics);
  const Eigen::MatrixXd jacobian = kinematics.jacobian;
  const Eigen::MatrixXd map = (jacobian * jacobian.transpose()).ldlt().solve(jacobian);
  const JointVector friction = rig.sim().friction_loss();
  const int n = static_cast<int>(friction.size());
  FrictionBand band;
  for (long corner = 0; corner < (1L << n); ++corner) {
    Eigen::VectorXd tau(n);
    for (int i = 0; i < n; ++i) tau[i] = (corner >> i & 1) ? friction[i] : -friction[i];
    const Vector6d wrench = map * tau;
    band.force = std::max(band.force, wrench.head<3>().norm());
    band.torque = std::max(band.torque, wrench.tail<3>().norm());
  }
  return band;
}

// ---- the scenarios ----------------------------------------------------------------------------

// 1. Hold: a payload the robot's firmware does not know about (1 kg at the flange) makes the
// spring sag by m g / K, and the arm then stays there. A dead controller would let it fall.
Outcome hold(const RobotSetup& robot, const MomentCallback& moment) {
  Rig rig(robot, base_parameters(robot));
  rig.run(0.5);
  const Pose reference = rig.loop().state().controller.filtered.pose;
  const double payload = 1.0;  // [kg]
  rig.push(Eigen::Vector3d(0.0, 0.0, -9.81 * payload));
  rig.run(3.0);
  const Pose loaded = rig.flange();
  rig.run(2.0);
  notify(moment, "holding a 1 kg payload", rig);
  const Pose end = rig.flange();
  const Parameters& parameters = rig.loop().controller().parameters();
  const double stiffness = parameters.stiffness.translation.z();
  const FrictionBand band = friction_band(rig);
  const double sag = 1e3 * (reference.position - end.position).z();
  return {
      {compare("hold", "sag under an unknown 1 kg payload (m g / K)",
               1e3 * 9.81 * payload / stiffness, sag, "mm", 1e3 * band.force / stiffness,
               "tolerance: what joint friction can hold"),
       at_most("hold", "sideways motion", 1.0 + 1e3 * band.force / stiffness,
               1e3 * (end.position - reference.position).head<2>().norm(), "mm"),
       at_most("hold", "rotation", 0.01 + band.torque / parameters.stiffness.rotation.minCoeff(),
               rotation_between(reference, end).norm(), "rad"),
       // MuJoCo's joint friction is a soft constraint: a joint it holds still creeps, by
       // about 0.1 mm/s at the flange a few seconds after a change.
       at_most("hold", "drift over the last 2 s", 0.5,
               1e3 * (end.position - loaded.position).norm(), "mm")},
      rig.samples()};
}

// Displacement and rotation of the flange caused by a constant push, from the spring's rest
// position (the reference). The joints' Coulomb friction stops the arm anywhere in a band around
// the spring's equilibrium; approaching it once from below (loading from rest) and once from
// above (unloading from a 1.5 times larger push) and averaging cancels that band, as in a
// hysteresis measurement. Measuring from the reference rather than from where the arm rested
// before keeps the band of that earlier rest out of the result too.
struct PushResponse {
  Eigen::Vector3d displacement;
  Eigen::Vector3d rotation;
};

PushResponse respond(Rig& rig, const Eigen::Vector3d& force, const Eigen::Vector3d& torque) {
  rig.release();
  rig.run(2.0);  // back at rest from whatever came before
  const Pose reference = rig.loop().state().controller.filtered.pose;
  rig.push(force, torque);
  rig.run(3.0);
  const Pose loaded = rig.flange();
  rig.push(1.5 * force, 1.5 * torque);
  rig.run(2.0);
  rig.push(force, torque);
  rig.run(3.0);
  const Pose unloaded = rig.flange();
  return {0.5 * ((loaded.position - reference.position) + (unloaded.position - reference.position)),
          0.5 * (rotation_between(reference, loaded) + rotation_between(reference, unloaded))};
}

// 2 and 3. Compliance: a force F against stiffness K settles at F / K, a torque at T / K_rot;
// doubling K halves the displacement.
Outcome compliance(const RobotSetup& robot, const MomentCallback& moment) {
  Parameters parameters = base_parameters(robot);
  parameters.stiffness.translation.setConstant(500.0);
  parameters.stiffness.rotation.setConstant(50.0);
  Rig rig(robot, parameters);
  Outcome outcome;
  const char* axes = "xyz";
  // Loads well above the joints' friction (0.1-0.2 Nm), which would otherwise hold the arm a
  // few per cent short of the spring's equilibrium.
  const double force = 20.0, torque = 5.0;
  for (int axis = 0; axis < 3; ++axis) {
    const Eigen::Vector3d direction = Eigen::Vector3d::Unit(axis);
    const double expected = 1e3 * force / parameters.stiffness.translation[axis];
    const double measured =
        1e3 * respond(rig, force * direction, Eigen::Vector3d::Zero()).displacement.dot(direction);
    if (axis == 0) notify(moment, "pushed 20 N along x", rig);
    outcome.results.push_back(
        compare("compliance", std::string("force along ") + axes[axis] + ": 20 N at 500 N/m",
                expected, measured, "mm", 0.05 * expected));
  }
  for (int axis = 0; axis < 3; ++axis) {
    const Eigen::Vector3d direction = Eigen::Vector3d::Unit(axis);
    const double expected = torque / parameters.stiffness.rotation[axis];
    const double measured =
        respond(rig, Eigen::Vector3d::Zero(), torque * direction).rotation.dot(direction);
    outcome.results.push_back(
        compare("compliance", std::string("torque about ") + axes[axis] + ": 5 Nm at 50 Nm/rad",
                expected, measured, "rad", 0.05 * expected));
  }
  // A sweep along x: displacement against force is a line of slope 1 / K.
  for (const double sweep : {5.0, 10.0, 15.0, 20.0}) {
    const double expected = 1e3 * sweep / parameters.stiffness.translation.x();
    const double measured =
        1e3 * respond(rig, Eigen::Vector3d(sweep, 0, 0), Eigen::Vector3d::Zero()).displacement.x();
    char quantity[64];
    std::snprintf(quantity, sizeof(quantity), "displacement along x under %.0f N", sweep);
    outcome.results.push_back(
        compare("compliance sweep", quantity, expected, measured, "mm", 0.05 * expected));
  }
  // Doubling K online (filtered) halves the displacement under the same push.
  const double soft =
      respond(rig, Eigen::Vector3d(force, 0, 0), Eigen::Vector3d::Zero()).displacement.x();
  rig.loop().set_stiffness(six(1000, 500, 500, 50, 50, 50));
  const double stiff =
      respond(rig, Eigen::Vector3d(force, 0, 0), Eigen::Vector3d::Zero()).displacement.x();
  notify(moment, "stiffness doubled", rig);
  rig.release();
  outcome.results.push_back(compare("stiffness change", "displacement at 1000 N/m / at 500 N/m",
                                    0.5, stiff / soft, "", 0.05 * 0.5));
  outcome.samples = rig.samples();
  return outcome;
}

// 4. Reference step: reaches a new pose without exceeding the torque-rate limit, and with a
// damping ratio of 1 (critical damping of the end effector's own mass) without overshoot.
Outcome reference_step(const RobotSetup& robot, const MomentCallback& moment) {
  Parameters parameters = base_parameters(robot);
  parameters.damping_ratio.translation.setOnes();
  parameters.damping_ratio.rotation.setOnes();
  Rig rig(robot, parameters);
  rig.run(0.2);
  const Pose start = rig.flange();
  Pose target = start;
  const Eigen::Vector3d step(0.10, 0.05, -0.05);
  target.position += step;
  target.orientation =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())) * start.orientation;
  rig.loop().set_reference_pose(target);
  // Overshoot: how far the flange goes past the target along the step, and past the target
  // orientation about the turn's axis.
  double overshoot = -kForever, turn_overshoot = -kForever;
  for (int k = 0; k < 400; ++k) {
    rig.run(0.01);
    const Pose now = rig.flange();
    overshoot = std::max(overshoot, (now.position - target.position).dot(step.normalized()));
    turn_overshoot =
        std::max(turn_overshoot, orientation_error(now.orientation, target.orientation).z());
  }
  notify(moment, "reached the new reference", rig);
  const Pose end = rig.flange();
  return {{at_most("reference step", "position error after 4 s (step of 122 mm)", 2.0,
                   1e3 * (end.position - target.position).norm(), "mm"),
           at_most("reference step", "orientation error after 4 s (step of 0.3 rad)", 0.01,
                   rotation_between(target, end).norm(), "rad"),
           // Zero for a linear critically damped system; 1 % of the step for an arm that is not
           // linear (the task-space inertia changes along the way).
           at_most("reference step", "overshoot along the step at damping ratio 1", 1.0,
                   1e3 * std::max(overshoot, 0.0), "mm"),
           at_most("reference step", "overshoot of the turn at damping ratio 1", 0.003,
                   std::max(turn_overshoot, 0.0), "rad"),
           at_most("reference step", "largest torque rate / limit", 1.0 + 1e-9,
                   rig.largest_rate_fraction(), "")},
          rig.samples()};
}

// 5. Wrench: with the vertical stiffness released, a commanded downward force presses on a table
// with exactly that force.
Outcome wrench_on_table(const RobotSetup& robot, const MomentCallback& moment) {
  Parameters parameters = base_parameters(robot);
  Rig probe(robot, parameters);
  const Pose flange = probe.flange();
  // A table whose top is 3 cm under the flange.
  const sim::Box table = sim::Box::table(flange.position.head<2>(), Eigen::Vector2d(0.15, 0.15),
                                         flange.position.z() - 0.03, "table");
  Rig rig(robot, parameters, {table});
  rig.run(0.2);
  rig.loop().set_stiffness(six(parameters.stiffness.translation.x(),
                               parameters.stiffness.translation.y(), 0.0,
                               parameters.stiffness.rotation.x(), parameters.stiffness.rotation.y(),
                               parameters.stiffness.rotation.z()));
  const double force = 10.0;
  rig.loop().set_wrench(six(0, 0, -force, 0, 0, 0));
  rig.run(3.0);
  notify(moment, "pressing on the table", rig);
  double average = 0.0;
  for (int k = 0; k < 100; ++k) {
    rig.run(0.005);
    average += rig.contact_force().z() / 100.0;
  }
  return {{compare("wrench", "contact force under a commanded 10 N", force, average, "N",
                   0.05 * force)},
          rig.samples()};
}

// 6. Nullspace: moving the nullspace target moves the elbow while the end effector stays.
Outcome nullspace(const RobotSetup& robot, const MomentCallback& moment) {
  Parameters parameters = base_parameters(robot);
  parameters.stiffness.translation.setConstant(1500.0);
  parameters.stiffness.rotation.setConstant(150.0);
  parameters.nullspace.stiffness = JointVector::Constant(1, 10.0);
  parameters.filter.nullspace.time = 1.0;
  Rig rig(robot, parameters);
  rig.run(0.2);
  const Pose start = rig.flange();
  const JointVector q_start = rig.sim().q();
  JointVector target = q_start;
  // The first joint turns the arm about the vertical, the third joint (both robots' elbow
  // rotation) counters it: a self-motion that keeps the flange where it is.
  target[0] += 0.3;
  target[2] -= 0.3;
  rig.loop().set_nullspace_target(target);
  double worst = 0.0;
  for (int k = 0; k < 400; ++k) {
    rig.run(0.01);
    worst = std::max(worst, (rig.flange().position - start.position).norm());
  }
  notify(moment, "elbow moved", rig);
  const double elbow = (rig.sim().q() - q_start).norm();
  return {
      {at_most("nullspace", "largest end-effector motion while the elbow moves", 2.0, 1e3 * worst,
               "mm"),
       at_least("nullspace", "joint motion toward the new nullspace target", 0.1, elbow, "rad")},
      rig.samples()};
}

// 7. Teaching: with zero stiffness a push moves the end effector, which stops soon after the
// release and stays where it was left. With only the damping floor d acting, the push cannot
// move the flange faster than F / d, and after the release it coasts D^-1 Lambda v (v its twist,
// Lambda the task-space inertia, D = diag(d, d, d, d_rot, d_rot, d_rot)), less what friction
// takes.
Outcome teaching(const RobotSetup& robot, const MomentCallback& moment) {
  Rig rig(robot, base_parameters(robot));
  rig.loop().start_teaching();
  rig.run(1.0);
  const Pose start = rig.flange();
  const double force = 10.0, duration = 0.3;  // a hand's gentle push
  rig.push(Eigen::Vector3d(0, force, 0));
  rig.run(duration);
  rig.release();
  const Pose released = rig.flange();
  const Parameters& parameters = rig.loop().controller().parameters();
  // The linear prediction of the coast, from the state at the release.
  ModelWorkspace workspace(rig.model());
  Kinematics kinematics = workspace.make_kinematics();
  workspace.compute(rig.sim().q(), rig.sim().dq(), kinematics, true);
  JointMatrix mass = kinematics.mass;
  mass.diagonal() += per_joint(parameters.dynamics.armature, rig.model().num_joints());
  Matrix6d inertia;
  task_space_inertia(kinematics.jacobian, mass, 0.0, inertia);
  const Vector6d twist = kinematics.jacobian * rig.sim().dq();
  Vector6d damping_inverse;
  damping_inverse << Eigen::Vector3d::Constant(1.0 / parameters.minimum_damping.translation),
      Eigen::Vector3d::Constant(1.0 / parameters.minimum_damping.rotation);
  const double predicted_coast =
      1e3 * (damping_inverse.asDiagonal() * (inertia * twist)).head<3>().norm();
  rig.run(3.0);
  const Pose rest = rig.flange();
  rig.run(1.0);
  notify(moment, "left where it was pushed", rig);
  const double pushed = 1e3 * (released.position - start.position).norm();
  const double coast = 1e3 * (rest.position - released.position).norm();
  const double final_distance = 1e3 * (rest.position - start.position).norm();
  char limit[96];
  std::snprintf(limit, sizeof(limit),
                "distance the push moved the flange (at most F t / d = %.0f mm)",
                1e3 * force * duration / parameters.minimum_damping.translation);
  return {{at_least("teaching", "distance the push moved the flange", 20.0, pushed, "mm"),
           at_most("teaching", limit,
                   1e3 * force * duration / parameters.minimum_damping.translation, pushed, "mm"),
           at_most("teaching", "coast after the release (at most D^-1 Lambda v)",
                   1.1 * predicted_coast + 1.0, coast, "mm",
                   "10 % + 1 mm for the model's inertia against the simulation's"),
           at_least("teaching", "distance from the start after release (no spring back)", pushed,
                    final_distance, "mm", "at least the pushed distance"),
           at_most("teaching", "drift in the last second", 0.5,
                   1e3 * (rig.flange().position - rest.position).norm(), "mm")},
          rig.samples()};
}

// 8. Trajectory: tracked, and reported finished only once the robot is there.
Outcome trajectory(const RobotSetup& robot, const MomentCallback& moment) {
  Parameters parameters = base_parameters(robot);
  parameters.stiffness.translation.setConstant(1500.0);
  parameters.stiffness.rotation.setConstant(150.0);
  // The redundant joint is held by the nullspace spring alone: against 0.1-0.2 Nm of joint
  // friction, 50 Nm/rad keeps it within a few mrad of the goal.
  parameters.nullspace.stiffness = JointVector::Constant(1, 50.0);
  Rig rig(robot, parameters);
  rig.run(0.2);
  const JointVector start = rig.sim().q();
  JointVector goal = start;
  const JointVector offsets = (JointVector(7) << 0.4, 0.2, -0.3, 0.3, 0.3, -0.3, 0.5).finished();
  for (int i = 0; i < goal.size() && i < offsets.size(); ++i) goal[i] += offsets[i];
  JointTrajectory trajectory;
  trajectory.joint_names = rig.model().joint_names();
  const int points = 30;
  for (int k = 1; k <= points; ++k) {
    const double s = static_cast<double>(k) / points;
    const JointVector q = start + (0.5 - 0.5 * std::cos(M_PI * s)) * (goal - start);
    trajectory.times.push_back(3.0 * s);
    trajectory.positions.emplace_back(q.data(), q.data() + q.size());
  }
  rig.loop().execute_trajectory(trajectory);
  const double tolerance = parameters.trajectory.goal_tolerance;
  double error_when_finished = -1.0, finish_time = -1.0, worst_tracking = 0.0;
  for (int k = 0; k < 600 && error_when_finished < 0.0; ++k) {
    rig.run(0.01);
    const LoopState& state = rig.loop().state();
    if (state.trajectory.state == TrajectoryState::executing) {
      worst_tracking = std::max(worst_tracking, state.controller.pose_error.head<3>().norm());
    }
    if (state.trajectory.state == TrajectoryState::finished) {
      error_when_finished = (rig.sim().q() - goal).cwiseAbs().maxCoeff();
      finish_time = state.trajectory.time;
    }
  }
  notify(moment, "trajectory finished", rig);
  return {{at_least("trajectory", "reported finished (1 = yes)", 1.0,
                    error_when_finished >= 0.0 ? 1.0 : 0.0, ""),
           at_most("trajectory", "largest joint error when reported finished", tolerance,
                   error_when_finished < 0.0 ? 1e9 : error_when_finished, "rad"),
           at_least("trajectory", "time of the report (the last point is at 3 s)", 3.0, finish_time,
                    "s"),
           at_most("trajectory", "largest Cartesian tracking error while moving", 20.0,
                   1e3 * worst_tracking, "mm")},
          rig.samples()};
}

// 9. Stability grid: every combination converges after a reference step, and the energy of the
// closed loop (kinetic + spring) never exceeds what the step put in.
Outcome stability_grid(const RobotSetup& robot, const MomentCallback&) {
  Outcome outcome;
  const double translations[] = {100, 300, 1000, 3000};
  const double rotations[] = {10, 30, 100, 300};
  int stable = 0, total = 0;
  std::ostringstream failures;
  for (double kt : translations) {
    for (double kr : rotations) {
      Parameters parameters = base_parameters(robot);
      parameters.stiffness.translation.setConstant(kt);
      parameters.stiffness.rotation.setConstant(kr);
      parameters.filter.pose.time = 0.0;  // a true step: the spring energy is known at once
      parameters.limits.pose_error = {1.0, 1.0};
      Rig rig(robot, parameters);
      rig.run(0.1);
      const Pose start = rig.flange();
      Pose target = start;
      target.position.x() += 0.03;
      target.orientation =
          Eigen::Quaterniond(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitY())) * start.orientation;
      rig.loop().set_reference_pose(target);
      ModelWorkspace workspace(rig.model());
      Kinematics kinematics = workspace.make_kinematics();
      double initial = -1.0, peak = 0.0;
      for (int k = 0; k < 2500; ++k) {
        rig.run(0.001);
        const LoopState& state = rig.loop().state();
        const Vector6d& e = state.controller.pose_error;
        const JointVector& dq = rig.sim().dq();
        workspace.compute(rig.sim().q(), dq, kinematics, true);
        const double kinetic = 0.5 * dq.dot(kinematics.mass * dq);
        const double spring =
            0.5 * (kt * e.head<3>().squaredNorm() + kr * e.tail<3>().squaredNorm());
        if (initial < 0.0) initial = spring + kinetic;
        peak = std::max(peak, spring + kinetic);
      }
      const double error = 1e3 * (rig.flange().position - target.position).norm();
      const double angle = rotation_between(target, rig.flange()).norm();
      // Converged: within 2 mm and 0.01 rad plus what the joints' friction can hold against the
      // spring; and the energy never above what the step put in (+5 %): a passive, stable
      // closed loop.
      const FrictionBand band = friction_band(rig);
      const bool ok = error <= 2.0 + 1e3 * band.force / kt && angle <= 0.01 + band.torque / kr &&
                      peak <= 1.05 * initial;
      ++total;
      if (ok) {
        ++stable;
      } else {
        failures << " K=" << kt << "/" << kr << " (error " << error << " mm, " << angle
                 << " rad, energy x" << peak / initial << ")";
      }
    }
  }
  outcome.results.push_back(compare("stability grid",
                                    "combinations of 100..3000 N/m x 10..300 Nm/rad that converge",
                                    total, stable, "", 0.0, failures.str()));
  return outcome;
}

// 9b. Convergence at the shipped limits: random reachable references at the largest stiffness
// the configuration allows, with its torque-rate limit, each settle. (A rate limiter that scaled
// the whole torque change let 6 and 10 of 60 such steps oscillate for good on the Panda and the
// iiwa; the 4 x 4 grid above did not catch it.) Each reference is the flange pose of a random
// configuration near the start, which is also the nullspace target, so that the arm is asked to
// go somewhere it can reach without crossing a joint limit.
Outcome convergence(const RobotSetup& robot, const MomentCallback&) {
  Parameters parameters = base_parameters(robot);
  parameters.stiffness.translation.setConstant(parameters.limits.stiffness.translation.max);
  parameters.stiffness.rotation.setConstant(parameters.limits.stiffness.rotation.max);
  const int cases = 60;
  std::mt19937 rng(20261123);
  std::uniform_real_distribution<double> offset(-0.3, 0.3);
  int settled = 0;
  double fastest_late = 0.0;
  std::ostringstream failures;
  for (int c = 0; c < cases; ++c) {
    Rig rig(robot, parameters);
    const JointLimits& limits = rig.model().limits();
    JointVector q_target = rig.sim().q();
    for (int i = 0; i < q_target.size(); ++i) {
      const double low = std::max(limits.position_lower[i] + 0.2, -kForever);
      const double high = std::min(limits.position_upper[i] - 0.2, kForever);
      q_target[i] = std::clamp(q_target[i] + offset(rng), low, high);
    }
    ModelWorkspace workspace(rig.model());
    Pose target;
    workspace.compute_pose(q_target, target);
    rig.loop().set_reference_pose(target);
    rig.loop().set_nullspace_target(q_target);
    rig.run(7.0);
    double fastest = 0.0;
    bool limited = false;
    for (int k = 0; k < 100; ++k) {
      rig.run(0.01);
      fastest = std::max(fastest, rig.sim().dq().cwiseAbs().maxCoeff());
      limited |= rig.loop().state().controller.limits.torque_rate_limited;
    }
    fastest_late = std::max(fastest_late, fastest);
    const FrictionBand band = friction_band(rig);
    const double error = (rig.flange().position - target.position).norm();
    const double angle = rotation_between(target, rig.flange()).norm();
    const bool ok = fastest <= 0.01 && !limited &&
                    error <= 0.002 + band.force / parameters.stiffness.translation.x() &&
                    angle <= 0.01 + band.torque / parameters.stiffness.rotation.x();
    if (ok) {
      ++settled;
    } else {
      failures << " #" << c << " (error " << 1e3 * error << " mm, " << angle << " rad, |dq| "
               << fastest << " rad/s" << (limited ? ", rate-limited" : "") << ")";
    }
  }
  char quantity[128];
  std::snprintf(quantity, sizeof(quantity),
                "random reachable references that settle within 8 s at %.0f N/m, %.0f Nm/rad",
                parameters.stiffness.translation.x(), parameters.stiffness.rotation.x());
  return {{compare("convergence", quantity, cases, settled, "", 0.0, failures.str()),
           at_most("convergence", "largest joint speed in each run's last second", 0.01,
                   fastest_late, "rad/s")},
          {}};
}

// 10. Two arms in one scene, each with its own controller: pushing one does not move the other.
// The arms share nothing but the simulation, so "does not move" is checked exactly: against a
// twin run of the same scene without the push (or without the step), the other arm's path must
// be the same to a micrometre (MuJoCo solves the joints' friction of both arms together, which
// may round differently).
struct TwoArmRun {
  Pose left_start, right_start;    // before the push
  Pose left_pushed, right_pushed;  // 3 s into the push (or the same time without it)
  Pose left_rest, right_rest;      // 3 s after the release
  Pose left_end, right_end;        // 3 s after the right arm's reference step (if any)
};

TwoArmRun run_two_arms(bool push_left, bool step_right, Mutation mutation,
                       const MomentCallback& moment) {
  const std::string source = CARTESIAN_IMPEDANCE_SOURCE_DIR;
  RobotSetup left = builtin_robot("panda", source);
  RobotSetup right = builtin_robot("iiwa14", source);
  left.flange = "panda_flange";  // site names in the two-arm scene (models/scenes)
  right.flange = "iiwa_flange";
  const RobotModel left_model =
      RobotModel::from_urdf_file(left.urdf, left.base_link, left.tip_link);
  const RobotModel right_model =
      RobotModel::from_urdf_file(right.urdf, right.base_link, right.tip_link);
  sim::SimulationOptions options;
  options.joint_names = left_model.joint_names();
  options.joint_names.insert(options.joint_names.end(), right_model.joint_names().begin(),
                             right_model.joint_names().end());
  sim::Simulation sim =
      sim::Simulation::from_mjcf_file(source + "/models/scenes/two_arms.xml", options);
  ControlLoop left_loop(left_model, base_parameters(left));
  ControlLoop right_loop(right_model, base_parameters(right));
  // Each loop drives its own arm: the first seven joints of the scene, and the next seven.
  sim::ClosedLoopRunner runner(sim, {&left_loop, &right_loop});
  set_mutation(runner, mutation);
  runner.start();
  TwoArmRun result;
  runner.run_for(0.5);
  result.left_start = sim.site_pose(left.flange);
  result.right_start = sim.site_pose(right.flange);
  if (push_left) sim.push(left.flange, six(0, 20, 0, 0, 0, 0), kForever);
  runner.run_for(3.0);
  if (moment) moment("left arm pushed, right arm holding", sim);
  result.left_pushed = sim.site_pose(left.flange);
  result.right_pushed = sim.site_pose(right.flange);
  sim.clear_pushes();
  runner.run_for(3.0);
  result.left_rest = sim.site_pose(left.flange);
  result.right_rest = sim.site_pose(right.flange);
  if (step_right) {
    Pose right_target = right_loop.state().controller.pose;
    right_target.position.z() -= 0.05;
    right_loop.set_reference_pose(right_target);
  }
  runner.run_for(3.0);
  result.left_end = sim.site_pose(left.flange);
  result.right_end = sim.site_pose(right.flange);
  return result;
}

Outcome two_arms(const RobotSetup& robot, const MomentCallback& moment) {
  // The mutation of `robot` (tests of the tests) applies to both arms.
  const TwoArmRun both = run_two_arms(true, true, robot.mutation, moment);
  const TwoArmRun push_only = run_two_arms(true, false, robot.mutation, {});
  const TwoArmRun neither = run_two_arms(false, false, robot.mutation, {});
  const double left_moved = (both.left_pushed.position - both.left_start.position).y();
  const double right_step = (both.right_end.position - both.right_rest.position).z();
  const double right_difference =
      (both.right_pushed.position - neither.right_pushed.position).norm();
  const double left_difference = (both.left_end.position - push_only.left_end.position).norm();
  return {{compare("two arms", "left arm (Panda) displacement under 20 N at 500 N/m", 40.0,
                   1e3 * left_moved, "mm", 0.05 * 40.0),
           at_most("two arms", "right arm (iiwa14): difference to a run without the push", 1e-3,
                   1e3 * right_difference, "mm"),
           compare("two arms", "right arm reference step down", -50.0, 1e3 * right_step, "mm", 2.0),
           at_most("two arms", "left arm: difference to a run without the step", 1e-3,
                   1e3 * left_difference, "mm")},
          {}};
}

}  // namespace

// ---- Rig ----------------------------------------------------------------------------------------

RobotSetup builtin_robot(const std::string& name, const std::string& source_dir) {
  if (name == "panda") {
    return {"panda",
            source_dir + "/models/panda/panda.urdf",
            source_dir + "/models/panda/panda.xml",
            "panda_link0",
            "panda_link8",
            "flange",
            source_dir + "/config/panda.yaml"};
  }
  if (name == "iiwa14") {
    return {"iiwa14",
            source_dir + "/models/iiwa14/iiwa14.urdf",
            source_dir + "/models/iiwa14/iiwa14.xml",
            "iiwa_link_0",
            "iiwa_link_ee",
            "flange",
            source_dir + "/config/iiwa14.yaml"};
  }
  throw Error("robot '" + name + "' is not built in (panda, iiwa14); give --urdf for your own");
}

Parameters base_parameters(const RobotSetup& robot) {
  return robot.parameters_file.empty() ? Parameters{} : load_parameters(robot.parameters_file);
}

namespace {
sim::Simulation make_simulation(const RobotSetup& robot, const RobotModel& model,
                                const std::vector<sim::Box>& boxes) {
  sim::SimulationOptions options;
  options.joint_names = model.joint_names();
  if (boxes.empty()) {
    return robot.mjcf.empty() ? sim::Simulation::from_urdf_file(robot.urdf, options)
                              : sim::Simulation::from_mjcf_file(robot.mjcf, options);
  }
  return sim::make_scene(robot.mjcf.empty() ? robot.urdf : robot.mjcf, boxes, options);
}
}  // namespace

Rig::Rig(const RobotSetup& robot, const Parameters& parameters, const std::vector<sim::Box>& boxes)
    : robot_(robot),
      model_(RobotModel::from_urdf_file(robot.urdf, robot.base_link, robot.tip_link)),
      sim_(make_simulation(robot, model_, boxes)),
      loop_(std::make_unique<ControlLoop>(model_, parameters)),
      runner_(sim_, *loop_) {
  // The tip is a site in the project's MJCF files; a robot simulated from its URDF has only
  // bodies, named like its links.
  try {
    sim_.site_pose(robot_.flange);
  } catch (const Error&) {
    flange_is_site_ = false;
    sim_.body_pose(robot_.flange);  // throws, naming it, if it is neither
  }
  set_mutation(runner_, robot_.mutation);
  runner_.start();
  previous_tau_ = JointVector::Zero(model_.num_joints());
}

Pose Rig::flange() const {
  const Pose base = sim_.body_pose(robot_.base_link);
  const Pose tip = flange_is_site_ ? sim_.site_pose(robot_.flange) : sim_.body_pose(robot_.flange);
  const Eigen::Quaterniond to_base = base.orientation.conjugate();
  return Pose{to_base * (tip.position - base.position), to_base * tip.orientation};
}

Eigen::Vector3d Rig::contact_force() const {
  return sim_.contact_wrench(robot_.tip_link).head<3>();
}

void Rig::push(const Eigen::Vector3d& force, const Eigen::Vector3d& torque) {
  sim_.clear_pushes();
  Vector6d wrench;
  wrench << force, torque;
  sim_.push(robot_.flange, wrench, kForever);
  push_force_ = force;
}

void Rig::release() {
  sim_.clear_pushes();
  push_force_.setZero();
}

void Rig::run(double seconds) {
  const Parameters& parameters = loop_->controller().parameters();
  const JointVector rate_limit =
      per_joint(parameters.limits.joint_torque_rate, model_.num_joints());
  runner_.run_for(seconds, [&](std::int64_t) {
    const JointVector& tau = runner_.torque();
    const JointVector rate = (tau - previous_tau_).cwiseAbs() / kDt;
    largest_rate_fraction_ =
        std::max(largest_rate_fraction_, rate.cwiseQuotient(rate_limit).maxCoeff());
    rate_since_sample_ = std::max(rate_since_sample_, rate.maxCoeff());
    previous_tau_ = tau;
    time_ += kDt;
    if (++steps_ % 10 == 0) {
      const LoopState& state = loop_->state();
      Sample sample;
      sample.time = time_;
      sample.position = flange().position;
      sample.reference = state.controller.filtered.pose.position;
      sample.commanded = state.controller.commanded.pose.position;
      sample.pose_error = state.controller.pose_error;
      sample.stiffness_x = state.controller.filtered.stiffness(0, 0);
      sample.commanded_stiffness_x = state.controller.commanded.stiffness(0, 0);
      sample.push = push_force_;
      sample.contact = contact_force();
      sample.wrench = state.controller.wrench_base.head<3>();
      sample.tau = tau;
      sample.max_torque_rate = rate_since_sample_;
      rate_since_sample_ = 0.0;
      samples_.push_back(sample);
    }
  });
}

// ---- registry -----------------------------------------------------------------------------------

namespace {
using Scenario = Outcome (*)(const RobotSetup&, const MomentCallback&);
const std::vector<std::pair<std::string, Scenario>>& registry() {
  static const std::vector<std::pair<std::string, Scenario>> scenarios = {
      {"hold", hold},
      {"compliance", compliance},
      {"reference_step", reference_step},
      {"wrench", wrench_on_table},
      {"nullspace", nullspace},
      {"teaching", teaching},
      {"trajectory", trajectory},
      {"stability_grid", stability_grid},
      {"convergence", convergence},
      {"two_arms", two_arms},
  };
  return scenarios;
}
}  // namespace

const std::vector<std::string>& scenario_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> list;
    for (const auto& [name, scenario] : registry()) list.push_back(name);
    return list;
  }();
  return names;
}

Outcome run_scenario(const std::string& name, const RobotSetup& robot,
                     const MomentCallback& moment) {
  for (const auto& [known, scenario] : registry()) {
    if (known == name) return scenario(robot, moment);
  }
  std::string names;
  for (const std::string& known : scenario_names()) names += (names.empty() ? "" : ", ") + known;
  throw Error("unknown scenario '" + name + "' (valid: " + names + ")");
}

}  // namespace cartesian_impedance::scenarios
