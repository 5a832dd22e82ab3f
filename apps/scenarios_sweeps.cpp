#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <random>
#include <sstream>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "scenario_support.hpp"

namespace cartesian_impedance::scenarios::detail {

// 8. Trajectory: tracked, and reported finished only once the robot is there.
Outcome trajectory(const RobotSetup& robot, const MomentCallback& moment) {
  Parameters parameters = base_parameters(robot);
  // The redundant joint is held by the nullspace spring alone: against 0.1-0.2 Nm of joint
  // friction, 50 Nm/rad keeps it within a few mrad of the goal.
  set_stiffness_within_limits(parameters, 1500.0, 150.0, 50.0);
  {
    // The joints' friction tau_f can hold each joint short of the goal by up to
    // (J^T K J + N^T K_n N)^-1 tau_f (the springs the law puts on the joints: the Cartesian one
    // through J, the nullspace one through the projector N), largest at a corner of the box of
    // friction torques. Where that is more than the configured goal tolerance (an arm whose
    // limits.stiffness keeps the spring soft) the trajectory could never be reported finished:
    // the scenario then allows twice it.
    Rig probe(robot, parameters);
    const Eigen::MatrixXd jacobian = jacobian_now(probe);
    const int n = probe.model().num_joints();
    Vector6d k;
    k << parameters.stiffness.translation, parameters.stiffness.rotation;
    const Eigen::MatrixXd projector =
        Eigen::MatrixXd::Identity(n, n) -
        Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(jacobian).pseudoInverse() *
            jacobian;
    const Eigen::MatrixXd joint_stiffness =
        jacobian.transpose() * k.asDiagonal() * jacobian +
        projector.transpose() * per_joint(parameters.nullspace.stiffness, n).asDiagonal() *
            projector;
    const Eigen::MatrixXd compliance =
        Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(joint_stiffness).pseudoInverse();
    const JointVector friction = probe.sim().friction_loss();
    double held = 0.0;
    for (long corner = 0; corner < (1L << n); ++corner) {
      Eigen::VectorXd tau(n);
      for (int i = 0; i < n; ++i) tau[i] = (corner >> i & 1) ? friction[i] : -friction[i];
      held = std::max(held, (compliance * tau).cwiseAbs().maxCoeff());
    }
    parameters.trajectory.goal_tolerance =
        std::min(1.0, std::max(parameters.trajectory.goal_tolerance, 2.0 * held));
  }
  Rig rig(robot, parameters);
  rig.run(0.2);
  const JointVector start = rig.sim().true_q();
  // Every joint moves 0.2-0.5 rad; one that would come within 0.2 rad of a limit goes the other
  // way, and one that has no room either way moves as far as it can.
  JointVector goal = start;
  const double offsets[] = {0.4, 0.2, -0.3, 0.3, 0.3, -0.3, 0.5};
  const JointLimits& limits = rig.model().limits();
  for (int i = 0; i < goal.size(); ++i) {
    const double offset = offsets[i % 7], low = limits.position_lower[i] + 0.2,
                 high = limits.position_upper[i] - 0.2;
    goal[i] = start[i] + offset;
    if (goal[i] < low || goal[i] > high) goal[i] = start[i] - offset;
    goal[i] = std::clamp(goal[i], std::min(low, start[i]), std::max(high, start[i]));
  }
  // 3 s as tuned, or longer where a joint would pass half its URDF velocity limit: the cosine
  // profile's peak speed is pi / 2 x the joint's motion / the duration. Half leaves the other
  // half for the impedance's tracking error, and keeps the accelerations (pi^2 / 2 x the motion /
  // the duration squared, at most 0.3 rad/s^2 in 3 s) to small torques.
  double duration = 3.0;
  for (int i = 0; i < goal.size(); ++i) {
    duration =
        std::max(duration, 0.5 * M_PI * std::abs(goal[i] - start[i]) / (0.5 * limits.velocity[i]));
  }
  JointTrajectory trajectory;
  trajectory.joint_names = rig.model().joint_names();
  const int points = 30;
  for (int k = 1; k <= points; ++k) {
    const double s = static_cast<double>(k) / points;
    const JointVector q = start + (0.5 - 0.5 * std::cos(M_PI * s)) * (goal - start);
    trajectory.times.push_back(duration * s);
    trajectory.positions.emplace_back(q.data(), q.data() + q.size());
  }
  rig.remember_pose("at the start");
  rig.phase(format("joint trajectory of %.3g s", duration));
  rig.loop().execute_trajectory(trajectory);
  const double tolerance = parameters.trajectory.goal_tolerance;
  double error_when_finished = -1.0, finish_time = -1.0, worst_tracking = 0.0;
  for (int k = 0; k < static_cast<int>(100 * (duration + 3.0)) && error_when_finished < 0.0; ++k) {
    rig.run(0.01);
    const LoopState& state = rig.loop().state();
    if (state.trajectory.state == TrajectoryState::executing) {
      worst_tracking = std::max(worst_tracking, state.controller.pose_error.head<3>().norm());
    }
    if (state.trajectory.state == TrajectoryState::finished) {
      error_when_finished = (rig.sim().true_q() - goal).cwiseAbs().maxCoeff();
      finish_time = state.trajectory.time;
    }
  }
  notify(moment, "trajectory finished", rig,
         {format("every joint moved 0.2-0.5 rad in %.3g s; reported finished %.2f s after its "
                 "start, the largest joint error then %.4f rad",
                 duration, finish_time, error_when_finished)});
  return {
      {at_least("trajectory", "reported finished (1 = yes)", 1.0,
                error_when_finished >= 0.0 ? 1.0 : 0.0, ""),
       at_most("trajectory", "largest joint error when reported finished", tolerance,
               error_when_finished < 0.0 ? 1e9 : error_when_finished, "rad"),
       at_least("trajectory", format("time of the report (the last point is at %.3g s)", duration),
                duration, finish_time, "s"),
       at_most("trajectory", "largest Cartesian tracking error while moving", 20.0,
               1e3 * worst_tracking, "mm")},
      rig.samples(),
      overrides(robot, parameters)};
}

// 9. Stability grid: every combination converges after a reference step, and the energy of the
// closed loop (kinetic + spring) never exceeds what the step put in.
Outcome stability_grid(const RobotSetup& robot, const MomentCallback&) {
  Outcome outcome;
  // Four stiffnesses a factor of about 3 apart, up to the largest limits.stiffness allows (the
  // Panda's 3000 N/m: 100, 300, 1000, 3000), from the parameters in force rather than numbers
  // that one arm's limits would saturate.
  const Parameters configured = base_parameters(robot);
  const double top = configured.limits.stiffness.translation.max;
  const double top_rotation = configured.limits.stiffness.rotation.max;
  const double shares[] = {1.0 / 30.0, 0.1, 1.0 / 3.0, 1.0};
  double translations[4], rotations[4];
  for (int i = 0; i < 4; ++i) {
    translations[i] = std::max(shares[i] * top, configured.limits.stiffness.translation.min);
    rotations[i] = std::max(shares[i] * top_rotation, configured.limits.stiffness.rotation.min);
  }
  int stable = 0, total = 0;
  bool saturated = false;
  std::ostringstream failures;
  Table grid{"grid",
             {"translation_stiffness", "rotation_stiffness", "converged", "error_mm", "error_rad",
              "energy_ratio", "torque_limited"},
             {}};
  for (double kt : translations) {
    for (double kr : rotations) {
      Parameters parameters = base_parameters(robot);
      parameters.stiffness.translation.setConstant(kt);
      parameters.stiffness.rotation.setConstant(kr);
      // A true step: the spring energy is known at once (the speed cap would ramp the reference,
      // feeding the energy in over the ramp).
      parameters.filter.pose.time = 0.0;
      parameters.safety.max_speed = {0.0, 0.0};
      parameters.limits.pose_error = {1.0, 1.0};
      // Nor ramped by the speed cap (the shipped configurations' 1 m/s made every step a ramp
      // whose start held a few thousandths of the energy the grid compares with: 0 of 16).
      parameters.safety.max_speed = MaxSpeedParameters{};
      Rig rig(robot, parameters);
      // 3 cm along x and 0.05 rad about y, or along and about directions the arm can move in;
      // the step at most 5 % of the flange's distance from the base, and both halved until the
      // joints get there (to first order) 0.1 rad inside their limits.
      const TaskDirections directions = task_directions(rig);
      const int along = directions.first_of({0, 2, 1});
      const int about = directions.first_of({4, 5, 3});
      const Capacity can = capacity(rig);
      Vector6d twist = Vector6d::Zero();
      if (along >= 0) twist[along] = std::min(0.03, 0.05 * can.reach);
      if (about >= 0) twist[about] = 0.05;
      twist *= can.fraction_within_limits(twist, 0.1);
      rig.run(0.1);
      const Pose start = rig.flange();
      Pose target = start;
      target.position += twist.head<3>();
      if (about >= 0) {
        target.orientation =
            Eigen::Quaterniond(Eigen::AngleAxisd(twist[about], Eigen::Vector3d::Unit(about - 3))) *
            start.orientation;
      }
      rig.loop().set_reference_pose(target);
      ModelWorkspace workspace(rig.model());
      Kinematics kinematics = workspace.make_kinematics();
      const JointVector armature = per_joint(rig.loop().controller().parameters().dynamics.armature,
                                             rig.model().num_joints());
      // Energy balance: E(t) = E(0) - dissipated + W(t), where W is the work the torque limits
      // did, integral of (tau - tau_law)^T dq dt, tau_law the law's torque before the joint
      // torque and rate limits. A passive closed loop never has E - W above E(0); a limited torque
      // is no longer the spring's gradient and may feed energy in, which W accounts for. The
      // spring is the stiffness the law used: the configured limits.stiffness saturate the grid's
      // (the planar arm's rotation at 50 Nm/rad).
      double initial = -1.0, peak = 0.0, limit_work = 0.0;
      Matrix6d stiffness = Matrix6d::Zero();
      bool limited = false;
      JointVector dq_before = rig.sim().true_dq();
      // 2.5 s, or 6 time constants d / K of the minimum damping against the spring where that
      // is longer (a soft grid point is overdamped by it: e^-6 leaves 0.25 % of the step). The
      // joints' own damping (the simulation's; 0.5 Nm s/rad on a URDF without <dynamics>) adds
      // to d: at the flange it is J^+T diag(d_joint) J^+, and at 1.5 Nm/rad it alone left 0.017
      // rad of a 0.05 rad turn after 2.5 s, which a friction band no longer hides.
      const MinimumDampingParameters& floor = rig.loop().controller().parameters().minimum_damping;
      const Eigen::MatrixXd to_flange =
          Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(jacobian_now(rig).transpose())
              .pseudoInverse();
      const Matrix6d joint_damping =
          to_flange * rig.sim().joint_damping().asDiagonal() * to_flange.transpose();
      const double joint_translation =
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(joint_damping.topLeftCorner<3, 3>())
              .eigenvalues()
              .maxCoeff();
      const double joint_rotation =
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(joint_damping.bottomRightCorner<3, 3>())
              .eigenvalues()
              .maxCoeff();
      const double settle =
          std::max(2.5, 6.0 * std::max((floor.translation + joint_translation) / kt,
                                       (floor.rotation + joint_rotation) / kr));
      for (int k = 0; k < static_cast<int>(settle / kDt); ++k) {
        rig.run(kDt);
        const ControllerState& state = rig.loop().state().controller;
        const Vector6d& e = state.pose_error;
        const JointVector& dq = rig.sim().true_dq();
        const JointVector tau_law =
            state.tau_cartesian + state.tau_nullspace + state.tau_wrench + state.tau_gravity;
        limit_work += kDt * (state.tau - tau_law).dot(0.5 * (dq_before + dq));
        dq_before = dq;
        workspace.compute(rig.sim().true_q(), dq, kinematics, true);
        // The rotors' kinetic energy too: the simulated arm has them (dynamics.armature).
        const double kinetic =
            0.5 * dq.dot(kinematics.mass * dq) + 0.5 * dq.dot(armature.cwiseProduct(dq));
        stiffness = state.stiffness_base();
        const double spring = 0.5 * e.dot(stiffness * e);
        if (initial < 0.0) initial = spring + kinetic;
        peak = std::max(peak, spring + kinetic - limit_work);
        limited |= state.limits.joint_torque_saturated || state.limits.torque_rate_limited;
      }
      const double error = 1e3 * (rig.flange().position - target.position).norm();
      const double angle = rotation_between(target, rig.flange()).norm();
      // Converged: within 2 mm and 0.01 rad plus what the joints' friction can hold against the
      // spring; and E - W never above what the step put in (+5 % for the 1 ms discretisation and
      // the rotation error's small-angle energy).
      // ... and what the nullspace torque lets through to the flange (nullspace_wrench), which
      // on a frictionless arm is all that holds it off the target.
      const FrictionBand band = friction_band(rig);
      const Vector6d leak = nullspace_wrench(rig);
      const double kt_used = stiffness.diagonal().head<3>().maxCoeff();
      const double kr_used = stiffness.diagonal().tail<3>().maxCoeff();
      saturated |= kt_used < (1.0 - 1e-9) * kt || kr_used < (1.0 - 1e-9) * kr;
      const bool ok = error <= 2.0 + 1e3 * (band.force + leak.head<3>().norm()) / kt_used &&
                      angle <= 0.01 + (band.torque + leak.tail<3>().norm()) / kr_used &&
                      peak <= 1.05 * initial;
      grid.rows.push_back(
          {kt, kr, ok ? 1.0 : 0.0, error, angle, peak / initial, limited ? 1.0 : 0.0});
      ++total;
      if (ok) {
        ++stable;
      } else {
        failures << " K=" << kt_used << "/" << kr_used << " (error " << error << " mm, " << angle
                 << " rad, nullspace torque at the flange " << leak.head<3>().norm() << " N, "
                 << leak.tail<3>().norm() << " Nm, energy less the limits' work x" << peak / initial
                 << (limited ? ", torque-limited" : "") << ")";
      }
    }
  }
  outcome.results.push_back(
      compare("stability grid",
              format("combinations of %.4g..%.4g N/m x %.4g..%.4g Nm/rad that converge",
                     translations[0], translations[3], rotations[0], rotations[3]),
              total, stable, "", 0.0, failures.str()));
  outcome.overrides.push_back(
      std::string("stiffness: each of the grid's 16 combinations, from limits.stiffness") +
      (saturated ? " (saturated to the configured limits.stiffness)" : "") +
      "; filter.pose.time = 0 and safety.max_speed = 0 (a true step); limits.pose_error = 1 m, "
      "1 rad (unclipped)");
  outcome.tables.push_back(grid);
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
  // A settled arm moves at no more than 0.01 rad/s, plus what the plant's noise keeps it moving
  // at: five standard deviations (the largest of a second's samples, correlated over a few ms,
  // lies within about three), zero on the nominal plant.
  double settled_speed = 0.01;
  double expected_limited = 0.0;  // the most rate-limited cycles the noise explains in a run
  std::ostringstream failures;
  for (int c = 0; c < cases; ++c) {
    Rig rig(robot, parameters);
    const JointLimits& limits = rig.model().limits();
    JointVector q_target = rig.sim().true_q();
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
    int limited_cycles = 0;
    for (int k = 0; k < 1000; ++k) {
      rig.run(kDt);
      fastest = std::max(fastest, rig.sim().true_dq().cwiseAbs().maxCoeff());
      limited_cycles += rig.loop().state().controller.limits.torque_rate_limited ? 1 : 0;
    }
    // A settled arm's torque changes by no more than the rate limit allows: not once on the
    // nominal plant (a rate-limited cycle at rest is a chatter); on a plant with sensor noise
    // as often as the noise alone reaches the limit, with five standard deviations of a Poisson
    // count on top.
    const double noise_cycles = noise_rate_limited_cycles(rig, robot.plant);
    const double limited_allowed =
        noise_cycles > 0.0 ? noise_cycles + 5.0 * std::sqrt(noise_cycles) + 5.0 : 0.0;
    const bool limited = limited_cycles > limited_allowed;
    expected_limited = std::max(expected_limited, noise_cycles);
    fastest_late = std::max(fastest_late, fastest);
    const double still = 0.01 + 5.0 * noise_speed(rig, robot.plant);
    settled_speed = std::max(settled_speed, still);
    const FrictionBand band = friction_band(rig);
    const double error = (rig.flange().position - target.position).norm();
    const double angle = rotation_between(target, rig.flange()).norm();
    const bool ok = fastest <= still && !limited &&
                    error <= 0.002 + band.force / parameters.stiffness.translation.x() &&
                    angle <= 0.01 + band.torque / parameters.stiffness.rotation.x();
    if (ok) {
      ++settled;
    } else {
      failures << " #" << c << " (error " << 1e3 * error << " mm, " << angle << " rad, |dq| "
               << fastest << " rad/s" << (limited ? ", rate-limited" : "") << " in "
               << limited_cycles << " cycles)";
    }
  }
  char quantity[128];
  std::snprintf(quantity, sizeof(quantity),
                "random reachable references that settle within 8 s at %.0f N/m, %.0f Nm/rad",
                parameters.stiffness.translation.x(), parameters.stiffness.rotation.x());
  std::string note = failures.str();
  if (expected_limited > 0.0) {
    note = format(
               "a settled run's torque may be rate-limited in as many of its last second's "
               "cycles as the sensor noise explains (up to %.1f, plus five Poisson standard "
               "deviations and 5)",
               expected_limited) +
           (note.empty() ? "" : ";" + note);
  }
  return {{compare("convergence", quantity, cases, settled, "", 0.0, note),
           at_most("convergence", "largest joint speed in each run's last second", settled_speed,
                   fastest_late, "rad/s",
                   settled_speed > 0.01 ? "0.01 and five times the plant's noise speed" : "")},
          {},
          overrides(robot, parameters)};
}

// 10. Two arms in one scene, each with its own controller: pushing one does not move the other.
// The Panda and the iiwa14 share the project's MJCF scene (models/scenes/two_arms.xml); any other
// robot, and every robot on DART (which simulates URDF only), stands beside a copy of itself,
// both simulated from its URDF. The arms share nothing but
// the simulation, so "does not move" is checked exactly: against a twin run of the same scene
// without the push (or without the step), the other arm's path must be the same to a micrometre
// (MuJoCo solves the joints' friction of both arms together, which may round differently).
struct ArmPair {
  RobotSetup left, right;
  std::string left_tip, right_tip;  // sites of the MJCF scene, or the URDF copies' tip bodies
  bool sites = true;
  int push_axis = 1;         // the left arm is pushed along y, or the first axis it can move along
  int step_axis = 2;         // the right arm steps down, or along the first axis it can move along
  double push_force = 20.0;  // [N], less where the spring would pass limits.pose_error
  double push_travel_tolerance = 0.0;  // [m] friction band / stiffness along push_axis
  double step_tolerance = 0.0;         // [m] the same along step_axis
  double step = 0.05;                  // [m] the right arm's reference step, less on a small arm
};

ArmPair arm_pair(const RobotSetup& robot) {
  ArmPair pair;
  const std::string source = CARTESIAN_IMPEDANCE_SOURCE_DIR;
  if ((robot.name == "panda" || robot.name == "iiwa14") && !robot.mjcf.empty()) {
    pair.left = builtin_robot("panda", source);
    pair.right = builtin_robot("iiwa14", source);
    pair.left_tip = "panda_flange";
    pair.right_tip = "iiwa_flange";
  } else {
    pair.left = pair.right = robot;
    pair.left_tip = "left_" + robot.flange;
    pair.right_tip = "right_" + robot.flange;
    pair.sites = false;
  }
  pair.left.mutation = pair.right.mutation = robot.mutation;
  // Directions and friction from the left arm alone at its start (both start alike).
  Rig rig(pair.left, base_parameters(pair.left));
  const TaskDirections directions = task_directions(rig);
  pair.push_axis = directions.first_of({1, 0, 2});
  pair.step_axis = directions.first_of({2, 0, 1});
  const Capacity can = capacity(rig);
  if (pair.push_axis >= 0) {
    // 20 N as tuned, or what the joints hold with room to spare, within 4 cm of the spring; and
    // the spring pulls back with at most K times the clipped error: push with less than that.
    const Parameters parameters = base_parameters(pair.left);
    const double stiffness = parameters.stiffness.translation[pair.push_axis];
    pair.push_force = std::min(
        fitted_load(20.0, can.force_along(Eigen::Vector3d::Unit(pair.push_axis)), stiffness, 0.04),
        0.8 * parameters.limits.pose_error.translation * stiffness);
  }
  if (pair.step_axis >= 0) {
    // 5 cm as tuned, at most a tenth of the flange's distance from the base, halved until the
    // joints get there (to first order) 0.1 rad inside their limits.
    Vector6d twist = Vector6d::Zero();
    twist[pair.step_axis] = -std::min(0.05, 0.1 * can.reach);
    pair.step = -twist[pair.step_axis] * can.fraction_within_limits(twist, 0.1);
  }
  if (!pair.sites && pair.push_axis >= 0 && pair.step_axis >= 0) {
    // Twins: the joints' friction may hold each short of the spring's rest by this much.
    const FrictionBand band = friction_band(rig);
    const Eigen::Vector3d stiffness = base_parameters(robot).stiffness.translation;
    pair.push_travel_tolerance = band.force / stiffness[pair.push_axis];
    pair.step_tolerance = band.force / stiffness[pair.step_axis];
  }
  return pair;
}

Parameters arm_parameters(const RobotSetup& arm, const JointVector& simulated_armature) {
  Parameters parameters = base_parameters(arm);
  if (!(parameters.dynamics.armature.array() != 0.0).any()) {
    parameters.dynamics.armature = simulated_armature;  // as Rig does
  }
  return parameters;
}

struct TwoArmRun {
  Pose left_start, right_start;    // before the push
  Pose left_pushed, right_pushed;  // 3 s into the push (or the same time without it)
  Pose left_rest, right_rest;      // 3 s after the release
  Pose left_end, right_end;        // 3 s after the right arm's reference step (if any)
  Table motion{"motion",
               {"time", "phase", "left_dx_mm", "left_dy_mm", "left_dz_mm", "right_dx_mm",
                "right_dy_mm", "right_dz_mm"},
               {}};  // every 10 ms; phase 0 before the push, 1 pushed, 2 released, 3 right step
};

std::string display_name(const RobotSetup& robot) {
  return robot.name == "panda" ? "Panda" : robot.name;
}

TwoArmRun run_two_arms(const ArmPair& pair, bool push_left, bool step_right,
                       const MomentCallback& moment) {
  const RobotModel left_model =
      RobotModel::from_urdf_file(pair.left.urdf, pair.left.base_link, pair.left.tip_link);
  const RobotModel right_model =
      RobotModel::from_urdf_file(pair.right.urdf, pair.right.base_link, pair.right.tip_link);
  const int n_left = left_model.num_joints(), n_right = right_model.num_joints();
  sim::SimulationOptions options;
  options.engine = pair.left.engine;
  options.boxes_for_missing_meshes = pair.left.boxes_for_missing_meshes;
  options.plant = pair.left.plant;
  std::optional<sim::Simulation> scene;
  if (pair.sites) {
    options.joint_names = left_model.joint_names();
    options.joint_names.insert(options.joint_names.end(), right_model.joint_names().begin(),
                               right_model.joint_names().end());
    scene.emplace(sim::Simulation::from_mjcf_file(
        std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/scenes/two_arms.xml", options));
  } else {
    for (const std::string& name : left_model.joint_names()) {
      options.joint_names.push_back("left_" + name);
    }
    for (const std::string& name : right_model.joint_names()) {
      options.joint_names.push_back("right_" + name);
    }
    if (pair.left.start_q.size() == n_left) {
      options.start_q.resize(n_left + n_right);
      options.start_q << pair.left.start_q, pair.right.start_q;
    }
    const Parameters configured = base_parameters(pair.left);
    if ((configured.dynamics.armature.array() != 0.0).any()) {
      const JointVector armature = per_joint(configured.dynamics.armature, n_left);
      options.armature.resize(2 * n_left);
      options.armature << armature, armature;
    }
    // Side by side along y, twice the flange's reach at the start apart.
    ModelWorkspace workspace(left_model);
    Pose flange;
    workspace.compute_pose(
        pair.left.start_q.size() == n_left ? pair.left.start_q : JointVector::Zero(n_left), flange);
    const double half = std::max(0.5, flange.position.norm() + 0.2);
    scene.emplace(
        sim::make_robots_scene({{pair.left.urdf, "left_", Eigen::Vector3d(0, half, 0)},
                                {pair.right.urdf, "right_", Eigen::Vector3d(0, -half, 0)}},
                               options));
  }
  sim::Simulation& sim = *scene;
  const JointVector armature = sim.armature();
  ControlLoop left_loop(left_model, arm_parameters(pair.left, armature.head(n_left)));
  ControlLoop right_loop(right_model, arm_parameters(pair.right, armature.tail(n_right)));
  // Each loop drives its own arm: the scene's first joints, and the next ones.
  sim::ClosedLoopRunner runner(
      sim, {&left_loop, &right_loop},
      pair.sites ? std::vector<std::string>{} : std::vector<std::string>{"left_", "right_"});
  set_mutation(runner, pair.left.mutation);
  runner.start();
  const auto tip = [&](const std::string& name) {
    return pair.sites ? sim.site_pose(name) : sim.body_pose(name);
  };
  TwoArmRun result;
  runner.run_for(0.5);
  result.left_start = tip(pair.left_tip);
  result.right_start = tip(pair.right_tip);
  const JointVector q_start = sim.true_q();
  double phase = 0.0;
  const auto record = [&](std::int64_t step) {
    if (step % 10 != 0) return;  // every 10 ms
    const Eigen::Vector3d l = 1e3 * (tip(pair.left_tip).position - result.left_start.position);
    const Eigen::Vector3d r = 1e3 * (tip(pair.right_tip).position - result.right_start.position);
    result.motion.rows.push_back({sim.time(), phase, l.x(), l.y(), l.z(), r.x(), r.y(), r.z()});
  };
  const char axis = "xyz"[pair.push_axis];
  if (push_left) {
    Vector6d push = Vector6d::Zero();
    push[pair.push_axis] = pair.push_force;
    sim.push(pair.left_tip, push, kForever);
  }
  phase = 1.0;
  runner.run_for(3.0, record);
  if (moment) {
    // From in front of the two arms, so that neither hides the other.
    const double stiffness = base_parameters(pair.left).stiffness.translation[pair.push_axis];
    sim::RenderOverlay overlay;
    overlay.caption =
        "left arm pushed, right arm holding\n" +
        format(
            "t = %.2f s: %g N along +%c on the %s's flange (orange arrow) moved it %.1f mm "
            "(theory %g N / %g N/m = %.1f mm)",
            sim.time(), pair.push_force, axis, display_name(pair.left).c_str(),
            1e3 * (tip(pair.left_tip).position - result.left_start.position)[pair.push_axis],
            pair.push_force, stiffness, 1e3 * pair.push_force / stiffness) +
        "\nthe " + display_name(pair.right) +
        " beside it has its own controller and does not move\n"
        "RGB axes: each arm's reference pose; green ghost: both arms before the push";
    Eigen::Vector3d force = Eigen::Vector3d::Zero();
    force[pair.push_axis] = pair.push_force;
    overlay.arrows.push_back({tip(pair.left_tip).position, force, 0.015,
                              Eigen::Vector4f(1.0f, 0.5f, 0.0f, 1.0f),
                              format("%g N", pair.push_force)});
    const std::string left_base = pair.sites ? pair.left.base_link : "left_" + pair.left.base_link;
    const std::string right_base =
        pair.sites ? pair.right.base_link : "right_" + pair.right.base_link;
    for (const auto& [loop, base] : {std::make_pair(&left_loop, sim.body_pose(left_base)),
                                     std::make_pair(&right_loop, sim.body_pose(right_base))}) {
      const Pose reference = loop->state().controller.filtered.pose;
      overlay.frames.push_back({{base.position + base.orientation * reference.position,
                                 base.orientation * reference.orientation},
                                0.1,
                                1.0f,
                                ""});
    }
    overlay.ghost_q = q_start;
    overlay.azimuth = 150.0;
    moment("left arm pushed, right arm holding", sim, overlay);
  }
  result.left_pushed = tip(pair.left_tip);
  result.right_pushed = tip(pair.right_tip);
  sim.clear_pushes();
  phase = 2.0;
  runner.run_for(3.0, record);
  result.left_rest = tip(pair.left_tip);
  result.right_rest = tip(pair.right_tip);
  if (step_right) {
    Pose right_target = right_loop.state().controller.pose;
    right_target.position[pair.step_axis] -= pair.step;
    right_loop.set_reference_pose(right_target);
    phase = 3.0;
  }
  runner.run_for(3.0, record);
  result.left_end = tip(pair.left_tip);
  result.right_end = tip(pair.right_tip);
  return result;
}

Outcome two_arms(const RobotSetup& robot, const MomentCallback& moment) {
  const ArmPair pair = arm_pair(robot);
  if (pair.push_axis < 0 || pair.step_axis < 0) {
    return {{not_applicable("two arms", "one arm pushed, the other unmoved",
                            "the arm cannot move its flange along x, y or z")},
            {}};
  }
  if (pair.step == 0.0) {
    return {{not_applicable("two arms", "one arm pushed, the other unmoved",
                            "even a small reference step would take a joint within 0.1 rad of "
                            "its limit")},
            {}};
  }
  // The mutation of `robot` (tests of the tests) applies to both arms.
  const TwoArmRun both = run_two_arms(pair, true, true, moment);
  const TwoArmRun push_only = run_two_arms(pair, true, false, {});
  const TwoArmRun neither = run_two_arms(pair, false, false, {});
  const double left_moved = (both.left_pushed.position - both.left_start.position)[pair.push_axis];
  const double right_step = (both.right_end.position - both.right_rest.position)[pair.step_axis];
  const double right_difference =
      (both.right_pushed.position - neither.right_pushed.position).norm();
  const double left_difference = (both.left_end.position - push_only.left_end.position).norm();
  const char* axes = "xyz";
  const double stiffness = base_parameters(pair.left).stiffness.translation[pair.push_axis];
  const double travel = 1e3 * pair.push_force / stiffness;
  char pushed[160], stepped[96];
  std::snprintf(pushed, sizeof(pushed), "left arm (%s) displacement under %g N%s at %g N/m",
                display_name(pair.left).c_str(), pair.push_force,
                pair.push_axis == 1 ? "" : (std::string(" along ") + axes[pair.push_axis]).c_str(),
                stiffness);
  std::snprintf(
      stepped, sizeof(stepped), "right arm reference step %s",
      pair.step_axis == 2 ? "down" : (std::string("along -") + axes[pair.step_axis]).c_str());
  const std::string right = "right arm (" + display_name(pair.right) + ")";
  return {{compare("two arms", pushed, travel, 1e3 * left_moved, "mm",
                   0.05 * travel + 1e3 * pair.push_travel_tolerance),
           at_most("two arms", right + ": difference to a run without the push", 1e-3,
                   1e3 * right_difference, "mm"),
           compare("two arms", stepped, -1e3 * pair.step, 1e3 * right_step, "mm",
                   2.0 + 1e3 * pair.step_tolerance),
           at_most("two arms", "left arm: difference to a run without the step", 1e-3,
                   1e3 * left_difference, "mm")},
          {},
          {},
          {both.motion}};
}

}  // namespace cartesian_impedance::scenarios::detail
