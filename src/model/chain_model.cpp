// Native kinematics and dynamics of a serial chain (chain_model.hpp).
//
// The dynamics work in the base frame with spatial vectors taken at the base origin (Featherstone,
// "Rigid Body Dynamics Algorithms", ch. 2 and 5, in absolute coordinates): a joint's motion
// subspace is then S_i = [w; v] = [z_i; p_i x z_i] (revolute) or [0; z_i] (prismatic), a body's
// inertia is (m, h = m c, I_O) and no spatial transform is needed between bodies, so the
// composite inertias of the composite-rigid-body algorithm are plain sums. For arms of a few
// metres the terms that cancel in this form (m |c|^2) stay within a few units of the result, so
// nothing measurable is lost to rounding.

#include "chain_model.hpp"

#include <cmath>
#include <kdl/chain.hpp>
#include <kdl/frames.hpp>
#include <kdl/joint.hpp>
#include <kdl/rigidbodyinertia.hpp>
#include <kdl/rotationalinertia.hpp>
#include <kdl/segment.hpp>
#include <string>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance::detail {
namespace {

struct Transform {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p = Eigen::Vector3d::Zero();

  Transform operator*(const Transform& other) const { return {R * other.R, R * other.p + p}; }
  Transform inverse() const { return {R.transpose(), -(R.transpose() * p)}; }
};

Transform to_transform(const KDL::Frame& frame) {
  Transform result;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) result.R(r, c) = frame.M(r, c);
    result.p[r] = frame.p[r];
  }
  return result;
}

Eigen::Vector3d to_eigen(const KDL::Vector& v) {
  return Eigen::Vector3d(v.x(), v.y(), v.z());
}

// m (|c|^2 E - c c^T): what a point mass m at c adds to an inertia about the origin.
Eigen::Matrix3d point_inertia(double m, const Eigen::Vector3d& c) {
  return m * (c.squaredNorm() * Eigen::Matrix3d::Identity() - c * c.transpose());
}

// Mass, first moment and rotational inertia about the origin of one frame: bodies seen from the
// same frame simply add.
struct BodySum {
  double mass = 0.0;
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();

  // Adds a segment's inertia (KDL: expressed in the segment's tip frame, about its origin),
  // whose tip frame is at `T` in this frame.
  void add(const Transform& T, const KDL::RigidBodyInertia& body) {
    const double m = body.getMass();
    const Eigen::Vector3d cog = to_eigen(body.getCOG());
    const KDL::RotationalInertia about_origin = body.getRotationalInertia();
    const Eigen::Matrix3d at_origin = Eigen::Map<const Eigen::Matrix3d>(about_origin.data);
    const Eigen::Matrix3d about_cog = at_origin - point_inertia(m, cog);
    const Eigen::Vector3d c = T.R * cog + T.p;
    mass += m;
    moment += m * c;
    inertia += T.R * about_cog * T.R.transpose() + point_inertia(m, c);
  }

  void store(ChainJoint& joint) const {
    joint.mass = mass;
    joint.com = mass > 0.0 ? Eigen::Vector3d(moment / mass) : Eigen::Vector3d::Zero();
    joint.inertia = inertia - point_inertia(mass, joint.com);
    // The tensor is symmetric; rounding in the sums above must not make it otherwise.
    joint.inertia = 0.5 * (joint.inertia + joint.inertia.transpose()).eval();
  }
};

// A rotation whose z column is the unit vector `axis`. Its x column is the coordinate axis least
// aligned with `axis`, made orthogonal to it, so that an axis along a coordinate axis gives a
// signed permutation: exact zeros stay exact (a planar arm's Jacobian has rows that are exactly
// zero, as with KDL).
Eigen::Matrix3d frame_with_z(const Eigen::Vector3d& axis) {
  Eigen::Index least = 0;
  axis.cwiseAbs().minCoeff(&least);
  const Eigen::Vector3d e = Eigen::Vector3d::Unit(least);
  const Eigen::Vector3d x = (e - e.dot(axis) * axis).normalized();
  Eigen::Matrix3d C;
  C.col(0) = x;
  C.col(1) = axis.cross(x);
  C.col(2) = axis;
  return C;
}

bool is_prismatic(KDL::Joint::JointType type) {
  return type == KDL::Joint::TransAxis || type == KDL::Joint::TransX ||
         type == KDL::Joint::TransY || type == KDL::Joint::TransZ;
}

}  // namespace

ChainModel make_chain_model(const KDL::Chain& chain, const Eigen::Vector3d& gravity_base) {
  ChainModel model;
  model.gravity = gravity_base;
  // From the current frame (the base, then the last movable joint's frame J_k at q = 0) to the
  // tip frame of the last segment walked.
  Transform T;
  BodySum body;
  int k = -1;
  for (unsigned int s = 0; s < chain.getNrOfSegments(); ++s) {
    const KDL::Segment& segment = chain.getSegment(s);
    const KDL::Joint& joint = segment.getJoint();
    const Transform tip = to_transform(segment.getFrameToTip());
    if (joint.getType() == KDL::Joint::None) {
      T = T * tip;
      // Bodies fixed to the base before the first joint do not move: they are not dynamics.
      if (k >= 0) body.add(T, segment.getInertia());
      continue;
    }
    if (k + 1 >= kMaxJoints) {
      throw Error("the chain has more than kMaxJoints = " + std::to_string(kMaxJoints) +
                  " movable joints");
    }
    if (k >= 0) body.store(model.joints[static_cast<std::size_t>(k)]);
    ++k;
    // KDL moves the segment by a rotation about (translation along) the axis a through the
    // origin o, both in the segment's parent frame: pose(q) = T(o) Rot(a, q) T(-o) tip. With C a
    // rotation that takes z to a, T(o) Rot(a, q) T(-o) = X Rz(q) X^-1 for X = (C, o), so the
    // joint frame is J_k = X and the segment's tip is X^-1 tip after it.
    const Eigen::Vector3d axis = to_eigen(joint.JointAxis()).normalized();
    Transform X;
    X.R = frame_with_z(axis);
    X.p = to_eigen(joint.JointOrigin());
    ChainJoint& entry = model.joints[static_cast<std::size_t>(k)];
    const Transform placed = T * X;
    entry.rotation = placed.R;
    entry.translation = placed.p;
    entry.prismatic = is_prismatic(joint.getType());
    T = X.inverse() * tip;
    body = BodySum();
    body.add(T, segment.getInertia());
  }
  if (k < 0) throw Error("the chain has no movable joint; expected at least 1");
  body.store(model.joints[static_cast<std::size_t>(k)]);
  model.n = k + 1;
  model.tool_rotation = T.R;
  model.tool_translation = T.p;
  return model;
}

void ChainSolver::forward(const JointVector& q) noexcept {
  const ChainModel& model = *model_;
  for (int i = 0; i < model.n; ++i) {
    const ChainJoint& joint = model.joints[static_cast<std::size_t>(i)];
    Eigen::Matrix3d& R = R_[static_cast<std::size_t>(i)];
    Eigen::Vector3d& p = p_[static_cast<std::size_t>(i)];
    Eigen::Matrix3d B;
    if (i == 0) {
      B = joint.rotation;
      p = joint.translation;
    } else {
      const Eigen::Matrix3d& R_prev = R_[static_cast<std::size_t>(i - 1)];
      B.noalias() = R_prev * joint.rotation;
      p.noalias() = p_[static_cast<std::size_t>(i - 1)] + R_prev * joint.translation;
    }
    if (joint.prismatic) {
      p += q[i] * B.col(2);
      R = B;
    } else {
      // Adjacent sin and cos of one argument: GCC emits one sincos call.
      const double s = std::sin(q[i]);
      const double c = std::cos(q[i]);
      R.col(0) = c * B.col(0) + s * B.col(1);
      R.col(1) = c * B.col(1) - s * B.col(0);
      R.col(2) = B.col(2);
    }
  }
  const Eigen::Matrix3d& R_last = R_[static_cast<std::size_t>(model.n - 1)];
  tool_R_.noalias() = R_last * model.tool_rotation;
  tool_p_.noalias() = p_[static_cast<std::size_t>(model.n - 1)] + R_last * model.tool_translation;
}

void ChainSolver::jacobian(Jacobian& J) const noexcept {
  const ChainModel& model = *model_;
  J.resize(6, model.n);
  for (int i = 0; i < model.n; ++i) {
    const auto z = R_[static_cast<std::size_t>(i)].col(2);
    if (model.joints[static_cast<std::size_t>(i)].prismatic) {
      J.col(i).head<3>() = z;
      J.col(i).tail<3>().setZero();
    } else {
      J.col(i).head<3>() = z.cross(tool_p_ - p_[static_cast<std::size_t>(i)]);
      J.col(i).tail<3>() = z;
    }
  }
}

void ChainSolver::bodies(bool inertias) noexcept {
  const ChainModel& model = *model_;
  for (int i = 0; i < model.n; ++i) {
    const std::size_t k = static_cast<std::size_t>(i);
    const ChainJoint& joint = model.joints[k];
    const Eigen::Matrix3d& R = R_[k];
    const auto z = R.col(2);
    if (joint.prismatic) {
      w_[k].setZero();
      v_[k] = z;
    } else {
      w_[k] = z;
      v_[k] = p_[k].cross(z);
    }
    com_[k].noalias() = p_[k] + R * joint.com;
    if (inertias) {
      Eigen::Matrix3d RI;
      RI.noalias() = R * joint.inertia;
      inertia_[k].noalias() = RI * R.transpose();
      inertia_[k] += point_inertia(joint.mass, com_[k]);
    }
  }
}

void ChainSolver::mass(JointMatrix& M) const noexcept {
  const ChainModel& model = *model_;
  M.resize(model.n, model.n);
  // Composite body of joints i..n-1, accumulated from the tip.
  double m = 0.0;
  Eigen::Vector3d h = Eigen::Vector3d::Zero();
  Eigen::Matrix3d I = Eigen::Matrix3d::Zero();
  for (int i = model.n - 1; i >= 0; --i) {
    const std::size_t k = static_cast<std::size_t>(i);
    const double mi = model.joints[k].mass;
    m += mi;
    h += mi * com_[k];
    I += inertia_[k];
    // F = I_c S_i: the force that moves the composite body along joint i at unit speed.
    const Eigen::Vector3d angular = I * w_[k] + h.cross(v_[k]);
    const Eigen::Vector3d linear = m * v_[k] - h.cross(w_[k]);
    for (int j = 0; j <= i; ++j) {
      const std::size_t l = static_cast<std::size_t>(j);
      const double value = w_[l].dot(angular) + v_[l].dot(linear);
      M(j, i) = value;
      M(i, j) = value;
    }
  }
}

void ChainSolver::gravity(JointVector& g) const noexcept {
  const ChainModel& model = *model_;
  g.resize(model.n);
  // With the chain at rest, each joint carries the weight of everything after it: the force
  // -m_c g at the composite centre of mass.
  double m = 0.0;
  Eigen::Vector3d h = Eigen::Vector3d::Zero();
  for (int i = model.n - 1; i >= 0; --i) {
    const std::size_t k = static_cast<std::size_t>(i);
    const double mi = model.joints[k].mass;
    m += mi;
    h += mi * com_[k];
    const Eigen::Vector3d linear = -m * model.gravity;
    const Eigen::Vector3d angular = h.cross(-model.gravity);
    g[i] = w_[k].dot(angular) + v_[k].dot(linear);
  }
}

void ChainSolver::coriolis(const JointVector& dq, JointVector& c) const noexcept {
  const ChainModel& model = *model_;
  c.resize(model.n);
  std::array<Eigen::Vector3d, kMaxJoints> torque;  // body forces at the base origin
  std::array<Eigen::Vector3d, kMaxJoints> force;
  Eigen::Vector3d vw = Eigen::Vector3d::Zero(), vv = Eigen::Vector3d::Zero();  // velocity
  Eigen::Vector3d aw = Eigen::Vector3d::Zero(), av = Eigen::Vector3d::Zero();  // acceleration
  for (int i = 0; i < model.n; ++i) {
    const std::size_t k = static_cast<std::size_t>(i);
    const Eigen::Vector3d sw = w_[k] * dq[i];
    const Eigen::Vector3d sv = v_[k] * dq[i];
    vw += sw;
    vv += sv;
    // In base coordinates the subspace moves with its body: dS/dt = V x S.
    aw += vw.cross(sw);
    av += vw.cross(sv) + vv.cross(sw);
    const double m = model.joints[k].mass;
    const Eigen::Vector3d h = m * com_[k];
    const Eigen::Matrix3d& I = inertia_[k];
    // f = I a + V x* (I V)
    const Eigen::Vector3d momentum_angular = I * vw + h.cross(vv);
    const Eigen::Vector3d momentum_linear = m * vv - h.cross(vw);
    torque[k] = I * aw + h.cross(av) + vw.cross(momentum_angular) + vv.cross(momentum_linear);
    force[k] = m * av - h.cross(aw) + vw.cross(momentum_linear);
  }
  Eigen::Vector3d n = Eigen::Vector3d::Zero(), f = Eigen::Vector3d::Zero();
  for (int i = model.n - 1; i >= 0; --i) {
    const std::size_t k = static_cast<std::size_t>(i);
    n += torque[k];
    f += force[k];
    c[i] = w_[k].dot(n) + v_[k].dot(f);
  }
}

void ChainSolver::coriolis_transposed(const JointVector& dq, JointVector& ct) const noexcept {
  const ChainModel& model = *model_;
  ct.resize(model.n);
  // S_k x V_k (the motion cross product; S_k x S_k = 0, so V_k may include joint k itself) and
  // each body's spatial momentum, at the base origin.
  std::array<Eigen::Vector3d, kMaxJoints> turn_angular, turn_linear;
  std::array<Eigen::Vector3d, kMaxJoints> momentum_angular, momentum_linear;
  Eigen::Vector3d vw = Eigen::Vector3d::Zero(), vv = Eigen::Vector3d::Zero();
  for (int i = 0; i < model.n; ++i) {
    const std::size_t k = static_cast<std::size_t>(i);
    vw += w_[k] * dq[i];
    vv += v_[k] * dq[i];
    turn_angular[k] = w_[k].cross(vw);
    turn_linear[k] = w_[k].cross(vv) + v_[k].cross(vw);
    const double m = model.joints[k].mass;
    const Eigen::Vector3d h = m * com_[k];
    momentum_angular[k] = inertia_[k] * vw + h.cross(vv);
    momentum_linear[k] = m * vv - h.cross(vw);
  }
  Eigen::Vector3d n = Eigen::Vector3d::Zero(), f = Eigen::Vector3d::Zero();
  for (int i = model.n - 1; i >= 0; --i) {
    const std::size_t k = static_cast<std::size_t>(i);
    n += momentum_angular[k];
    f += momentum_linear[k];
    ct[i] = -(turn_angular[k].dot(n) + turn_linear[k].dot(f));
  }
}

}  // namespace cartesian_impedance::detail
