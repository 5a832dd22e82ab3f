#include "cartesian_impedance/core/controller.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <initializer_list>
#include <string>

#include "cartesian_impedance/core/checks.hpp"
#include "law.hpp"

namespace cartesian_impedance {
namespace {

bool clamp_each(Eigen::Ref<Eigen::VectorXd> values, const Range& range) {
  bool clamped = false;
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    const double value = std::clamp(values[i], range.min, range.max);
    clamped |= value != values[i];
    values[i] = value;
  }
  return clamped;
}

// Diagonal stiffness/damping from the [translation; rotation] halves of the parameters.
Vector6d stacked(const Eigen::Vector3d& translation, const Eigen::Vector3d& rotation) {
  Vector6d result;
  result << translation, rotation;
  return result;
}

}  // namespace

const char* to_string(Status status) noexcept {
  switch (status) {
    case Status::ok:
      return "ok";
    case Status::not_started:
      return "not_started";
    case Status::invalid_dt:
      return "invalid_dt";
    case Status::invalid_robot_state:
      return "invalid_robot_state";
    case Status::numerical_error:
      return "numerical_error";
    case Status::missing_dynamics:
      return "missing_dynamics";
    case Status::model_error:
      return "model_error";
    case Status::motion_halted:
      return "motion_halted";
  }
  return "unknown";
}

const char* to_string(TorqueShaping shaping) noexcept {
  switch (shaping) {
    case TorqueShaping::none:
      return "none";
    case TorqueShaping::nullspace:
      return "nullspace";
    case TorqueShaping::spring:
      return "spring";
    case TorqueShaping::wrench:
      return "wrench";
    case TorqueShaping::payload:
      return "payload";
    case TorqueShaping::damping:
      return "damping";
    case TorqueShaping::gravity:
      return "gravity";
  }
  return "unknown";
}

namespace {
Matrix6d in_base(const Matrix6d& matrix, Frame frame, const Eigen::Quaterniond& orientation) {
  if (frame == Frame::base) return matrix;
  const Matrix6d rotation6 = block_rotation(orientation.toRotationMatrix());
  return rotation6 * matrix * rotation6.transpose();
}
}  // namespace

Matrix6d ControllerState::stiffness_base() const noexcept {
  return in_base(filtered.stiffness, stiffness_frame, pose.orientation);
}

Matrix6d ControllerState::damping_base() const noexcept {
  return in_base(damping, stiffness_frame, pose.orientation);
}

CartesianImpedanceController::LawHandle::LawHandle(int num_joints)
    : law_(std::make_unique<Law>(num_joints)) {}
CartesianImpedanceController::LawHandle::~LawHandle() = default;
// The workspace is copied with the rest: a copy continues exactly where the original is.
CartesianImpedanceController::LawHandle::LawHandle(const LawHandle& other)
    : law_(std::make_unique<Law>(*other.law_)) {}
CartesianImpedanceController::LawHandle& CartesianImpedanceController::LawHandle::operator=(
    const LawHandle& other) {
  if (this != &other) law_ = std::make_unique<Law>(*other.law_);
  return *this;
}
CartesianImpedanceController::LawHandle::LawHandle(LawHandle&& other) noexcept = default;
CartesianImpedanceController::LawHandle& CartesianImpedanceController::LawHandle::operator=(
    LawHandle&& other) noexcept = default;

CartesianImpedanceController::CartesianImpedanceController(int num_joints,
                                                           const Parameters& parameters)
    : num_joints_(num_joints), law_(std::clamp(num_joints, 1, kMaxJoints)) {
  if (num_joints < 1 || num_joints > kMaxJoints) {
    throw Error("num_joints = " + std::to_string(num_joints) + " is outside [1, " +
                std::to_string(kMaxJoints) + "]");
  }
  const Eigen::Index n = num_joints;
  Targets& commanded = state_.commanded;
  commanded.stiffness.setZero();
  commanded.damping_ratio.setZero();
  commanded.nullspace_q = JointVector::Zero(n);
  commanded.nullspace_stiffness = JointVector::Zero(n);
  commanded.wrench.setZero();
  commanded.twist.setZero();
  commanded.nullspace_dq = JointVector::Zero(n);
  state_.filtered = commanded;
  state_.pose_error.setZero();
  state_.wrench_base.setZero();
  state_.tau_cartesian = JointVector::Zero(n);
  state_.tau_nullspace = JointVector::Zero(n);
  state_.tau_wrench = JointVector::Zero(n);
  state_.tau_gravity = JointVector::Zero(n);
  state_.tau = JointVector::Zero(n);
  state_.joint_torque_limit = JointVector::Zero(n);
  tau_previous_ = JointVector::Zero(n);
  scheduled_nullspace_damping_ = JointVector::Zero(n);
  scheduled_damping_.setZero();
  state_.damping.setZero();
  set_parameters(parameters);
}

CartesianImpedanceController::~CartesianImpedanceController() = default;
CartesianImpedanceController::CartesianImpedanceController(
    const CartesianImpedanceController& other) = default;
CartesianImpedanceController& CartesianImpedanceController::operator=(
    const CartesianImpedanceController& other) = default;
CartesianImpedanceController::CartesianImpedanceController(
    CartesianImpedanceController&& other) noexcept = default;
CartesianImpedanceController& CartesianImpedanceController::operator=(
    CartesianImpedanceController&& other) noexcept = default;

void CartesianImpedanceController::apply_saturation(Targets& commanded, ActiveLimits& limits,
                                                    unsigned commanded_now) const noexcept {
  // Every commanded value is brought within the (possibly new) limits. A quantity's flag says
  // whether its last command was saturated: it is set afresh for the quantities just commanded
  // and otherwise only raised, never cleared by an unrelated command.
  const LimitParameters& l = parameters_.limits;
  auto update = [commanded_now](bool& flag, bool saturated, unsigned quantity) {
    flag = (commanded_now & quantity) != 0 ? saturated : (flag || saturated);
  };
  update(limits.stiffness_saturated,
         saturate_stiffness(commanded.stiffness, l.stiffness.translation.min,
                            l.stiffness.translation.max, l.stiffness.rotation.min,
                            l.stiffness.rotation.max),
         Commanded::stiffness);
  Eigen::Matrix<double, 1, 1> nullspace_zeta(commanded.nullspace_damping_ratio);
  const bool cartesian_zeta = clamp_each(commanded.damping_ratio, l.damping_ratio);
  const bool nullspace_zeta_clamped = clamp_each(nullspace_zeta, l.damping_ratio);
  commanded.nullspace_damping_ratio = nullspace_zeta[0];
  update(limits.damping_ratio_saturated, cartesian_zeta || nullspace_zeta_clamped,
         Commanded::damping_ratio);
  update(limits.nullspace_stiffness_saturated,
         clamp_each(commanded.nullspace_stiffness, l.nullspace_stiffness),
         Commanded::nullspace_stiffness);
  const bool force_clipped = clip_norm(commanded.wrench.head<3>(), l.wrench.force);
  const bool torque_clipped = clip_norm(commanded.wrench.tail<3>(), l.wrench.torque);
  update(limits.wrench_saturated, force_clipped || torque_clipped, Commanded::wrench);
}

void CartesianImpedanceController::change_frames(Frame stiffness_frame,
                                                 Frame wrench_frame) noexcept {
  // The filtered values live in the frame they were commanded in; when the frame changes they
  // are re-expressed in the new one (with the last measured orientation) so the filter carries
  // on from where the robot is instead of jumping.
  if (!started_) return;
  const Eigen::Matrix3d rotation = state_.pose.orientation.toRotationMatrix();
  const Matrix6d rotation6 = block_rotation(rotation);
  Targets& filtered = state_.filtered;
  if (stiffness_frame != parameters_.stiffness.frame) {
    filtered.stiffness = stiffness_frame == Frame::base
                             ? Matrix6d(rotation6 * filtered.stiffness * rotation6.transpose())
                             : Matrix6d(rotation6.transpose() * filtered.stiffness * rotation6);
  }
  if (wrench_frame != parameters_.wrench.frame) {
    const Vector6d wrench = filtered.wrench;
    if (wrench_frame == Frame::base) {
      filtered.wrench.head<3>().noalias() = rotation * wrench.head<3>();
      filtered.wrench.tail<3>().noalias() = rotation * wrench.tail<3>();
    } else {
      filtered.wrench.head<3>().noalias() = rotation.transpose() * wrench.head<3>();
      filtered.wrench.tail<3>().noalias() = rotation.transpose() * wrench.tail<3>();
    }
  }
}

void CartesianImpedanceController::commit(const Parameters& parameters, Targets commanded,
                                          unsigned commanded_now) noexcept {
  // Callers have validated everything; from here on nothing can fail, so a rejected command
  // never leaves a half-applied change behind. A command of the impedance ends a schedule().
  scheduled_ = false;
  change_frames(parameters.stiffness.frame, parameters.wrench.frame);
  parameters_ = parameters;
  state_.stiffness_frame = parameters.stiffness.frame;
  state_.wrench_frame = parameters.wrench.frame;
  apply_saturation(commanded, state_.limits, commanded_now);
  state_.commanded = commanded;
  if (!started_) {
    state_.filtered = state_.commanded;
    state_.safety.payload_mass = parameters.payload.mass;
    state_.safety.payload_center_of_mass = parameters.payload.center_of_mass;
    state_.safety.tank_level = parameters.safety.energy_tank.initial;
    state_.safety.pose_error_in_force = parameters.limits.pose_error;
    state_.safety.workspace_in_force = parameters.safety.workspace;
  }
  state_.safety.tank_level =
      std::min(state_.safety.tank_level, parameters.safety.energy_tank.capacity);
  refresh_damping_mode();
  joint_torque_limit_ = per_joint(parameters.limits.joint_torque, num_joints_, kDefaultJointTorque);
  joint_torque_rate_limit_ = per_joint(parameters.limits.joint_torque_rate, num_joints_);
  joint_velocity_bound_ = per_joint(parameters.plausibility.joint_velocity, num_joints_);
  // A raised bound holds at once (the rate limit keeps the torque continuous); a lowered one
  // ramps down from the torque being commanded (limit_torque()), so that neither the rate limit
  // nor the bound in force is ever exceeded.
  if (started_) {
    state_.joint_torque_limit =
        joint_torque_limit_.cwiseMax(state_.joint_torque_limit.cwiseMin(tau_previous_.cwiseAbs()));
  } else {
    state_.joint_torque_limit = joint_torque_limit_;
  }
  gains_.dt = -1.0;
}

void CartesianImpedanceController::refresh_damping_mode() noexcept {
  stiffness_diagonal_ =
      is_diagonal(state_.commanded.stiffness) && is_diagonal(state_.filtered.stiffness);
  if (stiffness_diagonal_) law_->damping_frame.setZero();
  law_->forget_damping();
}

void CartesianImpedanceController::start(const RobotState& robot) {
  start(robot, Eigen::VectorXd::Zero(num_joints_));
}

void CartesianImpedanceController::start(const RobotState& robot,
                                         const Eigen::Ref<const Eigen::VectorXd>& tau_previous) {
  // The checks of every cycle, thrown instead of failing closed.
  checks::raise(checks::robot_state(robot, num_joints_, &joint_velocity_bound_), "robot.");
  checks::size("tau_previous", tau_previous.size(), num_joints_);
  checks::finite_vector("tau_previous", tau_previous, "Nm");
  const Pose pose{robot.pose.position, robot.pose.orientation.normalized()};
  Targets& commanded = state_.commanded;
  commanded.pose = pose;
  commanded.nullspace_q = robot.q;
  commanded.twist.setZero();
  commanded.nullspace_dq.setZero();
  state_.filtered = commanded;
  state_.filtered.wrench.setZero();
  // The arm already carries its payload: its compensation holds from the first cycle.
  SafetyState& safety = state_.safety;
  safety.payload_mass = parameters_.payload.mass;
  safety.payload_center_of_mass = parameters_.payload.center_of_mass;
  safety.tank_level = parameters_.safety.energy_tank.initial;
  // The settings that store energy start as configured, except a box the arm starts outside of:
  // it starts around the end effector (no wall energy that nothing paid for) and closes in as the
  // end effector moves into the configured box.
  safety.pose_error_in_force = parameters_.limits.pose_error;
  safety.workspace_in_force = parameters_.safety.workspace;
  safety.workspace_in_force.min = safety.workspace_in_force.min.cwiseMin(pose.position);
  safety.workspace_in_force.max = safety.workspace_in_force.max.cwiseMax(pose.position);
  law_->wall_position = pose.position;
  law_->wall_force_sent.setZero();
  law_->wall_spring_sent.setZero();
  law_->wall_damper_sent.setZero();
  law_->wall_energy = 0.0;
  law_->expecting = false;
  law_->disturbance.setZero();
  refresh_damping_mode();
  state_.pose = pose;
  state_.tau = tau_previous;
  tau_previous_ = tau_previous;
  state_.joint_torque_limit = joint_torque_limit_.cwiseMax(tau_previous_.cwiseAbs());
  state_.limits.joint_torque_limit_ramping =
      (state_.joint_torque_limit.array() > joint_torque_limit_.array()).any();
  state_.fault = Fault{};
  state_.tau_cartesian.setZero();
  state_.tau_nullspace.setZero();
  state_.tau_wrench.setZero();
  state_.status = Status::ok;
  const Range& plausible = parameters_.plausibility.dt;
  last_valid_dt_ = std::clamp(1e-3, plausible.min, plausible.max);
  gains_.dt = -1.0;
  episodes_ = 0;
  in_episode_ = false;
  halted_ = false;
  halted_oscillating_ = false;
  safety.oscillation_scale = 1.0;
  safety.oscillations = 0;
  law_->oscillation_scale_filtered = 1.0;
  law_->oscillation_damping_scale = 1.0;
  forget_oscillation();
  safety.passivity_scale.setOnes();
  safety.passivity_halvings = 0;
  forget_passivity();
  state_.collision = CollisionState{};
  state_.collision.residual.setZero(num_joints_);
  state_.collision.unexpected.setZero(num_joints_);
  state_.collision.threshold.setZero(num_joints_);
  forget_collision_observer();
  resume_pending_ = false;
  state_.limits.holding = false;
  started_ = true;
}

void CartesianImpedanceController::apply(const Command& command) {
  const ValidCommand valid = validate_command(command, num_joints_);
  if (const auto* update = std::get_if<ParameterUpdate>(&valid.command())) {
    Parameters merged = parameters_;
    copy_parameters(update->values, merged, update->names);
    checks::raise(consistency_fault(merged));
  }
  apply(valid);
}

bool CartesianImpedanceController::apply(const ValidCommand& valid) noexcept {
  if (valid.num_joints() != 0 && valid.num_joints() != num_joints_) return false;
  bool applied = true;
  // The reference pose and nullspace target are filtered toward directly; every other command
  // also changes the configuration (parameters() keeps what was commanded) and is saturated.
  const auto change = [this](unsigned quantities, const auto& edit) noexcept {
    Parameters parameters = parameters_;
    Targets commanded = state_.commanded;
    edit(parameters, commanded);
    commit(parameters, commanded, quantities);
  };
  std::visit(
      Overloaded{
          [this](const ReferencePose& c) {
            // A collision's reaction holds the arm until Resume, whoever streams references.
            if (collision_latched()) {
              ++state_.collision.commands_held;
              return;
            }
            state_.commanded.pose = c.pose_base;
            state_.limits.holding = false;
          },
          [this](const NullspaceTarget& c) {
            if (collision_latched()) {
              ++state_.collision.commands_held;
              return;
            }
            state_.commanded.nullspace_q = c.q_desired;
          },
          [this](const Resume&) { resume_pending_ = collision_latched(); },
          [&](const Stiffness& c) {
            change(Commanded::stiffness, [&](Parameters& parameters, Targets& commanded) {
              // parameters() keeps the diagonal; a full matrix lives in the commanded targets.
              parameters.stiffness.translation = c.stiffness.diagonal().head<3>();
              parameters.stiffness.rotation = c.stiffness.diagonal().tail<3>();
              parameters.stiffness.frame = c.frame.value_or(parameters_.stiffness.frame);
              commanded.stiffness = c.stiffness;
            });
          },
          [&](const DampingRatio& c) {
            change(Commanded::damping_ratio, [&](Parameters& parameters, Targets& commanded) {
              parameters.damping_ratio.translation = c.ratio.head<3>();
              parameters.damping_ratio.rotation = c.ratio.tail<3>();
              commanded.damping_ratio = c.ratio;
            });
          },
          [&](const NullspaceStiffness& c) {
            change(Commanded::nullspace_stiffness, [&](Parameters& parameters, Targets& commanded) {
              parameters.nullspace.stiffness = c.stiffness;
              commanded.nullspace_stiffness = per_joint(c.stiffness, num_joints_);
            });
          },
          [&](const NullspaceDampingRatio& c) {
            change(Commanded::damping_ratio, [&](Parameters& parameters, Targets& commanded) {
              parameters.nullspace.damping_ratio = c.ratio;
              commanded.nullspace_damping_ratio = c.ratio;
            });
          },
          [&](const Wrench& c) {
            change(Commanded::wrench, [&](Parameters& parameters, Targets& commanded) {
              parameters.wrench.force = c.wrench.head<3>();
              parameters.wrench.torque = c.wrench.tail<3>();
              parameters.wrench.frame = c.frame.value_or(parameters_.wrench.frame);
              commanded.wrench = c.wrench;
            });
          },
          [&](const Parameters& c) {
            change(Commanded::everything, [&](Parameters& parameters, Targets& commanded) {
              parameters = c;
              recommand(parameters, Commanded::everything, commanded);
            });
          },
          [&](const ParameterUpdate& c) {
            // Merged into the parameters in force now, which may differ from those the sender
            // checked it against (another update came first): the result must still hold
            // together, else nothing changes.
            Parameters merged = parameters_;
            copy_parameters(c.values, merged, c.names);
            if (consistency_fault(merged)) {
              applied = false;
              return;
            }
            const unsigned quantities = quantities_named(c.names);
            change(quantities, [&](Parameters& parameters, Targets& commanded) {
              parameters = merged;
              recommand(parameters, quantities, commanded);
            });
          },
      },
      valid.command());
  return applied;
}

unsigned CartesianImpedanceController::quantities_named(const ParameterNames& names) noexcept {
  // The rows of each commanded quantity, found once by name.
  static const auto rows_of = [](std::initializer_list<std::string_view> prefixes) {
    ParameterNames rows;
    const std::vector<ParameterInfo>& table = parameter_table();
    for (std::size_t i = 0; i < table.size(); ++i) {
      for (const std::string_view prefix : prefixes) {
        if (table[i].name.substr(0, prefix.size()) == prefix) rows[i] = true;
      }
    }
    return rows;
  };
  static const ParameterNames stiffness = rows_of({"stiffness."});
  static const ParameterNames damping = rows_of({"damping_ratio.", "nullspace.damping_ratio"});
  static const ParameterNames nullspace = rows_of({"nullspace.stiffness"});
  static const ParameterNames wrench = rows_of({"wrench."});
  // Saturation re-reads every commanded value against the limits anyway; the flags of the
  // quantities named are set afresh.
  return ((names & stiffness).any() ? Commanded::stiffness : 0u) |
         ((names & damping).any() ? Commanded::damping_ratio : 0u) |
         ((names & nullspace).any() ? Commanded::nullspace_stiffness : 0u) |
         ((names & wrench).any() ? Commanded::wrench : 0u);
}

void CartesianImpedanceController::recommand(const Parameters& parameters, unsigned quantities,
                                             Targets& commanded) const noexcept {
  if ((quantities & Commanded::stiffness) != 0) {
    commanded.stiffness =
        stacked(parameters.stiffness.translation, parameters.stiffness.rotation).asDiagonal();
  }
  if ((quantities & Commanded::damping_ratio) != 0) {
    commanded.damping_ratio =
        stacked(parameters.damping_ratio.translation, parameters.damping_ratio.rotation);
    commanded.nullspace_damping_ratio = parameters.nullspace.damping_ratio;
  }
  if ((quantities & Commanded::nullspace_stiffness) != 0) {
    commanded.nullspace_stiffness = per_joint(parameters.nullspace.stiffness, num_joints_);
  }
  if ((quantities & Commanded::wrench) != 0) {
    commanded.wrench << parameters.wrench.force, parameters.wrench.torque;
  }
}

void CartesianImpedanceController::update_gains(double dt) noexcept {
  if (dt == gains_.dt) return;
  const FilterParameters& filter = parameters_.filter;
  gains_.dt = dt;
  gains_.pose = filter_gain(dt, filter.pose.time, filter.pose.fraction);
  gains_.stiffness = filter_gain(dt, filter.stiffness.time, filter.stiffness.fraction);
  gains_.nullspace = filter_gain(dt, filter.nullspace.time, filter.nullspace.fraction);
  gains_.wrench = filter_gain(dt, filter.wrench.time, filter.wrench.fraction);
}

void CartesianImpedanceController::filter_targets() noexcept {
  // a_{k+1} = (1 - a) a_k + a a_d, written in this form so that a = 1 lands exactly on a_d.
  const Targets& commanded = state_.commanded;
  Targets& filtered = state_.filtered;
  law_->reference_before = filtered.pose;
  law_->stiffness_before = filtered.stiffness;
  law_->nullspace_q_before = filtered.nullspace_q;
  law_->nullspace_stiffness_before = filtered.nullspace_stiffness;
  const double a_pose = gains_.pose;
  filtered.pose.position =
      (1.0 - a_pose) * filtered.pose.position + a_pose * commanded.pose.position;
  filtered.pose.orientation =
      filtered.pose.orientation.slerp(a_pose, commanded.pose.orientation).normalized();
  const double a_stiffness = gains_.stiffness;
  // The oscillation watch's scale enters the filter's target: the stiffness leaves as smoothly
  // as a command would take it away.
  // So do the passivity controller's scales of its springs.
  const double scale = state_.safety.oscillation_scale;
  const Eigen::Vector3d& springs = state_.safety.passivity_scale;
  if (stiffness_diagonal_) {
    Vector6d target = (a_stiffness * scale) * commanded.stiffness.diagonal();
    target.head<3>() *= springs[0];
    target.tail<3>() *= springs[1];
    filtered.stiffness.diagonal() = (1.0 - a_stiffness) * filtered.stiffness.diagonal() + target;
  } else {
    Matrix6d target = (a_stiffness * scale) * commanded.stiffness;
    scale_stiffness_groups(target, springs);
    filtered.stiffness = (1.0 - a_stiffness) * filtered.stiffness + target;
  }
  if (law_->oscillation_scale_filtered != scale) {  // only after the watch found something
    law_->oscillation_scale_filtered =
        (1.0 - a_stiffness) * law_->oscillation_scale_filtered + a_stiffness * scale;
    law_->oscillation_damping_scale = std::sqrt(law_->oscillation_scale_filtered);
  }
  filtered.damping_ratio =
      (1.0 - a_stiffness) * filtered.damping_ratio + a_stiffness * commanded.damping_ratio;
  const double a_nullspace = gains_.nullspace;
  filtered.nullspace_q =
      (1.0 - a_nullspace) * filtered.nullspace_q + a_nullspace * commanded.nullspace_q;
  filtered.nullspace_stiffness = (1.0 - a_nullspace) * filtered.nullspace_stiffness +
                                 (a_nullspace * scale * springs[2]) * commanded.nullspace_stiffness;
  filtered.nullspace_damping_ratio = (1.0 - a_nullspace) * filtered.nullspace_damping_ratio +
                                     a_nullspace * commanded.nullspace_damping_ratio;
  filtered.twist = commanded.twist;
  filtered.nullspace_dq = commanded.nullspace_dq;
  const double a_wrench = gains_.wrench;
  filtered.wrench = (1.0 - a_wrench) * filtered.wrench + a_wrench * commanded.wrench;
  filter_payload();
}

void CartesianImpedanceController::track(const Pose& pose_base, const Vector6d& twist_base,
                                         const JointVector& q_desired,
                                         const JointVector& dq_desired) noexcept {
  if (collision_latched()) return;  // the reaction holds the reference until Resume
  for (Targets* targets : {&state_.commanded, &state_.filtered}) {
    targets->pose = pose_base;
    targets->twist = twist_base;
    targets->nullspace_q = q_desired;
    targets->nullspace_dq = dq_desired;
  }
}

void CartesianImpedanceController::schedule(const ScheduledImpedance& impedance) noexcept {
  const bool latched = collision_latched();  // the reaction holds the reference until Resume
  for (Targets* targets : {&state_.commanded, &state_.filtered}) {
    if (!latched) {
      targets->pose = impedance.reference;
      targets->nullspace_q = impedance.nullspace_q;
    }
    targets->stiffness = impedance.stiffness;
    targets->nullspace_stiffness = impedance.nullspace_stiffness;
    targets->wrench = impedance.wrench;
  }
  // The oscillation watch's scale as far as it has come through the filter.
  const double scale = law_->oscillation_scale_filtered;
  const Eigen::Vector3d& springs = state_.safety.passivity_scale;
  state_.filtered.stiffness *= scale;
  scale_stiffness_groups(state_.filtered.stiffness, springs);
  state_.filtered.nullspace_stiffness *= scale * springs[2];
  scheduled_damping_ = impedance.damping;
  scheduled_damping_diagonal_ = is_diagonal(impedance.damping);
  scheduled_nullspace_damping_ = impedance.nullspace_damping;
  scheduled_ = true;
  refresh_damping_mode();
}

void CartesianImpedanceController::stop_tracking() noexcept {
  state_.commanded.twist.setZero();
  state_.commanded.nullspace_dq.setZero();
}

Status CartesianImpedanceController::fail_closed(Status status, const Fault& fault,
                                                 double dt) noexcept {
  // No trustworthy law output: ramp the last command as fast as the rate limit allows toward
  // zero, or toward the last gravity torque when the law compensates gravity (zero would drop
  // the arm).
  if (!started_) {
    state_.tau.setZero();
    state_.status = Status::not_started;
    return state_.status;
  }
  const Range& plausible = parameters_.plausibility.dt;
  if (!(dt >= plausible.min && dt <= plausible.max)) dt = last_valid_dt_;
  time_ += dt;
  if (status == Status::invalid_robot_state) count_implausible_motion(fault);
  state_.tau = state_.tau_gravity;
  state_.tau_cartesian.setZero();
  state_.tau_nullspace.setZero();
  state_.tau_wrench.setZero();
  // The walls' observer counts no work while they do not act; they start again from nothing.
  // Nor does the governor's disturbance observer.
  law_->expecting = false;
  law_->wall_force_sent.setZero();
  law_->wall_spring_sent.setZero();
  law_->wall_damper_sent.setZero();
  // Nor does the passivity observer: the torque it would pair is not the law's. The collision
  // monitor starts again from the next measurement.
  forget_passivity();
  forget_collision_observer();
  limit_torque(dt);
  state_.status = status;
  state_.fault = fault;
  return status;
}

void CartesianImpedanceController::count_implausible_motion(const Fault& fault) noexcept {
  // Only a measured motion the arm cannot make: a joint too fast, or past its limit (the loop's
  // faults with a bound). A non-finite or missing value is a broken measurement, not motion.
  const bool motion = fault.has_bound &&
                      (std::strcmp(fault.input, "dq") == 0 || std::strcmp(fault.input, "q") == 0);
  if (!motion || in_episode_) return;
  in_episode_ = true;
  // The last kHoldEpisodes beginnings, oldest first.
  if (episodes_ == kHoldEpisodes) {
    std::copy(episode_began_.begin() + 1, episode_began_.end(), episode_began_.begin());
    --episodes_;
  }
  episode_began_[static_cast<std::size_t>(episodes_++)] = time_;
  if (episodes_ == kHoldEpisodes && time_ - episode_began_[0] <= kHoldWindow) {
    halted_ = true;
    at_rest_for_ = 0.0;
    halted_for_ = 0.0;
    episodes_ = 0;
    // Swings past the plausible speed, again and again, are the closed loop's instability at its
    // most violent (a delay far past the stiffness's margin): the oscillation watch halves the
    // stiffness the arm is held with afterwards, as it does for a slower limit cycle.
    halve_stiffness();
  }
}

void CartesianImpedanceController::hold_where_the_arm_is(const RobotState& robot) noexcept {
  // What start() does with the targets, keeping the parameters, the impedance and the torque:
  // the spring holds the arm where it is, so the energy of the motion is damped out instead of
  // turned back into the motion.
  const Pose pose{robot.pose.position, robot.pose.orientation.normalized()};
  for (Targets* targets : {&state_.commanded, &state_.filtered}) {
    targets->pose = pose;
    targets->nullspace_q = robot.q;
    targets->twist.setZero();
    targets->nullspace_dq.setZero();
  }
  halted_ = false;
  halted_oscillating_ = false;
  state_.limits.holding = true;
}

Status CartesianImpedanceController::update(const RobotState& robot, double dt) noexcept {
  return cycle(robot, dt, checks::robot_state(robot, num_joints_, &joint_velocity_bound_));
}

Status CartesianImpedanceController::update_measured(const RobotState& robot, double dt) noexcept {
  return cycle(robot, dt, checks::kinematics(robot, num_joints_));
}

Status CartesianImpedanceController::cycle(const RobotState& robot, double dt,
                                           const Fault& input_fault) noexcept {
  if (!started_) {
    state_.tau.setZero();
    state_.status = Status::not_started;
    return state_.status;
  }
  if (const Fault fault = checks::time_step(dt, parameters_.plausibility.dt)) {
    return fail_closed(Status::invalid_dt, fault, dt);
  }
  if (input_fault) return fail_closed(Status::invalid_robot_state, input_fault, dt);
  const DynamicsParameters& dynamics = parameters_.dynamics;
  if ((dynamics.inertia_shaped_damping || dynamics.dynamically_consistent_nullspace) &&
      robot.mass.rows() != num_joints_) {
    return fail_closed(
        Status::missing_dynamics,
        Fault{"mass", -1, static_cast<double>(robot.mass.rows()),
              "is missing (dynamics options need M(q))", 0.0, false, "", Fault::Form::statement},
        dt);
  }
  if (dynamics.gravity_compensation && robot.gravity.size() != num_joints_) {
    return fail_closed(Status::missing_dynamics,
                       Fault{"gravity", -1, static_cast<double>(robot.gravity.size()),
                             "is missing (dynamics.gravity_compensation needs g(q))", 0.0, false,
                             "", Fault::Form::statement},
                       dt);
  }
  if (parameters_.collision.detection && parameters_.collision.measured_torque) {
    const bool torque = robot.measured_torque.size() != num_joints_;
    if (torque || robot.gravity.size() != num_joints_) {
      return fail_closed(
          Status::missing_dynamics,
          Fault{torque ? "measured_torque" : "gravity", -1,
                static_cast<double>(torque ? robot.measured_torque.size() : robot.gravity.size()),
                torque ? "is missing (collision.measured_torque needs the robot's joint torques)"
                       : "is missing (collision.measured_torque subtracts g(q) from them)",
                0.0, false, "", Fault::Form::statement},
          dt);
    }
  }
  last_valid_dt_ = dt;
  in_episode_ = false;
  if (halted_) {
    // Springs off, only the minimum damping, until the arm is at rest; then it holds where it
    // stopped.
    at_rest_for_ = robot.dq.cwiseAbs().maxCoeff() <= kRestSpeed ? at_rest_for_ + dt : 0.0;
    // A halt whose damping has not brought the arm to rest within kHoldWindow acts on late
    // measurements: its damping goes down with the stiffness the arm will be held with.
    halted_for_ += dt;
    if (halted_for_ > kHoldWindow) {
      halted_for_ = 0.0;
      halve_stiffness();
    }
    if (at_rest_for_ < kRestTime) {
      static constexpr Fault kHalted{"joint motion",
                                     -1,
                                     0.0,
                                     "was implausible (beyond plausibility.joint_velocity or the "
                                     "joint limits) in 3 episodes within 1 s: springs off, the "
                                     "minimum damping brings the arm to rest",
                                     0.0,
                                     false,
                                     "",
                                     Fault::Form::statement};
      static constexpr Fault kOscillating{"oscillation",
                                          -1,
                                          0.0,
                                          "of the closed loop persisted at 1/256 of the commanded "
                                          "stiffness: springs off, the minimum damping brings the "
                                          "arm to rest",
                                          0.0,
                                          false,
                                          "",
                                          Fault::Form::statement};
      time_ += dt;
      forget_passivity();
      forget_collision_observer();
      Fault fault;
      if (!evaluate_halt(robot, fault)) return fail_closed(Status::numerical_error, fault, dt);
      limit_torque(dt);
      state_.status = Status::motion_halted;
      state_.fault = halted_oscillating_ ? kOscillating : kHalted;
      return state_.status;
    }
    hold_where_the_arm_is(robot);
  }
  time_ += dt;
  observe_collision(robot, dt);
  const bool reflex = collision_latched() && state_.collision.reaction == CollisionReaction::reflex;
  if (reflex) hold_where_the_arm_is(robot);

  update_gains(dt);
  // The reference is clipped into the box before it is filtered and held to the speed cap: a box
  // moved past the reference moves it, but no faster than the cap (measured before: a reference
  // clipped 6 cm in one cycle, with a full stiffness matrix, turned the wrist at 1.1 x its cap).
  update_caps_in_force(robot);
  clip_reference_to_workspace(false);
  filter_targets();
  if (collision_latched()) {
    // Nothing presses on toward the contact; the reflex lets the arm comply, damped.
    state_.filtered.wrench.setZero();
    if (reflex) {
      state_.filtered.stiffness.setZero();
      state_.filtered.nullspace_stiffness.setZero();
    }
  }
  limit_reference_speed(dt);
  if (!(state_.safety.max_speed_in_force.translation > 0.0)) clip_reference_to_workspace(true);
  Fault fault;
  if (!evaluate_law(robot, dt, fault)) return fail_closed(Status::numerical_error, fault, dt);
  identify_contact(robot);
  limit_torque(dt, &robot);
  observe_passivity(robot, dt);
  expect_acceleration(robot);
  state_.status = Status::ok;
  state_.fault = Fault{};
  return state_.status;
}

}  // namespace cartesian_impedance
