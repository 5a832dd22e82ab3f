#pragma once
// Internal to the sim target: what Simulation holds behind its pointer, and the helpers the
// sources share. Not installed.

#include <mujoco/mujoco.h>

#include <memory>
#include <string>
#include <vector>

#include "cartesian_impedance/error.hpp"
#include "cartesian_impedance/sim/simulation.hpp"
#include "renderer.hpp"

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

/// Compiles `path` (looked up in `vfs` first when given) and builds the simulation.
/// `kind` ("MJCF", "URDF", "scene") only shapes error messages.
Simulation load_simulation(const std::string& path, const mjVFS* vfs, const std::string& kind,
                           SimulationOptions options);

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
};

/// MJCF text of the robot in `urdf_path` with every link kept as a body (fixed joints too),
/// armature and damping on each joint, non-colliding arm geoms, a floor, lights and a sky.
std::string mjcf_from_urdf(const std::string& urdf_path, const UrdfImportOptions& options);

/// "a, b, c" of every named object of `type` (mjtObj), "(none)" if there is none.
std::string list_names(const mjModel* model, int type);

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
  int keyframe_id = -1;  // -1: default qpos

  std::vector<std::string> joint_names;
  std::vector<int> joint_ids;     // MuJoCo joint id per exchanged joint
  std::vector<int> qpos_address;  // index into qpos
  std::vector<int> dof_address;   // index into qvel, qfrc_*
  std::vector<int> actuator_ids;  // -1: torque through qfrc_applied
  JointVector ctrl_per_torque;    // ctrl = tau * ctrl_per_torque for actuated joints

  JointVector q, dq;
  JointVector tau;                   // applied commanded torque (after clipping)
  JointVector tau_lower, tau_upper;  // joint torque range

  std::vector<Push> pushes;
  bool gravity_on = false;  // compensation requested and gravity enabled in the model
  mutable bool kinematics_current = true;  // xpos, site_xpos, ... belong to the current qpos

  mutable std::unique_ptr<detail::Renderer> renderer;  // created by the first render_png()
  mutable detail::DataPtr ghost_data;  // kinematics of a render's ghost, made when first needed

  void reset();
  void read_state() noexcept;
  void apply_inputs() noexcept;  // needs kinematics and subtree_com of the current qpos
  void update_kinematics() const noexcept;
  int find_body(const std::string& name) const;  // throws Error naming the body
};

}  // namespace cartesian_impedance::sim
