#pragma once
/// @file
/// Robot model: the serial chain between a base link and a tip link of a URDF, loaded once, and a
/// per-cycle workspace that computes the end-effector pose, the geometric Jacobian and, on
/// request, the joint-space mass matrix, gravity and Coriolis torques (C dq and C^T dq).
///
/// The model is constant after construction and cheap to copy (copies share the loaded chain).
/// Each control loop or thread owns one ModelWorkspace, whose compute() allocates nothing, takes
/// no lock and never throws. Users of this header need only Eigen: the URDF parser (urdfdom) and
/// the dynamics library (KDL, kept as a selectable reference backend) stay private to the model
/// library.
///
/// Frames: every pose, Jacobian and gravity vector is expressed in the base frame (the frame of
/// `base_link`). Units: SI (m, rad, kg, N, Nm); prismatic joints are in m, m/s and N.

#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "cartesian_impedance/core/parameters.hpp"
#include "cartesian_impedance/core/types.hpp"

namespace cartesian_impedance {

/// Kind of a movable joint of the chain (fixed joints are part of the chain but not listed).
enum class JointType {
  revolute,    ///< rotation with position limits [rad]
  continuous,  ///< rotation without position limits [rad]
  prismatic    ///< translation along its axis [m]
};

/// "revolute", "continuous" or "prismatic".
const char* to_string(JointType type) noexcept;

/// Joint limits from the URDF, one entry per movable joint (base to tip).
struct JointLimits {
  JointVector position_lower;  ///< [rad or m]; -inf for continuous joints
  JointVector position_upper;  ///< [rad or m]; +inf for continuous joints
  JointVector velocity;        ///< [rad/s or m/s]; +inf where the URDF gives no <limit>
  JointVector effort;          ///< [Nm or N]; +inf where the URDF gives no <limit>
};

/// The dynamic terms a ModelWorkspace::compute call produces besides pose and Jacobian: a set of
/// bits, combined with | (e.g. ModelTerms::mass | ModelTerms::gravity). Each costs time, so the
/// control cycle asks only for what its options use.
enum class ModelTerms : unsigned {
  none = 0,
  mass = 1,      ///< M(q)
  gravity = 2,   ///< g(q)
  coriolis = 4,  ///< C(q, dq) dq
  /// C(q, dq)^T dq: what the generalized momentum M dq gains from the motion itself (dp/dt =
  /// tau - g + C^T dq + tau_ext), for a momentum observer. C is the Christoffel matrix, so that
  /// dM/dt = C + C^T.
  coriolis_transposed = 8,
  all = 15
};

constexpr ModelTerms operator|(ModelTerms a, ModelTerms b) noexcept {
  return static_cast<ModelTerms>(static_cast<unsigned>(a) | static_cast<unsigned>(b));
}
constexpr ModelTerms operator&(ModelTerms a, ModelTerms b) noexcept {
  return static_cast<ModelTerms>(static_cast<unsigned>(a) & static_cast<unsigned>(b));
}
constexpr ModelTerms operator~(ModelTerms a) noexcept {
  return static_cast<ModelTerms>(~static_cast<unsigned>(a) &
                                 static_cast<unsigned>(ModelTerms::all));
}
constexpr ModelTerms& operator|=(ModelTerms& a, ModelTerms b) noexcept {
  return a = a | b;
}
constexpr ModelTerms& operator&=(ModelTerms& a, ModelTerms b) noexcept {
  return a = a & b;
}
/// True if every term of `wanted` is in `terms`.
constexpr bool includes(ModelTerms terms, ModelTerms wanted) noexcept {
  return (terms & wanted) == wanted;
}

/// Which implementation computes a model's kinematics and dynamics.
enum class ModelBackend {
  native,  ///< the library's own algorithms for serial chains (default; several times faster)
  kdl      ///< the Orocos KDL solvers (FK, JntToJac, ChainDynParam), as a reference
};

/// "native" or "kdl".
const char* to_string(ModelBackend backend) noexcept;

/// What one call of ModelWorkspace::compute produces. Pose and Jacobian always; of mass, gravity
/// and the Coriolis terms only those requested (the others keep their previous values).
struct Kinematics {
  Pose pose;             ///< T_base_ee: tip link times the tool offset, in the base frame
  Jacobian jacobian;     ///< geometric, 6 x n, rows [linear; angular], reference point the
                         ///< end-effector (tool) origin, base frame
  JointMatrix mass;      ///< M(q) [kg m^2, kg m or kg], symmetric positive definite
  JointVector gravity;   ///< g(q) [Nm or N]: torques that hold the arm still against gravity
  JointVector coriolis;  ///< C(q, dq) dq [Nm or N]: Coriolis and centrifugal torques
  JointVector coriolis_transposed;  ///< C(q, dq)^T dq [Nm or N] (ModelTerms::coriolis_transposed)
  /// The terms among mass, gravity and the Coriolis terms that belong to the same q (and dq) as
  /// pose.
  ModelTerms terms = ModelTerms::none;
  /// true if mass, gravity and coriolis are current (C^T dq need not be: only an observer asks).
  bool has_dynamics = false;
};

namespace detail {
struct ModelData;
}

/// The kinematic and dynamic description of the chain base_link -> tip_link of a URDF, plus a
/// fixed tool offset. Constant after construction; copies share the loaded data.
///
/// What the chain contains: every joint from base_link down to tip_link (fixed ones too). The
/// inertia of each link is its own plus that of every link rigidly attached to it by fixed joints
/// but not on the chain (e.g. a hand fixed to the flange). Links beyond a movable joint that is
/// not on the chain (gripper fingers, side branches) and the base link itself are not part of
/// the dynamics.
class RobotModel {
 public:
  /// Loads the URDF file at `path` (see from_urdf_string for the arguments).
  /// @throw LoadError if the file does not exist or cannot be read, is not a regular file (a FIFO,
  ///        a device such as /dev/zero, a directory) or is larger than kMaxFileBytes (16 MiB; see
  ///        core/files.hpp), and for every reason listed at from_urdf_string; the message names
  ///        the path.
  static RobotModel from_urdf_file(
      const std::string& path, const std::string& base_link, const std::string& tip_link,
      const Eigen::Isometry3d& T_tip_tool = Eigen::Isometry3d::Identity(),
      const Eigen::Vector3d& gravity_base = Eigen::Vector3d(0.0, 0.0, -9.81));

  /// Builds the model of the chain from `base_link` down to `tip_link` of the URDF document `xml`.
  /// @param T_tip_tool  tool offset: the end-effector frame expressed in the tip-link frame [m]
  /// @param gravity_base  gravitational acceleration in the base frame [m/s^2]
  /// @throw Error if T_tip_tool is not a finite rigid transform or gravity_base is not finite.
  /// @throw LoadError if the text is not well-formed XML or not a URDF (urdfdom's own words);
  ///        if it contains a NUL byte, is not valid UTF-8 (or has U+FEFF, U+FFFE or U+FFFF after
  ///        its start), nests XML elements more than 100 deep, has an element with more than 64
  ///        attributes, a malformed character reference (&#...;), a comment, tag or quoted value
  ///        that is never closed, or an XML declaration other than a plain one at its start
  ///        (these are checked before the XML parser runs; the message gives the line);
  ///        if its joints do not form a tree: two joints with one name, a joint from a link to
  ///        itself, a link with two parent joints, or a loop of links anywhere in the file (the
  ///        joints and links are named);
  ///        if base_link or tip_link is not a link of the URDF (the message lists some that are),
  ///        if tip_link is not below base_link in the tree, if the chain has no movable joint or
  ///        more than kMaxJoints, if a joint of the chain is floating, planar or a mimic joint,
  ///        has an axis that is not finite or whose norm is outside [1e-9, 1e9], or inconsistent
  ///        limits (a prismatic joint's beyond +-1000 m);
  ///        if a joint of the chain, or one that fixes a link to it, has an origin coordinate
  ///        outside +-1000 m or a non-finite rotation; if a link of the chain or one fixed to it
  ///        has an inertial origin outside +-1000 m; if any link of the file has an <inertial>
  ///        that physical_link_inertia() refuses (mass outside [0, 1e6] kg, an inertia entry
  ///        outside +-1e6 kg m^2, a negative principal moment);
  ///        and if the pose, Jacobian, mass matrix or gravity torques of the loaded model are not
  ///        finite at q = 0.
  static RobotModel from_urdf_string(
      const std::string& xml, const std::string& base_link, const std::string& tip_link,
      const Eigen::Isometry3d& T_tip_tool = Eigen::Isometry3d::Identity(),
      const Eigen::Vector3d& gravity_base = Eigen::Vector3d(0.0, 0.0, -9.81));

  /// Number of movable joints n (1..kMaxJoints).
  int num_joints() const noexcept;
  /// Names of the movable joints, base to tip; the order of every joint vector.
  const std::vector<std::string>& joint_names() const noexcept;
  const std::vector<JointType>& joint_types() const noexcept;
  const JointLimits& limits() const noexcept;
  /// The URDF's <robot name="...">.
  const std::string& robot_name() const noexcept;
  const std::string& base_link() const noexcept;
  const std::string& tip_link() const noexcept;
  /// T_tip_tool: the end-effector frame in the tip-link frame.
  const Eigen::Isometry3d& tool() const noexcept;
  /// Gravitational acceleration in the base frame [m/s^2]; (0, 0, -9.81) unless given.
  const Eigen::Vector3d& gravity_base() const noexcept;
  /// Total mass the dynamics include: the chain's links after the base and what is fixed to
  /// them [kg].
  double moving_mass() const noexcept;
  /// The link each movable joint moves (its child link in the URDF), base to tip.
  const std::vector<std::string>& joint_links() const noexcept;
  /// The movable joints (indices into joint_names(), base to tip) whose motion moves no mass:
  /// the links from the joint's link down to the tip, and those fixed to them, have no mass and,
  /// for a revolute joint, no rotational inertia (a URDF without <inertial> on its last moving
  /// links). M(q) has a zero row and column for each at every q: singular unless
  /// dynamics.armature gives each such joint a rotor inertia (see check_dynamics()).
  const std::vector<int>& massless_joints() const noexcept;
  /// What the loader repaired in the file, one sentence each naming the link, the values and the
  /// repair (today: inertias that break the triangle inequality; see link_inertia.hpp, which
  /// the simulation applies the same way). Empty for a file used as it is.
  const std::vector<std::string>& warnings() const noexcept;

  /// The implementation every ModelWorkspace (and so every ControlLoop) made from this model
  /// uses: ModelBackend::native unless chosen with with_backend().
  ModelBackend backend() const noexcept;
  /// A copy of this model (sharing the loaded data) whose workspaces use `backend`.
  RobotModel with_backend(ModelBackend backend) const noexcept;

 private:
  friend class ModelWorkspace;
  explicit RobotModel(std::shared_ptr<const detail::ModelData> data) noexcept;
  // `source` names the origin of `xml` in error messages.
  static RobotModel from_urdf_source(const std::string& xml, const std::string& source,
                                     const std::string& base_link, const std::string& tip_link,
                                     const Eigen::Isometry3d& T_tip_tool,
                                     const Eigen::Vector3d& gravity_base);
  std::shared_ptr<const detail::ModelData> data_;
  ModelBackend backend_ = ModelBackend::native;
};

/// Refuses `dynamics` for `model` where they need M(q) (dynamics.inertia_shaped_damping or
/// dynamics.dynamically_consistent_nullspace) and M(q) + diag(dynamics.armature) is singular at
/// every q, because a joint moves no mass (RobotModel::massless_joints()) and has no armature: the
/// damping shaped by the task-space inertia, (J M^-1 J^T)^-1, does not exist there, and every
/// cycle would fail closed. A floor on M would be physics the file does not describe, and
/// damping the other directions only would leave the arm undamped along this joint's motion. The
/// control loop checks this when it is made and for every parameter set sent to it.
/// @throws Error naming the joint, its link, and each way to make it work: an <inertial> for the
///         link, dynamics.armature for the joint, or the options that need M(q) off.
void check_dynamics(const RobotModel& model, const DynamicsParameters& dynamics);

/// Per-cycle workspace of one RobotModel: solvers and buffers sized once at construction. One per
/// control loop or thread (a workspace is not shared between threads; many may share a model).
class ModelWorkspace {
 public:
  /// Sizes every buffer for `model` (allocates; keeps the model's data alive).
  explicit ModelWorkspace(const RobotModel& model);
  ~ModelWorkspace();
  /// A copy is a fresh workspace for the same model.
  ModelWorkspace(const ModelWorkspace& other);
  ModelWorkspace& operator=(const ModelWorkspace& other);
  /// A moved-from workspace only accepts destruction and assignment; its compute returns false.
  ModelWorkspace(ModelWorkspace&& other) noexcept;
  ModelWorkspace& operator=(ModelWorkspace&& other) noexcept;

  const RobotModel& model() const noexcept;

  /// A Kinematics sized for the model: identity pose, zero Jacobian and dynamics.
  Kinematics make_kinematics() const;

  /// Computes the pose and Jacobian at `q` and the dynamic `terms` among M(q), g(q), C(q, dq) dq
  /// and C(q, dq)^T dq (the KDL backend, which has no solver for it, takes the latter from the
  /// native one); the other terms of `out` are left as they
  /// were and out.terms says which are current. Allocates nothing, takes no lock, never throws.
  /// @param q  joint positions [rad or m], size num_joints()
  /// @param dq  joint velocities [rad/s or m/s], size num_joints() (checked even when
  ///            Coriolis is not requested)
  /// @return false if q or dq has the wrong size or a non-finite entry, or if a result would not
  ///         be finite. `out` is then left as it was (resized for the model and with non-finite
  ///         entries zeroed if it was not already a valid result), so it is always finite.
  bool compute(const JointVector& q, const JointVector& dq, Kinematics& out,
               ModelTerms terms) noexcept;

  /// As compute(q, dq, out, ModelTerms::mass | gravity | coriolis) if `dynamics`, else with
  /// ModelTerms::none.
  bool compute(const JointVector& q, const JointVector& dq, Kinematics& out,
               bool dynamics = false) noexcept;

  /// Forward kinematics only: T_base_ee at `q`. Same rules as compute(); `T_base_ee` is left
  /// unchanged on failure.
  bool compute_pose(const JointVector& q, Pose& T_base_ee) noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// How well a configuration suits Cartesian control: how near a singularity and a joint limit.
struct ConfigurationCheck {
  /// Singular values of the 6 x n Jacobian, largest first: min(6, n) of them [m/rad, m/m or
  /// rad/rad: rows are mixed]. A chain controls as many task directions as it has values well
  /// above zero; the smallest says how near it is to losing one.
  Eigen::VectorXd singular_values;
  int closest_joint = -1;  ///< index of the joint nearest a position limit (-1: none limited)
  double limit_distance = std::numeric_limits<double>::infinity();  ///< [rad or m]
  std::vector<std::string> warnings;  ///< what a user should be told; empty: none
};

/// Checks `q` for `model`: warns when the smallest singular value of the Jacobian is below
/// `singular_threshold` (naming it) and when a joint is within `limit_margin` of a position
/// limit (naming the joint, the value and the limit).
/// @throws Error if q has the wrong size or a non-finite value.
ConfigurationCheck check_configuration(const RobotModel& model, const JointVector& q,
                                       double singular_threshold = 0.02, double limit_margin = 0.1);

/// Copies q, dq and the pose and Jacobian of `kinematics` into `state` (sizes follow q).
void fill_robot_state(const JointVector& q, const JointVector& dq, const Kinematics& kinematics,
                      RobotState& state) noexcept;

}  // namespace cartesian_impedance
