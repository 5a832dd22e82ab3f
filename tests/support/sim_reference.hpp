#pragma once
// What the simulation's test files share: the model files, joint vectors, error expectations
// and an independent raw-MuJoCo copy of a model to compare the Simulation with.

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include <functional>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/core/types.hpp"

namespace sim_test {

namespace ci = cartesian_impedance;
using ci::JointMatrix;
using ci::JointVector;

inline constexpr double kPi = 3.14159265358979323846;

inline std::string model_file(const std::string& relative) {
  return std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/models/" + relative;
}
inline const std::string kPandaXml = model_file("panda/panda.xml");
inline const std::string kIiwaXml = model_file("iiwa14/iiwa14.xml");
inline const std::string kPandaUrdf = model_file("panda/panda.urdf");
inline const std::string kIiwaUrdf = model_file("iiwa14/iiwa14.urdf");
inline const std::string kUr5eUrdf = model_file("ur5e/ur5e.urdf");
inline const std::string kPlanar3Urdf = model_file("planar3/planar3.urdf");

inline JointVector joints(std::initializer_list<double> values) {
  JointVector v(static_cast<Eigen::Index>(values.size()));
  Eigen::Index i = 0;
  for (double value : values) v[i++] = value;
  return v;
}

inline JointVector panda_ready() {
  return joints({0, -kPi / 4, 0, -3 * kPi / 4, 0, kPi / 2, kPi / 4});
}
inline JointVector iiwa_ready() {
  return joints({0, kPi / 6, 0, -kPi / 2, 0, kPi / 3, 0});
}

// Expects `call` to throw ci::Error whose message contains every one of `parts`; the macro adds
// the line of the check to a failure.
inline void expect_error_impl(const std::function<void()>& call,
                              const std::vector<std::string>& parts) {
  try {
    call();
    ADD_FAILURE() << "expected cartesian_impedance::Error";
  } catch (const ci::Error& error) {
    const std::string message = error.what();
    for (const std::string& part : parts) {
      EXPECT_NE(message.find(part), std::string::npos)
          << "message \"" << message << "\" lacks \"" << part << "\"";
    }
  }
}
#define EXPECT_ERROR(...)           \
  do {                              \
    SCOPED_TRACE("EXPECT_ERROR");   \
    expect_error_impl(__VA_ARGS__); \
  } while (false)

// An independent MuJoCo model and data of the same file, driven through the raw C API with
// qfrc_applied only: the reference the Simulation is compared with.
class Reference {
 public:
  explicit Reference(const std::string& path) {
    char error[1000] = "";
    model_ = mj_loadXML(path.c_str(), nullptr, error, sizeof(error));
    if (model_ == nullptr) throw std::runtime_error(error);
    model_->opt.timestep = 0.001;
    model_->opt.enableflags |= mjENBL_MULTICCD;  // as SimulationOptions::multi_point_contacts
    data_ = mj_makeData(model_);
    scratch_ = mj_makeData(model_);
    const int key = mj_name2id(model_, mjOBJ_KEY, "ready");
    if (key >= 0) {
      mj_resetDataKeyframe(model_, data_, key);
    }
    mj_forward(model_, data_);
  }
  ~Reference() {
    mj_deleteData(scratch_);
    mj_deleteData(data_);
    mj_deleteModel(model_);
  }
  Reference(const Reference&) = delete;
  Reference& operator=(const Reference&) = delete;

  int nv() const { return model_->nv; }
  const mjModel* model() const { return model_; }
  const mjData* data() const { return data_; }

  void set_state(const JointVector& q, const JointVector& dq) {
    for (int i = 0; i < nv(); ++i) {
      data_->qpos[i] = q[i];
      data_->qvel[i] = dq[i];
    }
    mj_forward(model_, data_);
  }
  JointVector q() const { return Eigen::Map<const Eigen::VectorXd>(data_->qpos, nv()); }
  JointVector dq() const { return Eigen::Map<const Eigen::VectorXd>(data_->qvel, nv()); }

  // Joint-space inertia including armature.
  JointMatrix mass_matrix() const {
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> dense(nv(), nv());
    mj_fullM(model_, dense.data(), data_->qM);
    return dense;
  }
  JointMatrix damping() const {
    return Eigen::Map<const Eigen::VectorXd>(model_->dof_damping, nv()).asDiagonal();
  }
  JointVector frictionloss() const {
    return Eigen::Map<const Eigen::VectorXd>(model_->dof_frictionloss, nv());
  }

  // After mj_step, data's kinematics belong to the positions before the step; the scratch copy
  // is brought up to date with the current positions (and zero velocity) instead.
  const mjData* fresh() {
    mju_copy(scratch_->qpos, data_->qpos, model_->nq);
    mju_zero(scratch_->qvel, model_->nv);
    mj_forward(model_, scratch_);
    return scratch_;
  }

  // 6 x nv geometric Jacobian [linear; angular] of the origin of a body or a site, at the current
  // positions.
  Eigen::MatrixXd jacobian(const std::string& body_or_site) {
    const mjData* d = fresh();
    int site = mj_name2id(model_, mjOBJ_SITE, body_or_site.c_str());
    const int body = site >= 0 ? model_->site_bodyid[site]
                               : mj_name2id(model_, mjOBJ_BODY, body_or_site.c_str());
    const mjtNum* point = site >= 0 ? d->site_xpos + 3 * site : d->xpos + 3 * body;
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> linear(3, nv());
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> angular(3, nv());
    mj_jac(model_, d, linear.data(), angular.data(), point, body);
    Eigen::MatrixXd jacobian(6, nv());
    jacobian << linear, angular;
    return jacobian;
  }

  // g(q): qfrc_bias at the current positions with zero velocity.
  JointVector gravity() { return Eigen::Map<const Eigen::VectorXd>(fresh()->qfrc_bias, nv()); }
  Eigen::Vector3d site_position(const std::string& site) {
    return Eigen::Map<const Eigen::Vector3d>(fresh()->site_xpos +
                                             3 * mj_name2id(model_, mjOBJ_SITE, site.c_str()));
  }

  // One step with qfrc_applied = f (no actuators used).
  void step(const JointVector& generalized_force) {
    for (int i = 0; i < nv(); ++i) data_->qfrc_applied[i] = generalized_force[i];
    mj_step(model_, data_);
  }

 private:
  mjModel* model_ = nullptr;
  mjData* data_ = nullptr;
  mjData* scratch_ = nullptr;
};

// dq after one step from rest under generalized force f, and the bound on its error from joint
// friction: each friction force is at most that joint's frictionloss, so per joint i
// |dq_i - predicted_i| <= dt sum_j |(M + dt D)^-1_ij| frictionloss_j.
struct OneStepPrediction {
  JointVector dq;
  JointVector bound;
};
inline OneStepPrediction predict_one_step(const Reference& reference, const JointVector& force) {
  const double dt = 0.001;
  const JointMatrix a_inverse = (reference.mass_matrix() + dt * reference.damping()).inverse();
  return {dt * a_inverse * force, dt * a_inverse.cwiseAbs() * reference.frictionloss()};
}

// The measured one-step dq agrees with the prediction within the friction bound (+ round-off),
// and the bound is small against the prediction, so the check means something.
inline void expect_one_step(const JointVector& dq, const OneStepPrediction& prediction) {
  ASSERT_LT(prediction.bound.norm(), 0.1 * prediction.dq.norm());
  for (int i = 0; i < dq.size(); ++i) {
    EXPECT_LE(std::abs(dq[i] - prediction.dq[i]), prediction.bound[i] + 1e-12)
        << "joint " << i + 1 << ": dq " << dq[i] << ", predicted " << prediction.dq[i];
  }
}

}  // namespace sim_test
