#include "cartesian_impedance/sim/simulation.hpp"

#include "cartesian_impedance/core/checks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <locale>
#include <sstream>
#include <utility>

#include "simulation_impl.hpp"

namespace cartesian_impedance::sim {
namespace detail {
namespace {

[[noreturn]] void throw_mujoco_error(const char* message) {
  // MuJoCo prefixes nothing and sometimes ends with a newline.
  std::string text = message != nullptr ? message : "unknown error";
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  throw Error("MuJoCo error: " + text);
}

std::string trim(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  return text;
}

const char* joint_type_name(int type) {
  switch (type) {
    case mjJNT_FREE:
      return "free";
    case mjJNT_BALL:
      return "ball";
    case mjJNT_SLIDE:
      return "slide";
    case mjJNT_HINGE:
      return "hinge";
    default:
      return "unknown";
  }
}

std::string actuator_label(const mjModel* model, int actuator) {
  const char* name = mj_id2name(model, mjOBJ_ACTUATOR, actuator);
  return name != nullptr ? "'" + std::string(name) + "'" : "#" + std::to_string(actuator);
}

}  // namespace

MujocoErrorTrap::MujocoErrorTrap() noexcept : previous_(mju_user_error) {
  mju_user_error = &throw_mujoco_error;
}

MujocoErrorTrap::~MujocoErrorTrap() {
  mju_user_error = previous_;
}

std::string list_names(const mjModel* model, int type) {
  int count = 0;
  switch (type) {
    case mjOBJ_BODY:
      count = model->nbody;
      break;
    case mjOBJ_JOINT:
      count = model->njnt;
      break;
    case mjOBJ_SITE:
      count = model->nsite;
      break;
    case mjOBJ_CAMERA:
      count = model->ncam;
      break;
    case mjOBJ_KEY:
      count = model->nkey;
      break;
    default:
      break;
  }
  std::string names;
  for (int id = 0; id < count; ++id) {
    const char* name = mj_id2name(model, type, id);
    if (name == nullptr || name[0] == '\0') continue;
    if (!names.empty()) names += ", ";
    names += name;
  }
  return names.empty() ? "(none)" : names;
}

Simulation load_simulation(const std::string& path, const mjVFS* vfs, const std::string& kind,
                           SimulationOptions options, const UrdfScene* urdf_scene,
                           const std::vector<std::string>& uncompensated_bodies) {
  if (options.engine == Engine::dart && urdf_scene == nullptr) {
    throw Error("engine 'dart' cannot simulate " + kind + " file '" + path +
                "': DART loads URDF files (Simulation::from_urdf_file, make_scene with a URDF "
                "robot, make_robots_scene); give the robot's URDF");
  }
  if (options.engine != Engine::mujoco && options.engine != Engine::dart) {
    throw Error("SimulationOptions.engine = " + std::to_string(static_cast<int>(options.engine)) +
                " is not an engine (mujoco, dart)");
  }
  if (!std::isfinite(options.timestep) || options.timestep <= 0.0) {
    throw Error("SimulationOptions.timestep = " + format_number(options.timestep) +
                " s is not a positive finite number");
  }
  if (vfs == nullptr) {
    std::error_code error_code;
    if (!std::filesystem::is_regular_file(path, error_code)) {
      throw Error(kind + " file '" + path + "' does not exist or is not a regular file");
    }
  }

  auto impl = std::make_unique<Simulation::Impl>();
  impl->source = path;
  if (urdf_scene != nullptr) impl->warnings = urdf_scene->warnings;
  {
    MujocoErrorTrap trap;
    char error[1024] = "";
    impl->model.reset(mj_loadXML(path.c_str(), vfs, error, sizeof(error)));
    if (!impl->model) {
      throw Error("cannot load " + kind + " file '" + path + "': " + trim(error));
    }
    impl->data.reset(mj_makeData(impl->model.get()));
  }
  mjModel* model = impl->model.get();
  model->opt.timestep = options.timestep;
  if (options.multi_point_contacts) model->opt.enableflags |= mjENBL_MULTICCD;
  impl->model_name = model->nnames > 0 ? std::string(model->names) : std::string();

  // Exchanged joints: as requested by name, or every hinge/slide joint in model order.
  std::vector<int> joints;
  if (options.joint_names.empty()) {
    for (int joint = 0; joint < model->njnt; ++joint) {
      const int type = model->jnt_type[joint];
      if (type == mjJNT_HINGE || type == mjJNT_SLIDE) joints.push_back(joint);
    }
  } else {
    for (std::size_t i = 0; i < options.joint_names.size(); ++i) {
      const std::string& name = options.joint_names[i];
      const int joint = mj_name2id(model, mjOBJ_JOINT, name.c_str());
      if (joint < 0) {
        throw Error("SimulationOptions.joint_names[" + std::to_string(i) + "] = '" + name +
                    "' is not a joint of " + kind + " file '" + path +
                    "'; its joints are: " + list_names(model, mjOBJ_JOINT));
      }
      const int type = model->jnt_type[joint];
      if (type != mjJNT_HINGE && type != mjJNT_SLIDE) {
        throw Error("SimulationOptions.joint_names[" + std::to_string(i) + "] = '" + name +
                    "' is a " + joint_type_name(type) +
                    " joint; only hinge and slide joints can be exchanged");
      }
      if (std::find(joints.begin(), joints.end(), joint) != joints.end()) {
        throw Error("SimulationOptions.joint_names[" + std::to_string(i) + "] = '" + name +
                    "' is listed twice");
      }
      joints.push_back(joint);
    }
  }
  if (joints.empty()) {
    throw Error(kind + " file '" + path + "' has no hinge or slide joint to control");
  }
  if (static_cast<int>(joints.size()) > kMaxJoints) {
    throw Error(kind + " file '" + path + "' has " + std::to_string(joints.size()) +
                " hinge/slide joints, more than kMaxJoints = " + std::to_string(kMaxJoints) +
                "; choose the robot's joints with SimulationOptions.joint_names");
  }

  const int n = static_cast<int>(joints.size());
  impl->joint_ids = joints;
  impl->actuator_ids.assign(n, -1);
  impl->ctrl_per_torque = JointVector::Zero(n);
  impl->tau_lower = JointVector::Constant(n, -std::numeric_limits<double>::infinity());
  impl->tau_upper = JointVector::Constant(n, std::numeric_limits<double>::infinity());
  for (int i = 0; i < n; ++i) {
    const int joint = joints[i];
    const char* name = mj_id2name(model, mjOBJ_JOINT, joint);  // nullptr for an unnamed joint
    impl->joint_names.emplace_back(
        name != nullptr ? std::string(name) : "(unnamed joint " + std::to_string(joint) + ")");
    impl->qpos_address.push_back(model->jnt_qposadr[joint]);
    impl->dof_address.push_back(model->jnt_dofadr[joint]);
  }

  // Actuators are matched through their transmission: a motor acting on an exchanged joint turns
  // the commanded joint torque into ctrl. Joint torque = gear * gain * ctrl for a plain motor.
  for (int actuator = 0; actuator < model->nu; ++actuator) {
    const int trntype = model->actuator_trntype[actuator];
    if (trntype != mjTRN_JOINT && trntype != mjTRN_JOINTINPARENT) continue;
    const int joint = model->actuator_trnid[2 * actuator];
    const auto it = std::find(joints.begin(), joints.end(), joint);
    if (it == joints.end()) continue;
    const int i = static_cast<int>(it - joints.begin());
    const std::string joint_name = impl->joint_names[i];
    if (impl->actuator_ids[i] >= 0) {
      throw Error("joint '" + joint_name + "' is driven by two actuators, " +
                  actuator_label(model, impl->actuator_ids[i]) + " and " +
                  actuator_label(model, actuator) + "; expected at most one");
    }
    const mjtNum* bias = model->actuator_biasprm + mjNBIAS * actuator;
    const bool has_bias = model->actuator_biastype[actuator] != mjBIAS_NONE &&
                          std::any_of(bias, bias + mjNBIAS, [](mjtNum b) { return b != 0.0; });
    const double gain = model->actuator_gainprm[mjNGAIN * actuator];
    const double gear = model->actuator_gear[6 * actuator];
    if (model->actuator_dyntype[actuator] != mjDYN_NONE ||
        model->actuator_gaintype[actuator] != mjGAIN_FIXED || has_bias || gain * gear == 0.0) {
      throw Error("actuator " + actuator_label(model, actuator) + " on joint '" + joint_name +
                  "' is not a plain torque motor (expected no dynamics, a fixed non-zero gain, "
                  "no bias and a non-zero gear, as <motor> gives)");
    }
    impl->actuator_ids[i] = actuator;
    impl->ctrl_per_torque[i] = 1.0 / (gain * gear);
    double lower = -std::numeric_limits<double>::infinity();
    double upper = std::numeric_limits<double>::infinity();
    if (model->actuator_ctrllimited[actuator]) {
      const double a = gain * gear * model->actuator_ctrlrange[2 * actuator];
      const double b = gain * gear * model->actuator_ctrlrange[2 * actuator + 1];
      lower = std::max(lower, std::min(a, b));
      upper = std::min(upper, std::max(a, b));
    }
    if (model->actuator_forcelimited[actuator]) {
      const double a = gear * model->actuator_forcerange[2 * actuator];
      const double b = gear * model->actuator_forcerange[2 * actuator + 1];
      lower = std::max(lower, std::min(a, b));
      upper = std::min(upper, std::max(a, b));
    }
    impl->tau_lower[i] = lower;
    impl->tau_upper[i] = upper;
  }

  // MuJoCo runs its collision pipeline every step even when no two geoms can ever touch (a robot
  // whose geoms only collide with an environment that is not there: about a quarter of the step
  // for the project's arms). If no pair of geoms on different bodies passes the contype /
  // conaffinity filter and no explicit <pair> exists, no contact can arise; switching detection
  // off then changes nothing but the cost.
  bool contact_possible = model->npair > 0;
  for (int a = 0; a < model->ngeom && !contact_possible; ++a) {
    for (int b = a + 1; b < model->ngeom && !contact_possible; ++b) {
      contact_possible = model->geom_bodyid[a] != model->geom_bodyid[b] &&
                         ((model->geom_contype[a] & model->geom_conaffinity[b]) != 0 ||
                          (model->geom_contype[b] & model->geom_conaffinity[a]) != 0);
    }
  }
  if (!contact_possible) model->opt.disableflags |= mjDSBL_CONTACT;

  // Armature: one value for all joints or one per joint, replacing the model's.
  const JointVector& armature = options.armature;
  if (armature.size() != 0) {
    if (armature.size() != 1 && armature.size() != n) {
      throw Error("SimulationOptions.armature has " + std::to_string(armature.size()) +
                  " values; expected 1 or one per joint (" + std::to_string(n) + ")");
    }
    for (int i = 0; i < n; ++i) {
      const double value = armature[armature.size() == 1 ? 0 : i];
      if (!std::isfinite(value) || value < 0.0) {
        throw Error("SimulationOptions.armature[" + std::to_string(i) +
                    "] = " + format_number(value) + " for joint '" + impl->joint_names[i] +
                    "' is not a finite value >= 0");
      }
      model->dof_armature[impl->dof_address[i]] = value;
    }
  }
  // Start configuration: finite and inside each limited joint's range.
  const JointVector& start = options.start_q;
  if (start.size() != 0) {
    if (start.size() != n) {
      throw Error("SimulationOptions.start_q has " + std::to_string(start.size()) +
                  " values; expected one per joint (" + std::to_string(n) + ")");
    }
    for (int i = 0; i < n; ++i) {
      const int joint = joints[i];
      const double low = model->jnt_range[2 * joint], high = model->jnt_range[2 * joint + 1];
      if (!std::isfinite(start[i]) ||
          (model->jnt_limited[joint] && (start[i] < low || start[i] > high))) {
        throw Error("SimulationOptions.start_q[" + std::to_string(i) + "] = " +
                    format_number(start[i]) + " for joint '" + impl->joint_names[i] + "' is " +
                    (std::isfinite(start[i]) ? "outside its range [" + format_number(low) + ", " +
                                                   format_number(high) + "]"
                                             : std::string("not finite")));
      }
    }
  }
  impl->keyframe_id =
      options.keyframe.empty() ? -1 : mj_name2id(model, mjOBJ_KEY, options.keyframe.c_str());
  impl->gravity_on = options.gravity_compensation &&
                     (model->opt.disableflags & mjDSBL_GRAVITY) == 0 &&
                     (model->opt.gravity[0] != 0.0 || model->opt.gravity[1] != 0.0 ||
                      model->opt.gravity[2] != 0.0);
  for (const std::string& name : uncompensated_bodies) {
    const int body = mj_name2id(model, mjOBJ_BODY, name.c_str());
    if (body < 0) throw Error("attached body '" + name + "' is missing from the compiled scene");
    for (int k = 0; k < n; ++k) {
      const int joint_body = model->jnt_bodyid[joints[k]];
      for (int b = body; b > 0; b = model->body_parentid[b]) {
        if (b == joint_body) {
          impl->uncompensated.emplace_back(k, body);
          break;
        }
      }
    }
  }
  detail::check_plant(options.plant);
  impl->model_armature.resize(n);
  for (int i = 0; i < n; ++i) {
    impl->model_armature[i] = model->dof_armature[impl->dof_address[static_cast<std::size_t>(i)]];
  }
  if (detail::changes_model(options.plant)) {
    std::vector<int> exact_bodies;  // the attached bodies: a load the user knows
    for (const auto& entry : impl->uncompensated) exact_bodies.push_back(entry.second);
    impl->perturbed_bodies = perturb_model(model, joints, exact_bodies, options.plant);
    mj_setConst(model, impl->data.get());
  }
  impl->plant.configure(options.plant, model->opt.timestep, n);
  impl->options = std::move(options);
  impl->pushes.reserve(16);
  impl->q = impl->dq = impl->true_q = impl->true_dq = JointVector::Zero(n);
  impl->measured_torque = impl->true_torque = JointVector::Zero(n);
  impl->tau = impl->tau_command = JointVector::Zero(n);
  impl->reset();
  if (impl->options.engine == Engine::dart) impl->physics = make_dart_physics(*urdf_scene, *impl);
  return Simulation(std::move(impl));
}

}  // namespace detail

// ---------------------------------------------------------------------------------------------
// Impl

void Simulation::Impl::reset() {
  mjModel* m = model.get();
  mjData* d = data.get();
  if (keyframe_id >= 0) {
    mj_resetDataKeyframe(m, d, keyframe_id);
  } else {
    mj_resetData(m, d);
  }
  for (std::size_t i = 0; i < qpos_address.size() && options.start_q.size() != 0; ++i) {
    d->qpos[qpos_address[i]] = options.start_q[static_cast<Eigen::Index>(i)];
  }
  tau.setZero();
  tau_command.setZero();
  pushes.clear();
  tracked_sum.setZero();
  tracked_steps = 0;
  mj_forward(m, d);
  kinematics_current = true;
  if (physics) physics->set_state(*this);
  read_state(true);
}

void Simulation::Impl::update_kinematics() const noexcept {
  if (kinematics_current) return;
  // Only position-dependent frames are refreshed; contacts stay those of the last step.
  mj_kinematics(model.get(), data.get());
  kinematics_current = true;
}

void Simulation::Impl::apply_inputs() noexcept {
  const mjModel* m = model.get();
  mjData* d = data.get();
  mju_zero(d->qfrc_applied, m->nv);
  mju_zero(d->xfrc_applied, 6 * m->nbody);

  const mjtNum* gravity = m->opt.gravity;
  for (std::size_t k = 0; k < joint_ids.size(); ++k) {
    const auto i = static_cast<Eigen::Index>(k);
    const int joint = joint_ids[k];
    double generalized_force = 0.0;
    if (gravity_on) {
      // g(q) for this joint, the gravity part of qfrc_bias: gravity on the joint's whole subtree,
      // of mass M with centre of mass c, acts as the force M g at c. For a hinge with axis a at p
      // its generalized force is a . ((c - p) x M g), for a slide a . M g; the compensation is the
      // negative. O(1) per joint with MuJoCo's subtree_com (valid after mj_step1/mj_comPos).
      const int body = m->jnt_bodyid[joint];
      const mjtNum mass = m->body_subtreemass[body];
      const mjtNum* axis = d->xaxis + 3 * joint;
      mjtNum weight[3] = {mass * gravity[0], mass * gravity[1], mass * gravity[2]};
      if (m->jnt_type[joint] == mjJNT_HINGE) {
        mjtNum lever[3];
        mjtNum moment[3];
        mju_sub3(lever, d->subtree_com + 3 * body, d->xanchor + 3 * joint);
        mju_cross(moment, lever, weight);
        generalized_force = -mju_dot3(axis, moment);
      } else {
        generalized_force = -mju_dot3(axis, weight);
      }
    }
    const int actuator = actuator_ids[k];
    if (actuator >= 0) {
      d->ctrl[actuator] = tau[i] * ctrl_per_torque[i];
    } else {
      generalized_force += tau[i];
    }
    d->qfrc_applied[dof_address[k]] += generalized_force;
  }
  // An attached body's weight is a load the firmware does not know: add back what the
  // compensation above took from it (the same moment, of its own mass at its own centre).
  for (const auto& [k, body] : uncompensated) {
    if (!gravity_on) break;
    const int joint = joint_ids[static_cast<std::size_t>(k)];
    const mjtNum mass = m->body_mass[body];
    const mjtNum* axis = d->xaxis + 3 * joint;
    const mjtNum weight[3] = {mass * gravity[0], mass * gravity[1], mass * gravity[2]};
    double generalized_force = mju_dot3(axis, weight);
    if (m->jnt_type[joint] == mjJNT_HINGE) {
      mjtNum lever[3];
      mjtNum moment[3];
      mju_sub3(lever, d->xipos + 3 * body, d->xanchor + 3 * joint);
      mju_cross(moment, lever, weight);
      generalized_force = mju_dot3(axis, moment);
    }
    d->qfrc_applied[dof_address[static_cast<std::size_t>(k)]] += generalized_force;
  }

  // Pushes: xfrc_applied acts at the body's centre of mass (xipos), so a wrench given at a point
  // p is moved there: torque_com = torque + (p - xipos) x force.
  expire_pushes();
  for (const Push& push : pushes) {
    const mjtNum* point = push.site >= 0 ? d->site_xpos + 3 * push.site : d->xpos + 3 * push.body;
    mjtNum offset[3];
    mjtNum shift[3];
    const mjtNum force[3] = {push.wrench_world[0], push.wrench_world[1], push.wrench_world[2]};
    mju_sub3(offset, point, d->xipos + 3 * push.body);
    mju_cross(shift, offset, force);
    mjtNum* target = d->xfrc_applied + 6 * push.body;
    for (int j = 0; j < 3; ++j) {
      target[j] += force[j];
      target[3 + j] += push.wrench_world[3 + j] + shift[j];
    }
  }
}

void Simulation::Impl::expire_pushes() noexcept {
  const double expiry = data->time + 0.5 * model->opt.timestep;
  pushes.erase(std::remove_if(pushes.begin(), pushes.end(),
                              [expiry](const Push& push) { return push.end_time < expiry; }),
               pushes.end());
}

int Simulation::Impl::find_body(const std::string& name) const {
  const int body = mj_name2id(model.get(), mjOBJ_BODY, name.c_str());
  if (body < 0) {
    throw Error("body '" + name + "' not found in model '" + model_name +
                "'; its bodies are: " + detail::list_names(model.get(), mjOBJ_BODY));
  }
  return body;
}

// ---------------------------------------------------------------------------------------------
// Simulation

Simulation::Simulation(std::unique_ptr<Impl> impl) noexcept : impl_(std::move(impl)) {}
Simulation::Simulation(Simulation&&) noexcept = default;
Simulation& Simulation::operator=(Simulation&&) noexcept = default;
Simulation::~Simulation() = default;

Simulation Simulation::from_mjcf_file(const std::string& path, SimulationOptions options) {
  return detail::load_simulation(path, nullptr, "MJCF", std::move(options));
}

Simulation Simulation::from_urdf_file(const std::string& path, SimulationOptions options) {
  std::error_code error_code;
  if (!std::filesystem::is_regular_file(path, error_code)) {
    throw Error("URDF file '" + path + "' does not exist or is not a regular file");
  }
  detail::UrdfScene scene{{SceneRobot{path, "", Eigen::Vector3d::Zero()}}, {}, {}};
  detail::UrdfImportOptions import;
  import.boxes_for_missing_meshes = options.boxes_for_missing_meshes;
  import.warnings = &scene.warnings;
  const std::string mjcf = detail::mjcf_from_urdf(path, import);
  const std::filesystem::path absolute = std::filesystem::absolute(path);
  const std::string name = absolute.stem().string() + "_cartesian_impedance.xml";
  const detail::VirtualFile file(name, mjcf);
  return detail::load_simulation((absolute.parent_path() / name).string(), file.vfs(), "URDF",
                                 std::move(options), &scene);
}

int Simulation::num_joints() const noexcept {
  return static_cast<int>(impl_->joint_ids.size());
}
const std::vector<std::string>& Simulation::joint_names() const noexcept {
  return impl_->joint_names;
}
double Simulation::time() const noexcept {
  return impl_->data->time;
}
double Simulation::timestep() const noexcept {
  return impl_->model->opt.timestep;
}
const JointVector& Simulation::q() const noexcept {
  return impl_->q;
}
const JointVector& Simulation::dq() const noexcept {
  return impl_->dq;
}
const JointVector& Simulation::true_q() const noexcept {
  return impl_->true_q;
}
const JointVector& Simulation::true_dq() const noexcept {
  return impl_->true_dq;
}
const JointVector& Simulation::torque() const noexcept {
  return impl_->tau;
}
const JointVector& Simulation::torque_lower_limits() const noexcept {
  return impl_->tau_lower;
}
const JointVector& Simulation::torque_upper_limits() const noexcept {
  return impl_->tau_upper;
}
const JointVector& Simulation::model_armature() const noexcept {
  return impl_->model_armature;
}
double Simulation::measurement_age() const noexcept {
  return impl_->plant.measurement_steps() * timestep();
}
double Simulation::actuation_delay() const noexcept {
  return impl_->plant.actuation_steps() * timestep();
}
JointVector Simulation::armature() const {
  JointVector values(num_joints());
  for (int i = 0; i < num_joints(); ++i) {
    values[i] = impl_->model->dof_armature[impl_->dof_address[static_cast<std::size_t>(i)]];
  }
  return values;
}
JointVector Simulation::friction_loss() const {
  JointVector values(num_joints());
  for (int i = 0; i < num_joints(); ++i) {
    values[i] = impl_->model->dof_frictionloss[impl_->dof_address[static_cast<std::size_t>(i)]];
  }
  return values;
}
JointVector Simulation::joint_damping() const {
  JointVector values(num_joints());
  for (int i = 0; i < num_joints(); ++i) {
    values[i] = impl_->model->dof_damping[impl_->dof_address[static_cast<std::size_t>(i)]];
  }
  return values;
}
const std::string& Simulation::model_name() const noexcept {
  return impl_->model_name;
}
Engine Simulation::engine() const noexcept {
  return impl_->physics ? impl_->physics->engine() : Engine::mujoco;
}

namespace {

// One value per joint, each finite: the core's checks, with the joint's name added.
void check_joint_vector(const JointVector& value, int expected_size, const char* what,
                        const std::vector<std::string>& joint_names) {
  if (const Fault size = checks::count(what, value.size(), expected_size, "entries")) {
    throw Error(size, to_string(size) + " (one per joint)");
  }
  for (int i = 0; i < expected_size; ++i) {
    if (!std::isfinite(value[i])) {
      const Fault fault{what, i, value[i], "is not finite"};
      throw Error(fault, to_string(fault) + " (joint '" + joint_names[i] + "')");
    }
  }
}

void check_finite(const Eigen::Ref<const Eigen::VectorXd>& value, const std::string& field) {
  checks::finite_vector(field, value);
}

}  // namespace

void Simulation::set_state(const JointVector& q, const JointVector& dq) {
  Impl& s = *impl_;
  check_joint_vector(q, num_joints(), "q", s.joint_names);
  check_joint_vector(dq, num_joints(), "dq", s.joint_names);
  mjData* d = s.data.get();
  for (int i = 0; i < num_joints(); ++i) {
    d->qpos[s.qpos_address[i]] = q[i];
    d->qvel[s.dof_address[i]] = dq[i];
  }
  mj_forward(s.model.get(), d);
  s.kinematics_current = true;
  if (s.physics) s.physics->set_state(s);
  s.read_state(true, false);
}

void Simulation::reset() {
  impl_->reset();
}

bool Simulation::set_torque(const JointVector& tau) {
  Impl& s = *impl_;
  check_joint_vector(tau, num_joints(), "tau", s.joint_names);
  s.tau_command = tau.cwiseMax(s.tau_lower).cwiseMin(s.tau_upper);
  if (!s.plant.actuates()) s.tau = s.tau_command;
  return s.tau_command != tau;
}

void Simulation::step() noexcept {
  Impl& s = *impl_;
  const mjModel* m = s.model.get();
  mjData* d = s.data.get();
  // The state's own copy is what the last step left (true_dq is not written until read_state).
  const JointVector& dq_before = s.true_dq;
  if (s.plant.actuates()) {
    s.plant.actuate(s.tau_command, s.tau);
    s.tau = s.tau.cwiseMax(s.tau_lower).cwiseMin(s.tau_upper);
  }
  if (s.physics) {
    s.physics->step(s);
  } else if (m->opt.integrator == mjINT_RK4) {
    // mj_step2 would fall back to Euler; evaluate the inputs on fresh kinematics instead and let
    // mj_step recompute them (one extra kinematics pass).
    mj_kinematics(m, d);
    mj_comPos(m, d);
    s.apply_inputs();
    mj_step(m, d);
  } else {
    // Split step: positions and velocities first, then the inputs at exactly this state, then
    // the rest (identical to mj_step for the Euler and implicit integrators).
    mj_step1(m, d);
    s.apply_inputs();
    mj_step2(m, d);
  }
  if (!s.physics) s.sense_torque(dq_before);
  s.kinematics_current = false;
  s.read_state();
  if (s.tracked_body >= 0) {
    s.tracked_sum += s.contact_wrench(s.tracked_body);
    ++s.tracked_steps;
  }
}

void Simulation::push(const std::string& body_or_site, const Vector6d& wrench_world,
                      double duration) {
  Impl& s = *impl_;
  const mjModel* m = s.model.get();
  for (int i = 0; i < 6; ++i) {
    if (!std::isfinite(wrench_world[i])) {
      throw Error("push wrench_world[" + std::to_string(i) +
                  "] = " + format_number(wrench_world[i]) + (i < 3 ? " N" : " Nm") +
                  " is not a finite number");
    }
  }
  if (std::isnan(duration) || duration <= 0.0) {
    throw Error("push duration = " + format_number(duration) +
                " s is not > 0 (use infinity for a push until clear_pushes())");
  }
  Push push;
  push.site = mj_name2id(m, mjOBJ_SITE, body_or_site.c_str());
  if (push.site >= 0) {
    push.body = m->site_bodyid[push.site];
  } else {
    push.body = mj_name2id(m, mjOBJ_BODY, body_or_site.c_str());
    if (push.body < 0) {
      throw Error("push target '" + body_or_site + "' is neither a site nor a body of model '" +
                  s.model_name + "'; sites: " + detail::list_names(m, mjOBJ_SITE) +
                  "; bodies: " + detail::list_names(m, mjOBJ_BODY));
    }
  }
  if (push.body == 0) {
    throw Error("push target '" + body_or_site + "' belongs to the world body, which cannot move");
  }
  push.wrench_world = wrench_world;
  push.end_time = s.data->time + duration;
  s.pushes.push_back(push);
}

void Simulation::clear_pushes() noexcept {
  impl_->pushes.clear();
}

Pose Simulation::site_pose(const std::string& site) const {
  const Impl& s = *impl_;
  const int id = mj_name2id(s.model.get(), mjOBJ_SITE, site.c_str());
  if (id < 0) {
    throw Error("site '" + site + "' not found in model '" + s.model_name +
                "'; its sites are: " + detail::list_names(s.model.get(), mjOBJ_SITE));
  }
  s.update_kinematics();
  const mjData* d = s.data.get();
  Pose pose;
  pose.position = Eigen::Map<const Eigen::Vector3d>(d->site_xpos + 3 * id);
  // site_xmat is row-major.
  const Eigen::Matrix3d rotation =
      Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(d->site_xmat + 9 * id);
  pose.orientation = Eigen::Quaterniond(rotation).normalized();
  return pose;
}

Pose Simulation::body_pose(const std::string& body) const {
  const Impl& s = *impl_;
  const int id = s.find_body(body);
  if (s.physics) return s.physics->body_pose(id);
  s.update_kinematics();
  const mjData* d = s.data.get();
  Pose pose;
  pose.position = Eigen::Map<const Eigen::Vector3d>(d->xpos + 3 * id);
  const mjtNum* quat = d->xquat + 4 * id;  // w, x, y, z
  pose.orientation = Eigen::Quaterniond(quat[0], quat[1], quat[2], quat[3]).normalized();
  return pose;
}

const std::vector<std::string>& Simulation::warnings() const noexcept {
  return impl_->warnings;
}

void Simulation::render_png(const std::string& path, int width, int height,
                            const std::string& camera) const {
  render_png(path, width, height, RenderOverlay{}, camera);
}

void Simulation::render_png(const std::string& path, int width, int height,
                            const RenderOverlay& overlay, const std::string& camera) const {
  const Impl& s = *impl_;
  constexpr int kMaxSize = 8192;
  if (width < 1 || width > kMaxSize || height < 1 || height > kMaxSize) {
    throw Error("render_png size = " + std::to_string(width) + " x " + std::to_string(height) +
                " pixels is outside [1, " + std::to_string(kMaxSize) + "] x [1, " +
                std::to_string(kMaxSize) + "]");
  }
  if (path.empty()) throw Error("render_png path is empty; expected a file name");
  int camera_id = -1;
  if (!camera.empty()) {
    camera_id = mj_name2id(s.model.get(), mjOBJ_CAMERA, camera.c_str());
    if (camera_id < 0) {
      throw Error("camera '" + camera + "' not found in model '" + s.model_name +
                  "'; its cameras are: " + detail::list_names(s.model.get(), mjOBJ_CAMERA) +
                  " (or \"\" for the free camera)");
    }
  }
  const int n = static_cast<int>(s.joint_ids.size());
  if (overlay.ghost_q.size() != 0) {
    check_joint_vector(overlay.ghost_q, n, "render_png overlay.ghost_q", s.joint_names);
  }
  for (std::size_t i = 0; i < overlay.arrows.size(); ++i) {
    const std::string field = "render_png overlay.arrows[" + std::to_string(i) + "]";
    check_finite(overlay.arrows[i].from, field + ".from");
    check_finite(overlay.arrows[i].vector * overlay.arrows[i].scale, field + ".vector * scale");
  }
  for (std::size_t i = 0; i < overlay.frames.size(); ++i) {
    const std::string field = "render_png overlay.frames[" + std::to_string(i) + "]";
    check_finite(overlay.frames[i].pose.position, field + ".pose.position");
    check_finite(overlay.frames[i].pose.orientation.coeffs(), field + ".pose.orientation");
  }
  for (std::size_t i = 0; i < overlay.boxes.size(); ++i) {
    const std::string field = "render_png overlay.boxes[" + std::to_string(i) + "]";
    check_finite(overlay.boxes[i].min, field + ".min");
    check_finite(overlay.boxes[i].max, field + ".max");
  }
  if (!s.renderer) s.renderer = std::make_unique<detail::Renderer>();
  s.update_kinematics();
  // The ghost is the same model at other joint positions: its own data, with the kinematics of
  // those positions (the other degrees of freedom as they are now).
  mjData* ghost = nullptr;
  if (overlay.ghost_q.size() != 0) {
    if (!s.ghost_data) s.ghost_data.reset(mj_makeData(s.model.get()));
    ghost = s.ghost_data.get();
    mju_copy(ghost->qpos, s.data->qpos, s.model->nq);
    for (int i = 0; i < n; ++i) {
      ghost->qpos[s.qpos_address[static_cast<std::size_t>(i)]] = overlay.ghost_q[i];
    }
    mj_kinematics(s.model.get(), ghost);
  }
  s.renderer->render_png(s.model.get(), s.data.get(), path, width, height, camera_id, overlay,
                         ghost);
}

bool offscreen_rendering_available(std::string* reason) {
  const std::string& failure = detail::offscreen_rendering_failure();
  if (reason != nullptr) *reason = failure;
  return failure.empty();
}

}  // namespace cartesian_impedance::sim
