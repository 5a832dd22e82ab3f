// 13. Collision: a link in the middle of the arm (the forearm of a 7-joint arm) swung at the
// speed cap into a box beside its path while the flange follows its reference, then into the
// same box made soft (MuJoCo). The collision monitor must find the contact within 10 ms (or 3 ms
// after the contact's own torque, computed from the simulation's contact wrenches, passes a
// threshold, where that comes later) and name a joint at or before the touched link, also when
// its observer reads the joint torque sensors instead of the torque sent; each reaction must end
// the clamping force that the controller keeps up without one.

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "scenario_support.hpp"

namespace cartesian_impedance::scenarios::detail {

namespace {

constexpr const char* kName = "collision";
constexpr double kSpeedCap = 0.25;         // [m/s] the swing
constexpr double kDetectionBound = 0.010;  // [s] from the first contact
// [s] after the contact's filtered torque passed a threshold: the cycle that reads it, the
// realistic plant's 1 ms old readings and 1 ms late torques.
constexpr double kDetectionSlack = 0.003;
constexpr double kClampingFrom = 0.1;    // [s] after the detection: past the impact
constexpr double kWatched = 1.5;         // [s] measured after the first contact
constexpr std::size_t kBefore = 50;      // cycles of the force table before the first contact
constexpr double kClampingShare = 0.1;   // a reaction's clamping force, of report's at most
constexpr double kImpulseShare = 0.5;    // a reaction's impulse, of report's at most
constexpr double kLeastClamping = 10.0;  // [N] report's, for the shares to say something
constexpr double kBoxHalfSize = 0.04;    // [m]
constexpr double kLeastTravel = 0.08;    // [m] the struck link's, over the swing
constexpr double kArrowScale = 0.003;    // [m/N] 100 N are drawn 0.3 m long
// The soft box's contact time constant [s]: 2.5 times MuJoCo's default, a contact 6 times as
// compliant, whose force builds over some 10 ms instead of 2. (A cushion of 0.1 s is found
// 10 ms after the first contact on the Panda: the target's edge.)
constexpr double kSoftTimeConstant = 0.05;
const std::array<CollisionReaction, 4> kReactions = {
    CollisionReaction::report, CollisionReaction::stop, CollisionReaction::reflex,
    CollisionReaction::retract};

// The contact force on the whole arm, world frame [N]: the floor does not collide and the arm
// not with itself, so this is what the box presses with.
Eigen::Vector3d force_on_arm(Rig& rig, const RobotSetup& robot) {
  return rig.sim().contact_wrench_beyond(robot.base_link).head<3>();
}

// The chain's link (by its joint's index) that the box presses on most, or -1.
int touched_joint(Rig& rig, const RobotModel& model) {
  int best = -1;
  double most = 0.0;
  for (int i = 0; i < model.num_joints(); ++i) {
    const double force = rig.sim().contact_wrench(model.joint_links()[i]).head<3>().norm();
    if (force > most) {
      most = force;
      best = i;
    }
  }
  return best;
}

// The point of the contact force's line of action nearest the body's origin (world frame): the
// contact wrench gives the force and its moment about the origin, r x f = m, so r = f x m / |f|^2.
Eigen::Vector3d line_of_action(Rig& rig, const std::string& body) {
  const Vector6d wrench = rig.sim().contact_wrench(body);
  const Eigen::Vector3d f = wrench.head<3>(), m = wrench.tail<3>();
  const Eigen::Vector3d origin = rig.sim().body_pose(body).position;
  if (f.squaredNorm() < 1e-12) return origin;
  return origin + f.cross(m) / f.squaredNorm();
}

// The external torque the box's contacts put on the joints, from the simulation's contact
// wrenches: J_i^T w_i over the links i it touches, J_i the Jacobian of the chain up to link i at
// its origin (the wrench's torque is about it), both in the base frame. An independent
// computation of what the momentum observer estimates.
class ContactTorque {
 public:
  ContactTorque(const RobotSetup& robot, const RobotModel& model) : robot_(robot), model_(model) {}

  JointVector operator()(Rig& rig) {
    const int n = model_.num_joints();
    JointVector tau = JointVector::Zero(n);
    const Pose base = rig.sim().body_pose(robot_.base_link);
    const Eigen::Matrix3d to_base = base.orientation.conjugate().toRotationMatrix();
    const JointVector q = rig.sim().true_q();
    for (int i = 0; i < n; ++i) {
      const Vector6d world = rig.sim().contact_wrench(model_.joint_links()[i]);
      if (world.isZero()) continue;
      auto found = chains_.find(i);
      if (found == chains_.end()) {
        found = chains_
                    .try_emplace(i, RobotModel::from_urdf_file(robot_.urdf, robot_.base_link,
                                                               model_.joint_links()[i]))
                    .first;
      }
      Chain& chain = found->second;
      const int m = chain.model.num_joints();
      chain.workspace.compute(q.head(m), JointVector::Zero(m), chain.kinematics, false);
      Vector6d wrench;
      wrench << to_base * world.head<3>(), to_base * world.tail<3>();
      tau.head(m) += chain.kinematics.jacobian.transpose() * wrench;
    }
    return tau;
  }

 private:
  const RobotSetup& robot_;
  const RobotModel& model_;
  // The chain up to a touched link, made once (a map's node does not move: the workspace may
  // refer to its model).
  struct Chain {
    explicit Chain(RobotModel chain)
        : model(std::move(chain)), workspace(model), kinematics(workspace.make_kinematics()) {}
    RobotModel model;
    ModelWorkspace workspace;
    Kinematics kinematics;
  };
  std::map<int, Chain> chains_;
};

struct Swing {
  double contact = -1.0;   // [s] since the reference was sent; -1: none
  double detected = -1.0;  // [s] likewise
  // [s] when the contact's torque (ContactTorque), through the observer's first-order filter,
  // first passed a threshold the monitor had in force: the earliest the monitor could find it.
  double detectable = -1.0;
  double share = 0.0;         // the largest |that filtered torque| / threshold over the joints
  int touched = -1;           // joint index of the link the box pressed on first
  int named = -1;             // the joint the monitor named, once its isolation window closed
  double impact = 0.0;        // [N] largest within 10 ms of the contact
  double early = 0.0;         // [N] largest before kClampingFrom after the detection
  double clamping = 0.0;      // [N] largest from kClampingFrom after the detection
  double impulse = 0.0;       // [N s] over kWatched after it
  std::vector<double> force;  // [N] every cycle from kBefore cycles before the contact
  std::vector<std::vector<double>> residuals;  // every cycle: |unexpected|, threshold per joint
};

}  // namespace

Outcome collision(const RobotSetup& robot, const MomentCallback& moment) {
  Outcome outcome;
  Parameters parameters = base_parameters(robot);
  set_stiffness_within_limits(parameters, 1000.0, 100.0, parameters.nullspace.stiffness.maxCoeff());
  parameters.safety.max_speed.translation = kSpeedCap;
  parameters.collision.detection = true;
  const std::string quantity_any = "time from the first contact to the detection";

  // The swing: the reachable move of the flange, made at the cap, without a box, to find a link
  // in the middle of the chain that travels far enough and where it goes. By the controller as
  // it is: where the box stands is the arm's geometry, which a broken controller (a mutant)
  // must not make the scenario skip.
  RobotSetup intact = robot;
  intact.mutation = Mutation::none;
  Rig probe(intact, parameters);
  probe.run(0.2);
  const Move move = reachable_move(probe, 0.3);
  if (move.length == 0.0) {
    outcome.results.push_back(
        not_applicable(kName, quantity_any, "the flange reaches no move of 4 cm or more"));
    return outcome;
  }
  const RobotModel& model = probe.model();
  const int n = model.num_joints();
  const Pose start = probe.loop().state().controller.pose;
  Pose target = start;
  target.position += move.length * move.direction;
  const double swing_time = move.length / kSpeedCap + 0.5;
  std::vector<std::vector<Eigen::Vector3d>> paths(static_cast<std::size_t>(n));
  probe.loop().set_reference_pose(target);
  run_measured(probe, swing_time, [&](double) {
    for (int i = 0; i < n; ++i) {
      paths[static_cast<std::size_t>(i)].push_back(
          probe.sim().body_pose(model.joint_links()[i]).position);
    }
  });

  // The middle link first (a 7-joint arm's elbow), then toward the flange, then toward the base;
  // the box is centred where the link's origin has gone three quarters of its way, so that the
  // link's body runs into it and the box does not touch the arm at the start.
  std::vector<int> order;
  for (int i = n / 2; i < n - 1; ++i) order.push_back(i);
  for (int i = n / 2 - 1; i >= 1; --i) order.push_back(i);
  std::optional<sim::Box> box;
  int aimed = -1;
  for (const int i : order) {
    const std::string& link = model.joint_links()[i];
    if (!probe.sim().has_collision_geometry(link)) continue;
    const std::vector<Eigen::Vector3d>& path = paths[static_cast<std::size_t>(i)];
    const double travel = (path.back() - path.front()).norm();
    if (travel < kLeastTravel) continue;
    for (const Eigen::Vector3d& point : path) {
      if ((point - path.front()).norm() < 0.75 * travel) continue;
      sim::Box candidate;
      candidate.name = "obstacle";
      candidate.center = point;
      candidate.half_size.setConstant(kBoxHalfSize);
      Rig check(intact, parameters, {candidate});
      bool touches = false;
      for (int k = 0; k < 20 && !touches; ++k) {
        check.run(kDt);
        touches = !force_on_arm(check, robot).isZero();
      }
      if (!touches) {
        box = candidate;
        aimed = i;
      }
      break;
    }
    if (box) break;
  }
  if (!box) {
    outcome.results.push_back(not_applicable(
        kName, quantity_any,
        format("no link between the base and the flange travels %.0f cm on the flange's %.0f cm "
               "move with collision geometry that a box can be put beside",
               100.0 * kLeastTravel, 100.0 * move.length)));
    return outcome;
  }
  const std::string aimed_link = model.joint_links()[aimed];
  outcome.overrides.push_back(format(
      "stiffness %.4g N/m, %.4g Nm/rad; safety.max_speed.translation = %.2g m/s; a %.0f cm box "
      "in the way of %s; collision.reaction = report, stop, reflex, retract in turn",
      parameters.stiffness.translation.x(), parameters.stiffness.rotation.x(), kSpeedCap,
      200.0 * kBoxHalfSize, aimed_link.c_str()));

  // The pictures look across the swing, so that the box stands beside the link, not behind it:
  // square to the move (from the front of the arm for a move along y; turned 35 deg and from
  // 30 deg above, for depth), or along +y (the default view) for a vertical move.
  const Eigen::Vector3d across = Eigen::Vector3d::UnitZ().cross(move.direction);
  double view_azimuth = 90.0;
  if (across.norm() > 0.5) {
    const Eigen::Vector3d look = across.x() > 0.0 ? Eigen::Vector3d(-across) : across;
    view_azimuth = std::atan2(look.y(), look.x()) * 180.0 / M_PI;
  }
  sim::Box soft = *box;
  soft.time_constant = kSoftTimeConstant;
  // `pictures`: the rigid box's swings draw the detection, the pressing on and the retract.
  // `measured`: the observer reads the simulated joint torque sensors (collision.measured_torque).
  const auto swing = [&](CollisionReaction reaction, const sim::Box& obstacle, bool pictures,
                         bool measured = false) {
    Parameters used = parameters;
    used.collision.reaction = reaction;
    used.collision.measured_torque = measured;
    Rig rig(robot, used, {obstacle});
    rig.view(view_azimuth + 35.0, -30.0);
    rig.run(0.2);
    rig.remember_pose("before the swing");
    rig.phase(
        format("swing into the box, reaction %s", std::string(reaction_name(reaction)).c_str()));
    rig.loop().set_reference_pose(target);
    Swing result;
    ContactTorque contact_torque(robot, model);
    const double gain = 1.0 - std::exp(-used.collision.observer_gain * kDt);
    JointVector filtered = JointVector::Zero(n);
    const int steps = static_cast<int>(std::lround((swing_time + kWatched) / kDt));
    for (int k = 1; k <= steps; ++k) {
      rig.run(kDt);
      const double now = k * kDt;
      const double force = force_on_arm(rig, robot).norm();
      const CollisionState& state = rig.loop().state().controller.collision;
      if (result.contact < 0.0 && force > 0.0) {
        result.contact = now;
        result.touched = touched_joint(rig, model);
        result.force.assign(kBefore, 0.0);  // before the first contact: no force, by definition
      }
      if (result.detected < 0.0 && state.detected) {
        result.detected = now;
        if (pictures && reaction == CollisionReaction::report && result.touched >= 0) {
          const std::string& link = model.joint_links()[result.touched];
          const Eigen::Vector3d contact = force_on_arm(rig, robot);
          rig.mark({line_of_action(rig, link) - kArrowScale * contact, contact, kArrowScale,
                    Eigen::Vector4f(0.9f, 0.1f, 0.1f, 1.0f), format("%.0f N", contact.norm())},
                   format("red arrow: the box's force on %s, %.0f N, ending on its line of action",
                          link.c_str(), contact.norm()));
          notify(moment, "collision detected", rig,
                 {format("found %.0f ms after the first contact; the monitor names joint %d "
                         "(moving %s)",
                         1000.0 * (result.detected - result.contact), state.joint + 1,
                         state.joint >= 0 ? model.joint_links()[state.joint].c_str() : "-")});
        }
      }
      if (result.contact >= 0.0) {
        filtered += gain * (contact_torque(rig) - filtered);
        const double share = (filtered.cwiseAbs().array() / state.threshold.array()).maxCoeff();
        result.share = std::max(result.share, share);
        if (result.detectable < 0.0 && share > 1.0) result.detectable = now;
      }
      if (result.detected >= 0.0 && result.named < 0 &&
          now - result.detected > 2.0 * CartesianImpedanceController::kCollisionIsolationTime) {
        result.named = state.joint;
      }
      if (result.contact >= 0.0) {
        if (now - result.contact > kWatched) break;
        result.force.push_back(force);
      }
      if (pictures && reaction == CollisionReaction::report) {
        std::vector<double> row = {now};
        for (int i = 0; i < n; ++i) row.push_back(std::abs(state.unexpected[i]));
        for (int i = 0; i < n; ++i) row.push_back(state.threshold[i]);
        row.push_back(force);
        row.push_back(state.detected ? 1.0 : 0.0);
        result.residuals.push_back(row);
      }
    }
    // The clamping is what follows the reaction: from kClampingFrom after the detection (or
    // after the contact, where nothing was found).
    const double split = std::max(result.detected, result.contact) + kClampingFrom;
    for (std::size_t k = kBefore; k < result.force.size(); ++k) {
      const double force = result.force[k];
      const double when = result.contact + static_cast<double>(k - kBefore + 1) * kDt;
      if (when - result.contact <= 0.01) result.impact = std::max(result.impact, force);
      double& peak = when < split ? result.early : result.clamping;
      peak = std::max(peak, force);
      result.impulse += force * kDt;
    }
    if (!pictures) return result;
    if (reaction == CollisionReaction::report) {
      outcome.samples = rig.samples();
      notify(moment, "pressing on without a reaction", rig,
             {format("collision.reaction = report: the spring keeps pushing toward its "
                     "reference past the box (%.0f N from %.1f s after the detection on)",
                     result.clamping, kClampingFrom)});
    } else if (reaction == CollisionReaction::retract) {
      notify(moment, "retracted after the collision", rig,
             {format("collision.reaction = retract: the reference moved %.0f cm back, held until "
                     "Resume (%.1f N from %.1f s after the detection on)",
                     100.0 * used.collision.retract_distance, result.clamping, kClampingFrom)});
    }
    return result;
  };
  std::vector<Swing> swings;
  for (const CollisionReaction reaction : kReactions) swings.push_back(swing(reaction, *box, true));
  const Swing& report = swings.front();
  // The same swing with the observer on the joint torque sensors.
  const Swing sensed = swing(CollisionReaction::report, *box, false, true);
  // The soft box on MuJoCo (DART's contacts are rigid): without a reaction, and stopping.
  const bool soft_box = robot.engine == sim::Engine::mujoco;
  std::vector<Swing> soft_swings;
  if (soft_box) {
    for (const CollisionReaction reaction :
         {CollisionReaction::report, CollisionReaction::stop, CollisionReaction::retract}) {
      soft_swings.push_back(swing(reaction, soft, false));
    }
  }

  // The residuals of the swing without a reaction, and the force of each swing from 50 ms before
  // its contact.
  Table residuals{"residuals", {"time"}, report.residuals};
  for (const char* what : {"unexpected_", "threshold_"}) {
    for (int i = 0; i < n; ++i) residuals.columns.push_back(what + std::to_string(i + 1));
  }
  residuals.columns.push_back("contact_force");
  residuals.columns.push_back("detected");
  outcome.tables.push_back(residuals);
  Table force{"force", {"time_since_contact"}, {}};
  std::size_t rows = 0;
  for (std::size_t r = 0; r < swings.size(); ++r) {
    force.columns.push_back(std::string(reaction_name(kReactions[r])));
    rows = std::max(rows, swings[r].force.size());
  }
  if (soft_box) {
    for (const char* name : {"soft_report", "soft_stop", "soft_retract"}) {
      force.columns.push_back(name);
    }
  }
  for (std::size_t k = 0; k < rows; ++k) {
    std::vector<double> row = {(static_cast<double>(k) - static_cast<double>(kBefore)) * kDt};
    for (const std::vector<Swing>* runs : {&swings, &soft_swings}) {
      for (const Swing& s : *runs) row.push_back(k < s.force.size() ? s.force[k] : std::nan(""));
    }
    force.rows.push_back(row);
  }
  outcome.tables.push_back(force);

  // The lines. A swing that never touched the box fails each of them (infinite time, no link).
  const double kNever = std::numeric_limits<double>::infinity();
  const auto delay = [&](const Swing& s) {
    return s.contact >= 0.0 && s.detected >= s.contact ? s.detected - s.contact : kNever;
  };
  // A contact whose torque never passes a threshold cannot be found, and is not: a link near the
  // base pressing on the box with a weak arm's spring (the generated arms have some). Nothing
  // then reacts, so the rest does not apply.
  if (report.contact >= 0.0 && report.detectable < 0.0 && report.detected < 0.0) {
    outcome.results.push_back(not_applicable(
        kName, quantity_any,
        format("the box pressed on %s with at most %.0f N, whose torque reached %.0f %% of a "
               "threshold at most: a contact too gentle to find, and found by none",
               report.touched >= 0 ? model.joint_links()[report.touched].c_str() : "the arm",
               std::max(report.early, report.clamping), 100.0 * report.share)));
    return outcome;
  }
  // The 10 ms, or where the contact's own torque passed a threshold later (a weak arm's
  // slow press), 3 ms after that.
  for (std::size_t r = 0; r < swings.size(); ++r) {
    const Swing& s = swings[r];
    const std::string name(reaction_name(kReactions[r]));
    const double visible = s.detectable >= 0.0 ? s.detectable - s.contact : 0.0;
    const double bound = std::max(kDetectionBound, visible + kDetectionSlack + kDt / 2.0);
    outcome.results.push_back(
        at_most(kName, quantity_any + ", " + name, 1000.0 * bound, 1000.0 * delay(s), "ms",
                format("the %s swung at up to %.2g m/s into a %.0f cm box; its torque passed a "
                       "threshold %.0f ms after the contact",
                       aimed_link.c_str(), kSpeedCap, 200.0 * kBoxHalfSize, 1000.0 * visible)));
  }
  outcome.results.push_back(at_most(
      kName, "time from the contact's torque passing a threshold to the detection, report",
      1000.0 * kDetectionSlack + 0.5,
      report.detectable >= 0.0 && report.detected >= 0.0
          ? 1000.0 * (report.detected - report.detectable)
          : kNever,
      "ms",
      "the contact's torque J_link^T w from the simulation's contact wrenches, through the "
      "observer's filter, against the thresholds in force: the observer's estimate, computed "
      "without it"));
  outcome.results.push_back(at_most(
      kName,
      "time from the contact's torque passing a threshold to the detection, report, measured "
      "joint torques",
      1000.0 * kDetectionSlack + 0.5,
      sensed.detectable >= 0.0 && sensed.detected >= 0.0
          ? 1000.0 * (sensed.detected - sensed.detectable)
          : kNever,
      "ms",
      format("collision.measured_torque: the simulated link-side sensors less g(q); found %.0f ms "
             "after the first contact (%.0f ms with the torque sent)",
             1000.0 * delay(sensed), 1000.0 * delay(report))));
  // Isolation: a contact on a link acts on the joints before it only, so the last joint whose
  // residual crossed its threshold is at most the touched link's (earlier where the joints in
  // between cannot feel the force: their axes run along or through it).
  outcome.results.push_back(
      at_most(kName, "joint the monitor names, against the touched link's (1-based)",
              report.touched + 1.0, report.named >= 0 ? report.named + 1.0 : kNever, "",
              format("touched: %s; named: joint %d, moving %s",
                     report.touched >= 0 ? model.joint_links()[report.touched].c_str() : "none",
                     report.named + 1,
                     report.named >= 0 ? model.joint_links()[report.named].c_str() : "none")));
  outcome.results.push_back(at_least(
      kName, "clamping force without a reaction", kLeastClamping, report.clamping, "N",
      format("from %.1f s after the detection: the spring keeps pressing toward its reference past "
             "the box; the impact (first 10 ms) was %.0f N",
             kClampingFrom, report.impact)));
  for (std::size_t r = 1; r < swings.size(); ++r) {
    const Swing& s = swings[r];
    const std::string name(reaction_name(kReactions[r]));
    outcome.results.push_back(at_most(
        kName, "clamping force with " + name + ", share of report's", kClampingShare,
        s.contact >= 0.0 ? s.clamping / std::max(report.clamping, 1e-9) : kNever, "",
        format("%.1f N against %.0f N; impact %.0f N (no reaction after the contact changes it)",
               s.clamping, report.clamping, s.impact)));
    outcome.results.push_back(at_most(
        kName, "impulse with " + name + ", share of report's", kImpulseShare,
        s.contact >= 0.0 ? s.impulse / std::max(report.impulse, 1e-9) : kNever, "",
        format("%.2f N s against %.1f N s over %.1f s", s.impulse, report.impulse, kWatched)));
  }
  const std::string soft_line =
      "soft box (contact time constant " + format("%.2g s", kSoftTimeConstant) + ")";
  if (!soft_box) {
    outcome.results.push_back(
        not_applicable(kName, quantity_any + ", " + soft_line,
                       "DART's contacts are rigid: the soft box is simulated with MuJoCo"));
    return outcome;
  }
  const Swing& soft_report = soft_swings[0];
  const Swing& soft_stop = soft_swings[1];
  const Swing& soft_retract = soft_swings[2];
  // A soft contact's force builds over time; it is found once its torque through the observer's
  // filter passes a threshold, so that is the bound, with kDetectionSlack for the cycle that
  // reads it and the plant's delays. The 10 ms target holds where the force builds fast enough.
  if (soft_report.detectable < 0.0 && soft_report.detected < 0.0) {
    outcome.results.push_back(not_applicable(
        kName, quantity_any + ", " + soft_line,
        format("the soft box's force (at most %.0f N) never pressed past the thresholds: a "
               "contact too gentle to find, and found by none",
               std::max(soft_report.early, soft_report.clamping))));
    return outcome;
  }
  const double soft_bound =
      soft_report.detectable < 0.0
          ? kNever
          : soft_report.detectable - soft_report.contact + kDetectionSlack + kDt / 2.0;
  outcome.results.push_back(at_most(
      kName, quantity_any + ", " + soft_line, 1000.0 * soft_bound, 1000.0 * delay(soft_report),
      "ms",
      format("at most %.0f ms after its torque through the observer's filter passed a "
             "threshold (%.0f ms after the contact); the force builds slowly: impact %.0f N "
             "against the rigid box's %.0f N; the target, 10 ms, holds where it builds fast "
             "enough",
             1000.0 * kDetectionSlack, 1000.0 * (soft_report.detectable - soft_report.contact),
             soft_report.impact, report.impact)));
  // Stopped, the arm holds where it came to rest, in the dent it made: the cushion goes on
  // pushing back with what it held then, no more (the spring does not press on).
  outcome.results.push_back(at_most(
      kName, "clamping force with stop, " + soft_line, soft_stop.early,
      soft_stop.contact >= 0.0 ? soft_stop.clamping : kNever, "N",
      format("at most the force while braking; %.0f N without a reaction", soft_report.clamping)));
  outcome.results.push_back(at_most(
      kName, "clamping force with retract, " + soft_line + ", share of report's", kClampingShare,
      soft_retract.contact >= 0.0 ? soft_retract.clamping / std::max(soft_report.clamping, 1e-9)
                                  : kNever,
      "", format("%.1f N against %.0f N", soft_retract.clamping, soft_report.clamping)));
  return outcome;
}

}  // namespace cartesian_impedance::scenarios::detail
