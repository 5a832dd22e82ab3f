// 11. Safety: the caps of the safety layer (safety.*, payload.*) hold what they promise in closed
// loop, each measured against the same command without the cap.

#include <algorithm>
#include <cmath>
#include <string>
#include <tuple>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "scenario_support.hpp"

namespace cartesian_impedance::scenarios::detail {

namespace {

constexpr const char* kName = "safety";

// The caps the issue states its figures with (issue 30): a 0.1 m/s speed cap and a 40 N force
// cap against a table at 3000 N/m, a 0.25 m/s cap for a 300 mm reference jump.
constexpr double kTableSpeedCap = 0.1;   // [m/s]
constexpr double kTunedForceCap = 40.0;  // [N]
constexpr double kTunedSpeedCap = 0.25;  // [m/s]
constexpr double kStiff = 3000.0;        // [N/m]
constexpr double kSpeedMargin = 1.1;     // the speed cap's promise: at most 10 % above it
constexpr double kGravity = CartesianImpedanceController::kGravity;

Parameters without_caps(Parameters parameters) {
  parameters.safety.max_speed = MaxSpeedParameters{};
  parameters.safety.max_force = MaxForceParameters{};
  return parameters;
}

// What the robot's mutation removes from the parameters a check runs with.
Parameters mutated(Parameters parameters, Mutation mutation) {
  switch (mutation) {
    case Mutation::no_speed_cap:
      parameters.safety.max_speed = MaxSpeedParameters{};
      break;
    case Mutation::no_force_cap:
      parameters.safety.max_force = MaxForceParameters{};
      break;
    case Mutation::no_workspace:
      parameters.safety.workspace = WorkspaceParameters{};
      break;
    case Mutation::no_payload:
      parameters.payload = PayloadParameters{};
      break;
    default:
      break;
  }
  return parameters;
}

void set_translation_stiffness(Parameters& parameters, double stiffness) {
  parameters.stiffness.translation.setConstant(
      std::min(stiffness, parameters.limits.stiffness.translation.max));
}

struct TableRun {
  double peak = 0.0;          // [N] largest contact force, every cycle
  double settled = 0.0;       // [N] mean over the last 0.5 s
  double impact_speed = 0.0;  // [m/s] over the cycle before the first contact
  double impact_mass = 0.0;   // [kg] the most mass the table can meet then (mass_along)
  std::vector<double> force;  // every cycle [N]
  double leak = 0.0;          // [N] the nullspace torque's force at the flange at the end
};

// ---- 1. Table: the force cap (with the speed cap) ----------------------------------------------

void table_contact(const RobotSetup& robot, Outcome& outcome, const MomentCallback& moment) {
  const std::string quantity_any = "table at 3000 N/m: contact force with the caps";
  Parameters parameters = base_parameters(robot);
  set_translation_stiffness(parameters, kStiff);
  const double stiffness = parameters.stiffness.translation.z();
  Rig probe(robot, without_caps(parameters));
  const TaskDirections directions = task_directions(probe);
  if (!directions.controlled[2]) {
    outcome.results.push_back(not_applicable(kName, quantity_any,
                                             "the arm cannot move its flange along z (it moves "
                                             "in " +
                                                 directions.describe() + ")"));
    return;
  }
  probe.run(0.2);
  if (const std::string reason = flange_without_geometry(probe, robot); !reason.empty()) {
    outcome.results.push_back(not_applicable(kName, quantity_any, reason));
    return;
  }
  const Pose flange = probe.flange();
  if (flange.position.z() < 0.14) {
    outcome.results.push_back(not_applicable(
        kName, quantity_any,
        format("the flange is at z = %.3g m at the start: no room for a table 10 cm under it",
               flange.position.z())));
    return;
  }
  // The force cap: the tuned 40 N, or less where the spring at its clipped error (K x
  // limits.pose_error) would not press with three times that (the cap would not bind), or where
  // the joints could not press down with twice that (the impact comes on top of the cap).
  const double spring_limit = stiffness * parameters.limits.pose_error.translation;
  const double cap = std::min({kTunedForceCap, spring_limit / 3.0,
                               0.5 * capacity(probe).force_along(-Eigen::Vector3d::UnitZ())});
  const double band = friction_band(probe).force_along.z();
  // A table whose top is 10 cm under the flange, that only the flange touches on its way down.
  const double table_top = flange.position.z() - 0.10;
  const std::vector<sim::Box> candidates = tables_under(flange.position.head<2>(), table_top);
  const sim::Box* fits =
      first_table_only_the_flange_meets(robot, parameters, probe, candidates, 0.10);
  if (fits == nullptr) {
    outcome.results.push_back(
        not_applicable(kName, quantity_any,
                       "another link of the arm would touch every table (down to 6 x 6 cm) "
                       "10 cm under the flange before the flange does"));
    return;
  }
  Pose inside = flange;
  inside.position.z() = table_top - 0.05;
  // `ramp`: the reference moved down at 0.1 m/s instead of jumping there.
  const auto press = [&](bool caps, bool ramp, const char* label) {
    Parameters used = without_caps(parameters);
    if (caps) {
      used.safety.max_speed.translation = kTableSpeedCap;
      used.safety.max_force.force = cap;
      used = mutated(used, robot.mutation);
    }
    Rig rig(robot, used, {*fits});
    rig.run(0.2);
    rig.remember_pose("before pressing");
    rig.phase(format("%s, reference %s 5 cm into the table", caps ? "caps" : "no caps",
                     ramp ? "moved at 0.1 m/s" : "jumps"));
    TableRun run;
    const double ramp_time = ramp ? (flange.position.z() - inside.position.z()) / 0.1 : 0.0;
    if (!ramp) rig.loop().set_reference_pose(inside);
    const double duration = ramp_time + 3.0;
    double time = 0.0, settled_sum = 0.0, last_speed = 0.0;
    int settled_count = 0;
    run_measured(rig, duration, [&](double speed) {
      time += kDt;
      if (ramp && time <= ramp_time + kDt) {
        Pose reference = flange;
        reference.position.z() = flange.position.z() - 0.1 * std::min(time, ramp_time);
        rig.loop().set_reference_pose(reference);
      }
      const double force = rig.contact_force().norm();
      if (force > 0.0 && run.impact_mass == 0.0) {
        run.impact_speed = last_speed;
        run.impact_mass = mass_along(rig, Eigen::Vector3d::UnitZ());
      }
      last_speed = speed;
      run.force.push_back(force);
      run.peak = std::max(run.peak, force);
      if (time > duration - 0.5) {
        settled_sum += force;
        ++settled_count;
      }
    });
    run.settled = settled_sum / std::max(settled_count, 1);
    run.leak = nullspace_wrench(rig).head<3>().norm();
    if (label != nullptr) {
      notify(
          moment, label, rig,
          {format("reference 5 cm inside the table at %.4g N/m; caps %s: peak %.0f N, "
                  "settled %.1f N",
                  stiffness, caps ? format("%.2g m/s, %.3g N", kTableSpeedCap, cap).c_str() : "off",
                  run.peak, run.settled)});
    }
    if (caps && !ramp) outcome.samples = rig.samples();
    return run;
  };
  outcome.overrides.push_back(
      format("table: stiffness.translation = %.4g N/m; safety.max_speed.translation = 0, then %.2g "
             "m/s, and safety.max_force.force = 0, then %.3g N (without, then with the caps)",
             stiffness, kTableSpeedCap, cap));
  const TableRun free_jump = press(false, false, "pressing without caps");
  const TableRun capped_jump = press(true, false, "pressing with the caps");
  const TableRun free_ramp = press(false, true, nullptr);
  const TableRun capped_ramp = press(true, true, nullptr);
  Table force{
      "force",
      {"time", "jump_without_caps", "jump_with_caps", "ramp_without_caps", "ramp_with_caps", "cap"},
      {}};
  const std::size_t rows = std::max(free_jump.force.size(), free_ramp.force.size());
  const auto at = [](const TableRun& run, std::size_t i) {
    return i < run.force.size() ? run.force[i] : std::nan("");
  };
  for (std::size_t i = 0; i < rows; ++i) {
    force.rows.push_back({(i + 1) * kDt, at(free_jump, i), at(capped_jump, i), at(free_ramp, i),
                          at(capped_ramp, i), cap});
  }
  outcome.tables.push_back(force);

  // The speed cap lets the flange reach the table at most 10 % faster than it. MuJoCo's soft
  // contact then stops the mass m it meets (at most mass_along: the flange's face held flat on
  // the table) with its reference acceleration b v, b = 2 / (d_max timeconst) = 105/s (the
  // defaults timeconst 0.02 s, d_max 0.95; one contact point takes the fraction d <= d_max of
  // it, several up to all of it), on top of what the controller presses with: the cap plus
  // 105/s x m x 1.1 c. DART's contact is rigid: it takes the momentum m v in one 1 ms step, a
  // peak of m v / dt that says nothing about the controller, so there the impact speed is what
  // is checked.
  const double impact_bound = kSpeedMargin * kTableSpeedCap;
  const bool soft_contact = robot.engine == sim::Engine::mujoco;
  const auto peak_bound = [&](const TableRun& run) {
    return cap + 2.0 / (0.95 * 0.02) * run.impact_mass * impact_bound;
  };
  const double settled_bound = cap + band;
  const std::string caps = format("caps %.2g m/s, %.3g N", kTableSpeedCap, cap);
  const std::string note_peak =
      "bound: the cap + 105/s x m x 1.1 c: the soft contact stopping the arm's mass m along z";
  const std::string note_settled =
      "bound: the cap + what the joints' friction holds along z (J^T (F + F_contact) = "
      "tau_friction) + what the nullspace torque pushes at the flange";
  const std::string rigid =
      "DART's rigid contact takes the arm's momentum in one step: its peak is m v / dt";
  const std::string vacuous = "at least the capped bound: the case the caps are for";
  for (const bool ramp : {false, true}) {
    const TableRun& free = ramp ? free_ramp : free_jump;
    const TableRun& capped = ramp ? capped_ramp : capped_jump;
    const std::string what = ramp ? "table, reference at 0.1 m/s: " : "table, reference jumps: ";
    if (!ramp) {
      outcome.results.push_back(at_least(kName, what + "impact speed without caps", impact_bound,
                                         free.impact_speed, "m/s", vacuous));
    }
    // The reference moved at 0.1 m/s reaches the table as slowly without the caps: there the
    // peak is the impact's either way, and the caps show in the settled force.
    if (!ramp) {
      outcome.results.push_back(
          soft_contact ? at_least(kName, what + "peak force without caps", capped.peak, free.peak,
                                  "N", "at least the capped run's: the caps lower it")
                       : not_applicable(kName, what + "peak force without caps", rigid));
    }
    outcome.results.push_back(at_least(kName, what + "settled force without caps", settled_bound,
                                       free.settled, "N", vacuous));
    outcome.results.push_back(at_most(kName, what + "impact speed, " + caps, impact_bound,
                                      capped.impact_speed, "m/s", "bound: 1.1 x the speed cap"));
    outcome.results.push_back(soft_contact
                                  ? at_most(kName, what + "peak force, " + caps, peak_bound(capped),
                                            capped.peak, "N", note_peak)
                                  : not_applicable(kName, what + "peak force, " + caps, rigid));
    // The force cap bounds the spring; the nullspace torque's leak (nullspace_wrench) presses
    // on top, and with no friction band there is nothing else to cover it.
    outcome.results.push_back(at_most(kName, what + "settled force, " + caps,
                                      settled_bound + capped.leak, capped.settled, "N",
                                      note_settled));
  }
}

// ---- 2. Speed: reference jumps, a commanded wrench, a push from outside ------------------------

void speed_cap(const RobotSetup& robot, Outcome& outcome, const MomentCallback& moment) {
  Parameters parameters = without_caps(base_parameters(robot));
  set_translation_stiffness(parameters, kStiff);
  const double stiffness = parameters.stiffness.translation.minCoeff();
  Rig probe(robot, parameters);
  probe.run(0.2);
  const Move travel = reachable_move(probe, 0.3);
  if (travel.length == 0.0) {
    outcome.results.push_back(not_applicable(kName, "reference jump: peak speed with the cap",
                                             "even an eighth of the move would take a joint "
                                             "within 0.1 rad of its limit"));
    return;
  }
  const Eigen::Vector3d& u = travel.direction;
  const double band = friction_band(probe).force;
  struct Run {
    double peak = 0.0;         // [m/s]
    double error = 0.0;        // [m] from the target at the end
    double joint_speed = 0.0;  // [rad/s] |dq| at the end
    std::vector<double> speeds;
  };
  const auto jump_to = [&](double cap) {
    Parameters used = parameters;
    used.safety.max_speed.translation = cap;
    if (cap > 0.0) used = mutated(used, robot.mutation);
    Rig rig(robot, used);
    rig.run(0.2);
    Pose target = rig.flange();
    target.position += travel.length * u;
    rig.remember_pose("before the jump");
    rig.phase(cap > 0.0 ? format("reference jumps, speed cap %.2g m/s", cap)
                        : std::string("reference jumps, no speed cap"));
    rig.loop().set_reference_pose(target);
    // The nullspace target moves with it (as in the reference step scenario): left behind, its
    // spring would pull the flange short of the target on an arm without redundancy.
    rig.loop().set_nullspace_target(travel.goal);
    Run run;
    run_measured(rig, 3.0, [&](double speed) {
      run.peak = std::max(run.peak, speed);
      run.speeds.push_back(speed);
    });
    if (cap > 0.0) {
      notify(moment, "reference jump with the speed cap", rig,
             {format("a %.0f mm reference jump at %.4g N/m: the flange peaked at %.2f m/s (cap "
                     "%.2g m/s)",
                     1e3 * travel.length, stiffness, run.peak, cap)});
    }
    run.error = (rig.flange().position - target.position).norm();
    run.joint_speed = rig.sim().true_dq().norm();
    return run;
  };
  const Run free_jump = jump_to(0.0);
  // The cap: the tuned 0.25 m/s, or half the uncapped peak where that is less (the cap binds).
  const double cap = std::min(kTunedSpeedCap, 0.5 * free_jump.peak);
  const Run capped_jump = jump_to(cap);
  outcome.overrides.push_back(
      format("speed: stiffness.translation = %.4g N/m (0 along the commanded force); "
             "safety.max_force = 0; safety.max_speed.translation = 0, then %.2g m/s",
             stiffness, cap));

  // A joint trajectory to the same place twice as fast as the cap: tracked (track()), its
  // reference is not held back, but its velocity, which the damper pulls toward, is. Cosine-
  // shaped, its peak speed is about pi / 2 x the distance / the duration; no joint faster than
  // half its URDF limit, and where that makes it slower, a cap of half its speed.
  const JointVector start_q = probe.sim().true_q();
  double duration = 0.5 * M_PI * travel.length / (2.0 * cap);
  for (int i = 0; i < start_q.size(); ++i) {
    duration = std::max(duration, 0.5 * M_PI * std::abs(travel.goal[i] - start_q[i]) /
                                      (0.5 * probe.model().limits().velocity[i]));
  }
  const double trajectory_cap = std::min(cap, 0.25 * M_PI * travel.length / duration);
  double trajectory_reference_peak = 0.0;
  const Run trajectory = [&] {
    Parameters used = parameters;
    used.safety.max_speed.translation = trajectory_cap;
    used = mutated(used, robot.mutation);
    Rig rig(robot, used);
    rig.run(0.2);
    JointTrajectory trajectory;
    trajectory.joint_names = rig.model().joint_names();
    for (int k = 1; k <= 40; ++k) {
      const double s = 0.5 * (1.0 - std::cos(M_PI * k / 40.0));
      const JointVector q = start_q + s * (travel.goal - start_q);
      trajectory.times.push_back(duration * k / 40.0);
      trajectory.positions.emplace_back(q.data(), q.data() + q.size());
    }
    rig.phase(format("trajectory, speed cap %.2g m/s", trajectory_cap));
    try {
      rig.loop().execute_trajectory(trajectory);
    } catch (const Error& refused) {
      // A broken controller (a mutation) may leave the arm moving so fast that the segment
      // from where it is overshoots a limit: nothing is tracked, which the checks then show.
      (void)refused;
    }
    Run run;
    run_measured(rig, duration + 1.0, [&](double speed) {
      run.peak = std::max(run.peak, speed);
      run.speeds.push_back(speed);
      trajectory_reference_peak =
          std::max(trajectory_reference_peak,
                   rig.loop().state().controller.commanded.twist.head<3>().norm());
    });
    return run;
  }();

  // A commanded force in free space: no spring along it, so only the damping would hold it back
  // (F / d = 1.3 m/s for 40 N and 30 N s/m).
  Parameters soft = parameters;
  int axis = 0;
  u.cwiseAbs().maxCoeff(&axis);
  soft.stiffness.translation[axis] = 0.0;
  soft.safety.max_speed.translation = cap;
  soft = mutated(soft, robot.mutation);
  Rig pushed_by_wrench(robot, soft);
  const double wrench = std::min(
      {40.0, parameters.limits.wrench.force, 0.5 * capacity(pushed_by_wrench).force_along(u)});
  pushed_by_wrench.run(0.2);
  const Eigen::Vector3d start = pushed_by_wrench.flange().position;
  Vector6d force = Vector6d::Zero();
  force.head<3>() = wrench * u;
  pushed_by_wrench.phase(format("commanded %.3g N, no spring along it", wrench));
  pushed_by_wrench.loop().set_wrench(force);
  double wrench_peak = 0.0;
  std::vector<double> wrench_speeds;
  for (int k = 0; k < 2000 && (pushed_by_wrench.flange().position - start).dot(u) < travel.length;
       ++k) {
    run_measured(pushed_by_wrench, kDt, [&](double speed) {
      wrench_peak = std::max(wrench_peak, speed);
      wrench_speeds.push_back(speed);
    });
  }

  // A push from outside while teaching: faster than the cap, braked by damping (a force that
  // depends on the speed alone), not held by a spring.
  Parameters teaching = parameters;
  const double floor = parameters.minimum_damping.translation;
  const double push = std::min(20.0, kLoadShare * capacity(probe).force_along(u));
  const double push_cap = std::min(cap, 0.5 * push / floor);
  teaching.safety.max_speed.translation = push_cap;
  teaching = mutated(teaching, robot.mutation);
  Rig hand(robot, teaching);
  hand.loop().start_teaching();
  hand.phase("teaching");
  hand.run(0.5);
  const Eigen::Vector3d hand_start = hand.flange().position;
  hand.push(push * u);
  std::vector<double> push_speeds;
  double pushed_for = 0.0;
  while (pushed_for < 0.6 && (hand.flange().position - hand_start).dot(u) < travel.length) {
    run_measured(hand, kDt, [&](double speed) { push_speeds.push_back(speed); });
    pushed_for += kDt;
  }
  // Speed over the last 20 ms of the push, and the force the controller opposed it with.
  Eigen::Vector3d before = hand.flange().position;
  hand.run(0.02);
  const Eigen::Vector3d velocity = (hand.flange().position - before) / 0.02;
  const double speed = velocity.norm();
  // Above the speed the governor holds (kSpeedCapAim x the cap), its disturbance observer sees
  // the push as what accelerates the flange beyond the torque sent, and holds it: the flange stays
  // at the cap however hard it is pushed, and springs back nowhere (no stiffness: the brake acts
  // on the speed alone).
  notify(moment, "pushed faster than the cap", hand,
         {format("teaching (no spring); a %.3g N push against %.3g N s/m of damping would reach "
                 "%.2f m/s; the %.2g m/s cap holds it at %.2f m/s",
                 push, floor, push / floor, push_cap, speed)});
  hand.release();
  const Eigen::Vector3d released = hand.flange().position;
  hand.run(1.0);
  const double spring_back = std::max(0.0, -(hand.flange().position - released).dot(u));

  Table speeds{"speed",
               {"time", "jump_without_cap", "jump_with_cap", "trajectory_with_cap",
                "wrench_with_cap", "push_with_cap", "cap", "push_cap", "push_unbraked"},
               {}};
  const std::size_t rows =
      std::max({free_jump.speeds.size(), capped_jump.speeds.size(), trajectory.speeds.size(),
                wrench_speeds.size(), push_speeds.size()});
  const auto at = [](const std::vector<double>& v, std::size_t i) {
    return i < v.size() ? v[i] : std::nan("");
  };
  for (std::size_t i = 0; i < rows; ++i) {
    speeds.rows.push_back({(i + 1) * kDt, at(free_jump.speeds, i), at(capped_jump.speeds, i),
                           at(trajectory.speeds, i), at(wrench_speeds, i), at(push_speeds, i), cap,
                           push_cap, push / floor});
  }
  outcome.tables.push_back(speeds);

  const double bound = kSpeedMargin * cap;
  const std::string jump = format("%.0f mm jump at %.4g N/m", 1e3 * travel.length, stiffness);
  outcome.results.push_back(at_least(kName, jump + ": peak speed without a cap", bound,
                                     free_jump.peak, "m/s",
                                     "at least 1.1 x the cap: the case the cap is for"));
  outcome.results.push_back(at_most(kName, jump + format(": peak speed, cap %.2g m/s", cap), bound,
                                    capped_jump.peak, "m/s", "bound: 1.1 x the cap"));
  // Capped, the arm still gets there; where it does not come to rest within the 3 s even
  // without the cap (weak joints at their derived stiffness), that says nothing of the cap.
  const std::string reached = jump + ": position error 3 s later";
  outcome.results.push_back(
      free_jump.joint_speed < 0.01
          ? at_most(kName, reached, 1e3 * (0.002 + band / stiffness), 1e3 * capped_jump.error, "mm",
                    "bound: 2 mm + what joint friction can hold against the spring")
          : not_applicable(kName, reached,
                           format("without the cap the arm is still moving 3 s after the jump "
                                  "(|dq| = %.2g rad/s)",
                                  free_jump.joint_speed)));
  const double trajectory_bound = kSpeedMargin * trajectory_cap;
  outcome.results.push_back(at_least(kName, "trajectory: its own peak speed", trajectory_bound,
                                     trajectory_reference_peak, "m/s",
                                     "at least 1.1 x the cap: the case the cap is for"));
  outcome.results.push_back(
      at_most(kName, format("trajectory: peak speed, cap %.2g m/s", trajectory_cap),
              trajectory_bound, trajectory.peak, "m/s", "bound: 1.1 x the cap"));
  outcome.results.push_back(
      at_most(kName, format("commanded %.3g N, no spring: peak speed, cap %.2g m/s", wrench, cap),
              bound, wrench_peak, "m/s",
              format("bound: 1.1 x the cap; without it the damping alone would let it reach "
                     "F / d = %.2g m/s",
                     wrench / floor)));
  outcome.results.push_back(
      at_most(kName, format("%.3g N push while teaching: speed, cap %.2g m/s", push, push_cap),
              kSpeedMargin * push_cap, speed, "m/s",
              format("bound: 1.1 x the cap (without the cap: F / d = %.2g m/s)", push / floor)));
  outcome.results.push_back(at_most(kName, "spring-back after that push (none: no stiffness)", 1.0,
                                    1e3 * spring_back, "mm"));
}

// ---- 3. Workspace: walls while teaching, references clipped into the box ----------------------

void workspace(const RobotSetup& robot, Outcome& outcome, const MomentCallback& moment) {
  Parameters parameters = base_parameters(robot);
  if (!(parameters.safety.workspace.stiffness > 0.0))
    parameters.safety.workspace.stiffness = 2000.0;
  const double wall = parameters.safety.workspace.stiffness;
  Rig probe(robot, parameters);
  probe.run(0.2);
  const Move travel = reachable_move(probe, 0.3);
  if (travel.length == 0.0) {
    outcome.results.push_back(not_applicable(kName, "push toward a wall while teaching",
                                             "the arm cannot move its flange in x, y or z"));
    return;
  }
  const Eigen::Vector3d& u = travel.direction;
  int axis = 0;
  u.cwiseAbs().maxCoeff(&axis);
  const double sense = u[axis];
  // A box around the start whose wall faces the push 5 cm away; the other faces leave room.
  const Eigen::Vector3d start = probe.flange().position;
  const double gap = std::min(0.05, 0.5 * travel.length);
  Parameters boxed = parameters;
  boxed.safety.workspace.min = start - Eigen::Vector3d::Constant(0.3);
  boxed.safety.workspace.max = start + Eigen::Vector3d::Constant(0.3);
  (sense > 0.0 ? boxed.safety.workspace.max : boxed.safety.workspace.min)[axis] =
      start[axis] + sense * gap;
  const double face = start[axis] + sense * gap;
  // The box the checks measure against: the scenario's, also when a mutation removes it from
  // the controller's parameters.
  const WorkspaceParameters box = boxed.safety.workspace;
  boxed = mutated(boxed, robot.mutation);
  const double push = std::min(20.0, kLoadShare * capacity(probe).force_along(u));
  const double band = friction_band(probe).force_along[axis];
  outcome.overrides.push_back(
      format("workspace: safety.workspace.min/max = a box of +-0.3 m about the start, its face "
             "across %c %.3g m from the flange; safety.workspace.stiffness = %.4g N/m",
             "xyz"[axis], gap, wall));
  // How far beyond the face the flange is (positive: outside the box).
  const auto beyond = [&](const Eigen::Vector3d& position) {
    return sense * (position[axis] - face);
  };

  // The flange's path and the reference the law used, every 10 ms of both runs (run 0: pushed
  // while teaching; run 1: the reference outside), with the box and what was asked for.
  Table path{
      "workspace",
      {"time", "run", "x", "y", "z", "reference_x", "reference_y", "reference_z", "requested_x",
       "requested_y", "requested_z", "min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "axis"},
      {}};
  const auto record = [&](Rig& rig, double run, const Eigen::Vector3d& requested) {
    const Eigen::Vector3d p = rig.flange().position;
    const Eigen::Vector3d r = rig.loop().state().controller.filtered.pose.position;
    path.rows.push_back({rig.time(), run, p.x(), p.y(), p.z(), r.x(), r.y(), r.z(), requested.x(),
                         requested.y(), requested.z(), box.min.x(), box.min.y(), box.min.z(),
                         box.max.x(), box.max.y(), box.max.z(), static_cast<double>(axis)});
  };
  const Eigen::Vector3d nothing = Eigen::Vector3d::Constant(std::nan(""));

  // Teaching (no spring), pushed toward the wall.
  // Looking along the face (from the front for a push sideways): the wall is seen edge-on.
  const double azimuth = axis == 1 ? 150.0 : std::nan(""),
               elevation = axis == 1 ? -25.0 : std::nan("");
  Rig hand(robot, boxed);
  hand.view(azimuth, elevation);
  hand.loop().start_teaching();
  hand.phase("teaching");
  hand.run(0.5);
  hand.push(push * u);
  double deepest = -kForever, entry_speed = 0.0, entry_mass = 0.0, entry_damping = 0.0,
         entry_force_rate = kForever;
  for (int k = 0; k < 2000; ++k) {
    const double before = beyond(hand.flange().position);
    hand.run(kDt);
    const double now = beyond(hand.flange().position);
    if (before < 0.0 && now >= 0.0) {  // crossing the face
      entry_speed = (now - before) / kDt;
      entry_mass = mass_along(hand, u);
      entry_damping =
          u.dot(hand.loop().state().controller.damping_base().topLeftCorner<3, 3>() * u);
      // How fast the joints' torque-rate limits let a force along u at the flange change.
      const Eigen::VectorXd lever = jacobian_now(hand).topRows<3>().transpose() * u;
      const JointVector rates =
          per_joint(hand.loop().controller().parameters().limits.joint_torque_rate,
                    hand.model().num_joints());
      entry_force_rate = kForever;
      for (int i = 0; i < lever.size(); ++i) {
        if (std::abs(lever[i]) > 1e-9)
          entry_force_rate =
              std::min(entry_force_rate, CartesianImpedanceController::kWallRateShare * rates[i] /
                                             std::abs(lever[i]));
      }
    }
    deepest = std::max(deepest, now);
    if (k % 10 == 0) record(hand, 0.0, nothing);
    // A flange far beyond the wall (walls removed) is stopped here: 5 cm say enough.
    if (deepest > 0.05) break;
  }
  double rest = 0.0;
  for (int k = 0; k < 100; ++k) {
    hand.run(kDt);
    rest += beyond(hand.flange().position) / 100.0;
    if (k % 10 == 0) record(hand, 0.0, nothing);
  }
  Pose none;
  none.position.setConstant(std::nan(""));
  notify(showing_box_face(moment, robot.base_link, box, axis, face, none),
         "pushed against the wall", hand,
         {format("teaching (no spring): %.3g N toward a wall of %.4g N/m 5 cm away; at most %.1f "
                 "mm beyond it (theory F / K_wall = %.1f mm)",
                 push, wall, 1e3 * deepest, 1e3 * push / wall)});
  hand.release();

  // A reference 10 cm beyond the wall, at the configured stiffness.
  Rig reach(robot, boxed);
  reach.view(azimuth, elevation);
  reach.run(0.2);
  reach.remember_pose("at the start");
  Pose outside = reach.flange();
  outside.position += (gap + 0.1) * u;
  reach.phase("reference 10 cm outside the box");
  reach.loop().set_reference_pose(outside);
  double reference_out = 0.0;
  for (int k = 0; k < 3000; ++k) {
    reach.run(kDt);
    const Eigen::Vector3d r = reach.loop().state().controller.filtered.pose.position;
    reference_out = std::max(reference_out, (r - r.cwiseMax(box.min).cwiseMin(box.max)).norm());
    if (k % 10 == 0) record(reach, 1.0, outside.position);
  }
  const double reach_rest = beyond(reach.flange().position);
  notify(showing_box_face(moment, robot.base_link, box, axis, face, outside),
         "reference outside the box", reach,
         {format("the reference 10 cm beyond the box's face is clipped onto it; the flange "
                 "stops %.1f mm %s the face",
                 1e3 * std::abs(reach_rest), reach_rest > 0.0 ? "beyond" : "inside")});
  outcome.tables.push_back(path);
  const double stiffness = parameters.stiffness.translation[axis];
  // Beyond the face the flange moves outward, so the wall's spring and damper both act:
  // m x'' = F - F_wall - d x', from x = 0 at the speed it crossed with, where F_wall goes toward
  // K_wall x + D_wall x' no faster than the share of the joints' torque-rate limits the controller
  // gives a wall (kWallRateShare) lets a force along the push change (the damper's force starts as
  // a step of D_wall v at the face: 45 N on the Panda, which the rate limit spreads over some
  // 20 ms). The deepest point of that motion, with m the most
  // mass the flange can carry there (mass_along) and without the simulated joints' own damping
  // and friction, which only shorten it; plus what friction can hold against the wall.
  double x = 0.0, v = entry_speed, predicted = 0.0, wall_force = 0.0;
  for (int k = 0; k < 1000000 && v > 0.0 && entry_mass > 0.0; ++k) {
    const double wanted = wall * x + box.damping * v;
    wall_force +=
        std::clamp(wanted - wall_force, -entry_force_rate * 1e-6, entry_force_rate * 1e-6);
    v += 1e-6 * (push - wall_force - entry_damping * v) / entry_mass;
    x += 1e-6 * v;
    predicted = std::max(predicted, x);
  }
  outcome.results.push_back(at_most(
      kName, format("%.3g N push while teaching: deepest beyond the wall", push),
      1e3 * (predicted + band / wall), 1e3 * deepest, "mm",
      format("bound: m x'' = F - F_wall - d x' from the %.2g m/s it crossed with, m = %.3g "
             "kg, F_wall rate-limited toward K_wall x + D_wall x'; issue 30 asks F / K_wall + "
             "5 mm = %.3g mm of the shipped robots",
             entry_speed, entry_mass, 1e3 * (push / wall + 0.005))));
  outcome.results.push_back(
      compare(kName, format("%.3g N push while teaching: rest beyond the wall", push),
              1e3 * push / wall, 1e3 * rest, "mm", 1e3 * (0.05 * push / wall + band / wall),
              "theory F / K_wall; 5 % and what the joints' friction holds"));
  // The filter blends clipped references, each exactly inside; the blend rounds (measured
  // 1e-16 m on the realistic UR5e): a few units in the last place of a coordinate below 1 m.
  outcome.results.push_back(at_most(kName, "reference 10 cm outside: filtered reference outside",
                                    1e-9, 1e3 * reference_out, "mm", "round-off"));
  outcome.results.push_back(at_most(kName,
                                    "reference 10 cm outside: flange at rest beyond the face",
                                    1e3 * band / stiffness, 1e3 * std::max(reach_rest, 0.0), "mm",
                                    "bound: what joint friction can hold against the spring"));
}

// ---- 4. Payload: declared, compensated; undeclared, estimated -----------------------------------

void payload(const RobotSetup& robot, Outcome& outcome, const MomentCallback& moment) {
  const Parameters parameters = base_parameters(robot);
  Rig probe(robot, parameters);
  const TaskDirections directions = task_directions(probe);
  const std::string quantity_any = "payload declared: sag";
  if (!directions.controlled[2]) {
    outcome.results.push_back(not_applicable(kName, quantity_any,
                                             "the arm cannot move its flange along z (it moves "
                                             "in " +
                                                 directions.describe() + ")"));
    return;
  }
  const double stiffness = parameters.stiffness.translation.z();
  // 1 kg, or what the joints hold with room to spare and the spring carries within a few cm
  // (as the hold scenario).
  const double weight =
      fitted_load(kGravity, capacity(probe).force_along(-Eigen::Vector3d::UnitZ()), stiffness,
                  std::min(0.04, 0.9 * parameters.limits.pose_error.translation));
  const double mass = weight / kGravity;
  // As the hold scenario: what the joints' friction can hold at the flange (any direction).
  const double band = friction_band(probe).force;
  if (weight < 5.0 * band) {
    outcome.results.push_back(not_applicable(
        kName, quantity_any,
        format("the joints carry %.2g N with room to spare, not 5 x the %.2g N their friction "
               "holds along z",
               weight, band)));
    return;
  }
  // The payload hangs at the flange (its weight pushes there, as in the hold scenario), not
  // declared, or declared as it is hung (set_parameters; the change filtered with
  // filter.wrench).
  const auto hang = [&](bool declared, const char* label) {
    Rig rig(robot, parameters);
    rig.run(0.5);
    const Pose reference = rig.loop().state().controller.filtered.pose;
    rig.remember_pose("without the payload");
    rig.push(Eigen::Vector3d(0.0, 0.0, -weight));
    if (declared) {
      Parameters used = parameters;
      used.payload.mass = mass;
      rig.loop().set_parameters(mutated(used, robot.mutation));
    }
    rig.phase(format("%.3g kg payload, %s", mass, declared ? "declared" : "not declared"));
    // In two parts: the estimate averages the spring's force over the stillness
    // (kPayloadSettleTime), so what the flange still sagged over its last part the estimate has
    // not all seen yet.
    rig.run(3.0 - CartesianImpedanceController::kPayloadSettleTime);
    const double before = rig.flange().position.z();
    rig.run(CartesianImpedanceController::kPayloadSettleTime);
    const double sag = (reference.position - rig.flange().position).z();
    const double still_sagging = std::abs(rig.flange().position.z() - before);
    const SafetyState& safety = rig.loop().state().controller.safety;
    std::vector<std::string> details = {
        format("a %.3g kg payload %s: the flange sags %.1f mm (undeclared theory m g / K = "
               "%.1f mm)",
               mass, declared ? "declared (payload.mass)" : "not declared", 1e3 * sag,
               1e3 * weight / stiffness)};
    if (!declared) {
      details.push_back(format("the controller's estimate: %.3f kg (%s)",
                               safety.payload_estimate_mass,
                               safety.payload_estimate_valid ? "valid" : "not valid"));
    }
    notify(moment, label, rig, details);
    return std::make_tuple(
        sag, safety.payload_estimate_valid ? safety.payload_estimate_mass : std::nan(""),
        nullspace_wrench(rig).head<3>().norm(), still_sagging);
  };
  const auto [undeclared_sag, estimate, leak, lag] = hang(false, "payload not declared");
  const double declared_sag = std::get<0>(hang(true, "payload declared"));
  // What the joints' friction holds at the flange, and what keeps a frictionless arm off m g / K
  // once it has settled: the nullspace torque's leak (nullspace_wrench) and what the flange
  // still sagged over the last 0.5 s (K x that). The projector's damping (0.01) lets through
  // about 0.1 % of the load at a start chosen clear of singularities; more than 1 % means the
  // arm is not at the equilibrium the theory describes (a broken law, thrown to a joint limit),
  // and must not widen the check.
  const double settling = std::min(leak + stiffness * lag, 0.01 * weight);
  const double held = band + settling;
  outcome.overrides.push_back(format(
      "payload: payload.mass = %.3g kg sent with set_parameters as the payload is hung", mass));
  outcome.results.push_back(
      compare(kName, format("%.3g kg payload not declared: sag (m g / K)", mass),
              1e3 * weight / stiffness, 1e3 * undeclared_sag, "mm", 1e3 * held / stiffness,
              "tolerance: what joint friction holds, and the settling (nullspace torque, the "
              "last 0.5 s's sag) up to 1 % of the load"));
  outcome.results.push_back(at_most(kName, format("%.3g kg payload declared: |sag|", mass),
                                    std::max(1.0, 1e3 * band / stiffness),
                                    1e3 * std::abs(declared_sag), "mm",
                                    "bound: 1 mm (the issue's), or what joint friction can hold "
                                    "where that is more"));
  // At rest the spring holds the weight up to `held` (friction and settling, above).
  outcome.results.push_back(compare(
      kName, format("%.3g kg payload not declared: estimated mass", mass), mass,
      std::isnan(estimate) ? 0.0 : estimate, "kg", held / kGravity,
      std::isnan(estimate) ? "not valid: the flange was not still for 0.5 s"
                           : "tolerance: what joint friction holds, and the settling (nullspace "
                             "torque, the last 0.5 s's sag) up to 1 % of the load, / g"));
}

}  // namespace

Outcome safety(const RobotSetup& robot, const MomentCallback& moment) {
  Outcome outcome;
  // With one cap removed (a mutation, to show that its checks fail) only the parts that check
  // it run: the table checks the force cap and the speed at impact.
  const Mutation mutation = robot.mutation;
  const bool every = mutation != Mutation::no_speed_cap && mutation != Mutation::no_force_cap &&
                     mutation != Mutation::no_workspace && mutation != Mutation::no_payload;
  if (every || mutation == Mutation::no_force_cap || mutation == Mutation::no_speed_cap) {
    table_contact(robot, outcome, moment);
  }
  if (every || mutation == Mutation::no_speed_cap) speed_cap(robot, outcome, moment);
  if (every || mutation == Mutation::no_workspace) workspace(robot, outcome, moment);
  if (every || mutation == Mutation::no_payload) payload(robot, outcome, moment);
  return outcome;
}

}  // namespace cartesian_impedance::scenarios::detail
