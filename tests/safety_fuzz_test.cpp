// Issue 40's promise as a property, not as parts: seeded, generated compositions of valid commands
// on the four shipped robots and on generated arms nobody tuned (tests/arms/generate_arm.py), in
// MuJoCo and DART, each checked on every cycle against what the README's safety layer promises.
//
// Two families:
// - Commands: references in and out of reach and into a table, diagonal and full stiffness,
//   wrenches, payloads declared but not carried, workspace boxes moved past the flange with walls
//   up to 100,000 N/m, pose-error clips and filters changed, nullspace targets and stiffness,
//   teaching, pushes, run-time parameter updates; with speed and force caps drawn per
//   composition. Promises: the flange no faster than 1.1 x the speed caps (translation and
//   rotation) on every cycle that no push from outside drove (none in the last 0.5 s); the force
//   on a table at rest at most the force cap plus what the joints' friction holds.
// - Schedules: the energy-storing parameters changed at random while the arm is off its
//   reference (stiffness, damping, pose-error clips, the workspace box and its walls, filters),
//   caps off, no contact. Promise: kinetic + spring + wall + tank energy never grows.
//
// The counts per arm are for CI; SAFETY_FUZZ_SCALE=10 (an environment variable) runs ten times as
// many compositions for a long run. A failure prints the arm, engine, family, seed and the events
// that led to it.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/start_configuration.hpp"
#include "scenario_support.hpp"

namespace ci = cartesian_impedance;
namespace scenarios = cartesian_impedance::scenarios;

namespace {

constexpr double kDt = 0.001;
constexpr double kG = ci::CartesianImpedanceController::kGravity;

int scale() {
  const char* text = std::getenv("SAFETY_FUZZ_SCALE");
  const int value = text == nullptr ? 1 : std::atoi(text);
  return std::max(value, 1);
}

double uniform(std::mt19937& rng, double low, double high) {
  return std::uniform_real_distribution<double>(low, high)(rng);
}

// Log-uniform in [low, high].
double log_uniform(std::mt19937& rng, double low, double high) {
  return low * std::pow(high / low, uniform(rng, 0.0, 1.0));
}

bool chance(std::mt19937& rng, double p) {
  return uniform(rng, 0.0, 1.0) < p;
}

Eigen::Vector3d random_direction(std::mt19937& rng) {
  std::normal_distribution<double> normal;
  Eigen::Vector3d v(normal(rng), normal(rng), normal(rng));
  return v.normalized();
}

// An arm nobody tuned, from the generator the generated_arms test uses, started where the demo
// would start it.
scenarios::RobotSetup generated_arm(int seed) {
  const std::string path =
      ::testing::TempDir() + "/safety_fuzz_arm_" + std::to_string(seed) + ".urdf";
  const std::string command = "/usr/bin/python3 " CARTESIAN_IMPEDANCE_SOURCE_DIR
                              "/tests/arms/generate_arm.py --seed " +
                              std::to_string(seed) + " --out " + path + " > /dev/null";
  if (std::system(command.c_str()) != 0) throw ci::Error("cannot generate arm: " + command);
  scenarios::RobotSetup setup{
      "arm_seed_" + std::to_string(seed), path, "", "base_link", "tool0", "tool0", ""};
  setup.start_q = ci::find_start_configuration(
                      ci::RobotModel::from_urdf_file(path, setup.base_link, setup.tip_link))
                      .q;
  return setup;
}

scenarios::RobotSetup arm_named(const std::string& name) {
  if (name.rfind("arm_seed_", 0) == 0) return generated_arm(std::stoi(name.substr(9)));
  return scenarios::builtin_robot(name, CARTESIAN_IMPEDANCE_SOURCE_DIR);
}

// The flange's translational and angular speed over one cycle (ground truth).
struct Motion {
  double speed = 0.0;
  double angular = 0.0;
};

Motion step(scenarios::Rig& rig, ci::Pose& previous) {
  rig.run(kDt);
  const ci::Pose now = rig.flange();
  Motion motion{(now.position - previous.position).norm() / kDt,
                now.orientation.angularDistance(previous.orientation) / kDt};
  previous = now;
  return motion;
}

// What happened, for the failure message.
struct Log {
  std::ostringstream text;
  template <typename... Parts>
  void add(double time, const Parts&... parts) {
    text << "  t = " << time << " s:";
    ((text << " " << parts), ...);
    text << "\n";
  }
};

ci::JointVector random_configuration(const ci::RobotModel& model, const ci::JointVector& around,
                                     double spread, std::mt19937& rng) {
  const ci::JointLimits& limits = model.limits();
  ci::JointVector q = around;
  for (int i = 0; i < q.size(); ++i) {
    q[i] = std::clamp(q[i] + uniform(rng, -spread, spread), limits.position_lower[i] + 0.1,
                      limits.position_upper[i] - 0.1);
  }
  return q;
}

// An update of the rows named, from the parameters in force; one the loop refuses (it would
// break a rule that ties parameters together) is logged and skipped.
template <typename Edit>
void update(scenarios::Rig& rig, Log& log, double time,
            std::initializer_list<std::string_view> rows, const Edit& edit) {
  ci::Parameters values = rig.loop().latest_parameters();
  edit(values);
  try {
    rig.loop().update_parameters(ci::ParameterUpdate::of(values, rows));
    std::string names;
    for (const std::string_view row : rows) names += std::string(row) + " ";
    log.add(time, "update", names);
  } catch (const ci::Error& error) {
    log.add(time, "refused:", error.what());
  }
}

// ---- the command family ----------------------------------------------------------------------

struct CommandFigures {
  double worst_speed_fraction = 0.0;
  double worst_angular_fraction = 0.0;
  double worst_settled_excess = -1e9;  // [N] settled force - (cap + friction band)
  int settled_contacts = 0;
  int over_speed = 0;  // compositions that passed 1.1 x a cap somewhere
  int reported = 0;    // of those, the ones whose log was printed
};

void command_composition(const scenarios::RobotSetup& robot, std::uint32_t seed,
                         CommandFigures& figures) {
  std::mt19937 rng(seed);
  Log log;
  ci::Parameters p = scenarios::base_parameters(robot);
  ci::SafetyParameters& caps = p.safety;
  caps.max_speed = {uniform(rng, 0.1, 0.5), uniform(rng, 0.5, 2.0)};
  caps.max_force = {uniform(rng, 20.0, 80.0), uniform(rng, 5.0, 20.0)};
  caps.workspace = ci::WorkspaceParameters{};
  log.add(0.0, "caps", caps.max_speed.translation, "m/s", caps.max_speed.rotation, "rad/s",
          caps.max_force.force, "N", caps.max_force.torque, "Nm");
  // Half of them with a table under the flange that only the flange meets on its way down.
  std::vector<ci::sim::Box> boxes;
  {
    scenarios::Rig probe(robot, p);
    probe.run(0.05);
    const ci::Pose flange = probe.flange();
    if (chance(rng, 0.5) && flange.position.z() > 0.2) {
      const double depth = uniform(rng, 0.03, 0.08);
      const std::vector<ci::sim::Box> candidates =
          scenarios::detail::tables_under(flange.position.head<2>(), flange.position.z() - depth);
      const ci::sim::Box* table = scenarios::detail::first_table_only_the_flange_meets(
          robot, p, probe, candidates, depth + 0.03);
      if (table != nullptr) {
        boxes.push_back(*table);
        log.add(0.0, "table", depth, "m under the flange");
      }
    }
  }
  scenarios::Rig rig(robot, p, boxes);
  ci::ControlLoop& loop = rig.loop();
  const ci::RobotModel& model = rig.model();
  const ci::LimitParameters& limits = p.limits;
  const ci::JointVector home = rig.sim().q();
  ci::Pose previous = rig.flange();
  double last_push_end = -1.0, push_end = -1.0, last_contact = -1.0;
  const double duration = 4.0, quiet = 1.5;
  double next_event = uniform(rng, 0.05, 0.3);
  bool pressed = false;
  double worst = 0.0;           // the largest speed / cap past 1.1
  std::string violation;        // where it was
  std::vector<double> contact;  // the flange's contact force over the last 0.5 s [N]
  for (int k = 1; k <= static_cast<int>(duration / kDt); ++k) {
    const double time = k * kDt;
    if (!boxes.empty() && !pressed && time >= duration - quiet) {
      // The settled force: the reference into the table, a wrench down, the stiffness as it is.
      pressed = true;
      ci::Pose target = rig.flange();
      target.position.z() =
          boxes.front().center.z() + boxes.front().half_size.z() - uniform(rng, 0.02, 0.1);
      loop.set_reference_pose(target);
      if (chance(rng, 0.5)) {
        loop.set_wrench(
            (ci::Vector6d() << 0, 0, -uniform(rng, 0.0, limits.wrench.force), 0, 0, 0).finished());
      }
      log.add(time, "press into the table", target.position.transpose());
    }
    if (time >= next_event && time < duration - quiet) {
      next_event = time + uniform(rng, 0.1, 0.6);
      const ci::Pose now = rig.flange();
      try {
        switch (std::uniform_int_distribution<int>(0, 11)(rng)) {
          case 0: {  // a reference nearby, far, or into the table
            ci::Pose target = now;
            const double reach = chance(rng, 0.2) ? 0.6 : 0.2;
            target.position += uniform(rng, 0.0, reach) * random_direction(rng);
            if (!boxes.empty() && chance(rng, 0.4)) target.position.z() -= uniform(rng, 0.0, 0.12);
            target.orientation =
                Eigen::AngleAxisd(uniform(rng, 0.0, 0.4), random_direction(rng)) * now.orientation;
            loop.set_reference_pose(target);
            log.add(time, "reference", target.position.transpose());
            break;
          }
          case 1: {
            ci::Vector6d k;
            for (int i = 0; i < 3; ++i) k[i] = uniform(rng, 0.0, limits.stiffness.translation.max);
            for (int i = 3; i < 6; ++i) k[i] = uniform(rng, 0.0, limits.stiffness.rotation.max);
            loop.set_stiffness(k);
            log.add(time, "stiffness", k.transpose());
            break;
          }
          case 2: {  // a full matrix
            const ci::Matrix6d root = ci::Matrix6d::Random();
            ci::Matrix6d k = root * root.transpose();
            k *=
                uniform(rng, 0.0, 1.0) * limits.stiffness.translation.max / k.diagonal().maxCoeff();
            k.bottomRightCorner<3, 3>() *=
                limits.stiffness.rotation.max / limits.stiffness.translation.max;
            k.topRightCorner<3, 3>() *=
                std::sqrt(limits.stiffness.rotation.max / limits.stiffness.translation.max);
            k.bottomLeftCorner<3, 3>() = k.topRightCorner<3, 3>().transpose();
            loop.set_stiffness_matrix(k);
            log.add(time, "full stiffness");
            break;
          }
          case 3: {
            ci::Vector6d wrench;
            wrench << uniform(rng, 0.0, limits.wrench.force) * random_direction(rng),
                uniform(rng, 0.0, limits.wrench.torque) * random_direction(rng);
            loop.set_wrench(wrench);
            log.add(time, "wrench", wrench.transpose());
            break;
          }
          case 4:  // a payload declared that the arm does not carry
            update(rig, log, time, {"payload"}, [&](ci::Parameters& v) {
              v.payload.mass = uniform(rng, 0.0, 0.95 * v.safety.max_force.force / kG);
              v.payload.center_of_mass = uniform(rng, 0.0, 0.1) * random_direction(rng);
              const double moment = v.payload.mass * kG * v.payload.center_of_mass.norm();
              if (moment > 0.95 * v.safety.max_force.torque) {
                v.payload.center_of_mass *= 0.95 * v.safety.max_force.torque / moment;
              }
            });
            break;
          case 5:  // a box about the flange, sometimes past it, walls up to 100,000 N/m
            update(rig, log, time, {"safety.workspace"}, [&](ci::Parameters& v) {
              for (int i = 0; i < 3; ++i) {
                v.safety.workspace.min[i] = now.position[i] - uniform(rng, -0.15, 0.3);
                v.safety.workspace.max[i] = now.position[i] + uniform(rng, -0.15, 0.3);
                if (v.safety.workspace.min[i] > v.safety.workspace.max[i]) {
                  std::swap(v.safety.workspace.min[i], v.safety.workspace.max[i]);
                }
              }
              v.safety.workspace.stiffness = chance(rng, 0.2) ? 0.0 : log_uniform(rng, 100.0, 1e5);
              v.safety.workspace.damping = uniform(rng, 0.0, 500.0);
            });
            break;
          case 6:
            update(rig, log, time, {"limits.pose_error"}, [&](ci::Parameters& v) {
              v.limits.pose_error = {log_uniform(rng, 0.01, 0.5), log_uniform(rng, 0.05, 1.0)};
            });
            break;
          case 7:
            update(rig, log, time, {"filter"}, [&](ci::Parameters& v) {
              for (ci::FilterSettings* f :
                   {&v.filter.pose, &v.filter.stiffness, &v.filter.nullspace, &v.filter.wrench}) {
                f->time = chance(rng, 0.3) ? 0.0 : uniform(rng, 0.0, 0.5);
              }
            });
            break;
          case 8:
            loop.set_nullspace_target(random_configuration(model, home, 0.3, rng));
            loop.set_nullspace_stiffness(ci::JointVector::Constant(
                1, uniform(rng, 0.0, std::min(limits.nullspace_stiffness.max, 50.0))));
            log.add(time, "nullspace target and stiffness");
            break;
          case 9:
            loop.start_teaching(chance(rng, 0.5));
            log.add(time, "teaching");
            break;
          case 10: {  // a push from outside
            const Eigen::Vector3d force = uniform(rng, 5.0, 30.0) * random_direction(rng);
            rig.push(force);
            push_end = time + uniform(rng, 0.1, 0.5);
            log.add(time, "push", force.transpose(), "until", push_end);
            break;
          }
          default:
            update(rig, log, time, {"damping_ratio", "minimum_damping", "safety.energy_tank"},
                   [&](ci::Parameters& v) {
                     v.damping_ratio.translation.setConstant(uniform(rng, 0.3, 2.0));
                     v.damping_ratio.rotation.setConstant(uniform(rng, 0.3, 2.0));
                     v.minimum_damping.translation = uniform(rng, 5.0, 60.0);
                     v.safety.energy_tank.enabled = chance(rng, 0.8);
                     v.safety.energy_tank.capacity = log_uniform(rng, 1e-3, 0.05);
                     v.safety.energy_tank.initial =
                         std::min(v.safety.energy_tank.initial, v.safety.energy_tank.capacity);
                   });
        }
      } catch (const ci::Error& error) {
        log.add(time, "command refused:", error.what());
      }
    }
    if (push_end > 0.0 && time >= push_end) {
      rig.release();
      last_push_end = push_end;
      push_end = -1.0;
    }
    const Motion motion = step(rig, previous);
    const ci::ControllerState& state = loop.state().controller;
    const ci::SafetyParameters& in_force = loop.controller().parameters().safety;
    // Contact is a force from outside too: a link on the table (an impact, DART's rigid
    // contact), or a joint at its hard stop in the simulation.
    bool touching = rig.contact_force().norm() > 0.0;
    for (const std::string& link : model.joint_links()) {
      touching = touching || rig.sim().contact_wrench(link).head<3>().norm() > 0.0;
    }
    const ci::JointVector& q = rig.sim().q();
    const ci::JointLimits& range = model.limits();
    for (int i = 0; i < q.size(); ++i) {
      touching = touching || q[i] < range.position_lower[i] + 0.005 ||
                 q[i] > range.position_upper[i] - 0.005;
    }
    if (touching) last_contact = time;
    const bool pushed = push_end > 0.0 || (last_push_end > 0.0 && time - last_push_end < 0.5) ||
                        (last_contact > 0.0 && time - last_contact < 0.2);
    if (!pushed && state.status == ci::Status::ok) {
      const double fraction = motion.speed / in_force.max_speed.translation;
      const double angular = motion.angular / in_force.max_speed.rotation;
      figures.worst_speed_fraction = std::max(figures.worst_speed_fraction, fraction);
      figures.worst_angular_fraction = std::max(figures.worst_angular_fraction, angular);
      if (std::max(fraction, angular) > std::max(worst, 1.1)) {
        worst = std::max(fraction, angular);
        std::ostringstream what;
        what << robot.name << " seed " << seed << " at t = " << time << " s: flange at "
             << motion.speed << " m/s (cap " << in_force.max_speed.translation << "), "
             << motion.angular << " rad/s (cap " << in_force.max_speed.rotation << ")";
        violation = what.str();
      }
    }
    if (time > duration - 0.5 && !boxes.empty()) contact.push_back(rig.contact_force().norm());
  }
  if (!violation.empty()) {
    ++figures.over_speed;
    // Every one fails the test; the first few say what led to it.
    if (figures.reported++ < 3) {
      ADD_FAILURE() << violation << "\n" << log.text.str();
    } else {
      ADD_FAILURE() << violation;
    }
  }
  if (contact.empty()) return;
  double settled = 0.0;
  for (const double f : contact) settled += f / static_cast<double>(contact.size());
  if (settled < 1.0) return;  // not on the table
  ++figures.settled_contacts;
  const double band = scenarios::detail::friction_band(rig).force;
  const double cap = loop.controller().parameters().safety.max_force.force;
  const double excess = settled - (cap + band);
  figures.worst_settled_excess = std::max(figures.worst_settled_excess, excess);
  EXPECT_LE(excess, 1.0) << robot.name << " seed " << seed << ": settled force " << settled
                         << " N, cap " << cap << " N, friction band " << band << " N\n"
                         << log.text.str();
}

// ---- the schedule family ---------------------------------------------------------------------

// Kinetic energy (M(q) with the rotors), the clipped spring as in force, what the walls hold, and
// the tank. The simulated firmware holds gravity.
double stored_energy(scenarios::Rig& rig) {
  const ci::ControlLoop& loop = rig.loop();
  const ci::LoopState& state = loop.state();
  const ci::ControllerState& controller = state.controller;
  ci::ModelWorkspace workspace(rig.model());
  ci::Kinematics kinematics = workspace.make_kinematics();
  workspace.compute(state.q, state.dq, kinematics, ci::ModelTerms::mass);
  ci::JointMatrix mass = kinematics.mass;
  mass.diagonal() +=
      ci::per_joint(loop.controller().parameters().dynamics.armature, rig.model().num_joints());
  const double kinetic = 0.5 * state.dq.dot(mass * state.dq);
  const ci::Vector6d error = ci::pose_error(controller.pose, controller.filtered.pose);
  const ci::Vector6d k = controller.filtered.stiffness.diagonal();
  const ci::SafetyState& safety = controller.safety;
  // Isotropic stiffness per half (the schedules keep it so): the clipped spring's energy.
  const auto clipped = [](double length, double clip, double stiffness) {
    return length <= clip ? 0.5 * stiffness * length * length
                          : stiffness * clip * (length - 0.5 * clip);
  };
  // The walls hold what they took in (their passivity observer's account), not 1/2 k x^2: met at
  // speed a stiff wall's force comes at the joints' torque rate and lags the depth (an 80,000 N/m
  // wall entered 1 mm with a fraction of k x: 1/2 k x^2 = 40 mJ that was never stored).
  return kinetic + clipped(error.head<3>().norm(), safety.pose_error_in_force.translation, k[0]) +
         clipped(error.tail<3>().norm(), safety.pose_error_in_force.rotation, k[3]) +
         safety.wall_energy + safety.tank_level;
}

struct ScheduleFigures {
  double worst_growth = -1e9;  // [J] largest E(t) - E(0)
  double start_energy = 0.0;
};

void schedule_composition(const scenarios::RobotSetup& robot, std::uint32_t seed,
                          ScheduleFigures& figures) {
  std::mt19937 rng(seed);
  Log log;
  ci::Parameters p = scenarios::base_parameters(robot);
  p.safety.max_speed = {0.0, 0.0};
  p.safety.max_force = {0.0, 0.0};
  p.safety.workspace = ci::WorkspaceParameters{};
  // The nullspace springs act through the projector, whose torque has no energy function in
  // joint space; they are off, so that the energy below is the arm's whole store.
  p.nullspace.stiffness = ci::JointVector::Constant(1, 0.0);
  p.joint_limit_avoidance.stiffness = 0.0;
  const double k_t = p.limits.stiffness.translation.max, k_r = p.limits.stiffness.rotation.max;
  scenarios::Rig rig(robot, p);
  ci::ControlLoop& loop = rig.loop();
  rig.run(0.05);
  // A reference a few cm away, where the stiffness and clip changes store energy.
  ci::Pose reference = rig.flange();
  reference.position += uniform(rng, 0.01, 0.06) * random_direction(rng);
  loop.set_reference_pose(reference);
  loop.set_stiffness((ci::Vector6d() << Eigen::Vector3d::Constant(uniform(rng, 0.1, 1.0) * k_t),
                      Eigen::Vector3d::Constant(uniform(rng, 0.1, 1.0) * k_r))
                         .finished());
  rig.run(0.3);  // the filters land
  const double start = stored_energy(rig);
  figures.start_energy = start;
  double next_event = 0.0;
  for (int k = 1; k <= 3000; ++k) {
    const double time = k * kDt;
    if (time >= next_event) {
      next_event = time + log_uniform(rng, 0.005, 0.3);
      const ci::Pose now = rig.flange();
      try {
        switch (std::uniform_int_distribution<int>(0, 4)(rng)) {
          case 0: {  // isotropic per half, so that the clipped spring has an energy
            const ci::Vector6d stiffness =
                (ci::Vector6d() << Eigen::Vector3d::Constant(uniform(rng, 0.0, k_t)),
                 Eigen::Vector3d::Constant(uniform(rng, 0.0, k_r)))
                    .finished();
            loop.set_stiffness(stiffness);
            log.add(time, "stiffness", stiffness.transpose());
            break;
          }
          case 1:
            update(rig, log, time, {"limits.pose_error"}, [&](ci::Parameters& v) {
              v.limits.pose_error = {log_uniform(rng, 0.01, 1.0), log_uniform(rng, 0.01, 1.0)};
            });
            break;
          case 2:  // faces may pass the flange, never the reference (that would move it: a
                   // reference command, which the tank does not pay for)
            update(rig, log, time, {"safety.workspace"}, [&](ci::Parameters& v) {
              const Eigen::Vector3d& filtered = loop.state().controller.filtered.pose.position;
              for (int i = 0; i < 3; ++i) {
                const double low = std::min(now.position[i], reference.position[i]);
                const double high = std::max(now.position[i], reference.position[i]);
                const double inner_low = std::min(reference.position[i], filtered[i]) - 0.001;
                const double inner_high = std::max(reference.position[i], filtered[i]) + 0.001;
                v.safety.workspace.min[i] = std::min(low + uniform(rng, -0.05, 0.08), inner_low);
                v.safety.workspace.max[i] = std::max(high - uniform(rng, -0.05, 0.08), inner_high);
              }
              v.safety.workspace.stiffness = log_uniform(rng, 100.0, 1e5);
              v.safety.workspace.damping = uniform(rng, 0.0, 300.0);
            });
            break;
          case 3:
            update(rig, log, time, {"damping_ratio"}, [&](ci::Parameters& v) {
              v.damping_ratio.translation.setConstant(
                  uniform(rng, v.limits.damping_ratio.min, 1.0));
              v.damping_ratio.rotation.setConstant(uniform(rng, v.limits.damping_ratio.min, 1.0));
            });
            break;
          default:
            update(rig, log, time, {"filter.stiffness"}, [&](ci::Parameters& v) {
              v.filter.stiffness.time = chance(rng, 0.5) ? 0.0 : uniform(rng, 0.0, 0.3);
            });
        }
      } catch (const ci::Error& error) {
        log.add(time, "command refused:", error.what());
      }
    }
    rig.run(kDt);
    const double growth = stored_energy(rig) - start;
    figures.worst_growth = std::max(figures.worst_growth, growth);
    // The slack: the tank's capacity (it may pay that much into the springs), and 2 % of the
    // store for the kinetic energy's model (URDF inertias against the simulation's).
    const double capacity = loop.controller().parameters().safety.energy_tank.capacity;
    ASSERT_LE(growth, capacity + 0.02 * start + 1e-4)
        << robot.name << " seed " << seed << " at t = " << time << " s: the energy grew from "
        << start << " J by " << growth << " J\n"
        << log.text.str();
  }
}

// ---- the suites ------------------------------------------------------------------------------

struct FuzzCase {
  std::string arm;
  ci::sim::Engine engine;
  int commands;   // compositions of the command family
  int schedules;  // of the schedule family
};

std::string case_name(const ::testing::TestParamInfo<FuzzCase>& info) {
  return info.param.arm + (info.param.engine == ci::sim::Engine::dart ? "_dart" : "_mujoco");
}

// A seed of its own for each arm, engine and composition, so that no two arms repeat a draw.
std::uint32_t composition_seed(const FuzzCase& c, int index) {
  std::uint32_t seed = 2166136261u;  // FNV-1a over the name
  for (const char ch : c.arm) seed = (seed ^ static_cast<unsigned char>(ch)) * 16777619u;
  return seed + 7919u * static_cast<std::uint32_t>(c.engine) + static_cast<std::uint32_t>(index);
}

class SafetyFuzz : public ::testing::TestWithParam<FuzzCase> {};

TEST_P(SafetyFuzz, CommandsKeepTheSpeedAndForceCaps) {
  const FuzzCase& c = GetParam();
  std::string reason;
  if (!ci::sim::engine_available(c.engine, &reason)) GTEST_SKIP() << reason;
  const scenarios::RobotSetup robot = scenarios::with_engine(arm_named(c.arm), c.engine);
  CommandFigures figures;
  const int count = c.commands * scale();
  for (int i = 0; i < count && !HasFatalFailure(); ++i) {
    command_composition(robot, composition_seed(c, i), figures);
  }
  RecordProperty("compositions", count);
  RecordProperty("worst_speed_fraction", std::to_string(figures.worst_speed_fraction));
  RecordProperty("worst_angular_fraction", std::to_string(figures.worst_angular_fraction));
  RecordProperty("settled_contacts", figures.settled_contacts);
  RecordProperty("worst_settled_excess_N", std::to_string(figures.worst_settled_excess));
  std::cout << "[ fuzz     ] " << robot.name << ": " << count << " command compositions, "
            << figures.over_speed << " past 1.1 x a cap; worst speed / cap "
            << figures.worst_speed_fraction << ", angular " << figures.worst_angular_fraction
            << ", " << figures.settled_contacts
            << " settled on a table, worst settled force - (cap + friction) "
            << figures.worst_settled_excess << " N\n";
}

TEST_P(SafetyFuzz, ParameterSchedulesPumpNoEnergy) {
  const FuzzCase& c = GetParam();
  std::string reason;
  if (!ci::sim::engine_available(c.engine, &reason)) GTEST_SKIP() << reason;
  const scenarios::RobotSetup robot = scenarios::with_engine(arm_named(c.arm), c.engine);
  double worst = -1e9, worst_relative = -1e9;
  const int count = c.schedules * scale();
  for (int i = 0; i < count && !HasFailure(); ++i) {
    ScheduleFigures figures;
    schedule_composition(robot, composition_seed(c, 100000 + i), figures);
    worst = std::max(worst, figures.worst_growth);
    worst_relative = std::max(worst_relative, figures.worst_growth / figures.start_energy);
  }
  RecordProperty("compositions", count);
  RecordProperty("worst_energy_growth_J", std::to_string(worst));
  std::cout << "[ fuzz     ] " << robot.name << ": " << count
            << " parameter schedules, largest energy growth " << worst << " J ("
            << 100.0 * worst_relative << " % of the store)\n";
}

INSTANTIATE_TEST_SUITE_P(Arms, SafetyFuzz,
                         ::testing::Values(FuzzCase{"panda", ci::sim::Engine::mujoco, 24, 12},
                                           FuzzCase{"iiwa14", ci::sim::Engine::mujoco, 24, 12},
                                           FuzzCase{"ur5e", ci::sim::Engine::mujoco, 24, 12},
                                           FuzzCase{"planar3", ci::sim::Engine::mujoco, 24, 12},
                                           FuzzCase{"arm_seed_1", ci::sim::Engine::mujoco, 16, 8},
                                           FuzzCase{"arm_seed_2", ci::sim::Engine::mujoco, 16, 8},
                                           FuzzCase{"arm_seed_3", ci::sim::Engine::mujoco, 16, 8},
                                           FuzzCase{"panda", ci::sim::Engine::dart, 12, 6},
                                           FuzzCase{"arm_seed_4", ci::sim::Engine::dart, 8, 4}),
                         case_name);

}  // namespace
