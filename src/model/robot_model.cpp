#include "cartesian_impedance/model/robot_model.hpp"

#include <Eigen/SVD>
#include <cmath>
#include <cstdio>
#include <kdl/chain.hpp>
#include <kdl/chaindynparam.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainjnttojacsolver.hpp>
#include <kdl/frames.hpp>
#include <kdl/jacobian.hpp>
#include <kdl/jntarray.hpp>
#include <kdl/jntspaceinertiamatrix.hpp>
#include <sstream>
#include <utility>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/files.hpp"
#include "chain_model.hpp"
#include "urdf/urdf_to_kdl.hpp"

namespace cartesian_impedance {

namespace detail {

// Everything a RobotModel knows, shared (read-only) by its copies and workspaces.
struct ModelData {
  UrdfChain urdf;     // urdf.chain ends with one fixed "tool" segment for T_tip_tool
  ChainModel native;  // the same chain, prepared for the native backend
  std::string base_link;
  std::string tip_link;
  Eigen::Isometry3d T_tip_tool = Eigen::Isometry3d::Identity();
  Eigen::Vector3d gravity_base = Eigen::Vector3d::Zero();
};

}  // namespace detail

namespace {

// A rigid transform with an orthonormal, right-handed rotation; returned with the rotation
// re-orthonormalised (through a unit quaternion) so that rounding in the input does not scale.
Eigen::Isometry3d checked_tool(const Eigen::Isometry3d& T_tip_tool) {
  if (!T_tip_tool.matrix().allFinite()) {
    throw Error("tool offset T_tip_tool has a non-finite entry; expected a finite rigid transform");
  }
  const Eigen::Matrix3d rotation = T_tip_tool.linear();
  const double deviation =
      (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  // 1e-6 accepts rotations typed with 7 significant digits and rejects scaled or sheared ones.
  if (deviation > 1e-6 || rotation.determinant() < 0.0) {
    std::ostringstream message;
    message << "tool offset T_tip_tool rotation is not a rotation matrix: max |R^T R - I| = "
            << deviation << ", det R = " << rotation.determinant()
            << "; expected |R^T R - I| <= 1e-6 and det R = +1";
    throw Error(message.str());
  }
  Eigen::Isometry3d result = Eigen::Isometry3d::Identity();
  result.linear() = Eigen::Quaterniond(rotation).normalized().toRotationMatrix();
  result.translation() = T_tip_tool.translation();
  return result;
}

// Every number of the URDF was checked against its bounds, yet what matters is that the model
// computes: one that fails here would fail every control cycle, so it fails to load instead.
void check_computable(const RobotModel& model, const std::string& source) {
  ModelWorkspace workspace(model);
  const JointVector zero = JointVector::Zero(model.num_joints());
  Pose pose;
  Kinematics kinematics = workspace.make_kinematics();
  std::string failed;
  if (!workspace.compute_pose(zero, pose)) {
    failed = "the end-effector pose";
  } else if (!workspace.compute(zero, zero, kinematics, false)) {
    failed = "the Jacobian";
  } else if (!workspace.compute(zero, zero, kinematics, true)) {
    failed = "the mass matrix or the gravity torques (with gravity_base = " +
             detail::format_vector(model.gravity_base()) + " m/s^2)";
  }
  if (!failed.empty()) {
    throw LoadError(failed + " of the chain from '" + model.base_link() + "' to '" +
                    model.tip_link() + "' of " + source +
                    " is not finite at q = 0; expected a model that can be computed");
  }
}

}  // namespace

const char* to_string(JointType type) noexcept {
  switch (type) {
    case JointType::revolute:
      return "revolute";
    case JointType::continuous:
      return "continuous";
    case JointType::prismatic:
      return "prismatic";
  }
  return "unknown";
}

const char* to_string(ModelBackend backend) noexcept {
  switch (backend) {
    case ModelBackend::native:
      return "native";
    case ModelBackend::kdl:
      return "kdl";
  }
  return "unknown";
}

// ---------------------------------------------------------------------------------------------
// RobotModel

RobotModel::RobotModel(std::shared_ptr<const detail::ModelData> data) noexcept
    : data_(std::move(data)) {}

RobotModel RobotModel::from_urdf_file(const std::string& path, const std::string& base_link,
                                      const std::string& tip_link,
                                      const Eigen::Isometry3d& T_tip_tool,
                                      const Eigen::Vector3d& gravity_base) {
  const std::string text = read_regular_file(path, "URDF file");
  return from_urdf_source(text, "URDF file '" + path + "'", base_link, tip_link, T_tip_tool,
                          gravity_base);
}

RobotModel RobotModel::from_urdf_string(const std::string& xml, const std::string& base_link,
                                        const std::string& tip_link,
                                        const Eigen::Isometry3d& T_tip_tool,
                                        const Eigen::Vector3d& gravity_base) {
  return from_urdf_source(xml, "the URDF text", base_link, tip_link, T_tip_tool, gravity_base);
}

RobotModel RobotModel::from_urdf_source(const std::string& xml, const std::string& source,
                                        const std::string& base_link, const std::string& tip_link,
                                        const Eigen::Isometry3d& T_tip_tool,
                                        const Eigen::Vector3d& gravity_base) {
  // Cheap checks of the arguments first, so that their errors do not hide behind the URDF's.
  const Eigen::Isometry3d tool = checked_tool(T_tip_tool);
  if (!gravity_base.allFinite()) {
    throw Error("gravity_base = " + detail::format_vector(gravity_base) +
                " m/s^2 has a non-finite entry; expected a finite vector");
  }
  auto data = std::make_shared<detail::ModelData>();
  try {
    data->urdf = detail::urdf_to_kdl_chain(xml, source, base_link, tip_link);
  } catch (const LoadError&) {
    throw;
  } catch (const Error& error) {
    throw LoadError(error.what());
  }
  data->base_link = base_link;
  data->tip_link = tip_link;
  data->T_tip_tool = tool;
  data->gravity_base = gravity_base;
  // The tool is one more fixed, massless segment, so that KDL's pose and Jacobian refer to it.
  data->urdf.chain.addSegment(
      KDL::Segment("tool", KDL::Joint("tool", KDL::Joint::None), detail::to_kdl_frame(tool)));
  try {
    data->native = detail::make_chain_model(data->urdf.chain, gravity_base);
  } catch (const Error& error) {
    throw LoadError(error.what());
  }
  RobotModel model(std::move(data));
  // Either backend may be chosen later: both must compute.
  check_computable(model, source);
  check_computable(model.with_backend(ModelBackend::kdl), source);
  return model;
}

int RobotModel::num_joints() const noexcept {
  return static_cast<int>(data_->urdf.joint_names.size());
}
const std::vector<std::string>& RobotModel::joint_names() const noexcept {
  return data_->urdf.joint_names;
}
const std::vector<JointType>& RobotModel::joint_types() const noexcept {
  return data_->urdf.joint_types;
}
const JointLimits& RobotModel::limits() const noexcept {
  return data_->urdf.limits;
}
const std::string& RobotModel::robot_name() const noexcept {
  return data_->urdf.robot_name;
}
const std::string& RobotModel::base_link() const noexcept {
  return data_->base_link;
}
const std::string& RobotModel::tip_link() const noexcept {
  return data_->tip_link;
}
const Eigen::Isometry3d& RobotModel::tool() const noexcept {
  return data_->T_tip_tool;
}
const Eigen::Vector3d& RobotModel::gravity_base() const noexcept {
  return data_->gravity_base;
}
double RobotModel::moving_mass() const noexcept {
  return data_->urdf.moving_mass;
}
const std::vector<std::string>& RobotModel::joint_links() const noexcept {
  return data_->urdf.joint_links;
}
const std::vector<int>& RobotModel::massless_joints() const noexcept {
  return data_->urdf.massless_joints;
}
const std::vector<std::string>& RobotModel::warnings() const noexcept {
  return data_->urdf.warnings;
}

void check_dynamics(const RobotModel& model, const DynamicsParameters& dynamics) {
  std::string options;
  if (dynamics.inertia_shaped_damping) options = "dynamics.inertia_shaped_damping";
  if (dynamics.dynamically_consistent_nullspace) {
    options +=
        (options.empty() ? "" : " and ") + std::string("dynamics.dynamically_consistent_nullspace");
  }
  if (options.empty()) return;
  const JointVector& armature = dynamics.armature;
  for (const int joint : model.massless_joints()) {
    // One value for every joint or one per joint; another length is validate()'s to report.
    const Eigen::Index index = armature.size() == 1 ? 0 : joint;
    if (index >= armature.size() || armature[index] > 0.0) continue;
    const std::string& link = model.joint_links()[static_cast<std::size_t>(joint)];
    const std::string& name = model.joint_names()[static_cast<std::size_t>(joint)];
    const bool rotates =
        model.joint_types()[static_cast<std::size_t>(joint)] != JointType::prismatic;
    throw Error("joint '" + name + "' moves no mass: link '" + link +
                "' and the links after it up to the tip have no mass" +
                (rotates ? " or rotational inertia" : "") +
                " (no <inertial> in the URDF), so M(q) is singular at every q and " + options +
                " cannot be computed; give link '" + link + "' its <inertial>, or joint '" + name +
                "' its rotor inertia with dynamics.armature[" + std::to_string(joint) +
                "] > 0, or turn " + options + " off");
  }
}
ModelBackend RobotModel::backend() const noexcept {
  return backend_;
}
RobotModel RobotModel::with_backend(ModelBackend backend) const noexcept {
  RobotModel copy(*this);
  copy.backend_ = backend;
  return copy;
}

// ---------------------------------------------------------------------------------------------
// ModelWorkspace

namespace {

// The KDL backend: KDL's solvers and their in- and outputs, sized once.
struct KdlSolvers {
  KdlSolvers(const KDL::Chain& source, const Eigen::Vector3d& gravity, int n)
      : chain(source),
        fk(chain),
        jacobian_solver(chain),
        dynamics_solver(chain, KDL::Vector(gravity.x(), gravity.y(), gravity.z())),
        q(static_cast<unsigned int>(n)),
        dq(static_cast<unsigned int>(n)),
        jacobian(static_cast<unsigned int>(n)),
        mass(static_cast<unsigned int>(n)),
        gravity(static_cast<unsigned int>(n)),
        coriolis(static_cast<unsigned int>(n)) {}

  // The solvers keep references to `chain`, so this never moves (it lives behind a pointer).
  KdlSolvers(const KdlSolvers&) = delete;
  KdlSolvers& operator=(const KdlSolvers&) = delete;

  // Forward kinematics into `frame`; false if KDL fails or the result is not finite.
  bool compute_frame() noexcept {
    if (fk.JntToCart(q, frame) < 0) return false;
    return rotation().allFinite() && Eigen::Map<const Eigen::Vector3d>(frame.p.data).allFinite();
  }
  Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> rotation() const noexcept {
    return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(frame.M.data);
  }
  Eigen::Map<const Eigen::Vector3d> position() const noexcept {
    return Eigen::Map<const Eigen::Vector3d>(frame.p.data);
  }

  // A private copy of the chain: KDL::Joint caches its last rotation in mutable members
  // (Joint::pose is const but writes q_previous and joint_pose), so two threads computing on one
  // shared chain would race. Each workspace therefore owns its chain.
  KDL::Chain chain;
  KDL::ChainFkSolverPos_recursive fk;
  KDL::ChainJntToJacSolver jacobian_solver;
  KDL::ChainDynParam dynamics_solver;
  KDL::JntArray q;
  KDL::JntArray dq;
  KDL::Jacobian jacobian;
  KDL::JntSpaceInertiaMatrix mass;
  KDL::JntArray gravity;
  KDL::JntArray coriolis;
  KDL::Frame frame;
};

template <typename Rotation>
void write_pose(const Rotation& rotation, const Eigen::Vector3d& position, Pose& pose) noexcept {
  pose.position = position;
  pose.orientation = Eigen::Quaterniond(Eigen::Matrix3d(rotation));
  pose.orientation.normalize();
}

}  // namespace

struct ModelWorkspace::Impl {
  explicit Impl(const RobotModel& robot)
      : model(robot),
        n(robot.num_joints()),
        native(robot.data_->native),
        kdl(robot.backend() == ModelBackend::kdl
                ? std::make_unique<KdlSolvers>(robot.data_->urdf.chain, robot.gravity_base(), n)
                : nullptr) {}

  bool valid_input(const JointVector& q_in, const JointVector& dq_in) const noexcept {
    return q_in.size() == n && dq_in.size() == n && q_in.allFinite() && dq_in.allFinite();
  }

  bool compute_native(const JointVector& q, const JointVector& dq, ModelTerms terms,
                      Kinematics& out) noexcept;
  bool compute_kdl(const JointVector& q, const JointVector& dq, ModelTerms terms,
                   Kinematics& out) noexcept;

  RobotModel model;
  int n;
  detail::ChainSolver native;
  std::unique_ptr<KdlSolvers> kdl;  // only for ModelBackend::kdl
  // The native results, checked before any reaches the caller.
  Jacobian jacobian;
  JointMatrix mass;
  JointVector gravity;
  JointVector coriolis;
  JointVector coriolis_transposed;
};

bool ModelWorkspace::Impl::compute_native(const JointVector& q, const JointVector& dq,
                                          ModelTerms terms, Kinematics& out) noexcept {
  native.forward(q);
  if (!native.tool_rotation().allFinite() || !native.tool_position().allFinite()) return false;
  native.jacobian(jacobian);
  if (!jacobian.allFinite()) return false;
  const bool want_mass = includes(terms, ModelTerms::mass);
  const bool want_gravity = includes(terms, ModelTerms::gravity);
  const bool want_coriolis = includes(terms, ModelTerms::coriolis);
  const bool want_transposed = includes(terms, ModelTerms::coriolis_transposed);
  const bool inertias = want_mass || want_coriolis || want_transposed;
  if (inertias || want_gravity) native.bodies(inertias);
  if (want_mass) {
    native.mass(mass);
    if (!mass.allFinite()) return false;
  }
  if (want_gravity) {
    native.gravity(gravity);
    if (!gravity.allFinite()) return false;
  }
  if (want_coriolis) {
    native.coriolis(dq, coriolis);
    if (!coriolis.allFinite()) return false;
  }
  if (want_transposed) {
    native.coriolis_transposed(dq, coriolis_transposed);
    if (!coriolis_transposed.allFinite()) return false;
  }
  // Everything is finite: only now is `out` overwritten.
  write_pose(native.tool_rotation(), native.tool_position(), out.pose);
  out.jacobian = jacobian;
  if (want_mass) out.mass = mass;
  if (want_gravity) out.gravity = gravity;
  if (want_coriolis) out.coriolis = coriolis;
  if (want_transposed) out.coriolis_transposed = coriolis_transposed;
  return true;
}

bool ModelWorkspace::Impl::compute_kdl(const JointVector& q, const JointVector& dq,
                                       ModelTerms terms, Kinematics& out) noexcept {
  KdlSolvers& w = *kdl;
  w.q.data = q;  // same size: a copy, no allocation
  if (!w.compute_frame()) return false;
  if (w.jacobian_solver.JntToJac(w.q, w.jacobian) < 0 || !w.jacobian.data.allFinite()) {
    return false;
  }
  // ChainDynParam runs the recursive Newton-Euler algorithm with zero acceleration (and zero
  // gravity for the Coriolis term) on buffers it sized at construction: nothing allocates.
  const bool want_mass = includes(terms, ModelTerms::mass);
  const bool want_gravity = includes(terms, ModelTerms::gravity);
  const bool want_coriolis = includes(terms, ModelTerms::coriolis);
  if (want_mass && (w.dynamics_solver.JntToMass(w.q, w.mass) < 0 || !w.mass.data.allFinite())) {
    return false;
  }
  if (want_gravity &&
      (w.dynamics_solver.JntToGravity(w.q, w.gravity) < 0 || !w.gravity.data.allFinite())) {
    return false;
  }
  if (want_coriolis) {
    w.dq.data = dq;
    if (w.dynamics_solver.JntToCoriolis(w.q, w.dq, w.coriolis) < 0 ||
        !w.coriolis.data.allFinite()) {
      return false;
    }
  }
  // KDL has no solver for C^T dq: the native one gives it (tests check it against KDL's M).
  const bool want_transposed = includes(terms, ModelTerms::coriolis_transposed);
  if (want_transposed) {
    native.forward(q);
    native.bodies(true);
    native.coriolis_transposed(dq, coriolis_transposed);
    if (!coriolis_transposed.allFinite()) return false;
  }
  write_pose(w.rotation(), w.position(), out.pose);
  out.jacobian = w.jacobian.data;
  if (want_mass) out.mass = w.mass.data;
  if (want_gravity) out.gravity = w.gravity.data;
  if (want_coriolis) out.coriolis = w.coriolis.data;
  if (want_transposed) out.coriolis_transposed = coriolis_transposed;
  return true;
}

namespace {

// Gives the terms of `out` not in `fresh` the model's sizes and, where `check_values`, replaces
// anything non-finite in them. Resizing bounded Eigen objects never allocates.
void make_terms_sized_and_finite(int n, Kinematics& out, ModelTerms fresh,
                                 bool check_values) noexcept {
  if (!includes(fresh, ModelTerms::mass) &&
      (out.mass.rows() != n || out.mass.cols() != n || (check_values && !out.mass.allFinite()))) {
    out.mass.setZero(n, n);
    out.terms &= ~ModelTerms::mass;
  }
  if (!includes(fresh, ModelTerms::gravity) &&
      (out.gravity.size() != n || (check_values && !out.gravity.allFinite()))) {
    out.gravity.setZero(n);
    out.terms &= ~ModelTerms::gravity;
  }
  if (!includes(fresh, ModelTerms::coriolis) &&
      (out.coriolis.size() != n || (check_values && !out.coriolis.allFinite()))) {
    out.coriolis.setZero(n);
    out.terms &= ~ModelTerms::coriolis;
  }
  if (!includes(fresh, ModelTerms::coriolis_transposed) &&
      (out.coriolis_transposed.size() != n ||
       (check_values && !out.coriolis_transposed.allFinite()))) {
    out.coriolis_transposed.setZero(n);
    out.terms &= ~ModelTerms::coriolis_transposed;
  }
  out.has_dynamics =
      includes(out.terms, ModelTerms::mass | ModelTerms::gravity | ModelTerms::coriolis);
}

// The same for all of `out`, so that a failed compute() still leaves a usable (if stale) result.
void make_sized_and_finite(int n, Kinematics& out) noexcept {
  if (!out.pose.position.allFinite()) out.pose.position.setZero();
  if (!out.pose.orientation.coeffs().allFinite() || out.pose.orientation.norm() < 0.5) {
    out.pose.orientation.setIdentity();
  }
  if (out.jacobian.cols() != n || !out.jacobian.allFinite()) out.jacobian.setZero(6, n);
  make_terms_sized_and_finite(n, out, ModelTerms::none, true);
}

}  // namespace

ModelWorkspace::ModelWorkspace(const RobotModel& model) : impl_(std::make_unique<Impl>(model)) {}
ModelWorkspace::~ModelWorkspace() = default;
ModelWorkspace::ModelWorkspace(const ModelWorkspace& other)
    : impl_(other.impl_ ? std::make_unique<Impl>(other.impl_->model) : nullptr) {}
ModelWorkspace& ModelWorkspace::operator=(const ModelWorkspace& other) {
  if (this != &other) impl_ = other.impl_ ? std::make_unique<Impl>(other.impl_->model) : nullptr;
  return *this;
}
ModelWorkspace::ModelWorkspace(ModelWorkspace&& other) noexcept = default;
ModelWorkspace& ModelWorkspace::operator=(ModelWorkspace&& other) noexcept = default;

const RobotModel& ModelWorkspace::model() const noexcept {
  return impl_->model;
}

Kinematics ModelWorkspace::make_kinematics() const {
  Kinematics kinematics;
  make_sized_and_finite(impl_->n, kinematics);
  return kinematics;
}

bool ModelWorkspace::compute(const JointVector& q, const JointVector& dq, Kinematics& out,
                             ModelTerms terms) noexcept {
  if (!impl_) return false;
  Impl& w = *impl_;
  terms &= ModelTerms::all;
  // The backends overwrite `out` only once everything they computed is finite: the pose, the
  // Jacobian and the requested terms are then fresh, and only the rest needs checking.
  if (!w.valid_input(q, dq) ||
      !(w.kdl ? w.compute_kdl(q, dq, terms, out) : w.compute_native(q, dq, terms, out))) {
    make_sized_and_finite(w.n, out);
    return false;
  }
  // The terms left out keep what they had: sized and finite since the last compute(), unless
  // the caller wrote into them (only the sizes matter to the bounded storage).
  out.terms = terms;
  make_terms_sized_and_finite(w.n, out, terms, false);
  return true;
}

bool ModelWorkspace::compute(const JointVector& q, const JointVector& dq, Kinematics& out,
                             bool dynamics) noexcept {
  return compute(
      q, dq, out,
      dynamics ? ModelTerms::mass | ModelTerms::gravity | ModelTerms::coriolis : ModelTerms::none);
}

bool ModelWorkspace::compute_pose(const JointVector& q, Pose& T_base_ee) noexcept {
  if (!impl_) return false;
  Impl& w = *impl_;
  if (q.size() != w.n || !q.allFinite()) return false;
  if (w.kdl) {
    w.kdl->q.data = q;
    if (!w.kdl->compute_frame()) return false;
    write_pose(w.kdl->rotation(), w.kdl->position(), T_base_ee);
    return true;
  }
  w.native.forward(q);
  if (!w.native.tool_rotation().allFinite() || !w.native.tool_position().allFinite()) {
    return false;
  }
  write_pose(w.native.tool_rotation(), w.native.tool_position(), T_base_ee);
  return true;
}

ConfigurationCheck check_configuration(const RobotModel& model, const JointVector& q,
                                       double singular_threshold, double limit_margin) {
  const int n = model.num_joints();
  if (q.size() != n || !q.allFinite()) {
    std::ostringstream text;
    text << "check_configuration: q = [" << q.transpose() << "] must have " << n
         << " finite values (one per joint of '" << model.robot_name() << "')";
    throw Error(text.str());
  }
  ModelWorkspace workspace(model);
  Kinematics kinematics = workspace.make_kinematics();
  workspace.compute(q, JointVector::Zero(n), kinematics);
  ConfigurationCheck check;
  check.singular_values = Eigen::JacobiSVD<Eigen::MatrixXd>(kinematics.jacobian).singularValues();
  char text[256];
  const double smallest = check.singular_values[check.singular_values.size() - 1];
  if (smallest < singular_threshold) {
    std::snprintf(text, sizeof(text),
                  "the configuration is %s: the smallest singular value of the Jacobian is %.3g "
                  "(below %.3g); the arm cannot move, or only with large joint speeds, in one "
                  "task direction; start elsewhere (start_q)",
                  smallest < 1e-9 ? "singular" : "near a singularity", smallest,
                  singular_threshold);
    check.warnings.emplace_back(text);
  }
  const JointLimits& limits = model.limits();
  for (int i = 0; i < n; ++i) {
    const double distance =
        std::min(q[i] - limits.position_lower[i], limits.position_upper[i] - q[i]);
    if (std::isfinite(distance) && distance < check.limit_distance) {
      check.limit_distance = distance;
      check.closest_joint = i;
    }
  }
  if (check.closest_joint >= 0 && check.limit_distance < limit_margin) {
    const int i = check.closest_joint;
    const bool lower = q[i] - limits.position_lower[i] <= limits.position_upper[i] - q[i];
    std::snprintf(text, sizeof(text), "joint %s is at %.4g, %.3g from its %s limit %.4g%s",
                  model.joint_names()[static_cast<std::size_t>(i)].c_str(), q[i],
                  check.limit_distance, lower ? "lower" : "upper",
                  lower ? limits.position_lower[i] : limits.position_upper[i],
                  check.limit_distance < 0.0 ? " (outside its range)" : "");
    check.warnings.emplace_back(text);
  }
  return check;
}

void fill_robot_state(const JointVector& q, const JointVector& dq, const Kinematics& kinematics,
                      RobotState& state) noexcept {
  state.q = q;
  state.dq = dq;
  state.pose = kinematics.pose;
  state.jacobian = kinematics.jacobian;
}

}  // namespace cartesian_impedance
