#pragma once
// The parts of the Python module, each bound by one file; module.cpp calls them in this order
// (pybind11 names a type in a signature or a default argument only once it is registered).

#include <pybind11/pybind11.h>

namespace cartesian_impedance::python {

/// Frame, Status, TrajectoryState, JointType and Pose (controller.cpp).
void bind_enums_and_pose(pybind11::module_& m);
/// Parameters, parameter_table(), parameter_table_markdown(), load_parameters() (parameters.cpp).
void bind_parameters(pybind11::module_& m);
/// RobotState, make_robot_state(), Targets, ActiveLimits, Fault, ControllerState,
/// TrajectoryProgress, LoopState (controller.cpp).
void bind_states(pybind11::module_& m);
/// CartesianImpedanceController (controller.cpp).
void bind_controller(pybind11::module_& m);
/// JointLimits, Kinematics, RobotModel (loop.cpp).
void bind_robot_model(pybind11::module_& m);
/// ControlLoop (loop.cpp).
void bind_control_loop(pybind11::module_& m);
/// PolicyInterface (policy.cpp).
void bind_policy_interface(pybind11::module_& m);
/// The submodule runtime: ControlThread and the hand-offs MeasurementBuffer, TorqueOutbox
/// (runtime.cpp). After ControlLoop; before the simulation, whose SimulatedDriver uses them.
void bind_runtime(pybind11::module_& m);
#ifdef CARTESIAN_IMPEDANCE_PYTHON_SIM
/// The submodule sim (simulation.cpp).
void bind_simulation(pybind11::module_& m);
#endif

}  // namespace cartesian_impedance::python
