// Python bindings of the policy interface: cartesian_impedance.PolicyInterface, the C++ half of
// cartesian_impedance.envs.ActionInterface (actions into commands, the robot's observation).

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/loop/policy_interface.hpp"
#include "conversions.hpp"
#include "module.hpp"
#include "wrappers.hpp"

namespace cartesian_impedance::python {
namespace {

/// PolicyInterface plus the Python model it was made from (its workspace refers to the model).
struct Policy {
  Policy(py::object model_object, const ci::Parameters& parameters, bool wrench,
         const ci::PolicyActionLimits& limits)
      : model_object(std::move(model_object)),
        policy(this->model_object.cast<Model&>().model, parameters, wrench, limits) {}
  py::object model_object;
  ci::PolicyInterface policy;
};

ci::PolicyInterface::Action read_action(const ci::PolicyInterface& policy, py::handle action) {
  // real_array() first: forcecast alone would turn a complex action into its real part (with
  // only a ComplexWarning) and None into NaN, reported as a value that is not finite.
  const auto values = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(
      real_array(action, "action"));
  if (values.ndim() != 1 || values.shape(0) != policy.action_size()) {
    throw ci::Error("action has shape " + shape_text(values) + ", expected (" +
                    std::to_string(policy.action_size()) + ",) (" + policy.layout() + ")");
  }
  return policy.check(Eigen::Map<const Eigen::VectorXd>(values.data(), values.shape(0)));
}

py::array_t<double> action_array(const ci::PolicyInterface::Action& action) {
  return vector_array(action);
}

ci::Range read_range(py::handle object, const char* name) {
  Eigen::VectorXd values;
  read_vector(object, name, Length{2}, values);
  return ci::Range{values[0], values[1]};
}

}  // namespace

void bind_policy_interface(py::module_& m) {
  py::class_<Policy>(
      m, "PolicyInterface",
      "A learned policy's action turned into a ControlLoop's commands, and the robot part of its "
      "observation (the C++ class cartesian_impedance::PolicyInterface; "
      "cartesian_impedance.envs.ActionInterface wraps it). Action, each value in [-1, 1] "
      "(clipped; NaN or a wrong shape raise Error and change nothing): [0:3] translation "
      "increment of the reference (x max_translation_step [m], base frame), [3:6] rotation "
      "increment (rotation vector x max_rotation_step [rad]), [6:12] stiffness per axis (-1 "
      "stiffness_low, +1 stiffness_high), with wrench [12:15] force (x max_force [N]) and "
      "[15:18] torque (x max_torque [Nm]), base frame. The reference stays within the leash "
      "of the measured pose.")
      .def(py::init([](py::object model, const ci::Parameters& parameters, bool wrench,
                       double max_translation_step, double max_rotation_step,
                       py::handle stiffness_translation, py::handle stiffness_rotation,
                       double max_force, double max_torque, py::handle reference_leash) {
             ci::PolicyActionLimits limits;
             limits.max_translation_step = max_translation_step;
             limits.max_rotation_step = max_rotation_step;
             limits.stiffness_translation =
                 read_range(stiffness_translation, "stiffness_translation (low, high)");
             limits.stiffness_rotation =
                 read_range(stiffness_rotation, "stiffness_rotation (low, high)");
             limits.max_force = max_force;
             limits.max_torque = max_torque;
             if (!reference_leash.is_none()) {
               const ci::Range leash =
                   read_range(reference_leash, "reference_leash (translation, rotation)");
               limits.reference_leash = std::array<double, 2>{leash.min, leash.max};
             }
             if (!py::isinstance<Model>(model)) {  // as ControlLoop's constructor
               throw py::type_error("model must be a RobotModel, got " + type_name(model));
             }
             return std::make_unique<Policy>(std::move(model), parameters, wrench, limits);
           }),
           py::arg("model"), py::arg("parameters"), py::arg("wrench") = false,
           py::arg("max_translation_step") = 0.01, py::arg("max_rotation_step") = 0.05,
           py::arg("stiffness_translation") = py::make_tuple(100.0, 2000.0),
           py::arg("stiffness_rotation") = py::make_tuple(5.0, 150.0), py::arg("max_force") = 30.0,
           py::arg("max_torque") = 3.0, py::arg("reference_leash") = py::none(),
           "model: the loop's RobotModel; parameters: the loop's Parameters (their limits lower "
           "stiffness_high, max_force and max_torque; limits.pose_error is the leash unless "
           "reference_leash (translation [m], rotation [rad]) is given). Raises Error naming a "
           "limit that is not finite, negative, or a range with low > high.")
      .def_property_readonly("action_size",
                             [](const Policy& self) { return self.policy.action_size(); })
      .def_property_readonly(
          "observation_size", [](const Policy& self) { return self.policy.observation_size(); },
          "2 n + 32: the robot part of the observation.")
      .def_property_readonly("wrench", [](const Policy& self) { return self.policy.wrench(); })
      .def_property_readonly(
          "stiffness_low",
          [](const Policy& self) { return vector_array(self.policy.stiffness_low()); },
          "What -1 of the stiffness part asks for (6,) [N/m x3, Nm/rad x3].")
      .def_property_readonly(
          "stiffness_high",
          [](const Policy& self) { return vector_array(self.policy.stiffness_high()); },
          "What +1 asks for, after limits.stiffness.*.max (6,).")
      .def_property_readonly("max_force",
                             [](const Policy& self) { return self.policy.max_force(); })
      .def_property_readonly("max_torque",
                             [](const Policy& self) { return self.policy.max_torque(); })
      .def_property_readonly(
          "leash",
          [](const Policy& self) {
            return py::make_tuple(self.policy.leash()[0], self.policy.leash()[1]);
          },
          "(translation [m], rotation [rad]) the reference stays within of the measured pose.")
      .def_static(
          "field", [](int index) { return std::string(ci::PolicyInterface::field(index)); },
          py::arg("index"), "The field action[index] sets, e.g. 'stiffness.rotation.y'.")
      .def("layout", [](const Policy& self) { return self.policy.layout(); })
      .def(
          "check",
          [](const Policy& self, py::handle action) {
            return action_array(read_action(self.policy, action));
          },
          py::arg("action"),
          "The action as float64, clipped to [-1, 1]; raises TypeError for values that are not "
          "real numbers (complex, None, strings, bool), Error for a wrong shape or a value that "
          "is not finite, naming the index, the value and the field.")
      .def(
          "stiffness",
          [](const Policy& self, py::handle action) {
            return vector_array(self.policy.stiffness(read_action(self.policy, action)));
          },
          py::arg("action"), "The diagonal stiffness (6,) the action asks for.")
      .def(
          "stiffness_action",
          [](const Policy& self, ArrayLike stiffness) {
            ci::Vector6d values;
            read_vector(stiffness, "stiffness", Length{6}, values);
            return vector_array(self.policy.stiffness_action(values));
          },
          py::arg("stiffness"), "The action values [6:12] that ask for `stiffness` (6,).")
      .def(
          "reset",
          [](Policy& self, const Loop& loop) {
            self.policy.reset(loop.loop.latest_state().controller.pose);
          },
          py::arg("loop"), "Puts the reference at the flange's pose in loop.latest_state().")
      .def(
          "apply",
          [](Policy& self, py::handle action, Loop& loop) {
            const ci::PolicyInterface::Action checked = read_action(self.policy, action);
            self.policy.apply(checked, loop.loop, loop.loop.latest_state().controller.pose);
            return action_array(checked);
          },
          py::arg("action"), py::arg("loop"),
          "Checks the action (a bad one raises TypeError or Error and changes nothing), moves the "
          "reference "
          "(kept within the leash of the flange's pose in loop.latest_state()) and sends "
          "reference, stiffness and wrench to the loop in one send_all. Returns the checked "
          "action.")
      .def_property_readonly(
          "reference", [](const Policy& self) { return self.policy.reference(); },
          "The reference the last apply() sent (or reset() set).")
      .def(
          "observe",
          [](Policy& self, const Loop& loop, py::handle goal) {
            Eigen::VectorXd goal_values;
            if (!goal.is_none()) {  // any length, none included
              const py::array_t<double> values = real_array(goal, "goal");
              if (values.ndim() != 1) {
                throw py::value_error("goal must have shape (k,), got shape " + shape_text(values));
              }
              goal_values = Eigen::Map<const Eigen::VectorXd>(values.data(), values.shape(0));
            }
            const int robot = self.policy.observation_size();
            Eigen::VectorXd values(robot + goal_values.size());
            self.policy.observe(loop.loop.latest_state(), values.head(robot));
            values.tail(goal_values.size()) = goal_values;
            py::array_t<float> out(values.size());
            float* data = out.mutable_data();
            for (Eigen::Index i = 0; i < values.size(); ++i)
              data[i] = static_cast<float>(values[i]);
            return out;
          },
          py::arg("loop"), py::arg("goal") = py::none(),
          "The observation (float32): the robot part from loop.latest_state() (see "
          "observe_state), then `goal`.")
      .def(
          "observe_state",
          [](Policy& self, const ci::LoopState& state) {
            Eigen::VectorXd values(self.policy.observation_size());
            self.policy.observe(state, values);
            return vector_array(values);
          },
          py::arg("state"),
          "The robot part of the observation (float64, 2 n + 32) from a LoopState: q (n) [rad], "
          "dq (n) [rad/s], flange position (3) [m] and orientation (x, y, z, w; w >= 0), flange "
          "twist J dq (6) [m/s; rad/s], the external wrench estimate -(J^T)^+ (tau_cartesian + "
          "tau_wrench) (6) [N; Nm], the reference position (3) and orientation (4), the stiffness "
          "in force (diagonal of K in the base frame, 6) [N/m; Nm/rad].");
}

}  // namespace cartesian_impedance::python
