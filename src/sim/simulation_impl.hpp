#pragma once
// Internal to the sim target: what Simulation holds behind its pointer, and the helpers the
// sources share. Not installed.

#include <mujoco/mujoco.h>

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "plant_state.hpp"
#include "renderer.hpp"

namespace tinyxml2 {
class XMLElement;
}

namespace cartesian_impedance::sim {
namespace detail {

struct ModelDeleter {
  void operator()(mjModel* model) const noexcept { mj_deleteModel(model); }
};
struct DataDeleter {
  void operator()(mjData* data) const noexcept { mj_deleteData(data); }
};
using ModelPtr = std::unique_ptr<mjModel, ModelDeleter>;
using DataPtr = std::unique_ptr<mjData, DataDeleter>;

/// While alive, a fatal MuJoCo error (mju_error, whose default handler ends the process) throws
/// Error instead. MuJoCo's own Python bindings do the same. Not thread-safe: the handler is a
/// process-wide pointer.
class MujocoErrorTrap {
 public:
  MujocoErrorTrap() noexcept;
  ~MujocoErrorTrap();
  MujocoErrorTrap(const MujocoErrorTrap&) = delete;
  MujocoErrorTrap& operator=(const MujocoErrorTrap&) = delete;

 private:
  void (*previous_)(const char*);
};

/// What a scene is made of, for an engine that loads URDF files itself (DART): the robots with
/// their prefixes and bases, and the boxes. Names match the MuJoCo scene built from the same.
struct UrdfScene {
  std::vector<SceneRobot> robots;
  std::vector<Box> boxes;
  std::vector<std::string> warnings;  ///< Simulation::warnings() of the scene
};

/// Compiles `path` (looked up in `vfs` first when given) and builds the simulation.
/// `kind` ("MJCF", "URDF", "scene") only shapes error messages. `urdf_scene` describes the same
/// scene from its URDF files (nullptr for an MJCF model, which only MuJoCo can simulate).
/// `uncompensated_bodies`: bodies (attached boxes) whose weight the gravity compensation leaves
/// out.
Simulation load_simulation(const std::string& path, const mjVFS* vfs, const std::string& kind,
                           SimulationOptions options, const UrdfScene* urdf_scene = nullptr,
                           const std::vector<std::string>& uncompensated_bodies = {});

/// The name of attached box `index`: its own, or "attached_box_<index>".
std::string attached_name(const AttachedBox& box, std::size_t index);
/// Checks every attached box; errors name `field`[i] and the member.
void check_attached(const std::vector<AttachedBox>& attached, const std::string& field);
/// The MJCF `document` with each box welded to its body as a body of its own (inertial and box
/// geom). Checks them first.
/// @throw Error naming `field`[i] for a bad box or a body `source` does not have.
std::string attach_boxes(const std::string& document, const std::vector<AttachedBox>& attached,
                         const std::string& field, const std::string& source);

/// A MuJoCo virtual file system holding one document (about 2 MB: kept off the stack).
class VirtualFile {
 public:
  VirtualFile(const std::string& name, const std::string& content);
  ~VirtualFile();
  VirtualFile(const VirtualFile&) = delete;
  VirtualFile& operator=(const VirtualFile&) = delete;
  const mjVFS* vfs() const noexcept { return vfs_.get(); }

 private:
  std::unique_ptr<mjVFS> vfs_;
};

/// What a URDF lacks for a simulation, filled in by mjcf_from_urdf() where the URDF gives none.
struct UrdfImportOptions {
  double armature = 0.1;  ///< [kg m^2] reflected rotor inertia per joint
  double damping = 0.5;   ///< [N m s/rad] joint damping
  /// SimulationOptions::boxes_for_missing_meshes; each replacement is appended to `warnings`
  /// (if given).
  bool boxes_for_missing_meshes = false;
  std::vector<std::string>* warnings = nullptr;
};

/// The file a URDF <mesh filename> names, found as ROS tools find it: `package://NAME/rest` in
/// each ROS_PACKAGE_PATH entry (NAME/rest, or rest if the entry is the package NAME itself), in
/// each AMENT_PREFIX_PATH entry's share/NAME, then in a folder NAME beside or above the URDF's
/// folder (or the URDF's folder or one above it named NAME); `file://PATH` and plain paths as
/// they are if absolute, else against the URDF's folder. Returns the absolute path of a regular
/// file that MuJoCo 2.2 reads: the file itself if STL, OBJ or MSH, else its converted_mesh()
/// (COLLADA and the other formats assimp reads); throws Error naming `link`, the URI and every
/// place looked otherwise.
std::string resolve_mesh_file(const std::string& uri, const std::string& urdf_path,
                              const std::string& link);

/// A binary STL copy of the mesh file `source` (any format assimp reads; COLLADA with its
/// <unit> applied and its axes kept), in a cache folder under the temporary folder; `what`
/// ("link 'l': mesh 'uri'") names it in errors.
/// @throw Error if assimp cannot read the file or the copy cannot be written.
std::string converted_mesh(const std::string& source, const std::string& what);

/// Removes every <visual> of the <robot> element `robot` (parsed from `urdf_path`; not simulated)
/// and replaces every <collision> mesh's filename by its absolute path (resolve_mesh_file()), so
/// that both engines load the meshes the URDF names. Throws one Error naming every mesh that
/// cannot be used, before anything is loaded; or, with options.boxes_for_missing_meshes, gives
/// each link with such a mesh the box of its inertia instead and says so in options.warnings.
void resolve_collision_meshes(tinyxml2::XMLElement* robot, const std::string& urdf_path,
                              const UrdfImportOptions& options = {});

/// Gives every <inertial> of the <robot> element `robot` (parsed from `urdf_path`) the tensor
/// physical_link_inertia() makes of it, as the controller's RobotModel does (which reports the
/// repairs in RobotModel::warnings()): the model and both engines simulate the same arm.
/// @throw Error naming the URDF, the link and the value for an inertial it refuses.
void apply_physical_inertias(tinyxml2::XMLElement* robot, const std::string& urdf_path);

/// MJCF text of the robot in `urdf_path` with every link kept as a body (fixed joints too),
/// armature and damping on each joint, non-colliding arm geoms, a floor, lights and a sky.
std::string mjcf_from_urdf(const std::string& urdf_path, const UrdfImportOptions& options);

/// "a, b, c" of every named object of `type` (mjtObj), "(none)" if there is none.
std::string list_names(const mjModel* model, int type);

/// A physics engine other than MuJoCo's own. The MuJoCo model and data of Simulation::Impl
/// still hold the scene: the engine writes its state into `data` (qpos, qvel, time) after each
/// step, so names, kinematics and rendering work unchanged.
class Physics {
 public:
  virtual ~Physics() = default;
  virtual Engine engine() const noexcept = 0;
  /// Takes over qpos and qvel of every joint from `impl.data`; no contacts until the next step.
  virtual void set_state(const Simulation::Impl& impl) = 0;
  /// Applies the commanded torque, gravity compensation and pushes of `impl`, advances by one
  /// timestep and writes the new state into impl.data (qpos, qvel, time) and the torque the
  /// links took from their joints into impl.true_torque.
  virtual void step(Simulation::Impl& impl) noexcept = 0;
  /// Pose of MuJoCo body `body` (an id) in the world.
  virtual Pose body_pose(int body) const = 0;
  /// Contact wrench on the bodies whose MuJoCo weld id is `weld`, torque about `origin`.
  // `beyond`: also the contacts of every body below the weld in the tree (a hand's fingers).
  virtual Vector6d contact_wrench(int weld, const Eigen::Vector3d& origin, bool beyond) const = 0;
};

/// DART behind the scene of `impl` (whose joints, armature, damping and friction it copies).
/// @throw Error naming the engine if DART is not built in or cannot load or build the scene.
std::unique_ptr<Physics> make_dart_physics(const UrdfScene& scene, const Simulation::Impl& impl);

}  // namespace detail

/// An active push: a world-frame wrench at a point fixed in a body.
struct Push {
  int body = 0;
  int site = -1;  // point of application: this site's origin, or the body's origin if -1
  Vector6d wrench_world = Vector6d::Zero();
  double end_time = 0.0;  // active while time < end_time - timestep / 2
};

struct Simulation::Impl {
  detail::ModelPtr model;
  detail::DataPtr data;
  std::string source;  // file the model came from, for messages
  std::string model_name;
  SimulationOptions options;
  std::vector<std::string> warnings;  // Simulation::warnings()
  int keyframe_id = -1;               // -1: default qpos

  std::vector<std::string> joint_names;
  std::vector<int> joint_ids;     // MuJoCo joint id per exchanged joint
  std::vector<int> qpos_address;  // index into qpos
  std::vector<int> dof_address;   // index into qvel, qfrc_*
  std::vector<int> actuator_ids;  // -1: torque through qfrc_applied
  JointVector ctrl_per_torque;    // ctrl = tau * ctrl_per_torque for actuated joints

  JointVector q, dq;            // what the sensors read (the plant's delay and noise)
  JointVector true_q, true_dq;  // the engine's state
  JointVector measured_torque;  // what the joint torque sensors read (measured_torque())
  // What the link side of each joint took in the last step (Physics::step writes it): the
  // drive's torque and the firmware's compensation, less friction, damping and rotor inertia.
  JointVector true_torque;
  JointVector tau;                    // torque acting in the next step (after clipping)
  JointVector tau_command;            // what set_torque() was given last (after clipping)
  JointVector tau_lower, tau_upper;   // joint torque range
  JointVector model_armature;         // before the plant's model error
  detail::PlantState plant;           // delays and noise between the engine and the controller
  std::vector<int> perturbed_bodies;  // bodies whose inertia the plant changed

  std::vector<Push> pushes;
  // (exchanged joint, attached body) for every attached body in that joint's subtree: the
  // firmware's compensation takes their weight back out (they are a load it does not know).
  std::vector<std::pair<int, int>> uncompensated;
  bool gravity_on = false;  // compensation requested and gravity enabled in the model
  mutable bool kinematics_current = true;  // xpos, site_xpos, ... belong to the current qpos

  std::unique_ptr<detail::Physics> physics;  // null: MuJoCo integrates

  // track_contact_wrench(): the body (-1: none), and the sum of its contact wrench after each
  // step since the last take_mean_contact_wrench() or reset().
  int tracked_body = -1;
  Vector6d tracked_sum = Vector6d::Zero();
  std::int64_t tracked_steps = 0;

  mutable std::unique_ptr<detail::Renderer> renderer;  // created by the first render_png()
  mutable detail::DataPtr ghost_data;  // kinematics of a render's ghost, made when first needed

  void reset();
  // The engine's state into true_q, true_dq and through the plant into q, dq; `restart`: every
  // delayed reading becomes this state (reset, set_state), `reseed`: the noise starts over.
  void read_state(bool restart = false, bool reseed = true) noexcept;
  void apply_inputs() noexcept;  // needs kinematics and subtree_com of the current qpos
  // true_torque after MuJoCo's own step, `dq_before` the velocities it started from.
  void sense_torque(const JointVector& dq_before) noexcept;
  void expire_pushes() noexcept;  // drops the pushes that end before the next step
  void update_kinematics() const noexcept;
  int find_body(const std::string& name) const;  // throws Error naming the body
  Vector6d contact_wrench(int body, bool beyond = false) const noexcept;
};

}  // namespace cartesian_impedance::sim
