#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>

#include "cartesian_impedance/config/yaml.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/robot_limits.hpp"
#include "scenario_support.hpp"

namespace cartesian_impedance::scenarios {

using namespace detail;

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
  // Simulated from their URDF alone (no MJCF), as a user's own arm would be.
  if (name == "ur5e") {
    RobotSetup robot{"ur5e",  source_dir + "/models/ur5e/ur5e.urdf", "", "base_link", "tool0",
                     "tool0", source_dir + "/config/ur5e.yaml"};
    // In front of the base (+x) at about 0.5 m height, the tool pointing down (models/README.md).
    robot.start_q =
        (JointVector(6) << M_PI, -M_PI / 2, M_PI / 2, -M_PI / 2, -M_PI / 2, 0.0).finished();
    return robot;
  }
  if (name == "planar3") {
    RobotSetup robot{
        "planar3", source_dir + "/models/planar3/planar3.urdf", "", "base_link", "tool0",
        "tool0",   source_dir + "/config/planar3.yaml"};
    // Elbow up, the tool pointing down (models/README.md).
    robot.start_q = (JointVector(3) << 0.5, 1.5, M_PI - 2.0).finished();
    return robot;
  }
  throw Error("robot '" + name +
              "' is not built in (panda, iiwa14, ur5e, planar3); give --urdf for your own");
}

RobotSetup with_engine(RobotSetup robot, sim::Engine engine) {
  std::string reason;
  if (!sim::engine_available(engine, &reason)) {
    throw Error(std::string("engine '") + sim::engine_name(engine) +
                "' is not available: " + reason);
  }
  robot.engine = engine;
  if (engine == sim::Engine::mujoco || robot.mjcf.empty()) return robot;
  if (robot.start_q.size() == 0) {
    const RobotModel model =
        RobotModel::from_urdf_file(robot.urdf, robot.base_link, robot.tip_link);
    sim::SimulationOptions options;
    options.joint_names = model.joint_names();
    robot.start_q = sim::Simulation::from_mjcf_file(robot.mjcf, options).true_q();
  }
  robot.mjcf.clear();
  robot.flange = robot.tip_link;
  return robot;
}

Parameters base_parameters(const RobotSetup& robot) {
  // What the configuration leaves out is derived from the URDF (a robot without a configuration
  // gets only that), as the nodes and Python do.
  const Parameters defaults =
      default_parameters(RobotModel::from_urdf_file(robot.urdf, robot.base_link, robot.tip_link));
  return robot.parameters_file.empty() ? defaults
                                       : load_parameters(robot.parameters_file, defaults);
}

namespace {
// The simulation's rotor inertia is the controller's dynamics.armature where the configuration
// gives one; otherwise the model's own (the MJCF's, or the URDF import's default), which the
// controller then takes over, so that its M(q) is the simulated one.
bool configures_armature(const Parameters& parameters) {
  return (parameters.dynamics.armature.array() != 0.0).any();
}

sim::Simulation make_simulation(const RobotSetup& robot, const RobotModel& model,
                                const Parameters& parameters, const std::vector<sim::Box>& boxes) {
  sim::SimulationOptions options;
  options.joint_names = model.joint_names();
  options.start_q = robot.start_q;
  options.engine = robot.engine;
  options.boxes_for_missing_meshes = robot.boxes_for_missing_meshes;
  options.plant = robot.plant;
  if (configures_armature(parameters)) options.armature = parameters.dynamics.armature;
  if (boxes.empty()) {
    return robot.mjcf.empty() ? sim::Simulation::from_urdf_file(robot.urdf, options)
                              : sim::Simulation::from_mjcf_file(robot.mjcf, options);
  }
  return sim::make_scene(robot.mjcf.empty() ? robot.urdf : robot.mjcf, boxes, options);
}

// The controller's parameters in the simulation: its rotor inertia, and the mutation of the
// parameters a broken controller gets.
Parameters for_simulation(Parameters parameters, const sim::Simulation& sim, Mutation mutation) {
  // The model's rotor inertia, not the realistic plant's drawn one: the controller does not know
  // the plant's error.
  if (!configures_armature(parameters)) parameters.dynamics.armature = sim.model_armature();
  if (mutation == Mutation::no_energy_tank) parameters.safety.energy_tank.enabled = false;
  // The passivity observer pairs each torque with the velocity measured while it acted: here the
  // plant's delays are known exactly (a real robot's are its measurement's age and its drive's).
  parameters.safety.passivity.delay = sim.measurement_age() + sim.actuation_delay();
  return parameters;
}
}  // namespace

namespace {
// The oscillations the watch found, and the collision monitor's false alarms, in the rigs of the
// scenario this thread runs.
thread_local int oscillations_found = 0;
thread_local int false_alarms_found = 0;
}  // namespace

Rig::~Rig() {
  if (!oscillation_expected_) {
    const SafetyState& safety = loop_->state().controller.safety;
    oscillations_found += safety.oscillations + safety.passivity_halvings;
  }
  false_alarms_found += false_alarms_;
}

Rig::Rig(const RobotSetup& robot, const Parameters& parameters, const std::vector<sim::Box>& boxes)
    : robot_(robot),
      model_(RobotModel::from_urdf_file(robot.urdf, robot.base_link, robot.tip_link)),
      sim_(make_simulation(robot, model_, parameters, boxes)),
      loop_(
          std::make_unique<ControlLoop>(model_, for_simulation(parameters, sim_, robot.mutation))),
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
  // The rig owns its loop, and its scenarios change safety settings on purpose while the arm runs
  // (a payload declared as it is hung, torque limits lowered by a reload).
  loop_->allow_runtime_safety_changes();
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
  // A hand's fingers (on joints of their own) press for the flange, as on a wrist sensor.
  return sim_.contact_wrench_beyond(robot_.tip_link).head<3>();
}

namespace {
// "20 N along +x", or "(3, 4, 0) N" off the axes.
std::string describe_vector(const Eigen::Vector3d& v, const char* unit, const char* preposition) {
  char text[96];
  for (int axis = 0; axis < 3; ++axis) {
    if (std::abs(v[axis]) > 0.99 * v.norm()) {
      std::snprintf(text, sizeof(text), "%.3g %s %s %c%c", v.norm(), unit, preposition,
                    v[axis] > 0.0 ? '+' : '-', "xyz"[axis]);
      return text;
    }
  }
  std::snprintf(text, sizeof(text), "(%.3g, %.3g, %.3g) %s", v.x(), v.y(), v.z(), unit);
  return text;
}

// "500 N/m" when the three are equal, else "x 1000, y 500, z 500 N/m".
std::string describe_three(Eigen::Vector3d v, const char* unit) {
  char text[96];
  v = (v.array().abs() < 1e-9).select(0.0, v);  // "0", not "1.5e-17" from a filter's tail
  if ((v.array() == v.x()).all()) {
    std::snprintf(text, sizeof(text), "%.4g %s", v.x(), unit);
  } else {
    std::snprintf(text, sizeof(text), "x %.4g, y %.4g, z %.4g %s", v.x(), v.y(), v.z(), unit);
  }
  return text;
}
}  // namespace

void Rig::push(const Eigen::Vector3d& force, const Eigen::Vector3d& torque) {
  if (push_force_.isZero() && push_torque_.isZero()) remember_pose("before the push");
  sim_.clear_pushes();
  Vector6d wrench;
  wrench << force, torque;
  sim_.push(robot_.flange, wrench, kForever);
  push_force_ = force;
  push_torque_ = torque;
}

void Rig::release() {
  sim_.clear_pushes();
  push_force_.setZero();
  push_torque_.setZero();
}

void Rig::phase(const std::string& what) {
  phase_ = what;
}

void Rig::view(double azimuth, double elevation) {
  view_azimuth_ = azimuth;
  view_elevation_ = elevation;
}

void Rig::remember_pose(const std::string& what) {
  ghost_q_ = sim_.true_q();
  ghost_what_ = what;
}

void Rig::moment(const MomentCallback& moment, const std::string& label,
                 const std::vector<std::string>& details) {
  if (!moment) return;
  const ControllerState& state = loop_->state().controller;
  const Pose base = sim_.body_pose(robot_.base_link);
  const auto to_world = [&](const Pose& pose) {
    return Pose{base.position + base.orientation * pose.position,
                base.orientation * pose.orientation};
  };
  const Eigen::Vector3d tip = to_world(flange()).position;
  sim::RenderOverlay overlay;
  constexpr double kScale = 0.015;  // [m/N]: 20 N are drawn 0.3 m long
  const Vector6d stiffness = state.filtered.stiffness.diagonal();
  char line[160];
  std::snprintf(line, sizeof(line), "t = %.2f s, stiffness %s, %s", time_,
                describe_three(stiffness.head<3>(), "N/m").c_str(),
                describe_three(stiffness.tail<3>(), "Nm/rad").c_str());
  std::string caption = label + "\n" + line;
  if (!push_force_.isZero()) {
    caption += "\npushed with " + describe_vector(push_force_, "N", "along") +
               " at the flange (orange arrow)";
    overlay.arrows.push_back({tip, push_force_, kScale, Eigen::Vector4f(1.0f, 0.5f, 0.0f, 1.0f),
                              describe_vector(push_force_, "N", "along")});
  }
  if (!push_torque_.isZero()) {
    caption += "\ntwisted with " + describe_vector(push_torque_, "Nm", "about") + " at the flange";
  }
  if (push_force_.isZero() && push_torque_.isZero()) caption += "\nno external force";
  // The commanded force and the contact force act where the tip touches something, so drawn
  // there they would be inside the wrist or the table: they go beside the tip, on the camera's
  // side (the free camera looks along +y), ending or starting at its height.
  const Eigen::Vector3d beside(0.0, -0.1, 0.0);
  const Eigen::Vector3d wrench = base.orientation * state.wrench_base.head<3>();
  if (wrench.norm() > 0.5) {
    caption += "\ncommanded force " + describe_vector(wrench, "N", "along") +
               " (magenta arrow, beside the tip)";
    overlay.arrows.push_back({tip + beside - Eigen::Vector3d(0.05, 0.0, 0.0) - kScale * wrench,
                              wrench, kScale, Eigen::Vector4f(0.85f, 0.1f, 0.85f, 1.0f),
                              "commanded"});
  }
  const Eigen::Vector3d contact = contact_force();
  if (contact.norm() > 0.5) {
    caption += "\ncontact force on the tip " + describe_vector(contact, "N", "along") +
               " (yellow arrow, beside the tip)";
    overlay.arrows.push_back({tip + beside + Eigen::Vector3d(0.05, 0.0, 0.0), contact, kScale,
                              Eigen::Vector4f(1.0f, 0.85f, 0.0f, 1.0f), "contact"});
  }
  for (const auto& [arrow, text] : marks_) {
    overlay.arrows.push_back(arrow);
    caption += "\n" + text;
  }
  marks_.clear();
  for (const std::string& detail : details) caption += "\n" + detail;
  // The reference as the law uses it (filtered), and as commanded where it is still on its way.
  const Pose reference = to_world(state.filtered.pose);
  const Pose commanded = to_world(state.commanded.pose);
  overlay.frames.push_back({reference, 0.1, 1.0f, ""});
  std::string legend = "RGB axes: reference pose";
  if ((commanded.position - reference.position).norm() > 0.005 ||
      commanded.orientation.angularDistance(reference.orientation) > 0.02) {
    overlay.frames.push_back({commanded, 0.1, 0.4f, "commanded"});
    legend += " (pale: commanded)";
  }
  if (ghost_q_.size() == sim_.num_joints()) {
    overlay.ghost_q = ghost_q_;
    legend += "; green ghost: the arm " + ghost_what_;
  }
  overlay.caption = caption + "\n" + legend;
  overlay.azimuth = view_azimuth_;
  overlay.elevation = view_elevation_;
  moment(label, sim_, overlay);
}

void Rig::mark(const sim::RenderArrow& arrow, const std::string& caption) {
  marks_.emplace_back(arrow, caption);
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
    // Contacts are cheap to ask for when there are none (the scenes without boxes).
    if (!push_force_.isZero() || !push_torque_.isZero() ||
        !sim_.contact_wrench_beyond(robot_.base_link).isZero()) {
      last_touch_ = time_;
    }
    const int collisions = loop_->state().controller.collision.collisions;
    if (collisions > collisions_seen_) {
      if (time_ - last_touch_ > kTouchMemory) false_alarms_ += collisions - collisions_seen_;
      collisions_seen_ = collisions;
    }
    if (++steps_ % 10 == 0) {
      const LoopState& state = loop_->state();
      Sample sample;
      sample.time = time_;
      sample.phase = phase_;
      if (!push_force_.isZero()) {
        sample.phase += (sample.phase.empty() ? "" : ", ") + std::string("push ") +
                        describe_vector(push_force_, "N", "along");
      }
      if (!push_torque_.isZero()) {
        sample.phase += (sample.phase.empty() ? "" : ", ") + std::string("torque ") +
                        describe_vector(push_torque_, "Nm", "about");
      }
      sample.position = flange().position;
      sample.reference = state.controller.filtered.pose.position;
      sample.commanded = state.controller.commanded.pose.position;
      sample.pose_error = state.controller.pose_error;
      sample.stiffness = state.controller.filtered.stiffness.diagonal();
      sample.commanded_stiffness = state.controller.commanded.stiffness.diagonal();
      sample.push = push_force_;
      sample.push_torque = push_torque_;
      sample.contact = contact_force();
      sample.wrench = state.controller.wrench_base.head<3>();
      sample.commanded_wrench = state.controller.commanded.wrench.head<3>();
      sample.q = sim_.true_q();
      sample.nullspace_target = state.controller.filtered.nullspace_q;
      sample.commanded_nullspace_target = state.controller.commanded.nullspace_q;
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
      {"energy_tank", energy_tank},
      {"safety", safety},
      {"collision", collision},
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
    if (known != name) continue;
    // Every scenario's loop is stable, on the realistic plant too: a limit cycle the watch or the
    // passivity controller finds (and stops, so that the other lines may pass) fails the scenario.
    oscillations_found = 0;
    false_alarms_found = 0;
    Outcome outcome = scenario(robot, moment);
    const bool applies = std::any_of(outcome.results.begin(), outcome.results.end(),
                                     [](const Result& result) { return result.applicable; });
    if (!applies) return outcome;  // nothing ran that could oscillate (a nullspace on 6 joints)
    outcome.results.push_back(detail::at_most(
        name, "sustained oscillations of the closed loop", 0.0, oscillations_found, "",
        "found by the oscillation watch or the passivity controller; each halves a stiffness"));
    // Every scenario's contacts are meant; what the monitor finds with nothing touching is not.
    outcome.results.push_back(detail::at_most(
        name, "collisions found with nothing touching the arm", 0.0, false_alarms_found, "",
        detail::format("the collision monitor's false alarms: no push and no contact on the arm "
                       "in the last %.2g s",
                       Rig::kTouchMemory)));
    return outcome;
  }
  std::string names;
  for (const std::string& known : scenario_names()) names += (names.empty() ? "" : ", ") + known;
  throw Error("unknown scenario '" + name + "' (valid: " + names + ")");
}

}  // namespace cartesian_impedance::scenarios
