// Python bindings of the cartesian_impedance library: a thin shell that converts and delegates.
//
// Every array argument goes through the conversion helpers of conversions.hpp, which check
// the type (any real dtype is converted to float64; bool, complex, object and string arrays are
// rejected with TypeError) and the shape (ValueError naming the argument and the expected shape)
// before the library sees it. The library then validates the values and throws
// cartesian_impedance::Error, which Python sees as cartesian_impedance.Error (a ValueError) with
// the same message. Arrays leave as fresh NumPy copies, so nothing in Python aliases the library's
// storage.
//
// Threads: ControlLoop commands (the setters, execute_trajectory) may come from any Python thread,
// as in C++. Simulation.run() releases the GIL while it steps; the simulation and the loop's cycle
// (start, step, state) are claimed for that time, so another thread touching them gets a
// RuntimeError instead of a data race. A runtime.ControlThread and a sim.SimulatedDriver are C++
// threads that claim what they use the same way, from start() to stop(), and keep it alive.
//
// Files: module.cpp (this module and its exceptions), conversions.hpp/.cpp (Python <-> Eigen, the
// argument types), parameters.cpp (Parameters and the parameter table), controller.cpp
// (enumerations, Pose, the states, CartesianImpedanceController), loop.cpp (RobotModel,
// ControlLoop), runtime.hpp/.cpp (the submodule runtime: the control thread and its hand-offs),
// simulation.cpp (the submodule sim; driver.cpp: its SimulatedDriver), commands.hpp (the setters
// the controller and the loop share), wrappers.hpp (what Python owns beside a library object);
// cartesian_impedance/ (the package around this module: __init__.py with data_dir(), the stubs
// written by generate_stubs.py, py.typed).

#include <pybind11/pybind11.h>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/types.hpp"
#include "module.hpp"

namespace py = pybind11;
namespace ci = cartesian_impedance;

// The extension is cartesian_impedance._core, inside the package cartesian_impedance
// (python/cartesian_impedance/__init__.py re-exports it, beside the stubs and the shipped data).
// It takes the package's name before anything is bound: pybind11 records a type's module, and
// writes it into every signature, when the type is bound, and users meet these types as
// cartesian_impedance.Pose, not cartesian_impedance._core.Pose (in help(), reprs, errors, pickles
// and the stubs). The submodule sim is then cartesian_impedance.sim.
PYBIND11_MODULE(_core, m) {
  m.attr("__name__") = "cartesian_impedance";
  m.doc() =
      "Cartesian impedance control of torque-controlled robot arms (Python bindings).\n\n"
      "SI units everywhere (m, rad, s, N, Nm). Poses, Jacobians, wrenches and stiffnesses are in\n"
      "the base frame (the root link of the chain) unless a frame argument says end_effector.\n"
      "Quaternions are four numbers in the order x, y, z, w. Arrays are NumPy float64 (any real\n"
      "dtype is accepted and converted). Wrong types raise TypeError, wrong shapes ValueError,\n"
      "values the library rejects cartesian_impedance.Error (a ValueError) with its message.";
  m.attr("__version__") = CARTESIAN_IMPEDANCE_VERSION;
  m.attr("MAX_JOINTS") = ci::kMaxJoints;

  py::register_exception<ci::Error>(m, "Error", PyExc_ValueError);
  m.attr("Error").attr("__doc__") =
      "Raised for every input the library rejects; the message names the field, the value and "
      "the valid range. Derives from ValueError. A call that raises changes nothing.";
  // Registered after Error, so that its translator is tried first.
  py::register_exception<ci::QueueFull>(m, "QueueFull", PyExc_RuntimeError);
  m.attr("QueueFull").attr("__doc__") =
      "A valid command that could not be queued because the control loop's inbox was full (is "
      "the loop stepping?). Transient: the same command may succeed later. Derives from "
      "RuntimeError, not from Error.";
  py::register_exception<ci::LoadError>(m, "LoadError", m.attr("Error"));
  m.attr("LoadError").attr("__doc__") =
      "A URDF or parameter file (or text) that cannot be read, is malformed or lacks what was "
      "asked of it; the message names the file and, where known, the line. Derives from Error.";

  // In this order: pybind11 names a type in a signature or a default value only once it is bound.
  namespace python = cartesian_impedance::python;
  python::bind_enums_and_pose(m);
  python::bind_parameters(m);
  python::bind_states(m);
  python::bind_controller(m);
  python::bind_robot_model(m);
  python::bind_control_loop(m);
  python::bind_policy_interface(m);
  python::bind_runtime(m);
#ifdef CARTESIAN_IMPEDANCE_PYTHON_SIM
  python::bind_simulation(m);
#endif
}
