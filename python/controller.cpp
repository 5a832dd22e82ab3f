// Python bindings of the enumerations, Pose, the states the controller and the loop report
// (RobotState, Targets, ActiveLimits, SafetyState, Fault, ControllerState, TrajectoryProgress,
// LoopState) and CartesianImpedanceController.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <string>
#include <utility>

#include "cartesian_impedance/core/controller.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/types.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "commands.hpp"
#include "conversions.hpp"
#include "module.hpp"
#include "parameters.hpp"

namespace cartesian_impedance::python {

void bind_enums_and_pose(py::module_& m) {
  // ---- enumerations ----
  py::enum_<ci::Frame>(m, "Frame", "Frame in which a stiffness or a wrench is given.")
      .value("base", ci::Frame::base, "the root link of the kinematic chain")
      .value("end_effector", ci::Frame::end_effector,
             "the end-effector frame, rotated into the base frame every cycle");
  py::enum_<ci::Status>(m, "Status", "Outcome of one control cycle.")
      .value("ok", ci::Status::ok)
      .value("not_started", ci::Status::not_started)
      .value("invalid_dt", ci::Status::invalid_dt)
      .value("invalid_robot_state", ci::Status::invalid_robot_state)
      .value("numerical_error", ci::Status::numerical_error)
      .value("missing_dynamics", ci::Status::missing_dynamics)
      .value("model_error", ci::Status::model_error)
      .value("motion_halted", ci::Status::motion_halted);
  py::enum_<ci::TrajectoryState>(m, "TrajectoryState", "Where trajectory execution stands.")
      .value("idle", ci::TrajectoryState::idle)
      .value("executing", ci::TrajectoryState::executing)
      .value("finished", ci::TrajectoryState::finished)
      .value("aborted", ci::TrajectoryState::aborted)
      .value("cancelled", ci::TrajectoryState::cancelled);
  py::enum_<ci::JointType>(m, "JointType")
      .value("revolute", ci::JointType::revolute)
      .value("continuous", ci::JointType::continuous)
      .value("prismatic", ci::JointType::prismatic);

  // ---- Pose ----
  py::class_<ci::Pose>(m, "Pose",
                       "A frame's position [m] and orientation (unit quaternion, x, y, z, w), in "
                       "the base frame. Unpacks as `position, quaternion_xyzw = pose`.")
      .def(py::init([](ArrayLike position, ArrayLike orientation) {
             ci::Pose pose;
             if (!position.is_none()) read_vector(position, "position", Length{3}, pose.position);
             if (!orientation.is_none()) {
               pose.orientation = quaternion_xyzw(orientation, "orientation (x, y, z, w)");
             }
             return pose;
           }),
           py::arg("position") = py::none(), py::arg("orientation") = py::none(),
           "position (3,) [m] (default 0); orientation: quaternion (4,) in the order x, y, z, w "
           "(default identity). Stored as given; the library checks the quaternion's norm "
           "(within 1e-3) where a pose is commanded.")
      .def_static(
          "from_matrix", [](ArrayLike matrix) { return read_pose(matrix, "matrix"); },
          py::arg("matrix"),
          "Pose (quaternion x, y, z, w) from a 4x4 homogeneous transform T_base_frame [m]. "
          "Raises Error if the rotation "
          "part is not a rotation (within 1e-3) or the last row is not [0, 0, 0, 1].")
      .def_property(
          "position", [](const ci::Pose& pose) { return vector_array(pose.position); },
          [](ci::Pose& pose, py::handle value) {
            read_vector(value, "position", Length{3}, pose.position);
          },
          "Position (3,) [m], base frame.")
      .def_property(
          "orientation", [](const ci::Pose& pose) { return xyzw_array(pose.orientation); },
          [](ci::Pose& pose, py::handle value) {
            pose.orientation = quaternion_xyzw(value, "orientation (x, y, z, w)");
          },
          "Orientation as a quaternion (4,) in the order x, y, z, w.")
      .def(
          "matrix", [](const ci::Pose& pose) { return matrix_array(pose_matrix(pose)); },
          "The 4x4 homogeneous transform T_base_frame [m] (the quaternion normalised).")
      .def(
          "rotation_matrix",
          [](const ci::Pose& pose) {
            return matrix_array(pose.orientation.normalized().toRotationMatrix());
          },
          "The 3x3 rotation matrix R_base_frame (the quaternion normalised).")
      .def("__iter__",
           [](const ci::Pose& pose) {
             return py::iter(
                 py::make_tuple(vector_array(pose.position), xyzw_array(pose.orientation)));
           })
      .def("__repr__", &pose_repr)
      .def(py::pickle(
          [](const ci::Pose& pose) {
            return py::make_tuple(vector_array(pose.position), xyzw_array(pose.orientation));
          },
          [](const py::tuple& state) {
            ci::Pose pose;
            read_vector(state[0], "position", Length{3}, pose.position);
            pose.orientation = quaternion_xyzw(state[1], "orientation");
            return pose;
          }));
}

namespace {

// A per-joint vector of RobotState that may be absent: None reads and writes it empty.
void optional_vector_property(py::class_<ci::RobotState>& robot_state, const char* name,
                              ci::JointVector ci::RobotState::*member, const char* doc) {
  robot_state.def_property(
      name, [member](const ci::RobotState& s) { return optional_array(s.*member); },
      [member, name](ci::RobotState& s, py::handle v) {
        if (v.is_none()) {
          (s.*member).resize(0);
        } else {
          read_vector(v, name, Length{}, s.*member);
        }
      },
      doc);
}

}  // namespace

void bind_states(py::module_& m) {
  // ---- states ----
  py::class_<ci::RobotState> robot_state(
      m, "RobotState",
      "What the controller reads each cycle: measured joints and the kinematics at them.");
  robot_state
      .def(py::init([](ArrayLike q, ArrayLike dq, PoseLike pose, ArrayLike jacobian, ArrayLike mass,
                       ArrayLike gravity, ArrayLike secondary_torque) {
             ci::RobotState state;
             read_vector(q, "q", Length{}, state.q);
             read_vector(dq, "dq", Length{}, state.dq);
             state.pose = read_pose(pose, "pose");
             read_matrix(jacobian, "jacobian", Length{6}, Length{}, state.jacobian);
             if (!mass.is_none()) read_matrix(mass, "mass", Length{}, Length{}, state.mass, true);
             if (!gravity.is_none()) read_vector(gravity, "gravity", Length{}, state.gravity);
             if (!secondary_torque.is_none()) {
               read_vector(secondary_torque, "secondary_torque", Length{}, state.secondary_torque);
             }
             return state;
           }),
           py::arg("q"), py::arg("dq"), py::arg("pose"), py::arg("jacobian"),
           py::arg("mass") = py::none(), py::arg("gravity") = py::none(),
           py::arg("secondary_torque") = py::none(),
           "q (n,) [rad], dq (n,) [rad/s], pose T_base_ee (Pose, (position, quaternion x, y, z, "
           "w) or 4x4), jacobian (6, n): geometric, rows [linear; angular], reference point the "
           "end-effector origin, base frame. Optional: mass M(q) (n, n) [kg m^2], gravity g(q) "
           "(n,) [Nm], secondary_torque (n,) [Nm]. 1 <= n <= MAX_JOINTS.")
      .def_property(
          "q", [](const ci::RobotState& s) { return vector_array(s.q); },
          [](ci::RobotState& s, py::handle v) { read_vector(v, "q", Length{}, s.q); },
          "Joint positions (n,) [rad].")
      .def_property(
          "dq", [](const ci::RobotState& s) { return vector_array(s.dq); },
          [](ci::RobotState& s, py::handle v) { read_vector(v, "dq", Length{}, s.dq); },
          "Joint velocities (n,) [rad/s].")
      .def_property(
          "pose", [](const ci::RobotState& s) { return s.pose; },
          [](ci::RobotState& s, py::handle v) { s.pose = read_pose(v, "pose"); },
          "End-effector pose T_base_ee (quaternion x, y, z, w).")
      .def_property(
          "jacobian", [](const ci::RobotState& s) { return matrix_array(s.jacobian); },
          [](ci::RobotState& s, py::handle v) {
            read_matrix(v, "jacobian", Length{6}, Length{}, s.jacobian);
          },
          "Geometric Jacobian (6, n), rows [linear; angular], base frame.")
      .def_property(
          "mass",
          [](const ci::RobotState& s) -> py::object {
            if (s.mass.size() == 0) return py::none();
            return matrix_array(s.mass);
          },
          [](ci::RobotState& s, py::handle v) {
            if (v.is_none()) {
              s.mass.resize(0, 0);
            } else {
              read_matrix(v, "mass", Length{}, Length{}, s.mass, true);
            }
          },
          "Mass matrix M(q) (n, n) [kg m^2], or None.");
  optional_vector_property(robot_state, "gravity", &ci::RobotState::gravity,
                           "Gravity torques g(q) (n,) [Nm], or None.");
  optional_vector_property(robot_state, "secondary_torque", &ci::RobotState::secondary_torque,
                           "Extra nullspace torque tau_0 (n,) [Nm], or None.");
  optional_vector_property(
      robot_state, "measured_torque", &ci::RobotState::measured_torque,
      "Joint torques the robot measures (n,) [Nm], link side, gravity included (Franka's "
      "tau_J), or None; read with collision.measured_torque, which needs gravity too.");
  robot_state.def("__repr__", [](const ci::RobotState& s) {
    return "RobotState(q=" + numbers_text(s.q) + ", dq=" + numbers_text(s.dq) +
           ", pose=" + pose_repr(s.pose) + ")";
  });
  m.def(
      "make_robot_state",
      [](int num_joints) {
        if (num_joints < 1 || num_joints > ci::kMaxJoints) {
          throw ci::Error("num_joints = " + std::to_string(num_joints) + " is outside [1, " +
                          std::to_string(ci::kMaxJoints) + "]");
        }
        return ci::make_robot_state(num_joints);
      },
      py::arg("num_joints"),
      "A RobotState for num_joints joints, all zero, identity pose (quaternion x, y, z, w = 0, "
      "0, 0, 1), zero Jacobian.");

  py::class_<ci::Targets>(m, "Targets",
                          "Quantities the law is evaluated with (commanded or filtered).")
      .def_property_readonly(
          "pose", [](const ci::Targets& t) { return t.pose; },
          "Reference pose T_base_ref (quaternion x, y, z, w).")
      .def_property_readonly(
          "stiffness", [](const ci::Targets& t) { return matrix_array(t.stiffness); },
          "K (6, 6) in the stiffness frame [N/m, Nm/rad].")
      .def_property_readonly(
          "damping_ratio", [](const ci::Targets& t) { return vector_array(t.damping_ratio); },
          "zeta per axis of the stiffness frame (6,) [-].")
      .def_property_readonly(
          "nullspace_q", [](const ci::Targets& t) { return vector_array(t.nullspace_q); },
          "Nullspace target q_d (n,) [rad].")
      .def_property_readonly(
          "nullspace_stiffness",
          [](const ci::Targets& t) { return vector_array(t.nullspace_stiffness); },
          "K_ns per joint (n,) [Nm/rad].")
      .def_readonly("nullspace_damping_ratio", &ci::Targets::nullspace_damping_ratio,
                    "zeta_ns [-].")
      .def_property_readonly(
          "wrench", [](const ci::Targets& t) { return vector_array(t.wrench); },
          "F = [force; torque] (6,) in the wrench frame [N, Nm].")
      .def_property_readonly(
          "twist", [](const ci::Targets& t) { return vector_array(t.twist); },
          "Reference twist feed-forward (6,) [m/s; rad/s], base frame.")
      .def_property_readonly(
          "nullspace_dq", [](const ci::Targets& t) { return vector_array(t.nullspace_dq); },
          "Nullspace target velocity (n,) [rad/s].");

  py::class_<ci::ActiveLimits>(m, "ActiveLimits", "Which limits shaped the last command.")
      .def_readonly("stiffness_saturated", &ci::ActiveLimits::stiffness_saturated)
      .def_readonly("damping_ratio_saturated", &ci::ActiveLimits::damping_ratio_saturated)
      .def_readonly("nullspace_stiffness_saturated",
                    &ci::ActiveLimits::nullspace_stiffness_saturated)
      .def_readonly("wrench_saturated", &ci::ActiveLimits::wrench_saturated)
      .def_readonly("translation_error_clipped", &ci::ActiveLimits::translation_error_clipped)
      .def_readonly("rotation_error_clipped", &ci::ActiveLimits::rotation_error_clipped)
      .def_readonly("joint_torque_saturated", &ci::ActiveLimits::joint_torque_saturated)
      .def_property_readonly(
          "torque_shaping",
          [](const ci::ActiveLimits& l) { return std::string(ci::to_string(l.torque_shaping)); },
          "Which term of the law gave way to the torque bound: 'none', 'nullspace', 'spring', "
          "'wrench', 'damping' or 'gravity' (scaled in task space in that order; see "
          "torque_shaping_scale)")
      .def_readonly("torque_shaping_scale", &ci::ActiveLimits::torque_shaping_scale,
                    "The fraction of that term kept [0, 1]")
      .def_readonly("torque_rate_limited", &ci::ActiveLimits::torque_rate_limited)
      .def_readonly("joint_torque_limit_ramping", &ci::ActiveLimits::joint_torque_limit_ramping)
      .def_readonly("holding", &ci::ActiveLimits::holding,
                    "Repeated implausible motion made the controller hold where the arm is "
                    "(cleared by the next reference pose).")
      .def_readonly("joint_limit_held", &ci::ActiveLimits::joint_limit_held,
                    "The first joint (-1: none) the joint-limit bounds held off its position "
                    "limit against the task this cycle: the reference asks, as the law resolves "
                    "it locally, for a configuration past that limit, and the arm stays short of "
                    "it. A nullspace target that reaches the reference, or a joint trajectory, "
                    "takes it around.")
      .def("__repr__", [](const ci::ActiveLimits& l) {
        std::string active;
        const std::pair<const char*, bool> flags[] = {
            {"stiffness_saturated", l.stiffness_saturated},
            {"damping_ratio_saturated", l.damping_ratio_saturated},
            {"nullspace_stiffness_saturated", l.nullspace_stiffness_saturated},
            {"wrench_saturated", l.wrench_saturated},
            {"translation_error_clipped", l.translation_error_clipped},
            {"rotation_error_clipped", l.rotation_error_clipped},
            {"joint_torque_saturated", l.joint_torque_saturated},
            {"torque_rate_limited", l.torque_rate_limited},
            {"joint_torque_limit_ramping", l.joint_torque_limit_ramping},
            {"holding", l.holding}};
        for (const auto& [name, on] : flags) {
          if (on) active += (active.empty() ? "" : ", ") + std::string(name);
        }
        if (l.joint_limit_held >= 0) {
          active += (active.empty() ? "" : ", ") + std::string("joint_limit_held=") +
                    std::to_string(l.joint_limit_held);
        }
        return "ActiveLimits(" + (active.empty() ? std::string("none") : active) + ")";
      });

  py::class_<ci::PoseErrorLimits>(m, "PoseErrorLimits",
                                  "Pose-error clip in force (limits.pose_error.*).")
      .def_readonly("translation", &ci::PoseErrorLimits::translation,
                    "Largest norm of the translation error [m].")
      .def_readonly("rotation", &ci::PoseErrorLimits::rotation,
                    "Largest norm of the rotation error [rad].")
      .def("__repr__", [](const ci::PoseErrorLimits& l) {
        return "PoseErrorLimits(translation=" + ci::format_number(l.translation) +
               " m, rotation=" + ci::format_number(l.rotation) + " rad)";
      });

  py::class_<ci::WorkspaceParameters>(m, "Workspace",
                                      "Workspace box and walls in force (safety.workspace.*).")
      .def_property_readonly(
          "min", [](const ci::WorkspaceParameters& w) { return vector_array(w.min); },
          "Lower corner (3,) [m], base frame.")
      .def_property_readonly(
          "max", [](const ci::WorkspaceParameters& w) { return vector_array(w.max); },
          "Upper corner (3,) [m], base frame.")
      .def_readonly("stiffness", &ci::WorkspaceParameters::stiffness, "Wall spring [N/m].")
      .def_readonly("damping", &ci::WorkspaceParameters::damping,
                    "Wall damper, on motion out of the box [N s/m].")
      .def("__repr__", [](const ci::WorkspaceParameters& w) {
        const auto corner = [](const Eigen::Vector3d& v) {
          return "[" + ci::format_number(v.x()) + ", " + ci::format_number(v.y()) + ", " +
                 ci::format_number(v.z()) + "]";
        };
        return "Workspace(min=" + corner(w.min) + " m, max=" + corner(w.max) +
               " m, stiffness=" + ci::format_number(w.stiffness) +
               " N/m, damping=" + ci::format_number(w.damping) + " N s/m)";
      });

  py::class_<ci::SafetyState>(
      m, "SafetyState",
      "What the safety layer (parameters safety.*, payload.*) did in the last cycle. A scale is "
      "the fraction of a quantity that was kept (1: untouched).")
      .def_readonly("reference_speed_limited", &ci::SafetyState::reference_speed_limited,
                    "safety.max_speed: the reference was held back (it moves toward the commanded "
                    "pose no faster than the cap).")
      .def_readonly("translation_drive_scale", &ci::SafetyState::translation_drive_scale,
                    "safety.max_speed.translation: fraction of the spring + wrench push along "
                    "the end effector's linear velocity that was kept [0, 1] (below 1 from 0.8 "
                    "x the cap, 0 at the cap).")
      .def_readonly("rotation_drive_scale", &ci::SafetyState::rotation_drive_scale,
                    "safety.max_speed.rotation: the same along the angular velocity [0, 1].")
      .def_readonly("braking", &ci::SafetyState::braking,
                    "safety.max_speed: the end effector was faster than a cap, so its excess "
                    "speed was braked.")
      .def_readonly("force_scale", &ci::SafetyState::force_scale,
                    "safety.max_force.force: fraction of the spring + commanded force kept "
                    "[0, 1].")
      .def_readonly("torque_scale", &ci::SafetyState::torque_scale,
                    "safety.max_force.torque: fraction of the spring + commanded torque kept "
                    "[0, 1].")
      .def_readonly("nullspace_scale", &ci::SafetyState::nullspace_scale,
                    "Fraction of the nullspace torque kept [0, 1]: below 1 only where what it "
                    "leaks to the end effector (near a singularity) alone exceeds a force cap.")
      .def_readonly("reference_clipped", &ci::SafetyState::reference_clipped,
                    "safety.workspace: the reference was clipped into the box.")
      .def_property_readonly(
          "workspace_penetration",
          [](const ci::SafetyState& s) { return vector_array(s.workspace_penetration); },
          "How far the end effector's origin is outside the box (3,) [m], base frame (zero "
          "inside).")
      .def_property_readonly(
          "wall_force", [](const ci::SafetyState& s) { return vector_array(s.wall_force); },
          "Force of the workspace walls on the end effector (3,) [N], base frame.")
      .def_readonly("wall_energy", &ci::SafetyState::wall_energy,
                    "What the workspace walls hold [J]: the work the end effector did pushing "
                    "into them and the tank paid into them, less what they gave back.")
      .def_readonly("pose_error_in_force", &ci::SafetyState::pose_error_in_force,
                    "limits.pose_error as in force (PoseErrorLimits): it follows its parameter "
                    "as far as the energy tank pays for what a change stores.")
      .def_readonly("workspace_in_force", &ci::SafetyState::workspace_in_force,
                    "safety.workspace as in force (Workspace): the box and walls follow their "
                    "parameters as far as the tank pays; a box that would put the end effector "
                    "outside starts around it and closes in as it moves in.")
      .def_readonly("settings_held", &ci::SafetyState::settings_held,
                    "pose_error_in_force or workspace_in_force differs from its parameter, "
                    "waiting for the energy tank.")
      .def_readonly("joint_limit_wall", &ci::SafetyState::joint_limit_wall,
                    "While teaching, a joint inside joint_limit_avoidance.margin is held off its "
                    "limit by a joint-space wall.")
      .def_readonly("tank_level", &ci::SafetyState::tank_level,
                    "safety.energy_tank: the tank's level [J].")
      .def_readonly("tank_draw", &ci::SafetyState::tank_draw,
                    "Energy this cycle's stiffness change drew from the tank [J] (negative: "
                    "returned to it).")
      .def_readonly("stiffness_change_scale", &ci::SafetyState::stiffness_change_scale,
                    "Fraction of this cycle's stiffness change that was applied [0, 1] (below "
                    "1: the tank could not pay for all of it, the change waits).")
      .def_readonly("payload_mass", &ci::SafetyState::payload_mass,
                    "The payload being compensated (payload.mass, filtered) [kg].")
      .def_property_readonly(
          "payload_center_of_mass",
          [](const ci::SafetyState& s) { return vector_array(s.payload_center_of_mass); },
          "Its centre of mass (payload.center_of_mass, filtered) (3,) [m], end-effector frame.")
      .def_readonly("payload_estimate_valid", &ci::SafetyState::payload_estimate_valid,
                    "The end effector has been still long enough for the payload estimate.")
      .def_readonly("payload_estimate_mass", &ci::SafetyState::payload_estimate_mass,
                    "The payload mass that explains the static force the controller commands at "
                    "rest [kg] (the commanded wrench excluded).")
      .def_property_readonly(
          "payload_estimate_center_of_mass",
          [](const ci::SafetyState& s) { return vector_array(s.payload_estimate_center_of_mass); },
          "Its centre of mass across gravity (3,) [m], end-effector frame.")
      .def_readonly("static_wrench_unexplained", &ci::SafetyState::static_wrench_unexplained,
                    "At rest, the static wrench is not one a hanging load can make (it presses "
                    "down, pushes sideways or twists about the vertical): a contact; the "
                    "estimate is then not valid.")
      .def_readonly("payload_mismatch", &ci::SafetyState::payload_mismatch,
                    "The valid estimate differs from the declared payload (payload.mass, "
                    "filtered) by more than the tolerance: a load declared but not carried, or "
                    "carried but not declared. The compensation still follows the declaration.")
      .def_readonly("oscillation_scale", &ci::SafetyState::oscillation_scale,
                    "The fraction of the commanded Cartesian and nullspace stiffness the law is "
                    "given [1/256, 1]: each sustained oscillation of the closed loop (a delay "
                    "past the stiffness's margin) halves it, until start().")
      .def_readonly("oscillations", &ci::SafetyState::oscillations,
                    "Sustained oscillations found since start().")
      .def_readonly("generated_energy", &ci::SafetyState::generated_energy,
                    "[J] The energy the controller generated on its port to the arm within the "
                    "last 0.5 s (the passivity observer, safety.passivity): at or below 0 while "
                    "it is passive; behind a delay past the margin its springs put energy in.")
      .def_property_readonly(
          "passivity_scale",
          [](const ci::SafetyState& s) { return vector_array(s.passivity_scale); },
          "(3,) The fraction of the commanded stiffness the passivity controller left each "
          "spring (translation, rotation, nullspace) [1/256, 1], on top of oscillation_scale: "
          "halved where it generated energy, until start().")
      .def_readonly("passivity_halvings", &ci::SafetyState::passivity_halvings,
                    "Halvings by the passivity controller since start().")
      .def_property_readonly(
          "max_speed_in_force",
          [](const ci::SafetyState& s) {
            return py::make_tuple(s.max_speed_in_force.translation, s.max_speed_in_force.rotation);
          },
          "(translation [m/s], rotation [rad/s]) The speed caps in force: safety.max_speed, or "
          "tighter where power and force limiting (safety.pfl) asks for it (0: off).")
      .def_property_readonly(
          "max_force_in_force",
          [](const ci::SafetyState& s) {
            return py::make_tuple(s.max_force_in_force.force, s.max_force_in_force.torque);
          },
          "(force [N], torque [Nm]) The force caps in force (0: off).")
      .def_readonly("pfl_speed_limit", &ci::SafetyState::pfl_speed_limit,
                    "[m/s] The speed whose impact on safety.pfl.body_region stays within its "
                    "transient force limit, by the arm's effective mass (0: off).")
      .def_readonly("pfl_effective_mass", &ci::SafetyState::pfl_effective_mass,
                    "[kg] The arm's effective mass at the end effector along its motion (0: off; "
                    "inf without M(q)).")
      .def("__repr__", [](const ci::SafetyState& s) {
        return "SafetyState(drive_scale=" + ci::format_number(s.translation_drive_scale) + "/" +
               ci::format_number(s.rotation_drive_scale) +
               ", force_scale=" + ci::format_number(s.force_scale) + "/" +
               ci::format_number(s.torque_scale) + ", braking=" + (s.braking ? "True" : "False") +
               ", reference_clipped=" + (s.reference_clipped ? "True" : "False") +
               ", tank_level=" + ci::format_number(s.tank_level) +
               " J, payload_mass=" + ci::format_number(s.payload_mass) + " kg)";
      });

  py::enum_<ci::CollisionReaction>(m, "CollisionReaction",
                                   "What a collision does (the parameter collision.reaction).")
      .value("report", ci::CollisionReaction::report)
      .value("stop", ci::CollisionReaction::stop)
      .value("reflex", ci::CollisionReaction::reflex)
      .value("retract", ci::CollisionReaction::retract);

  py::class_<ci::CollisionState>(m, "CollisionState",
                                 "What the collision monitor (collision.*) sees and did.")
      .def_property_readonly(
          "residual", [](const ci::CollisionState& c) { return vector_array(c.residual); },
          "(n,) The momentum observer's estimate of the external torque on each joint [Nm].")
      .def_property_readonly(
          "unexpected", [](const ci::CollisionState& c) { return vector_array(c.unexpected); },
          "(n,) The part of it beyond the commanded wrench's reaction and a declared contact.")
      .def_property_readonly(
          "threshold", [](const ci::CollisionState& c) { return vector_array(c.threshold); },
          "(n,) The threshold in force this cycle [Nm].")
      .def_readonly("detected", &ci::CollisionState::detected,
                    "A collision was found (a reaction other than report holds until resume()).")
      .def_readonly("time", &ci::CollisionState::time, "[s] controller time of the detection.")
      .def_readonly("joint", &ci::CollisionState::joint,
                    "The last joint past its threshold: the contact is on its link or on one "
                    "after it whose joints cannot feel it (-1: none).")
      .def_readonly("ratio", &ci::CollisionState::ratio,
                    "|unexpected| / threshold of that joint at detection.")
      .def_property_readonly(
          "contact_wrench",
          [](const ci::CollisionState& c) { return vector_array(c.contact_wrench); },
          "(6,) The end-effector wrench that explains the residual [N; Nm], base frame, as "
          "the contact was isolated (20 ms after its detection).")
      .def_readonly("reaction", &ci::CollisionState::reaction)
      .def_readonly("collisions", &ci::CollisionState::collisions, "Found since start().")
      .def_readonly("commands_held", &ci::CollisionState::commands_held,
                    "References not followed while a reaction held the arm.")
      .def("__repr__", [](const ci::CollisionState& c) {
        return "CollisionState(detected=" + std::string(c.detected ? "True" : "False") +
               ", joint=" + std::to_string(c.joint) +
               ", reaction=" + std::string(ci::reaction_name(c.reaction)) +
               ", collisions=" + std::to_string(c.collisions) + ")";
      });

  py::class_<ci::Fault>(m, "Fault", "Which input made a cycle fail closed.")
      .def_property_readonly(
          "input", [](const ci::Fault& f) { return std::string(f.input); },
          "'dt', 'q', 'dq', 'pose', 'jacobian', 'mass', 'gravity', ... ('' if none)")
      .def_readonly("index", &ci::Fault::index, "element (joint) index, or -1")
      .def_readonly("value", &ci::Fault::value, "the offending value (the size, for a wrong size)")
      .def_property_readonly(
          "reason", [](const ci::Fault& f) { return std::string(f.reason); },
          "'is not finite', 'has the wrong size', 'is above plausibility.dt.max', ...")
      .def_property_readonly(
          "bound", [](const ci::Fault& f) { return f.has_bound ? py::cast(f.bound) : py::none(); },
          "the bound it broke, or None")
      .def("__str__", [](const ci::Fault& f) { return ci::to_string(f); })
      .def("__bool__", [](const ci::Fault& f) { return f.input[0] != '\0'; })
      .def("__repr__", [](const ci::Fault& f) { return "Fault('" + ci::to_string(f) + "')"; });

  py::class_<ci::ControllerState>(m, "ControllerState", "Snapshot written by every update().")
      .def_readonly("status", &ci::ControllerState::status)
      .def_readonly("fault", &ci::ControllerState::fault,
                    "Why the last cycle failed closed (falsy when status is ok).")
      .def_property_readonly(
          "joint_torque_limit",
          [](const ci::ControllerState& s) { return vector_array(s.joint_torque_limit); },
          "Torque bound in force per joint (n,) [Nm]: limits.joint_torque, or above it while "
          "ramping down to a lowered limit.")
      .def_property_readonly(
          "pose", [](const ci::ControllerState& s) { return s.pose; },
          "Measured end-effector pose T_base_ee (quaternion x, y, z, w).")
      .def_property_readonly(
          "pose_error", [](const ci::ControllerState& s) { return vector_array(s.pose_error); },
          "e = [p - p_d; log(R R_d^T)] (6,) [m; rad], base frame, after clipping.")
      .def_readonly("commanded", &ci::ControllerState::commanded,
                    "Targets as last commanded (after validation and saturation).")
      .def_readonly("filtered", &ci::ControllerState::filtered, "Targets the law used.")
      .def_readonly("stiffness_frame", &ci::ControllerState::stiffness_frame)
      .def_readonly("wrench_frame", &ci::ControllerState::wrench_frame)
      .def_property_readonly(
          "wrench_base", [](const ci::ControllerState& s) { return vector_array(s.wrench_base); },
          "Filtered F (6,) in the base frame [N; Nm].")
      .def_property_readonly(
          "tau_cartesian",
          [](const ci::ControllerState& s) { return vector_array(s.tau_cartesian); },
          "J^T (-K e - D J dq) (n,) [Nm].")
      .def_property_readonly(
          "tau_nullspace",
          [](const ci::ControllerState& s) { return vector_array(s.tau_nullspace); },
          "N tau_0 (n,) [Nm].")
      .def_property_readonly(
          "tau_wrench", [](const ci::ControllerState& s) { return vector_array(s.tau_wrench); },
          "J^T F (n,) [Nm].")
      .def_property_readonly(
          "tau_gravity", [](const ci::ControllerState& s) { return vector_array(s.tau_gravity); },
          "g(q) if dynamics.gravity_compensation, else 0 (n,) [Nm].")
      .def_property_readonly(
          "tau", [](const ci::ControllerState& s) { return vector_array(s.tau); },
          "Commanded torque after the torque and rate limits (n,) [Nm].")
      .def_readonly("limits", &ci::ControllerState::limits)
      .def_readonly("collision", &ci::ControllerState::collision,
                    "The collision monitor: the external torque estimate and what it found.")
      .def_readonly("safety", &ci::ControllerState::safety,
                    "What the safety layer (safety.*, payload.*) did in the last cycle.")
      .def(
          "stiffness_base",
          [](const ci::ControllerState& s) { return matrix_array(s.stiffness_base()); },
          "Filtered K (6, 6) in the base frame [N/m, Nm/rad].")
      .def(
          "damping_base",
          [](const ci::ControllerState& s) { return matrix_array(s.damping_base()); },
          "D the law used (6, 6) in the base frame [N s/m, Nm s/rad].")
      .def("__repr__", [](const ci::ControllerState& s) {
        return std::string("ControllerState(status=") + ci::to_string(s.status) +
               (s.fault.input[0] != '\0' ? ", fault='" + ci::to_string(s.fault) + "'" : "") +
               ", tau=" + numbers_text(s.tau) + ")";
      });

  py::class_<ci::TrajectoryProgress>(m, "TrajectoryProgress")
      .def_readonly("state", &ci::TrajectoryProgress::state)
      .def_readonly("id", &ci::TrajectoryProgress::id,
                    "id returned by execute_trajectory() of the one reported")
      .def_readonly("time", &ci::TrajectoryProgress::time, "[s] since it started")
      .def_readonly("duration", &ci::TrajectoryProgress::duration, "[s] of its last point")
      .def_readonly("goal_error", &ci::TrajectoryProgress::goal_error,
                    "[rad] largest |q - q_goal| (once past the end)")
      .def("__repr__", [](const ci::TrajectoryProgress& p) {
        return "TrajectoryProgress(" + trajectory_text(p) +
               ", goal_error=" + ci::format_number(p.goal_error) + ")";
      });

  py::class_<ci::LoopState>(m, "LoopState", "What one ControlLoop step publishes.")
      .def_readonly("controller", &ci::LoopState::controller,
                    "The law's snapshot: errors, targets, torque parts, limits.")
      .def_property_readonly(
          "q", [](const ci::LoopState& s) { return vector_array(s.q); },
          "Measured joint positions (n,) [rad].")
      .def_property_readonly(
          "dq", [](const ci::LoopState& s) { return vector_array(s.dq); },
          "Measured joint velocities (n,) [rad/s].")
      .def_readonly("trajectory", &ci::LoopState::trajectory)
      .def_readonly("cycle", &ci::LoopState::cycle, "steps since start()")
      .def_readonly("time", &ci::LoopState::time, "[s] sum of dt since start()")
      .def_readonly("commands_applied", &ci::LoopState::commands_applied)
      .def_readonly("safety_changes", &ci::LoopState::safety_changes,
                    "Parameter commands applied after start() that changed a safety setting "
                    "(only a loop made with allow_runtime_safety_changes=True accepts them).")
      .def_readonly("updates_refused", &ci::LoopState::updates_refused,
                    "Partial updates the cycle refused: merged into the parameters then in force "
                    "(another update came first) they broke a rule tying parameters together. "
                    "Nothing of such an update was applied.")
      .def("__repr__", [](const ci::LoopState& s) {
        return "LoopState(cycle=" + std::to_string(s.cycle) +
               ", time=" + ci::format_number(s.time) +
               " s, status=" + ci::to_string(s.controller.status) +
               ", trajectory=" + trajectory_text(s.trajectory) + ")";
      });
}

void bind_controller(py::module_& m) {
  // ---- controller ----
  using Controller = ci::CartesianImpedanceController;
  py::class_<Controller> controller(
      m, "CartesianImpedanceController",
      "The control law on its own: tau = J^T(-K e - D J dq) + N tau_0 + J^T F, with filters and "
      "limits. You provide the RobotState (kinematics) each cycle; ControlLoop does that from a "
      "RobotModel. Setters validate and raise Error (a rejected command changes nothing).");
  def_commands<Controller, Controller>(
      controller, [](Controller& self) -> Controller& { return self; }, "Sets");
  controller
      .def(py::init([](int num_joints, ParametersLike parameters) {
             return std::make_unique<Controller>(num_joints, read_parameters(parameters));
           }),
           py::arg("num_joints"), py::arg("parameters") = py::none(),
           "num_joints in [1, MAX_JOINTS]; parameters: Parameters, dict or None (defaults).")
      .def_property_readonly("num_joints", &Controller::num_joints)
      .def_property_readonly(
          "parameters", [](const Controller& c) { return c.parameters(); },
          "A copy of the configuration in force.")
      .def(
          "start",
          [](Controller& c, const ci::RobotState& robot, ArrayLike tau_previous) {
            if (tau_previous.is_none()) return c.start(robot);
            ci::JointVector tau;
            read_vector(tau_previous, "tau_previous", Length{c.num_joints()}, tau);
            c.start(robot, tau);
          },
          py::arg("robot"), py::arg("tau_previous") = py::none(),
          "Starts from the measured state: reference pose = current pose, nullspace target = q. "
          "tau_previous (n,) [Nm]: the torque the robot receives now (default zero).")
      .def_property_readonly("started", &Controller::started)
      .def(
          "update",
          [](Controller& c, const ci::RobotState& robot, Real dt) {
            return c.update(robot, read_scalar(dt, "dt"));
          },
          py::arg("robot"), py::arg("dt"),
          "One control cycle with the elapsed dt [s]. Never raises for bad values: returns a "
          "Status and ramps the torque toward zero instead.")
      .def_property_readonly(
          "torque", [](const Controller& c) { return vector_array(c.torque()); },
          "Commanded joint torque of the last update() (n,) [Nm].")
      .def_property_readonly(
          "state", [](const Controller& c) { return c.state(); },
          "A copy of the snapshot of the last update() (ControllerState).");
}

}  // namespace cartesian_impedance::python
