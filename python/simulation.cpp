// Python bindings of the simulation: the submodule cartesian_impedance.sim (Box, AttachedBox,
// SquareHole, Simulation, make_scene, hole_boxes, make_peg_in_hole_scene, engine_available,
// offscreen_rendering_available; BatchRunner and run_many in batch.cpp). Built when the
// simulation library is (CARTESIAN_IMPEDANCE_PYTHON_SIM).

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/types.hpp"
#include "cartesian_impedance/loop/control_loop.hpp"
#include "cartesian_impedance/model/start_configuration.hpp"
#include "cartesian_impedance/sim/closed_loop_runner.hpp"
#include "cartesian_impedance/sim/peg_in_hole.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "conversions.hpp"
#include "module.hpp"
#include "simulation.hpp"
#include "wrappers.hpp"

namespace cartesian_impedance::python {

namespace {

ci::sim::SimulationOptions simulation_options(py::handle timestep, bool gravity_compensation,
                                              const std::string& keyframe,
                                              const std::optional<std::vector<std::string>>& names,
                                              bool multi_point_contacts, py::handle start_q,
                                              py::handle armature, const std::string& engine,
                                              bool boxes_for_missing_meshes, py::handle plant) {
  ci::sim::SimulationOptions options;
  options.boxes_for_missing_meshes = boxes_for_missing_meshes;
  if (py::isinstance<py::str>(plant)) {
    options.plant = ci::sim::plant_from_name(plant.cast<std::string>());
  } else if (py::isinstance<ci::sim::PlantOptions>(plant)) {
    options.plant = plant.cast<ci::sim::PlantOptions>();
  } else {
    throw ci::Error("plant must be 'nominal', 'realistic' or a Plant, got " +
                    py::repr(plant).cast<std::string>());
  }
  options.engine = ci::sim::engine_from_name(engine);
  options.timestep = read_scalar(timestep, "timestep");
  options.gravity_compensation = gravity_compensation;
  options.keyframe = keyframe;
  if (names) options.joint_names = *names;
  options.multi_point_contacts = multi_point_contacts;
  // Their length against the model's joints is checked by the loader, which names the joint.
  if (!start_q.is_none()) read_vector(start_q, "start_q", Length{}, options.start_q);
  if (py::isinstance<py::float_>(armature) ||
      (py::isinstance<py::int_>(armature) && !py::isinstance<py::bool_>(armature))) {
    options.armature = JointVector::Constant(1, read_scalar(armature, "armature"));
  } else if (!armature.is_none()) {
    read_vector(armature, "armature", Length{}, options.armature, " or one number");
  }
  return options;
}

// Simulation.run() takes the GIL back this often to let Ctrl+C (KeyboardInterrupt) through.
constexpr std::int64_t kSignalCheckSteps = 1000;

}  // namespace

void bind_simulation(py::module_& m) {
  // ---- simulation ----
  py::module_ sim = m.def_submodule(
      "sim",
      "Simulation of a torque-controlled arm (MuJoCo, or DART for URDF robots: the engine "
      "option): joint torques in, joint state out, gravity "
      "compensated like Panda and iiwa firmware (on by default), pushes, static boxes, contact "
      "wrenches, offscreen rendering. Poses and wrenches are in MuJoCo's world frame, which is "
      "the controller's base frame for the project's robot files; wrenches are [force; torque].");
  // `import cartesian_impedance.sim` works too.
  py::module_::import("sys").attr("modules")["cartesian_impedance.sim"] = sim;

  const ci::sim::SimulationOptions default_options;
  const auto option_args = [&default_options]() {
    return std::make_tuple(
        py::arg("timestep") = default_options.timestep,
        py::arg("gravity_compensation") = default_options.gravity_compensation,
        py::arg("keyframe") = default_options.keyframe, py::arg("joint_names") = py::none(),
        py::arg("multi_point_contacts") = default_options.multi_point_contacts,
        py::arg("start_q") = py::none(), py::arg("armature") = py::none(),
        py::arg("engine") = ci::sim::engine_name(default_options.engine),
        py::arg("boxes_for_missing_meshes") = default_options.boxes_for_missing_meshes,
        py::arg("plant") = "nominal");
  };
  const char* options_doc =
      " Options: timestep [s] (replaces the model's); gravity_compensation: each joint receives "
      "tau + g(q), as robot firmware does; keyframe to reset to ('' or missing: the model's "
      "default qpos); joint_names: order of q, dq and tau (default: the model's hinge and slide "
      "joints); multi_point_contacts: steadier face-on-face contact forces; start_q: joint "
      "positions "
      "(n,) [rad or m] to start from and reset() to, instead of the keyframe, each checked against "
      "its joint's range; armature: rotor inertia per joint (n,) or one value for all [kg m^2], "
      "replacing the model's (use the same for the controller's dynamics.armature); engine: the "
      "physics engine, 'mujoco' or 'dart' (DART needs the robot from URDF; see "
      "engine_available()); boxes_for_missing_meshes: a URDF link whose collision mesh cannot be "
      "found or read is simulated as the box of its inertia (listed in warnings) instead of "
      "refusing the URDF; plant: 'nominal' (the model itself, read at once and exactly), "
      "'realistic' (Plant.realistic()) or a Plant: model error, delays and noise.";

  // A Spread as the tuple (low, high).
  const auto spread_property = [](py::class_<ci::sim::PlantOptions>& plant, const char* name,
                                  ci::sim::Spread ci::sim::PlantOptions::*member, const char* doc) {
    plant.def_property(
        name,
        [member](const ci::sim::PlantOptions& p) {
          return std::make_tuple((p.*member).low, (p.*member).high);
        },
        [member, name](ci::sim::PlantOptions& p, py::handle value) {
          Eigen::Vector2d range;
          read_vector(value, name, Length{2}, range);
          p.*member = {range[0], range[1]};
        },
        doc);
  };
  py::class_<ci::sim::PlantOptions> plant(
      sim, "Plant",
      "How the simulated arm differs from its model and how its sensors and drives behave "
      "(the plant option of the loaders). Plant() is the nominal plant; Plant.realistic(seed) "
      "one of the kind users meet. The model error is drawn once from seed, the noise every step "
      "(reset() starts it over). Checked by the loader, which names a field out of range.");
  plant.def(py::init<>())
      .def_static(
          "realistic", &ci::sim::PlantOptions::realistic, py::arg("seed") = 1,
          "Link inertias x U(0.7, 1.3), centres of mass moved up to 1 cm, friction x "
          "U(0.5, 1.5), damping and armature x U(0.8, 1.2); readings 1 ms old with 1e-5 rad "
          "and 0.005 rad/s of noise and a 19-bit encoder; torques acting 1 ms late with "
          "0.05 Nm of noise.")
      .def_property_readonly("nominal", &ci::sim::PlantOptions::nominal,
                             "Nothing differs from the model.")
      .def_readwrite("seed", &ci::sim::PlantOptions::seed)
      .def_readwrite("center_of_mass_offset", &ci::sim::PlantOptions::center_of_mass_offset,
                     "Each link's centre of mass moved by up to this [m].")
      .def_readwrite("measurement_delay", &ci::sim::PlantOptions::measurement_delay,
                     "Age of each reading [s] (whole timesteps).")
      .def_readwrite("position_noise", &ci::sim::PlantOptions::position_noise,
                     "Standard deviation [rad] of white noise on each position read.")
      .def_readwrite("velocity_noise", &ci::sim::PlantOptions::velocity_noise,
                     "Standard deviation [rad/s] of white noise on each velocity read.")
      .def_readwrite("position_resolution", &ci::sim::PlantOptions::position_resolution,
                     "The encoder's quantum [rad] (0: none).")
      .def_readwrite("actuation_delay", &ci::sim::PlantOptions::actuation_delay,
                     "Time from set_torque() until the torque acts [s] (whole timesteps).")
      .def_readwrite("torque_noise", &ci::sim::PlantOptions::torque_noise,
                     "Standard deviation [Nm] of white noise on each applied torque.")
      .def_readwrite("torque_sensor_noise", &ci::sim::PlantOptions::torque_sensor_noise,
                     "Standard deviation [Nm] of white noise on each measured joint torque.");
  spread_property(plant, "inertia", &ci::sim::PlantOptions::inertia,
                  "(low, high): each link's mass and inertia scaled by a factor drawn from it.");
  spread_property(plant, "friction", &ci::sim::PlantOptions::friction,
                  "(low, high): each joint's Coulomb friction scaled.");
  spread_property(plant, "damping", &ci::sim::PlantOptions::damping,
                  "(low, high): each joint's viscous damping scaled.");
  spread_property(plant, "armature", &ci::sim::PlantOptions::armature,
                  "(low, high): each joint's armature scaled.");

  py::class_<ci::sim::Box>(sim, "Box",
                           "A static box (table, wall, step) that collides with the robot.")
      .def(py::init([](ArrayLike center, ArrayLike half_size, ArrayLike orientation,
                       const std::string& name) {
             ci::sim::Box box;
             box.name = name;
             read_vector(center, "center", Length{3}, box.center);
             read_vector(half_size, "half_size", Length{3}, box.half_size);
             if (!orientation.is_none()) {
               box.orientation = quaternion_xyzw(orientation, "orientation (x, y, z, w)");
             }
             return box;
           }),
           py::arg("center"), py::arg("half_size"), py::arg("orientation") = py::none(),
           py::arg("name") = "",
           "center (3,) [m] in the world frame, half_size (3,) [m] along the box axes, "
           "orientation: quaternion (4,) x, y, z, w of the box axes (default identity); name: "
           "geom name ('' = scene_box_<index>).")
      .def_static(
          "table",
          [](ArrayLike center_xy, ArrayLike half_size_xy, Real top_z, const std::string& name) {
            Eigen::Vector2d center, half;
            read_vector(center_xy, "center_xy", Length{2}, center);
            read_vector(half_size_xy, "half_size_xy", Length{2}, half);
            return ci::sim::Box::table(center, half, read_scalar(top_z, "top_z"), name);
          },
          py::arg("center_xy"), py::arg("half_size_xy"), py::arg("top_z"), py::arg("name") = "",
          "A table on the floor whose top is at top_z [m], centred at center_xy (2,) [m], half "
          "extents half_size_xy (2,) [m].")
      .def_readwrite("name", &ci::sim::Box::name)
      .def_property(
          "center", [](const ci::sim::Box& b) { return vector_array(b.center); },
          [](ci::sim::Box& b, py::handle v) { read_vector(v, "center", Length{3}, b.center); },
          "(3,) [m], world frame")
      .def_property(
          "half_size", [](const ci::sim::Box& b) { return vector_array(b.half_size); },
          [](ci::sim::Box& b, py::handle v) {
            read_vector(v, "half_size", Length{3}, b.half_size);
          },
          "(3,) [m]")
      .def_property(
          "orientation", [](const ci::sim::Box& b) { return xyzw_array(b.orientation); },
          [](ci::sim::Box& b, py::handle v) {
            b.orientation = quaternion_xyzw(v, "orientation (x, y, z, w)");
          },
          "quaternion (4,) in the order x, y, z, w")
      .def("__repr__", [](const ci::sim::Box& b) {
        return "Box(name='" + b.name + "', center=" + numbers_text(b.center) +
               ", half_size=" + numbers_text(b.half_size) +
               ", orientation_xyzw=" + numbers_text(b.orientation.coeffs()) + ")";
      });

  py::class_<ci::sim::AttachedBox>(
      sim, "AttachedBox",
      "A box fixed to a body of the robot (a peg at the flange, a tool): it moves with the body, "
      "collides with the scene's boxes and adds its mass and inertia to the arm. The simulated "
      "firmware's gravity compensation does not know it: declare it to the controller as "
      "payload.mass and payload.center_of_mass.")
      .def(py::init([](const std::string& body, ArrayLike half_size, Real mass, ArrayLike position,
                       ArrayLike orientation, const std::string& name) {
             ci::sim::AttachedBox box;
             box.body = body;
             box.name = name;
             read_vector(half_size, "half_size", Length{3}, box.half_size);
             box.mass = read_scalar(mass, "mass");
             if (!position.is_none()) read_vector(position, "position", Length{3}, box.position);
             if (!orientation.is_none()) {
               box.orientation = quaternion_xyzw(orientation, "orientation (x, y, z, w)");
             }
             return box;
           }),
           py::arg("body"), py::arg("half_size"), py::arg("mass"), py::arg("position") = py::none(),
           py::arg("orientation") = py::none(), py::arg("name") = "",
           "body: the robot body (URDF link) it is fixed to, e.g. 'panda_link8'; half_size (3,) "
           "[m]; mass [kg] > 0 (a solid box's inertia); position (3,) [m] of its centre and "
           "orientation: quaternion (4,) x, y, z, w of its axes, both in the body's frame "
           "(default: at the body's origin, aligned); name: its body and geom in the scene "
           "('' = attached_box_<index>). Checked when a scene is made.")
      .def_readwrite("name", &ci::sim::AttachedBox::name)
      .def_readwrite("body", &ci::sim::AttachedBox::body)
      .def_readwrite("mass", &ci::sim::AttachedBox::mass, "[kg]")
      .def_property(
          "position", [](const ci::sim::AttachedBox& b) { return vector_array(b.position); },
          [](ci::sim::AttachedBox& b, py::handle v) {
            read_vector(v, "position", Length{3}, b.position);
          },
          "(3,) [m], in the body's frame")
      .def_property(
          "orientation", [](const ci::sim::AttachedBox& b) { return xyzw_array(b.orientation); },
          [](ci::sim::AttachedBox& b, py::handle v) {
            b.orientation = quaternion_xyzw(v, "orientation (x, y, z, w)");
          },
          "quaternion (4,) x, y, z, w, in the body's frame")
      .def_property(
          "half_size", [](const ci::sim::AttachedBox& b) { return vector_array(b.half_size); },
          [](ci::sim::AttachedBox& b, py::handle v) {
            read_vector(v, "half_size", Length{3}, b.half_size);
          },
          "(3,) [m]")
      .def("__repr__", [](const ci::sim::AttachedBox& b) {
        return "AttachedBox(name='" + b.name + "', body='" + b.body +
               "', half_size=" + numbers_text(b.half_size) + ", mass=" + format_number(b.mass) +
               ", position=" + numbers_text(b.position) +
               ", orientation_xyzw=" + numbers_text(b.orientation.coeffs()) + ")";
      });

  const ci::sim::SquareHole default_hole;
  const ci::sim::PegInHole default_peg_in_hole;
  py::class_<ci::sim::SquareHole>(
      sim, "SquareHole",
      "A square hole in a block made of static boxes (hole_boxes()): four walls and a floor.")
      .def(py::init([](PoseLike opening, Real peg_half_width, Real clearance, Real depth, Real wall,
                       Real floor, const std::string& name) {
             ci::sim::SquareHole hole;
             hole.opening = read_pose(opening, "opening");
             hole.peg_half_width = read_scalar(peg_half_width, "peg_half_width");
             hole.clearance = read_scalar(clearance, "clearance");
             hole.depth = read_scalar(depth, "depth");
             hole.wall = read_scalar(wall, "wall");
             hole.floor = read_scalar(floor, "floor");
             hole.name = name;
             return hole;
           }),
           py::arg("opening"), py::arg("peg_half_width") = default_hole.peg_half_width,
           py::arg("clearance") = default_hole.clearance, py::arg("depth") = default_hole.depth,
           py::arg("wall") = default_hole.wall, py::arg("floor") = default_hole.floor,
           py::arg("name") = default_hole.name,
           "opening: pose of the centre of the hole's opening in the block's top face (world "
           "frame; its z axis points out of the hole, its x and y axes along the hole's sides); "
           "peg_half_width [m]: half the width of the square peg it takes; clearance [m]: hole "
           "width minus peg width (clearance / 2 on each side of a centred peg); depth [m] to "
           "the hole's floor; wall [m]: block material beside the hole; floor [m] below it (0: "
           "a through hole); name: the boxes are <name>_wall_x_plus, ..., <name>_floor.")
      .def_property(
          "opening", [](const ci::sim::SquareHole& h) { return h.opening; },
          [](ci::sim::SquareHole& h, py::handle v) { h.opening = read_pose(v, "opening"); },
          "Pose of the opening's centre, world frame")
      .def_readwrite("peg_half_width", &ci::sim::SquareHole::peg_half_width, "[m]")
      .def_readwrite("clearance", &ci::sim::SquareHole::clearance, "hole width minus peg width [m]")
      .def_readwrite("depth", &ci::sim::SquareHole::depth, "[m]")
      .def_readwrite("wall", &ci::sim::SquareHole::wall, "[m]")
      .def_readwrite("floor", &ci::sim::SquareHole::floor, "[m]")
      .def_readwrite("name", &ci::sim::SquareHole::name)
      .def("__repr__", [](const ci::sim::SquareHole& h) {
        return "SquareHole(opening=" + pose_repr(h.opening) +
               ", peg_half_width=" + format_number(h.peg_half_width) +
               ", clearance=" + format_number(h.clearance) + ", depth=" + format_number(h.depth) +
               ", wall=" + format_number(h.wall) + ", floor=" + format_number(h.floor) +
               ", name='" + h.name + "')";
      });
  sim.def("hole_boxes", &ci::sim::hole_boxes, py::arg("hole"),
          "The static boxes (list of Box) of the block around a SquareHole: four walls and, "
          "unless hole.floor is 0, a floor; for make_scene().");

  py::class_<Sim> simulation(sim, "Simulation",
                             "A simulated robot (MuJoCo or DART). Not thread-safe: one thread "
                             "drives it. Loaders and setters "
                             "raise Error on bad input.");
  std::apply(
      [&](auto... args) {
        simulation.def_static(
            "from_mjcf_file",
            [](PathLike path, Real timestep, bool gravity_compensation, const std::string& keyframe,
               std::optional<std::vector<std::string>> names, bool multi_point_contacts,
               py::object start_q, py::object armature, const std::string& engine,
               bool boxes_for_missing_meshes, py::object plant) {
              return std::make_unique<Sim>(ci::sim::Simulation::from_mjcf_file(
                  read_path(path, "path"),
                  simulation_options(timestep, gravity_compensation, keyframe, names,
                                     multi_point_contacts, start_q, armature, engine,
                                     boxes_for_missing_meshes, plant)));
            },
            py::arg("path"), args...,
            (std::string("Loads an MJCF file (e.g. models/panda/panda.xml); each joint is "
                         "driven by its <motor>, or through qfrc_applied without one.") +
             options_doc)
                .c_str());
        simulation.def_static(
            "from_urdf_file",
            [](PathLike path, Real timestep, bool gravity_compensation, const std::string& keyframe,
               std::optional<std::vector<std::string>> names, bool multi_point_contacts,
               py::object start_q, py::object armature, const std::string& engine,
               bool boxes_for_missing_meshes, py::object plant, const Model* model) {
              ci::sim::SimulationOptions options = simulation_options(
                  timestep, gravity_compensation, keyframe, names, multi_point_contacts, start_q,
                  armature, engine, boxes_for_missing_meshes, plant);
              // A URDF has no start of its own and q = 0 is singular on most arms: with the
              // controller's model, the library chooses one.
              if (model != nullptr) {
                if (!names) options.joint_names = model->model.joint_names();
                if (start_q.is_none()) {
                  options.start_q = ci::find_start_configuration(model->model).q;
                }
              }
              return std::make_unique<Sim>(
                  ci::sim::Simulation::from_urdf_file(read_path(path, "path"), options));
            },
            py::arg("path"), args..., py::arg("model") = py::none(),
            (std::string("Loads a URDF with MuJoCo's importer (no actuators, no floor, no "
                         "keyframe). model: the controller's RobotModel of this URDF; with it, "
                         "the simulation exchanges model.joint_names (unless joint_names is "
                         "given) and, without start_q, starts and resets at "
                         "cartesian_impedance.find_start_configuration(model)['q'] instead of "
                         "q = 0 (which is singular on most arms).") +
             options_doc)
                .c_str());
        sim.def(
            "make_scene",
            [](PathLike path, const std::vector<ci::sim::Box>& boxes, Real timestep,
               bool gravity_compensation, const std::string& keyframe,
               std::optional<std::vector<std::string>> names, bool multi_point_contacts,
               py::object start_q, py::object armature, const std::string& engine,
               bool boxes_for_missing_meshes, py::object plant,
               const std::vector<ci::sim::AttachedBox>& attached) {
              return std::make_unique<Sim>(ci::sim::make_scene(
                  read_path(path, "robot_mjcf"), boxes, attached,
                  simulation_options(timestep, gravity_compensation, keyframe, names,
                                     multi_point_contacts, start_q, armature, engine,
                                     boxes_for_missing_meshes, plant)));
            },
            py::arg("robot_mjcf"), py::arg("boxes"), args...,
            py::arg("attached") = std::vector<ci::sim::AttachedBox>{},
            (std::string("Loads the robot file (MJCF, or URDF as from_urdf_file() completes it) "
                         "with the boxes (a list of Box) added to its world and the attached "
                         "boxes (a list of AttachedBox) fixed to its bodies, writing no file.") +
             options_doc)
                .c_str());
        sim.def(
            "make_peg_in_hole_scene",
            [](PathLike robot, const std::string& flange, const ci::sim::SquareHole& hole,
               Real peg_length, Real peg_mass, const std::string& peg_name, Real timestep,
               bool gravity_compensation, const std::string& keyframe,
               std::optional<std::vector<std::string>> names, bool multi_point_contacts,
               py::object start_q, py::object armature, const std::string& engine,
               bool boxes_for_missing_meshes, py::object plant) {
              ci::sim::PegInHole scene;
              scene.robot = read_path(robot, "robot");
              scene.flange = flange;
              scene.hole = hole;
              scene.peg_length = read_scalar(peg_length, "peg_length");
              scene.peg_mass = read_scalar(peg_mass, "peg_mass");
              scene.peg_name = peg_name;
              return std::make_unique<Sim>(ci::sim::make_peg_in_hole_scene(
                  scene, simulation_options(timestep, gravity_compensation, keyframe, names,
                                            multi_point_contacts, start_q, armature, engine,
                                            boxes_for_missing_meshes, plant)));
            },
            py::arg("robot"), py::arg("flange"), py::arg("hole"),
            py::arg("peg_length") = default_peg_in_hole.peg_length,
            py::arg("peg_mass") = default_peg_in_hole.peg_mass,
            py::arg("peg_name") = default_peg_in_hole.peg_name, args...,
            (std::string("The robot (URDF: MuJoCo or DART; MJCF: MuJoCo) holding a square peg "
                         "of 2 hole.peg_half_width x 2 hole.peg_half_width x peg_length [m] and "
                         "peg_mass [kg] along the flange body's z axis from its origin (the tip "
                         "at (0, 0, peg_length) in the flange frame, the sides along its x and "
                         "y), named peg_name, with the block of the SquareHole `hole` in the "
                         "world. The simulated firmware does not compensate the peg's weight: "
                         "declare it to the controller as payload.mass = peg_mass, "
                         "payload.center_of_mass = (0, 0, peg_length / 2).") +
             options_doc)
                .c_str());
      },
      option_args());

  simulation.def_property_readonly("num_joints", [](Sim& s) { return s.get().num_joints(); })
      .def_property_readonly(
          "joint_names", [](Sim& s) { return s.get().joint_names(); },
          "Joint names in the order q, dq and tau are exchanged.")
      .def_property_readonly(
          "warnings", [](Sim& s) { return s.get().warnings(); },
          "What the loading changed in the robot's description (list of str; meshes replaced by "
          "boxes). Inertias repaired alike in the model are in RobotModel.warnings.")
      .def_property_readonly(
          "time", [](Sim& s) { return s.get().time(); }, "Simulated time [s].")
      .def_property_readonly(
          "timestep", [](Sim& s) { return s.get().timestep(); }, "Integration step [s].")
      .def_property_readonly(
          "q", [](Sim& s) { return vector_array(s.get().q()); },
          "Joint positions (n,) [rad] as the sensors read them (the plant's delay and noise).")
      .def_property_readonly(
          "dq", [](Sim& s) { return vector_array(s.get().dq()); },
          "Joint velocities (n,) [rad/s] as the sensors read them.")
      .def_property_readonly(
          "true_q", [](Sim& s) { return vector_array(s.get().true_q()); },
          "The joints' actual positions (n,) [rad] (q for the nominal plant).")
      .def_property_readonly(
          "true_dq", [](Sim& s) { return vector_array(s.get().true_dq()); },
          "The joints' actual velocities (n,) [rad/s].")
      .def_property_readonly(
          "torque", [](Sim& s) { return vector_array(s.get().torque()); },
          "Applied commanded torque after clipping (n,) [Nm], without gravity compensation.")
      .def_property_readonly(
          "measured_torque", [](Sim& s) { return vector_array(s.get().measured_torque()); },
          "What the joint torque sensors read (n,) [Nm]: link side, gravity included (Franka's "
          "tau_J), less what friction, damping and the rotors took; late and noisy with the "
          "plant.")
      .def_property_readonly(
          "torque_lower_limits", [](Sim& s) { return vector_array(s.get().torque_lower_limits()); },
          "(n,) [Nm]; -inf without a limited actuator")
      .def_property_readonly(
          "torque_upper_limits", [](Sim& s) { return vector_array(s.get().torque_upper_limits()); },
          "(n,) [Nm]; +inf without a limited actuator")
      .def_property_readonly(
          "armature", [](Sim& s) { return vector_array(s.get().armature()); },
          "Rotor inertia per joint (n,) [kg m^2] as simulated (with a plant's model error, the "
          "drawn one).")
      .def_property_readonly(
          "model_armature", [](Sim& s) { return vector_array(s.get().model_armature()); },
          "Rotor inertia per joint (n,) [kg m^2] before the plant's model error: the value for "
          "the parameter dynamics.armature.")
      .def_property_readonly(
          "measurement_age", [](Sim& s) { return s.get().measurement_age(); },
          "[s] how old q and dq are when read: the plant's measurement delay in whole timesteps "
          "(0 for the nominal plant).")
      .def_property_readonly(
          "actuation_delay", [](Sim& s) { return s.get().actuation_delay(); },
          "[s] how late a torque set acts: the plant's actuation delay in whole timesteps. With "
          "measurement_age the loop's delay, the parameter safety.passivity.delay.")
      .def_property_readonly(
          "friction_loss", [](Sim& s) { return vector_array(s.get().friction_loss()); },
          "Coulomb friction per joint (n,) [Nm]")
      .def_property_readonly("model_name", [](Sim& s) { return s.get().model_name(); })
      .def_property_readonly(
          "engine", [](Sim& s) { return std::string(ci::sim::engine_name(s.get().engine())); },
          "The physics engine integrating this simulation: 'mujoco' or 'dart'.")
      .def(
          "set_state",
          [](Sim& s, ArrayLike q, ArrayLike dq) {
            ci::sim::Simulation& simulation = s.get();
            ci::JointVector joints, velocities;
            read_vector(q, "q", Length{simulation.num_joints()}, joints);
            read_vector(dq, "dq", Length{simulation.num_joints()}, velocities);
            simulation.set_state(joints, velocities);
          },
          py::arg("q"), py::arg("dq"),
          "Sets joint positions (n,) [rad] and velocities (n,) [rad/s]; time is kept.")
      .def(
          "reset", [](Sim& s) { s.get().reset(); },
          "Back to the keyframe at time 0: zero torque, no pushes.")
      .def(
          "set_torque",
          [](Sim& s, ArrayLike tau) {
            ci::sim::Simulation& simulation = s.get();
            ci::JointVector values;
            read_vector(tau, "tau", Length{simulation.num_joints()}, values);
            return simulation.set_torque(values);
          },
          py::arg("tau"),
          "Commands joint torques (n,) [Nm] from the next step on (gravity compensation comes on "
          "top), clipped to the actuator ranges. Returns True if any value was clipped.")
      .def(
          "step",
          [](Sim& s, std::int64_t count) {
            ci::sim::Simulation& simulation = s.get();
            if (count < 0) throw ci::Error("count = " + std::to_string(count) + " must be >= 0");
            if (count == 1) return simulation.step();
            Claim claim(s.running, "this Simulation");
            py::gil_scoped_release release;
            for (std::int64_t k = 0; k < count; ++k) simulation.step();
          },
          py::arg("count") = 1,
          "Advances by `count` timesteps at the commanded torque (releases the GIL).")
      .def(
          "run",
          [](Sim& self, Loop& control, Real seconds_object, bool until_trajectory_done) {
            ci::sim::Simulation& simulation = self.get();
            ci::ControlLoop& loop = control.cycle();
            const double seconds = read_scalar(seconds_object, "seconds");
            if (!(seconds >= 0.0) || !std::isfinite(seconds)) {
              throw ci::Error("seconds = " + ci::format_number(seconds) +
                              " must be finite and >= 0");
            }
            if (simulation.joint_names() != loop.model().joint_names()) {
              throw ci::Error("the simulation exchanges joints " +
                              std::string(py::str(py::cast(simulation.joint_names()))) +
                              " but the control loop's model has " +
                              std::string(py::str(py::cast(loop.model().joint_names()))) +
                              ": load the simulation with joint_names=loop.model.joint_names");
            }
            if (!loop.started()) {
              throw std::runtime_error(
                  "the control loop has not been started: call loop.start(sim.q, sim.dq) first");
            }
            ci::sim::ClosedLoopRunner runner(simulation, loop);  // may throw: GIL still held
            Claim simulation_claim(self.running, "this Simulation");
            Claim loop_claim(control.running, "this ControlLoop");
            py::gil_scoped_release release;
            const std::int64_t done = runner.run_for(seconds, [&](std::int64_t steps_done) {
              if (until_trajectory_done) {
                const ci::TrajectoryState state = loop.state().trajectory.state;
                if (state != ci::TrajectoryState::executing && state != ci::TrajectoryState::idle) {
                  runner.request_stop();
                }
              }
              if (steps_done % kSignalCheckSteps == 0) {
                py::gil_scoped_acquire acquire;
                if (PyErr_CheckSignals() != 0) throw py::error_already_set();
              }
            });
            return done;
          },
          py::arg("loop"), py::arg("seconds"), py::arg("until_trajectory_done") = false,
          "Closed loop for `seconds` of simulated time, in C++ with the GIL released: each "
          "timestep tau = loop.step(sim.q, sim.dq, timestep), set_torque(tau), step(). Other "
          "threads may send the loop commands meanwhile. until_trajectory_done: stop early once "
          "a trajectory is no longer executing (finished, aborted or cancelled). The loop must "
          "be started and have the simulation's joints in the same order. Returns the number of "
          "steps run. Ctrl+C interrupts it (checked every 1000 steps).")
      .def(
          "push",
          [](Sim& s, const std::string& name, ArrayLike wrench, Real duration) {
            ci::Vector6d values;
            read_vector(wrench, "wrench", Length{6}, values);
            s.get().push(name, values, read_scalar(duration, "duration"));
          },
          py::arg("body_or_site"), py::arg("wrench"),
          py::arg("duration") = std::numeric_limits<double>::infinity(),
          "Applies wrench [force; torque] (6,) [N; Nm], world frame, at the origin of the named "
          "site (or body) for `duration` [s] of simulated time from the next step (default: "
          "until clear_pushes()). The point moves with the body; pushes add up.")
      .def(
          "clear_pushes", [](Sim& s) { s.get().clear_pushes(); }, "Removes every push.")
      .def(
          "site_pose", [](Sim& s, const std::string& name) { return s.get().site_pose(name); },
          py::arg("site"), "Pose of a site in the world frame (quaternion x, y, z, w).")
      .def(
          "body_pose", [](Sim& s, const std::string& name) { return s.get().body_pose(name); },
          py::arg("body"), "Pose of a body in the world frame (quaternion x, y, z, w).")
      .def(
          "contact_wrench",
          [](Sim& s, const std::string& body) {
            return vector_array(s.get().contact_wrench(body));
          },
          py::arg("body"),
          "Total contact wrench [force; torque] (6,) [N; Nm] that everything else exerts on the "
          "body (and bodies welded to it): world frame, torque about the body origin.")
      .def(
          "contact_wrench_beyond",
          [](Sim& s, const std::string& body) {
            return vector_array(s.get().contact_wrench_beyond(body));
          },
          py::arg("body"),
          "What a force-torque sensor in the body measures: contact_wrench() plus the contacts of "
          "every body below it (a hand's fingers on joints of their own).")
      .def(
          "has_collision_geometry",
          [](Sim& s, const std::string& body) { return s.get().has_collision_geometry(body); },
          py::arg("body"),
          "Whether the body or a body welded to it has collision geometry (a URDF link without "
          "<collision> has none: nothing presses on it).")
      .def(
          "track_contact_wrench",
          [](Sim& s, const std::string& body) { s.get().track_contact_wrench(body); },
          py::arg("body"),
          "From now on every step (also inside run() and BatchRunner.run()) adds the body's "
          "contact_wrench after it; take_mean_contact_wrench() gives the mean. One body at a "
          "time; '' stops. Raises Error for an unknown body.")
      .def(
          "take_mean_contact_wrench",
          [](Sim& s) { return vector_array(s.get().take_mean_contact_wrench()); },
          "The mean contact wrench (6,) [N; Nm] of the tracked body over the steps since the "
          "previous take (or track_contact_wrench(), or reset()), and a new mean begins; zeros "
          "if no step ran. Raises Error if no body is tracked.")
      .def(
          "render_png",
          [](Sim& s, PathLike path, int width, int height, const std::string& camera) {
            const ci::sim::Simulation& simulation = s.get();
            const std::string file = read_path(path, "path");
            Claim claim(s.running, "this Simulation");
            py::gil_scoped_release release;
            simulation.render_png(file, width, height, camera);
          },
          py::arg("path"), py::arg("width") = 640, py::arg("height") = 480, py::arg("camera") = "",
          "Renders offscreen (EGL) to an RGB PNG of width x height pixels; camera: an MJCF "
          "camera name, '' = a free camera from the robot's right. Releases the GIL.")
      .def("__repr__", [](Sim& s) {
        if (const char* by = s.running.load())
          return std::string("Simulation(in use by ") + by + ")";
        const ci::sim::Simulation& simulation = s.sim;
        return "Simulation('" + simulation.model_name() + "', " +
               ci::sim::engine_name(simulation.engine()) + ", " +
               std::to_string(simulation.num_joints()) +
               " joints, t = " + ci::format_number(simulation.time()) + " s, timestep " +
               ci::format_number(simulation.timestep()) + " s)";
      });

  sim.def(
      "offscreen_rendering_available",
      []() {
        std::string reason;
        const bool available = ci::sim::offscreen_rendering_available(&reason);
        return std::make_pair(available, reason);
      },
      "(available, reason): whether render_png() can work in this process, and why not.");
  sim.def(
      "engine_available",
      [](const std::string& name) {
        std::string reason;
        const bool available = ci::sim::engine_available(ci::sim::engine_from_name(name), &reason);
        return std::make_pair(available, reason);
      },
      py::arg("engine"),
      "(available, reason): whether this build can simulate with the engine 'mujoco' or 'dart', "
      "and why not. Raises Error for an unknown name.");

  bind_batch(sim);
  bind_simulated_driver(sim);
}

}  // namespace cartesian_impedance::python
