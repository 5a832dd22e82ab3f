#pragma once
/// @file
/// Simulation of a torque-controlled arm: joint torques in, joint positions and velocities out,
/// with gravity compensation done the way Panda and iiwa firmware do it, external pushes, static
/// boxes (tables, walls) to touch, contact wrenches and offscreen rendering.
///
/// Two physics engines: MuJoCo and DART (SimulationOptions::engine). MuJoCo always holds the
/// scene (names, joint parameters, rendering); with DART, DART loads the same URDF files itself
/// and integrates the motion and the contacts, and MuJoCo draws DART's state.
///
/// This header includes neither engine; users need only Eigen. Loaders and setters validate and
/// throw `cartesian_impedance::Error`; `step()` is noexcept and allocates nothing.
///
/// Frames: every pose, force and wrench here is in MuJoCo's world frame. For the project's robot
/// files the robot base sits at the world origin, so world = base frame of the controller.
/// Wrenches are ordered `[force; torque]` [N; Nm].

#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "cartesian_impedance/core/types.hpp"
#include "cartesian_impedance/sim/engine.hpp"
#include "cartesian_impedance/sim/plant.hpp"

namespace cartesian_impedance::sim {

/// Whether this build can simulate with `engine` (MuJoCo always; DART if it was built with
/// CARTESIAN_IMPEDANCE_BUILD_DART). If not and `reason` is given, it receives why.
bool engine_available(Engine engine, std::string* reason = nullptr);

/// How a model is turned into a simulation. Fixed at construction.
struct SimulationOptions {
  /// Integration step [s]; replaces the model's own (MuJoCo's default for URDF is 2 ms).
  double timestep = 0.001;
  /// Like the Panda and iiwa firmware: each exchanged joint receives tau + g(q), where g(q) is the
  /// gravity part of MuJoCo's bias force (no Coriolis), recomputed every step at the current q.
  /// It is applied through qfrc_applied, so it is not limited by the actuator range.
  bool gravity_compensation = true;
  /// Reset to this keyframe if the model has one of that name; otherwise (or "") the model's
  /// default qpos (q = 0 for the project's robots, which violates the Panda's joint-4 range).
  std::string keyframe = "ready";
  /// Order in which q, dq and tau are exchanged, matched to MuJoCo joints by name. Empty: the
  /// model's hinge and slide joints in model order.
  std::vector<std::string> joint_names;
  /// Start configuration of the exchanged joints [rad or m], applied on top of the keyframe (or
  /// the default qpos) at construction and by reset(). Empty: the keyframe's (or q = 0). Each
  /// value must lie within its joint's range where the joint is limited.
  JointVector start_q;
  /// Reflected rotor inertia per exchanged joint [kg m^2 or kg] (MuJoCo's armature), replacing
  /// the model's: one value for every joint or one per joint. Empty: the model's own (a URDF gets
  /// 0.1 kg m^2 on each joint, as it carries none). Keep it equal to the controller's
  /// dynamics.armature: the controller's M(q) then is the simulated one.
  JointVector armature;
  /// MuJoCo's multi-point convex collision detection (mjENBL_MULTICCD, "experimental" in 2.2):
  /// a flat face resting on a flat face (the flange on a table) gets several contact points
  /// instead of one that jumps across the face, which makes the contact force steady (measured:
  /// Panda flange pressed on a table with 20 N, +-1.5 % instead of +-12 % step to step). About
  /// doubles the cost of a step while in contact; no cost without contact.
  bool multi_point_contacts = true;
  /// The physics engine. With Engine::dart the robot must come from URDF (from_urdf_file(),
  /// make_scene() with a URDF robot, make_robots_scene()); DART then parses it with its own
  /// loader, and takes from the MuJoCo scene only each joint's armature, damping and friction
  /// (DART 6.12 has no armature: it is added to each joint's articulated inertia, which is where
  /// a rotor's reflected inertia acts). Contacts and joint friction are DART's hard
  /// complementarity constraints instead of MuJoCo's soft ones.
  Engine engine = Engine::mujoco;
  /// A URDF <collision> mesh that cannot be found or read: false refuses the URDF (naming every
  /// such mesh and every place looked); true simulates the link with one box instead, the
  /// uniform box of the link's own mass and principal moments (placed and turned as its
  /// inertial), so that the controller can be tried before the meshes are in place. Each
  /// replacement is listed in Simulation::warnings(); a link without mass loses the geometry.
  bool boxes_for_missing_meshes = false;
  /// How the simulated arm differs from its model and how its sensors and drives behave (model
  /// error, delays, noise; plant.hpp). Default: the nominal plant, the model itself read at once.
  PlantOptions plant;
};

/// An arrow drawn into a picture: a force (or any vector) acting at a point.
struct RenderArrow {
  Eigen::Vector3d from = Eigen::Vector3d::Zero();    ///< tail, world frame [m]
  Eigen::Vector3d vector = Eigen::Vector3d::Zero();  ///< e.g. a force [N]; zero: not drawn
  /// Drawn length per unit of `vector` [m per unit]: 0.01 draws 20 N as 0.2 m.
  double scale = 0.01;
  Eigen::Vector4f rgba = Eigen::Vector4f(0.9f, 0.1f, 0.1f, 1.0f);
  std::string label;  ///< written at the arrow's head ("" none)
};

/// An axis-aligned box drawn by its twelve edges, e.g. the safety layer's workspace.
struct RenderBox {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();  ///< lower corner, world frame [m]
  Eigen::Vector3d max = Eigen::Vector3d::Zero();  ///< upper corner, world frame [m]
  Eigen::Vector4f rgba = Eigen::Vector4f(0.95f, 0.75f, 0.1f, 1.0f);
  std::string label;  ///< written at the upper corner ("" none)
};

/// A pose drawn as an axes triad: x red, y green, z blue.
struct RenderFrame {
  Pose pose;             ///< world frame
  double length = 0.12;  ///< of each axis [m]
  float alpha = 1.0f;    ///< below 1: translucent
  std::string label;     ///< written at the origin ("" none)
};

/// What a picture shows on top of the scene. Everything is optional; the default is the plain
/// scene.
struct RenderOverlay {
  /// Text in the top-left corner; lines separated by '\n', the first one in a larger font.
  std::string caption;
  std::vector<RenderArrow> arrows;
  std::vector<RenderFrame> frames;
  /// A translucent copy of the robot with its exchanged joints at these positions (same order
  /// as Simulation::joint_names()), e.g. where it was before a push. Empty: none.
  JointVector ghost_q;
  /// Free camera direction [deg] (MuJoCo's azimuth and elevation); NaN: the default view from
  /// the robot's right side. The distance is always chosen to fit the whole scene.
  double azimuth = std::numeric_limits<double>::quiet_NaN();
  double elevation = std::numeric_limits<double>::quiet_NaN();
  std::vector<RenderBox> boxes;
};

/// A simulated robot. Movable, not copyable, not thread-safe (one thread drives it). Loading and
/// the first render_png() briefly replace MuJoCo's process-wide error handler (so that MuJoCo
/// errors become `Error` instead of ending the process): do those from one thread at a time.
class Simulation {
 public:
  /// Loads an MJCF file. Each exchanged joint is driven by the `<motor>` acting on it (matched
  /// through its transmission, not its name; the torque is converted with the motor's gear and
  /// gain and limited to its ctrlrange/forcerange), or, if no actuator acts on it, through
  /// MuJoCo's `qfrc_applied`.
  /// @throw Error if the file does not exist or does not compile, a joint name is unknown or not
  ///        a hinge/slide joint, an actuator on an exchanged joint is not a plain torque motor, or
  ///        the options are invalid.
  static Simulation from_mjcf_file(const std::string& path, SimulationOptions options = {});

  /// Loads a URDF with MuJoCo's URDF importer. URDF has no actuators, so every torque goes through
  /// `qfrc_applied` and is not limited; there is no floor and no keyframe (q starts at 0).
  /// @throw Error as from_mjcf_file().
  static Simulation from_urdf_file(const std::string& path, SimulationOptions options = {});

  Simulation(Simulation&&) noexcept;
  Simulation& operator=(Simulation&&) noexcept;
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;
  ~Simulation();

  int num_joints() const noexcept;
  /// Joint names in the order q, dq and tau are exchanged.
  const std::vector<std::string>& joint_names() const noexcept;
  /// Simulated time since construction or the last reset() [s].
  double time() const noexcept;
  /// Integration step [s].
  double timestep() const noexcept;

  /// Joint positions [rad or m] and velocities [rad/s or m/s], in joint_names() order, as the
  /// robot's sensors report them: with a plant that is not nominal, late, noisy and quantised
  /// (SimulationOptions::plant); what a controller reads.
  const JointVector& q() const noexcept;
  const JointVector& dq() const noexcept;
  /// The joints' actual positions and velocities (what q() and dq() are for the nominal plant).
  const JointVector& true_q() const noexcept;
  const JointVector& true_dq() const noexcept;

  /// Sets positions and velocities of the exchanged joints (other degrees of freedom keep theirs)
  /// and recomputes every derived quantity (poses, contacts). Time is not changed. A plant's
  /// delayed readings all become this state, as if the arm had rested there, and a torque still
  /// on its way to the joints is dropped.
  /// @throw Error on a wrong size or a non-finite value (nothing is changed then).
  void set_state(const JointVector& q, const JointVector& dq);

  /// Back to the keyframe of the options (or the default qpos) at time 0: zero torque, no pushes.
  void reset();

  /// Commands joint torques tau [Nm or N], applied from the next step() until changed (gravity
  /// compensation, when on, comes on top). Like a real drive, each value is clipped to the
  /// torque range of its actuator (joints without an actuator are not limited).
  /// @return true if any value was clipped; torque() holds what is applied.
  /// @throw Error on a wrong size or a non-finite value (the previous torque stays then).
  bool set_torque(const JointVector& tau);

  /// The commanded torque on the joints, after clipping [Nm or N] (without gravity
  /// compensation): for a plant without actuation delay and torque noise what set_torque() set
  /// (it acts from the next step); with them, what acted in the last step (the torque set that
  /// many steps before, with its noise).
  const JointVector& torque() const noexcept;
  /// What a joint torque sensor on the link side of each drive reads [Nm or N], as Franka's
  /// tau_J: the drive's torque and the firmware's gravity compensation less what the joint's
  /// friction, damping and rotor inertia took in the last step; so gravity's part is in it, and
  /// a contact shows through the links' motion. With the plant's measurement_delay and
  /// torque_sensor_noise, like q() and dq(). After reset() or set_state(): what holds the arm
  /// there. ControlLoop::step() takes it for collision.measured_torque.
  const JointVector& measured_torque() const noexcept;
  /// Torque range per joint [Nm or N]; -inf/+inf where the joint has no limited actuator.
  const JointVector& torque_lower_limits() const noexcept;
  const JointVector& torque_upper_limits() const noexcept;

  /// Advances by one timestep: gravity compensation and pushes are evaluated at the current state,
  /// then the engine integrates. No exception; with MuJoCo no allocation (DART's collision
  /// detection and constraint solver allocate while the robot touches something).
  void step() noexcept;

  /// Applies `wrench_world` = [force; torque] [N; Nm] (world frame) at the origin of the named
  /// site, or of the named body if no site has that name, for `duration` [s] of simulated time
  /// starting with the next step() (+infinity: until clear_pushes()). The point of application
  /// moves with the body. Several pushes add up.
  /// @throw Error if the name is unknown, the wrench is not finite or duration is not > 0.
  void push(const std::string& body_or_site, const Vector6d& wrench_world, double duration);
  /// Removes every push.
  void clear_pushes() noexcept;

  /// Pose of a site or a body (origin and orientation) in the world frame, at the current q.
  /// @throw Error if the name is unknown.
  Pose site_pose(const std::string& site) const;
  Pose body_pose(const std::string& body) const;

  /// Whether `body`, or a body welded to it, has geometry that can touch the environment. A
  /// URDF link without <collision> (or whose meshes were stripped) has none: nothing presses on
  /// it, and contact_wrench() stays zero.
  /// @throw Error if the name is unknown.
  bool has_collision_geometry(const std::string& body) const;

  /// Total contact wrench [N; Nm] that everything else exerts on `body` and on the bodies welded
  /// to it (bodies without joints move with their parent, so the massless flange body
  /// `panda_link8` reports the contacts of `panda_link7`'s geoms). World frame, torque about the
  /// origin of `body`. MuJoCo: computed with mj_contactForce from the contacts of the last step()
  /// or set_state(). DART: the contact impulses of the last step() divided by the timestep (zero
  /// right after set_state() or reset(), as DART solves contacts only while stepping).
  /// @throw Error if the body is unknown.
  Vector6d contact_wrench(const std::string& body) const;
  /// What the loading changed in the robot's description, one sentence each (today: meshes
  /// replaced by boxes, see SimulationOptions::boxes_for_missing_meshes). Inertias repaired
  /// alike in the model are in RobotModel::warnings().
  const std::vector<std::string>& warnings() const noexcept;

  /// What a force-torque sensor in `body` measures: as contact_wrench(), plus the contacts of
  /// every body below it in the tree (a hand's fingers on their own joints). The demo presses
  /// with the flange this way: a hand's fingertips touch first.
  /// @throw Error if the body is unknown.
  Vector6d contact_wrench_beyond(const std::string& body) const;

  /// Averages contact_wrench(body) over steps without a call per step (so that a batch of
  /// simulations run by BatchRunner can measure it): from now on each step() adds the body's
  /// contact wrench after it, and take_mean_contact_wrench() returns the mean over the steps
  /// since the previous take (or since this call, or reset()) and starts a new mean. A contact
  /// force that alternates from one step to the next, as MuJoCo's on a sliding body does, means
  /// something only as such a mean. One body at a time; "" stops tracking.
  /// @throw Error if the body is unknown (the tracking is then unchanged).
  void track_contact_wrench(const std::string& body);
  /// The mean [N; Nm] (world frame, torque about the body's origin) of the tracked body's
  /// contact wrench over the steps since the previous take; zero if no step ran since.
  /// @throw Error if no body is tracked.
  Vector6d take_mean_contact_wrench();

  /// Renders the scene offscreen (EGL, no display needed) and writes an RGB PNG of
  /// width x height pixels. `camera` names an MJCF camera; "" is a free camera looking at the
  /// scene from the robot's right side, at a distance that fits every body of the scene (every
  /// robot's base and tip) into the picture. The first call sets up an OpenGL context (about
  /// 0.5 s with Mesa's software renderer); later calls reuse it. Floor reflections are not drawn
  /// (a mirrored arm reads as a second arm).
  /// @throw Error if EGL/OpenGL is unavailable (the message says why), the camera is unknown, the
  ///        size is not in [1, 8192] or the file cannot be written.
  void render_png(const std::string& path, int width, int height,
                  const std::string& camera = "") const;
  /// The same, with a caption, arrows, frames and a ghost of the robot drawn into the picture
  /// (the free camera fits them in too).
  /// @throw Error as above, or if the ghost's size is not num_joints() or a value is not finite.
  void render_png(const std::string& path, int width, int height, const RenderOverlay& overlay,
                  const std::string& camera = "") const;

  /// Rotor inertia (MuJoCo's armature) per exchanged joint [kg m^2 or kg], as simulated: with a
  /// plant's model error (SimulationOptions::plant) the drawn one.
  JointVector armature() const;
  /// The rotor inertia before the plant's model error (armature() for the nominal plant): what
  /// the controller's dynamics.armature should be for this robot, as a datasheet gives it.
  const JointVector& model_armature() const noexcept;
  /// [s] how old q() and dq() are when read: the plant's measurement delay in whole timesteps
  /// (0 for the nominal plant). A driver stamps its readings with it.
  double measurement_age() const noexcept;
  /// [s] how late a torque set acts: the plant's actuation delay in whole timesteps. With
  /// measurement_age() the loop's delay, the controller's safety.passivity.delay.
  double actuation_delay() const noexcept;
  /// Coulomb friction (MuJoCo's frictionloss) per exchanged joint [Nm or N]: the torque below
  /// which a joint at rest does not move, so a spring holds it only up to this.
  JointVector friction_loss() const;
  /// Viscous damping (MuJoCo's damping) per exchanged joint [Nm s/rad or N s/m]; DART uses the
  /// same.
  JointVector joint_damping() const;

  /// MuJoCo's model name (the `model` attribute of `<mujoco>` or the URDF robot name).
  const std::string& model_name() const noexcept;

  /// The physics engine integrating this simulation.
  Engine engine() const noexcept;

  /// Internal: MuJoCo model, data and bookkeeping (defined in the sim sources; users cannot
  /// create one, so they use the factories above).
  struct Impl;
  explicit Simulation(std::unique_ptr<Impl> impl) noexcept;

 private:
  std::unique_ptr<Impl> impl_;
};

/// A static box in the world (a table, a wall, a step), colliding with the robot.
struct Box {
  std::string name;                                     ///< geom name; "" = "scene_box_<index>"
  Eigen::Vector3d center = Eigen::Vector3d::Zero();     ///< world frame [m]
  Eigen::Vector3d half_size = Eigen::Vector3d::Ones();  ///< half extents along the box axes [m]
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< box axes in the world
  /// How soft its surface is: the time constant [s] with which a contact on it pushes back
  /// (MuJoCo's solref[0], the box's over the robot's); 0: the engine's own contact (MuJoCo's
  /// 0.02 s). Larger is softer, as a square: at 0.05 s, the most allowed, a contact sinks 6.25
  /// times as deep as at 0.02 s for the same force (softer ones let a body sink through). MuJoCo
  /// only: DART's contacts are rigid, and it refuses a scene with a soft box.
  double time_constant = 0.0;

  /// A table standing on the floor (z = 0) whose top surface is at height `top_z` [m], centred at
  /// `center_xy` with half extents `half_size_xy` [m].
  static Box table(const Eigen::Vector2d& center_xy, const Eigen::Vector2d& half_size_xy,
                   double top_z, const std::string& name = "");
};

/// A box fixed to a body of a robot: a peg at the flange, a tool, a grasped part. It moves with
/// the body, collides with the scene's static boxes (not with the robot itself), and adds its
/// mass and inertia (a solid box of uniform density) to the body, on both engines: a body of
/// its own, named `name`, welded to `body` (body_pose() and contact_wrench() take that name; the
/// contact_wrench() of `body` includes it).
///
/// The simulated firmware's gravity compensation (SimulationOptions::gravity_compensation) does
/// not know it, as a real arm's firmware does not know an undeclared load: its weight pulls on
/// the arm unless the controller declares it (`payload.mass`, `payload.center_of_mass`).
struct AttachedBox {
  std::string name;  ///< its body and geom; "" = "attached_box_<index>" (with the robot's prefix)
  std::string body;  ///< the robot body (URDF link) it is fixed to, e.g. "panda_link8"
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< its centre in `body`'s frame [m]
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< its axes in `body`'s
  Eigen::Vector3d half_size = Eigen::Vector3d::Constant(0.01);      ///< half extents [m], each > 0
  double mass = 0.1;  ///< [kg] > 0; inertia m (b^2 + c^2) / 3 about its axes (half sizes a, b, c)
};

/// Loads the MJCF robot file with the boxes added to its world, without writing any file (the
/// combined document is held in MuJoCo's virtual file system, placed in the robot file's
/// directory so that its relative asset and include paths still resolve).
/// @throw Error as Simulation::from_mjcf_file(), or if a box has a non-finite value or a half
///        size that is not > 0, or the robot file is not MJCF.
Simulation make_scene(const std::string& robot_mjcf, const std::vector<Box>& boxes,
                      SimulationOptions options = {});

/// The same, with `attached` boxes fixed to bodies of the robot (with a URDF robot on either
/// engine). `options` has no default, so that make_scene(robot, boxes, {}) stays the call above. An
/// attached body must be written in the robot file itself (not in an <include>).
/// @throw Error as above, or naming attached[i] and the field: a body the robot does not have
///        (the message lists its bodies), a non-finite value, a half size or mass not > 0, a
///        name used twice or not fit for XML.
Simulation make_scene(const std::string& robot_mjcf, const std::vector<Box>& boxes,
                      const std::vector<AttachedBox>& attached, SimulationOptions options);

/// A robot of make_robots_scene().
struct SceneRobot {
  std::string urdf;    ///< URDF file, simulated as Simulation::from_urdf_file() would
  std::string prefix;  ///< put before each of its names: body "tool0" becomes "left_tool0"
  /// Its root link, world frame [m]. (Write Eigen::Vector3d::Zero(), not {}: an Eigen vector
  /// made from {} is left uninitialised.)
  Eigen::Vector3d base_position = Eigen::Vector3d::Zero();
  /// Boxes fixed to its bodies (AttachedBox::body without the prefix; their names get it too).
  std::vector<AttachedBox> attached = {};
};

/// Several URDF robots in one world (two copies of one arm side by side, or different arms), each
/// completed as Simulation::from_urdf_file() completes one, with the first one's floor, lights
/// and sky. Every body, joint, geom, site and mesh of a robot is named with its prefix, so
/// options.joint_names lists prefixed names ("left_shoulder_pan_joint"); left empty, the joints
/// are the robots' in the given order. The robots do not collide with each other.
/// @throw Error as Simulation::from_urdf_file() for a robot's file, for no robots, a prefix used
///        twice or not fit for XML, or a non-finite base position (each naming robots[i]).
Simulation make_robots_scene(const std::vector<SceneRobot>& robots, SimulationOptions options = {});

/// Whether offscreen rendering can work in this process (an EGL display and an OpenGL context
/// can be created). If not and `reason` is given, it receives why.
bool offscreen_rendering_available(std::string* reason = nullptr);

}  // namespace cartesian_impedance::sim
