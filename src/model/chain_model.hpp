#pragma once
// Private to the model library: the native kinematics and dynamics of a serial chain, made for
// the control cycle. The chain is read once from the KDL chain the model already builds (so that
// parsing and the folding of fixed links stay one path); the cycle then runs on fixed-size Eigen
// types only: no heap, no virtual call, no exception.
//
// Each movable joint i gets a "joint frame" J_i whose z axis is the joint axis (at the joint
// origin), so that turning it costs one sin/cos pair and a few multiplications (R * Rz(q)), not a
// full Rodrigues matrix per cycle. Every fixed segment between two movable joints (and the tool at
// the end) is folded into one constant transform, and every body rigidly attached after joint i
// into one rigid body of joint i.

#include <Eigen/Core>
#include <array>

#include "cartesian_impedance/core/types.hpp"
#include "cartesian_impedance/model/robot_model.hpp"

namespace KDL {
class Chain;
}

namespace cartesian_impedance::detail {

/// One movable joint and the rigid body it moves, all constant.
struct ChainJoint {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  ///< of J_i (q = 0) in J_{i-1} (base)
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();   ///< of J_i (q = 0) in J_{i-1} [m]
  bool prismatic = false;  ///< translates along z of J_i; otherwise rotates about it
  double mass = 0.0;       ///< [kg] of everything rigidly attached after the joint
  Eigen::Vector3d com = Eigen::Vector3d::Zero();      ///< centre of mass in J_i [m]
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();  ///< about the com, J_i axes [kg m^2]
};

/// The whole chain: joints base to tip, then the tool frame in the last joint frame.
struct ChainModel {
  int n = 0;
  std::array<ChainJoint, kMaxJoints> joints{};
  Eigen::Matrix3d tool_rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d tool_translation = Eigen::Vector3d::Zero();
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();  ///< [m/s^2] in the base frame
};

/// Reads `chain` (one KDL segment per URDF joint, fixed ones as Joint::None, joints with scale 1
/// and offset 0, as urdf_to_kdl_chain builds it) into a ChainModel.
/// @throw Error if the chain has no movable joint or more than kMaxJoints.
ChainModel make_chain_model(const KDL::Chain& chain, const Eigen::Vector3d& gravity_base);

/// Per-cycle state and algorithms for one ChainModel. forward() first; then any of the others,
/// each of which reads only what forward() (and, for mass and coriolis, bodies()) left.
class ChainSolver {
 public:
  explicit ChainSolver(const ChainModel& model) noexcept : model_(&model) {}

  /// Joint frames and the tool frame at q (size n, not checked).
  void forward(const JointVector& q) noexcept;
  const Eigen::Matrix3d& tool_rotation() const noexcept { return tool_R_; }
  const Eigen::Vector3d& tool_position() const noexcept { return tool_p_; }

  /// Geometric Jacobian, rows [linear; angular], reference point the tool origin, base frame.
  void jacobian(Jacobian& J) const noexcept;

  /// Motion subspaces and centres of mass in the base frame; with `inertias` also each body's
  /// rotational inertia about the base origin (what mass() and coriolis() need).
  void bodies(bool inertias) noexcept;
  /// M(q) by the composite-rigid-body algorithm (after bodies(true)).
  void mass(JointMatrix& M) const noexcept;
  /// g(q), the torques that hold the chain against gravity (after bodies(false or true)).
  void gravity(JointVector& g) const noexcept;
  /// C(q, dq) dq by recursive Newton-Euler without gravity and acceleration (after
  /// bodies(true)).
  void coriolis(const JointVector& dq, JointVector& c) const noexcept;
  /// C(q, dq)^T dq = dT/dq, the kinetic energy's gradient (after bodies(true)): joint k turns
  /// every body after it, and its velocity V_i with it, about its axis S_k, which changes
  /// the kinetic energy by -(S_k x V_k) . H_k, H_k the spatial momentum of the bodies k..n-1.
  /// One pass out and one back, as the Coriolis term.
  void coriolis_transposed(const JointVector& dq, JointVector& ct) const noexcept;

 private:
  const ChainModel* model_;
  // Joint frames J_i in the base frame.
  std::array<Eigen::Matrix3d, kMaxJoints> R_;
  std::array<Eigen::Vector3d, kMaxJoints> p_;
  Eigen::Matrix3d tool_R_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d tool_p_ = Eigen::Vector3d::Zero();
  // Spatial motion subspace of each joint at the base origin: angular w, linear v.
  std::array<Eigen::Vector3d, kMaxJoints> w_;
  std::array<Eigen::Vector3d, kMaxJoints> v_;
  // Each body's centre of mass and rotational inertia about the base origin, base frame.
  std::array<Eigen::Vector3d, kMaxJoints> com_;
  std::array<Eigen::Matrix3d, kMaxJoints> inertia_;
};

}  // namespace cartesian_impedance::detail
