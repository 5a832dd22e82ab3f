#include "scenarios.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include "cartesian_impedance/config.hpp"
#include "cartesian_impedance/error.hpp"

namespace cartesian_impedance::scenarios {
namespace {

constexpr double kDt = 0.001;
constexpr double kForever = std::numeric_limits<double>::infinity();

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

// ---- the scenarios ----------------------------------------------------------------------------

// 1. Hold: no disturbance, the pose stays.
Outcome hold(const RobotSetup& robot, const MomentCallback& moment) {
  Rig rig(robot, base_parameters(robot));
  const Pose start = rig.flange();
  double worst_translation = 0.0, worst_rotation = 0.0;
  for (int k = 0; k < 500; ++k) {
    rig.run(0.01);
    worst_translation =
        std::max(worst_translation, (rig.flange().position - start.position).norm());
    worst_rotation = std::max(worst_rotation, rotation_between(start, rig.flange()).norm());
  }
  notify(moment, "holding", rig);
  return {{at_most("hold", "largest drift over 5 s", 1.0, 1e3 * worst_translation, "mm"),
           at_most("hold", "largest rotation over 5 s", 0.01, worst_rotation, "rad")},
          rig.samples()};
}

// Displacement and rotation of the flange caused by a constant push. The joints' Coulomb
// friction stops the arm anywhere in a band around the spring's equilibrium; approaching it once
// from below (loading from rest) and once from above (unloading from a 1.5 times larger push)
// and averaging cancels that band, as in a hysteresis measurement.
struct PushResponse {
  Eigen::Vector3d displacement;
  Eigen::Vector3d rotation;
};

PushResponse respond(Rig& rig, const Eigen::Vector3d& force, const Eigen::Vector3d& torque) {
  rig.release();
  rig.run(2.0);  // back at rest from whatever came before
  const Pose before = rig.flange();
  rig.push(force, torque);
  rig.run(3.0);
  const Pose loaded = rig.flange();
  rig.push(1.5 * force, 1.5 * torque);
  rig.run(2.0);
  rig.push(force, torque);
  rig.run(3.0);
  const Pose unloaded = rig.flange();
  return {0.5 * ((loaded.position - before.position) + (unloaded.position - before.position)),
          0.5 * (rotation_between(before, loaded) + rotation_between(before, unloaded))};
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
  const Pose rest = rig.flange();
  rig.loop().set_stiffness(six(1000, 500, 500, 50, 50, 50));
  rig.run(3.0);
  const double stiff = soft - (rest.position - rig.flange().position).x();
  notify(moment, "stiffness doubled", rig);
  rig.release();
  outcome.results.push_back(compare("stiffness change", "displacement at 1000 N/m / at 500 N/m",
                                    0.5, stiff / soft, "", 0.05 * 0.5));
  outcome.samples = rig.samples();
  return outcome;
}

// 4. Reference step: reaches a new pose without exceeding the torque-rate limit.
Outcome reference_step(const RobotSetup& robot, const MomentCallback& moment) {
  Rig rig(robot, base_parameters(robot));
  rig.run(0.2);
  const Pose start = rig.flange();
  Pose target = start;
  target.position += Eigen::Vector3d(0.10, 0.05, -0.05);
  target.orientation =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())) * start.orientation;
  rig.loop().set_reference_pose(target);
  rig.run(4.0);
  notify(moment, "reached the new reference", rig);
  const Pose end = rig.flange();
  return {{at_most("reference step", "position error after 4 s (step of 122 mm)", 2.0,
                   1e3 * (end.position - target.position).norm(), "mm"),
           at_most("reference step", "orientation error after 4 s (step of 0.3 rad)", 0.01,
                   rotation_between(target, end).norm(), "rad"),
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

// 7. Teaching: with zero stiffness a push moves the end effector and it stays where it was left.
Outcome teaching(const RobotSetup& robot, const MomentCallback& moment) {
  Rig rig(robot, base_parameters(robot));
  rig.loop().start_teaching();
  rig.run(1.0);
  const Pose start = rig.flange();
  rig.push(Eigen::Vector3d(0, 10, 0));  // a hand's gentle push
  rig.run(0.3);
  rig.release();
  const Pose released = rig.flange();
  rig.run(3.0);
  const Pose rest = rig.flange();
  rig.run(1.0);
  notify(moment, "left where it was pushed", rig);
  const double pushed = 1e3 * (released.position - start.position).norm();
  const double final_distance = 1e3 * (rest.position - start.position).norm();
  return {{at_least("teaching", "distance the push moved the flange", 20.0, pushed, "mm"),
           at_least("teaching", "distance from the start after release (no spring back)", pushed,
                    final_distance, "mm", "at least the pushed distance"),
           at_most("teaching", "drift in the last second", 1.0,
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
      // Converged: within 2 mm and 0.01 rad plus what the joints' friction (0.1-0.2 Nm per
      // joint, up to about 1 N and 0.3 Nm at the flange) can hold against the spring; and the
      // energy never above what the step put in (+5 %): a passive, stable closed loop.
      const bool ok =
          error <= 2.0 + 1e3 * 1.0 / kt && angle <= 0.01 + 0.3 / kr && peak <= 1.05 * initial;
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

// 10. Two arms in one scene, each with its own controller: pushing one does not move the other.
Outcome two_arms(const RobotSetup&, const MomentCallback& moment) {
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
  const int n_left = left_model.num_joints(), n_right = right_model.num_joints();
  left_loop.start(sim.q().head(n_left), sim.dq().head(n_left));
  right_loop.start(sim.q().tail(n_right), sim.dq().tail(n_right));
  JointVector q_left(n_left), dq_left(n_left), q_right(n_right), dq_right(n_right);
  JointVector tau(n_left + n_right);
  auto run = [&](double seconds) {
    for (int k = 0; k < static_cast<int>(std::lround(seconds / kDt)); ++k) {
      q_left = sim.q().head(n_left);
      dq_left = sim.dq().head(n_left);
      q_right = sim.q().tail(n_right);
      dq_right = sim.dq().tail(n_right);
      tau.head(n_left) = left_loop.step(q_left, dq_left, kDt);
      tau.tail(n_right) = right_loop.step(q_right, dq_right, kDt);
      sim.set_torque(tau);
      sim.step();
    }
  };
  run(0.5);
  const Pose left_start = sim.site_pose(left.flange), right_start = sim.site_pose(right.flange);
  sim.push(left.flange, six(0, 20, 0, 0, 0, 0), kForever);
  run(3.0);
  if (moment) moment("left arm pushed, right arm holding", sim);
  const double left_moved = (sim.site_pose(left.flange).position - left_start.position).y();
  const double right_still = (sim.site_pose(right.flange).position - right_start.position).norm();
  sim.clear_pushes();
  run(3.0);
  const Pose left_rest = sim.site_pose(left.flange), right_rest = sim.site_pose(right.flange);
  Pose right_target = right_loop.state().controller.pose;
  right_target.position.z() -= 0.05;
  right_loop.set_reference_pose(right_target);
  run(3.0);
  const double right_step = (sim.site_pose(right.flange).position - right_rest.position).z();
  const double left_still = (sim.site_pose(left.flange).position - left_rest.position).norm();
  return {{compare("two arms", "left arm (Panda) displacement under 20 N at 500 N/m", 40.0,
                   1e3 * left_moved, "mm", 0.05 * 40.0),
           at_most("two arms", "right arm (iiwa14) motion meanwhile", 0.1, 1e3 * right_still, "mm"),
           compare("two arms", "right arm reference step down", -50.0, 1e3 * right_step, "mm", 2.0),
           at_most("two arms", "left arm motion meanwhile", 0.1, 1e3 * left_still, "mm")},
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
  if (robot.mjcf.empty()) {
    if (!boxes.empty()) throw Error("scenes with a table need an MJCF model of the robot");
    return sim::Simulation::from_urdf_file(robot.urdf, options);
  }
  return sim::make_scene(robot.mjcf, boxes, options);
}
}  // namespace

Rig::Rig(const RobotSetup& robot, const Parameters& parameters, const std::vector<sim::Box>& boxes)
    : robot_(robot),
      model_(RobotModel::from_urdf_file(robot.urdf, robot.base_link, robot.tip_link)),
      sim_(make_simulation(robot, model_, boxes)),
      loop_(std::make_unique<ControlLoop>(model_, parameters)) {
  // The tip is a site in the project's MJCF files; a robot simulated from its URDF has only
  // bodies, named like its links.
  try {
    sim_.site_pose(robot_.flange);
  } catch (const Error&) {
    flange_is_site_ = false;
    sim_.body_pose(robot_.flange);  // throws, naming it, if it is neither
  }
  loop_->start(sim_.q(), sim_.dq());
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
  const long steps = std::lround(seconds / kDt);
  for (long k = 0; k < steps; ++k) {
    const JointVector& tau = loop_->step(sim_.q(), sim_.dq(), kDt);
    const JointVector rate = (tau - previous_tau_).cwiseAbs() / kDt;
    largest_rate_fraction_ =
        std::max(largest_rate_fraction_, rate.cwiseQuotient(rate_limit).maxCoeff());
    rate_since_sample_ = std::max(rate_since_sample_, rate.maxCoeff());
    previous_tau_ = tau;
    sim_.set_torque(tau);
    sim_.step();
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
  }
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
  throw Error("unknown scenario '" + name + "' (known: " + names + ")");
}

}  // namespace cartesian_impedance::scenarios
