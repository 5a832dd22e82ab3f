// Python bindings of the robot model (JointLimits, Kinematics, RobotModel) and ControlLoop.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <ctime>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/types.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/model/rate_check.hpp"
#include "cartesian_impedance/model/robot_limits.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "cartesian_impedance/model/start_configuration.hpp"
#include "commands.hpp"
#include "conversions.hpp"
#include "module.hpp"
#include "parameters.hpp"
#include "wrappers.hpp"

namespace cartesian_impedance::python {

namespace {

Eigen::Isometry3d isometry(const ci::Pose& pose) {
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  transform.linear() = pose.orientation.toRotationMatrix();
  transform.translation() = pose.position;
  return transform;
}

ci::ModelBackend read_backend(const std::string& name) {
  if (name == "native") return ci::ModelBackend::native;
  if (name == "kdl") return ci::ModelBackend::kdl;
  throw ci::Error("backend = '" + name + "'; expected 'native' or 'kdl'");
}

std::unique_ptr<Model> load_model(bool from_file, const std::string& source,
                                  const std::string& base_link, const std::string& tip_link,
                                  py::handle tool, py::handle gravity,
                                  const std::string& backend_name) {
  const ci::ModelBackend backend = read_backend(backend_name);
  const Eigen::Isometry3d tool_transform =
      tool.is_none() ? Eigen::Isometry3d::Identity() : isometry(read_pose(tool, "tool"));
  const auto load = [&](auto&&... gravity_argument) {
    return from_file ? ci::RobotModel::from_urdf_file(source, base_link, tip_link, tool_transform,
                                                      gravity_argument...)
                     : ci::RobotModel::from_urdf_string(source, base_link, tip_link, tool_transform,
                                                        gravity_argument...);
  };
  if (gravity.is_none()) return std::make_unique<Model>(load().with_backend(backend));
  Eigen::Vector3d gravity_base;
  read_vector(gravity, "gravity", Length{3}, gravity_base);
  return std::make_unique<Model>(load(gravity_base).with_backend(backend));
}

ci::JointVector finite_joints(py::handle object, std::string_view name, int num_joints) {
  ci::JointVector values;
  read_vector(object, name, Length{num_joints}, values);
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i])) {
      throw ci::Error(std::string(name) + "[" + std::to_string(i) +
                      "] = " + ci::format_number(values[i]) + " is not finite");
    }
  }
  return values;
}

}  // namespace

void bind_robot_model(py::module_& m) {
  // ---- robot model ----
  py::class_<ci::JointLimits>(m, "JointLimits", "Joint limits from the URDF, base to tip.")
      .def_property_readonly(
          "position_lower", [](const ci::JointLimits& l) { return vector_array(l.position_lower); },
          "[rad or m]; -inf for continuous joints")
      .def_property_readonly(
          "position_upper", [](const ci::JointLimits& l) { return vector_array(l.position_upper); },
          "[rad or m]; +inf for continuous joints")
      .def_property_readonly(
          "velocity", [](const ci::JointLimits& l) { return vector_array(l.velocity); },
          "[rad/s or m/s]; +inf where the URDF gives none")
      .def_property_readonly(
          "effort", [](const ci::JointLimits& l) { return vector_array(l.effort); },
          "[Nm or N]; +inf where the URDF gives none");

  py::class_<ci::Kinematics>(m, "Kinematics", "What RobotModel.compute() returns.")
      .def_property_readonly(
          "pose", [](const ci::Kinematics& k) { return k.pose; },
          "T_base_ee (quaternion x, y, z, w): tip link times the tool offset, base frame.")
      .def_property_readonly(
          "jacobian", [](const ci::Kinematics& k) { return matrix_array(k.jacobian); },
          "Geometric Jacobian (6, n), rows [linear; angular], reference point the end-effector "
          "origin, base frame.")
      .def_property_readonly(
          "mass",
          [](const ci::Kinematics& k) -> py::object {
            if (!k.has_dynamics) return py::none();
            return matrix_array(k.mass);
          },
          "M(q) (n, n) [kg m^2], or None without dynamics.")
      .def_property_readonly(
          "gravity",
          [](const ci::Kinematics& k) -> py::object {
            if (!k.has_dynamics) return py::none();
            return vector_array(k.gravity);
          },
          "g(q) (n,) [Nm]: torques that hold the arm against gravity, or None without dynamics.")
      .def_property_readonly(
          "coriolis",
          [](const ci::Kinematics& k) -> py::object {
            if (!k.has_dynamics) return py::none();
            return vector_array(k.coriolis);
          },
          "C(q, dq) dq (n,) [Nm], or None without dynamics.")
      .def_readonly("has_dynamics", &ci::Kinematics::has_dynamics)
      .def("__repr__", [](const ci::Kinematics& k) {
        return "Kinematics(pose=" + pose_repr(k.pose) +
               (k.has_dynamics ? ", with dynamics)" : ", kinematics only)");
      });

  py::class_<Model>(
      m, "RobotModel",
      "The chain base_link -> tip_link of a URDF (urdfdom + KDL), plus a fixed tool offset. "
      "Poses, Jacobians and gravity torques are in the base frame (the frame of base_link).")
      .def_static(
          "from_urdf_file",
          [](PathLike path, const std::string& base_link, const std::string& tip_link,
             PoseLike tool, ArrayLike gravity, const std::string& backend) {
            return load_model(true, read_path(path, "path"), base_link, tip_link, tool, gravity,
                              backend);
          },
          py::arg("path"), py::arg("base_link"), py::arg("tip_link"), py::arg("tool") = py::none(),
          py::arg("gravity") = py::none(), py::arg("backend") = "native",
          "Loads a URDF file. tool: T_tip_tool, the end-effector frame in the tip-link frame "
          "(Pose, (position [m], quaternion x, y, z, w) or 4x4; default identity). gravity: "
          "acceleration (3,) [m/s^2] in the base frame (default (0, 0, -9.81)). backend: "
          "'native' (default) or 'kdl', what computes the kinematics and dynamics (also of every "
          "ControlLoop made from the model). Raises LoadError naming the path for a missing "
          "file, one that is not a regular file (a FIFO, /dev/zero) or is over 16 MiB, unknown "
          "links, an unsupported chain, ...")
      .def_static(
          "from_urdf_string",
          [](const std::string& xml, const std::string& base_link, const std::string& tip_link,
             PoseLike tool, ArrayLike gravity, const std::string& backend) {
            return load_model(false, xml, base_link, tip_link, tool, gravity, backend);
          },
          py::arg("xml"), py::arg("base_link"), py::arg("tip_link"), py::arg("tool") = py::none(),
          py::arg("gravity") = py::none(), py::arg("backend") = "native",
          "As from_urdf_file(), from URDF text.")
      .def_property_readonly(
          "backend", [](const Model& s) { return ci::to_string(s.model.backend()); },
          "'native' or 'kdl'.")
      .def_property_readonly("num_joints", [](const Model& s) { return s.model.num_joints(); })
      .def_property_readonly(
          "joint_names", [](const Model& s) { return s.model.joint_names(); },
          "Movable joints, base to tip: the order of every joint vector.")
      .def_property_readonly("joint_types", [](const Model& s) { return s.model.joint_types(); })
      .def_property_readonly("limits", [](const Model& s) { return s.model.limits(); })
      .def_property_readonly("robot_name", [](const Model& s) { return s.model.robot_name(); })
      .def_property_readonly("base_link", [](const Model& s) { return s.model.base_link(); })
      .def_property_readonly("tip_link", [](const Model& s) { return s.model.tip_link(); })
      .def_property_readonly(
          "tool",
          [](const Model& s) {
            const Eigen::Isometry3d& tool = s.model.tool();
            return ci::Pose{tool.translation(), Eigen::Quaterniond(tool.rotation())};
          },
          "T_tip_tool (quaternion x, y, z, w).")
      .def_property_readonly(
          "gravity", [](const Model& s) { return vector_array(s.model.gravity_base()); },
          "Gravitational acceleration (3,) [m/s^2], base frame.")
      .def_property_readonly(
          "moving_mass", [](const Model& s) { return s.model.moving_mass(); },
          "Mass the dynamics include [kg].")
      .def_property_readonly(
          "warnings", [](const Model& s) { return s.model.warnings(); },
          "What the loader repaired in the file (list of str, each naming the link, the values "
          "and the repair; today: inertias that break the triangle inequality, repaired the same "
          "way in the simulation). Empty for a file used as it is.")
      .def(
          "default_parameters", [](const Model& s) { return ci::default_parameters(s.model); },
          "The library's defaults made to suit this arm (a Parameters): limits.joint_torque the "
          "URDF's efforts, limits.joint_torque_rate effort / 0.05 s, "
          "plausibility.joint_velocity twice the URDF's velocities, and stiffness, stiffness and "
          "wrench limits that the joints can deliver at the largest pose error "
          "(model/robot_limits.hpp). Start a configuration from these for an arm nobody tuned.")
      .def(
          "check_rate_limit",
          [](Model& s, ArrayLike q, ParametersLike parameters) {
            const ci::RateCheck check = ci::check_rate_limit(
                s.model, finite_joints(q, "q", s.model.num_joints()), read_parameters(parameters));
            py::dict result;
            result["stiffness"] = vector_array(check.stiffness);
            result["mass"] = vector_array(check.mass);
            result["frequency"] = vector_array(check.frequency);
            result["followed"] = vector_array(check.followed);
            result["lever"] = vector_array(check.lever);
            result["joint"] = std::vector<int>(check.joint.data(), check.joint.data() + 6);
            result["warnings"] = check.warnings;
            return result;
          },
          py::arg("q"), py::arg("parameters"),
          "Whether the torque-rate limit can follow the stiffness limits of `parameters` at q "
          "(n,) [rad]: per axis of the base frame (x, y, z, then rotations) the end effector's "
          "mode mass [kg, kg m^2], its frequency [rad/s], the joint that bounds it and its lever, "
          "and the largest oscillation the rate follows [m, rad]; 'warnings' lists each group "
          "below 3 mm or 5 mrad with the arithmetic.")
      .def(
          "compute",
          [](Model& s, ArrayLike q, ArrayLike dq, bool dynamics) {
            const int n = s.model.num_joints();
            const ci::JointVector joints = finite_joints(q, "q", n);
            const ci::JointVector velocities =
                dq.is_none() ? ci::JointVector::Zero(n) : finite_joints(dq, "dq", n);
            ci::Kinematics kinematics = s.workspace.make_kinematics();
            if (!s.workspace.compute(joints, velocities, kinematics, dynamics)) {
              throw ci::Error("RobotModel.compute: the result at q = " + numbers_text(joints) +
                              " is not finite");
            }
            return kinematics;
          },
          py::arg("q"), py::arg("dq") = py::none(), py::arg("dynamics") = true,
          "Kinematics at q (n,) [rad] and dq (n,) [rad/s] (default zero): pose T_base_ee "
          "(quaternion x, y, z, w), "
          "Jacobian (6, n) and, if dynamics, mass M(q), gravity g(q) and coriolis C(q, dq) dq. "
          "Raises Error for non-finite q or dq.")
      .def(
          "compute_pose",
          [](Model& s, ArrayLike q) {
            const ci::JointVector joints = finite_joints(q, "q", s.model.num_joints());
            ci::Pose pose;
            if (!s.workspace.compute_pose(joints, pose)) {
              throw ci::Error("RobotModel.compute_pose: the result is not finite");
            }
            return pose;
          },
          py::arg("q"), "Forward kinematics T_base_ee at q (n,) [rad] (quaternion x, y, z, w).")
      .def("__repr__", [](const Model& s) {
        return "RobotModel('" + s.model.robot_name() + "', " + s.model.base_link() + " -> " +
               s.model.tip_link() + ", " + std::to_string(s.model.num_joints()) + " joints)";
      });

  const ci::StartSearch search;
  m.def(
      "find_start_configuration",
      [](const Model& s, int samples, int refined, std::uint64_t seed, double singular_threshold,
         double limit_margin) {
        ci::StartSearch options;
        options.samples = samples;
        options.refined = refined;
        options.seed = seed;
        options.singular_threshold = singular_threshold;
        options.limit_margin = limit_margin;
        const ci::StartChoice choice = ci::find_start_configuration(s.model, options);
        py::dict result;
        result["q"] = vector_array(choice.q);
        result["smallest_singular_value"] = choice.smallest_singular_value;
        result["scaled_singular_value"] = choice.scaled_singular_value;
        result["limit_distance"] = choice.limit_distance;
        result["reach"] = choice.reach;
        result["score"] = choice.score;
        result["flange_position"] = vector_array(choice.flange_position);
        result["description"] = choice.description;
        return result;
      },
      py::arg("model"), py::arg("samples") = search.samples, py::arg("refined") = search.refined,
      py::arg("seed") = search.seed, py::arg("singular_threshold") = search.singular_threshold,
      py::arg("limit_margin") = search.limit_margin,
      "A well-conditioned start configuration for `model` within its joint limits, for a robot "
      "given by its URDF alone (q = 0 is singular on most arms). Maximises the smallest "
      "singular value of the Jacobian (translation rows divided by the arm's reach) times a "
      "factor that falls to 0 at limit_margin [rad or m] from a position limit, with a mild "
      "preference for a ready pose (flange in front of and above the base, at 35-80 % of the "
      "reach, tool pointing down), over `samples` seeded random configurations of which the "
      "`refined` best are improved by a coordinate search. Deterministic for a given seed. "
      "Returns a dict: q (n,) [rad or m], smallest_singular_value (as check_configuration "
      "computes it), scaled_singular_value, limit_distance [rad or m], reach [m], score, "
      "flange_position (3,) [m, base frame], description (one line). Raises Error for bad "
      "options, or if no configuration has a smallest singular value of at least "
      "singular_threshold with every joint limit_margin inside its limits (naming the best "
      "found).");
}

void bind_control_loop(py::module_& m) {
  // ---- control loop ----
  const ci::LoopCapacity default_capacity;
  py::class_<Loop> control_loop(
      m, "ControlLoop",
      "A robot model, the controller and a trajectory executor behind step(q, dq, dt) -> tau.\n\n"
      "One thread runs start()/step(); any thread may send commands (the set_* methods, "
      "execute_trajectory, cancel_trajectory) and read latest_state(). Commands are validated "
      "when sent (Error on bad input) and applied at the next step.");
  def_commands<Loop, ci::ControlLoop>(
      control_loop, [](Loop& self) -> ci::ControlLoop& { return self.loop; }, "Queues");
  control_loop
      .def(py::init([](py::object model, ParametersLike parameters, int commands, int points,
                       bool allow_safety_changes) {
             if (!py::isinstance<Model>(model)) {
               throw py::type_error("model must be a RobotModel, got " + type_name(model));
             }
             auto loop = std::make_unique<Loop>(std::move(model), read_parameters(parameters),
                                                ci::LoopCapacity{commands, points});
             // Decided here, before anything can start the loop (the C++ call throws after).
             if (allow_safety_changes) loop->loop.allow_runtime_safety_changes(true);
             return loop;
           }),
           py::arg("model"), py::arg("parameters") = py::none(),
           py::arg("command_capacity") = default_capacity.commands,
           py::arg("max_trajectory_points") = default_capacity.trajectory_points, py::kw_only(),
           py::arg("allow_runtime_safety_changes") = false,
           "model: RobotModel; parameters: Parameters, dict or None (defaults). Raises Error if "
           "the parameters are invalid for the model's joint count.\n\n"
           "allow_runtime_safety_changes: let set_parameters / update_parameters change safety "
           "settings (safety.*, limits.*, plausibility.*, payload.*, collision.*) after start(). "
           "By default "
           "they are locked once the loop runs: a change of one raises Error naming the "
           "setting, the value in force and the lock, so that no other code (a learning script, "
           "a remote client) can switch a cap off; configure them before start().")
      .def(
          "allow_runtime_safety_changes",
          [](Loop& self, bool allow) { self.loop.allow_runtime_safety_changes(allow); },
          py::arg("allow") = true,
          "Lets (or, with False, no longer lets) commands change safety settings after start(); "
          "as the constructor's keyword. Raises Error after start(): the owner decides before "
          "the loop runs.")
      .def_property_readonly(
          "runtime_safety_changes_allowed",
          [](const Loop& self) { return self.loop.runtime_safety_changes_allowed(); },
          "True if safety settings may change after start() (allow_runtime_safety_changes).")
      .def_property_readonly(
          "model", [](const Loop& self) { return self.model_object; }, "The RobotModel.")
      .def_property_readonly("num_joints", [](const Loop& self) { return self.loop.num_joints(); })
      .def_property_readonly(
          "started", [](Loop& self) { return self.cycle().started(); },
          "True once start() has been called.")
      .def(
          "start",
          [](Loop& self, ArrayLike q, ArrayLike dq, ArrayLike tau_previous) {
            ci::ControlLoop& loop = self.cycle();
            const int n = loop.num_joints();
            ci::JointVector joints, velocities;
            read_vector(q, "q", Length{n}, joints);
            read_vector(dq, "dq", Length{n}, velocities);
            if (tau_previous.is_none()) return loop.start(joints, velocities);
            ci::JointVector tau;
            read_vector(tau_previous, "tau_previous", Length{n}, tau);
            loop.start(joints, velocities, tau);
          },
          py::arg("q"), py::arg("dq"), py::arg("tau_previous") = py::none(),
          "Starts (or restarts) from the measured q (n,) [rad] and dq (n,) [rad/s]: reference "
          "pose = current pose, nullspace target = q. tau_previous (n,) [Nm]: the torque the "
          "robot receives now (default g(q) with dynamics.gravity_compensation, else zero). "
          "Raises Error for non-finite values.")
      .def(
          "step",
          [](Loop& self, ArrayLike q, ArrayLike dq, Real dt, ArrayLike measured_torque) {
            ci::ControlLoop& loop = self.cycle();
            const int n = loop.num_joints();
            ci::JointVector joints, velocities;
            read_vector(q, "q", Length{n}, joints);
            read_vector(dq, "dq", Length{n}, velocities);
            const double period = read_scalar(dt, "dt");
            if (measured_torque.is_none())
              return vector_array(loop.step(joints, velocities, period));
            ci::JointVector torques;
            read_vector(measured_torque, "measured_torque", Length{n}, torques);
            return vector_array(loop.step(joints, velocities, torques, period));
          },
          py::arg("q"), py::arg("dq"), py::arg("dt"), py::arg("measured_torque") = py::none(),
          "One control cycle: q (n,) [rad], dq (n,) [rad/s], dt [s] since the last step; "
          "measured_torque (n,) [Nm]: the joint torques the robot measures (link side, gravity "
          "included), read with collision.measured_torque. Returns the joint torque to command "
          "(n,) [Nm] (a new array). Wrong shapes or types raise; non-finite values do not: like "
          "the C++ cycle it then reports a Status (state.controller.status) and ramps the torque "
          "toward zero within the rate limit.")
      .def_property_readonly(
          "state", [](Loop& self) { return self.cycle().state(); },
          "A copy of the state after the last step (LoopState; cycle thread).")
      .def_property_readonly(
          "torque", [](Loop& self) { return vector_array(self.cycle().state().controller.tau); },
          "Torque of the last step (n,) [Nm].")
      .def(
          "latest_state", [](const Loop& self) { return self.loop.latest_state(); },
          "A copy of the newest published LoopState (any thread).")
      .def(
          "latest_parameters", [](const Loop& self) { return self.loop.latest_parameters(); },
          "Parameters in force as of the last step (any thread).")
      .def(
          "execute_trajectory",
          [](Loop& self, ArrayLike times, ArrayLike positions, ArrayLike velocities,
             std::optional<std::vector<std::string>> joint_names) {
            ci::JointTrajectory trajectory;
            trajectory.joint_names = joint_names ? *joint_names : self.loop.model().joint_names();
            const Length columns{static_cast<Eigen::Index>(trajectory.joint_names.size()),
                                 ci::kMaxJoints};
            Eigen::VectorXd time_values;
            read_vector(times, "times", Length{-1, kUnbounded}, time_values);
            trajectory.times.assign(time_values.data(), time_values.data() + time_values.size());
            const auto rows = [&](py::handle object, const char* name) {
              Eigen::MatrixXd matrix;
              read_matrix(object, name, Length{-1, kUnbounded}, columns, matrix, false, "points");
              std::vector<std::vector<double>> points(static_cast<std::size_t>(matrix.rows()));
              for (Eigen::Index i = 0; i < matrix.rows(); ++i) {
                points[static_cast<std::size_t>(i)].resize(static_cast<std::size_t>(matrix.cols()));
                for (Eigen::Index j = 0; j < matrix.cols(); ++j) {
                  points[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)] = matrix(i, j);
                }
              }
              return points;
            };
            trajectory.positions = rows(positions, "positions");
            if (!velocities.is_none()) trajectory.velocities = rows(velocities, "velocities");
            return self.loop.execute_trajectory(trajectory);
          },
          py::arg("times"), py::arg("positions"), py::arg("velocities") = py::none(),
          py::arg("joint_names") = py::none(),
          "Queues a joint trajectory and returns its id. times (m,) [s] from the start, strictly "
          "increasing (a point at 0 is taken as the start state); positions (m, k) [rad]; "
          "velocities (m, k) [rad/s] or None (smooth, shape-preserving); joint_names: k names in "
          "any order (default: the model's joint names). It starts at the next step from where "
          "the arm is (or from where a running trajectory is, which it preempts). Raises Error "
          "for unknown joints, times not increasing, positions outside the URDF limits, ...")
      .def(
          "cancel_trajectory", [](Loop& self) { self.loop.cancel_trajectory(); },
          "Stops a running trajectory; the arm holds where it is.")
      .def(
          "_benchmark_steps",
          [](Loop& self, ArrayLike q, ArrayLike dq, double dt, std::int64_t count) {
            ci::ControlLoop& loop = self.cycle();
            const int n = loop.num_joints();
            ci::JointVector joints, velocities;
            read_vector(q, "q", Length{n}, joints);
            read_vector(dq, "dq", Length{n}, velocities);
            Claim claim(self.running, "this ControlLoop");
            double sink = 0.0, cpu = 0.0;
            std::chrono::duration<double> elapsed{};
            {
              py::gil_scoped_release release;
              const auto begin = std::chrono::steady_clock::now();
              const std::clock_t cpu_begin = std::clock();
              for (std::int64_t k = 0; k < count; ++k) {
                sink += loop.step(joints, velocities, dt)[0];
              }
              cpu = static_cast<double>(std::clock() - cpu_begin) / CLOCKS_PER_SEC;
              elapsed = std::chrono::steady_clock::now() - begin;
            }
            return py::make_tuple(elapsed.count(), cpu, sink);  // with the GIL again
          },
          py::arg("q"), py::arg("dq"), py::arg("dt"), py::arg("count"),
          "Internal (python/benchmarks): `count` steps in C++ with the same q, dq, dt; returns "
          "(wall seconds, CPU seconds, checksum).")
      .def("__repr__", [](const Loop& self) {
        const ci::RobotModel& model = self.loop.model();
        std::string text = "ControlLoop(robot='" + model.robot_name() + "', " +
                           std::to_string(model.num_joints()) + " joints, ";
        if (const char* by = self.running.load()) return text + "in use by " + by + ")";
        const ci::LoopState& state = self.loop.state();
        if (!self.loop.started()) {
          text += "not started";
        } else {
          text += "started, cycle " + std::to_string(state.cycle) +
                  ", t = " + ci::format_number(state.time) + " s, status " +
                  ci::to_string(state.controller.status);
        }
        return text + ", trajectory " + trajectory_text(state.trajectory) + ")";
      });
}

}  // namespace cartesian_impedance::python
