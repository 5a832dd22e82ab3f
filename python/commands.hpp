#pragma once
// The command setters CartesianImpedanceController and ControlLoop share in Python.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <optional>
#include <string>

#include "cartesian_impedance/core/controller.hpp"
#include "cartesian_impedance/core/types.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "conversions.hpp"
#include "parameters.hpp"

namespace cartesian_impedance::python {

/// The parameters a partial update from a dict is decoded onto: those in force (the loop's as of
/// its last step, from any thread).
inline ci::Parameters parameters_in_force(const ci::CartesianImpedanceController& controller) {
  return controller.parameters();
}
inline ci::Parameters parameters_in_force(const ci::ControlLoop& loop) {
  return loop.latest_parameters();
}

// ---- Docstrings shared by several functions --------------------------------------------------

inline constexpr const char* kPoseForms =
    "A pose is a Pose, a pair (position (3,) [m], quaternion (4,) in the order x, y, z, w) or a "
    "4x4 homogeneous transform, expressed in the base frame.";

/// Binds the command setters CartesianImpedanceController and ControlLoop share. `target(self)`
/// gives the C++ object; `verb` starts each docstring ("Sets" for the controller, which applies
/// at once, "Queues" for the loop, which applies at its next step).
template <typename Self, typename Target>
void def_commands(py::class_<Self>& binding, Target& (*target)(Self&), const std::string& verb) {
  // pybind11 copies docstrings, so temporaries (alive until the end of the statement) will do.
  const auto doc = [verb](const std::string& text) { return verb + " " + text; };
  const std::string ends_trajectory = verb == "Queues" ? " Ends a running trajectory." : "";
  binding
      .def(
          "set_reference_pose",
          [target](Self& self, PoseLike pose) {
            target(self).set_reference_pose(read_pose(pose, "pose"));
          },
          py::arg("pose"),
          doc(std::string("the reference pose T_base_ref. ") + kPoseForms +
              " The quaternion must have unit norm within 1e-3." + ends_trajectory)
              .c_str())
      .def(
          "set_stiffness",
          [target](Self& self, ArrayLike stiffness, FrameLike frame) {
            const std::optional<ci::Frame> in = read_frame(frame, "frame");
            if (is_sequence(stiffness) || py::isinstance<py::array>(stiffness)) {
              const py::array_t<double> array = real_array(stiffness, "stiffness");
              if (array.ndim() == 2) {
                ci::Matrix6d matrix;
                read_matrix(array, "stiffness", Length{6}, Length{6}, matrix);
                return target(self).set_stiffness_matrix(matrix, in);
              }
            }
            ci::Vector6d diagonal;
            read_vector(stiffness, "stiffness", Length{6}, diagonal, " or (6, 6)");
            target(self).set_stiffness(diagonal, in);
          },
          py::arg("stiffness"), py::arg("frame") = py::none(),
          doc("the stiffness: diagonal (6,) [N/m x3, Nm/rad x3] or a full symmetric positive "
              "semi-definite (6, 6) matrix, in `frame` ('base' or 'end_effector'; default: the "
              "configured stiffness.frame). Values beyond limits.stiffness.* are saturated.")
              .c_str())
      .def(
          "set_damping_ratio",
          [target](Self& self, ArrayLike ratio) {
            ci::Vector6d values;
            read_vector(ratio, "damping_ratio", Length{6}, values);
            target(self).set_damping_ratio(values);
          },
          py::arg("damping_ratio"),
          doc("the damping ratio per axis of the stiffness frame (6,) [-].").c_str())
      .def(
          "set_nullspace_target",
          [target](Self& self, ArrayLike q) {
            ci::JointVector values;
            read_vector(q, "q_desired", Length{target(self).num_joints()}, values);
            target(self).set_nullspace_target(values);
          },
          py::arg("q_desired"),
          doc("the nullspace target configuration (n,) [rad]." + ends_trajectory).c_str())
      .def(
          "set_nullspace_stiffness",
          [target](Self& self, ArrayLike k) {
            target(self).set_nullspace_stiffness(read_one_or_vector(k, "stiffness", Length{}));
          },
          py::arg("stiffness"),
          doc("the nullspace stiffness [Nm/rad]: one number or (n,).").c_str())
      .def(
          "set_nullspace_damping_ratio",
          [target](Self& self, Real zeta) {
            target(self).set_nullspace_damping_ratio(read_scalar(zeta, "damping_ratio"));
          },
          py::arg("damping_ratio"), doc("the nullspace damping ratio [-].").c_str())
      .def(
          "set_wrench",
          [target](Self& self, ArrayLike wrench, FrameLike frame) {
            ci::Vector6d values;
            read_vector(wrench, "wrench", Length{6}, values);
            target(self).set_wrench(values, read_frame(frame, "frame"));
          },
          py::arg("wrench"), py::arg("frame") = py::none(),
          doc("the commanded wrench [force; torque] (6,) [N; Nm] on the environment, in `frame` "
              "('base' or 'end_effector'; default: the configured wrench.frame).")
              .c_str())
      .def(
          "set_parameters",
          [target](Self& self, ParametersLike parameters) {
            Target& t = target(self);
            // A dict names what it changes: only those rows, on top of whatever is in force
            // (a stiffness set since, another sender's change). A Parameters object is a whole
            // configuration and replaces it.
            if (is_mapping(parameters)) {
              return t.update_parameters(read_parameter_update(parameters, parameters_in_force(t)));
            }
            t.set_parameters(read_parameters(parameters));
          },
          py::arg("parameters"),
          doc("parameters. A dict (dotted names or nested) is a partial update: only the "
              "parameters it names change, everything else stays as it is in force (the same "
              "as update_parameters). A Parameters object (or None: the defaults) replaces the "
              "whole configuration. The commanded stiffness, damping, nullspace and wrench "
              "follow what is set through their filters." +
              std::string(
                  verb == "Queues"
                      ? " While the loop runs, a change of a safety setting (safety.*, "
                        "limits.*, plausibility.*, payload.*, collision.*) raises Error unless the "
                        "loop was made with allow_runtime_safety_changes=True."
                      : ""))
              .c_str())
      .def(
          "update_parameters",
          [target](Self& self, Mapping values) {
            Target& t = target(self);
            t.update_parameters(read_parameter_update(values, parameters_in_force(t)));
          },
          py::arg("values"),
          doc("the parameters a dict names (dotted names or nested), all or none; every other "
              "parameter keeps the value in force when the update is applied. Raises TypeError "
              "for a value of the wrong type, Error for an unknown name, a value out of range or "
              "an update that breaks a rule tying parameters together.")
              .c_str())
      .def(
          "start_teaching",
          [target](Self& self, bool keep_nullspace) {
            target(self).start_teaching(keep_nullspace);
          },
          py::arg("keep_nullspace") = false,
          doc("kinesthetic teaching: zero Cartesian stiffness (and nullspace stiffness unless "
              "keep_nullspace). Any later stiffness command ends it.")
              .c_str())
      .def(
          "resume", [target](Self& self) { target(self).resume(); },
          doc("the end of a collision's reaction (state.collision.detected with "
              "collision.reaction other than 'report'): the arm holds where it is and follows "
              "the reference poses, nullspace targets and trajectories sent from now on.")
              .c_str());
}

}  // namespace cartesian_impedance::python
