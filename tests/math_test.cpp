// The pieces of the law on their own: pose error, filter gain, limits, damping, projector.

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "cartesian_impedance/core/math.hpp"
#include "support/law_reference.hpp"
#include "support/random_cases.hpp"

namespace ci = cartesian_impedance;
using namespace random_cases;

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kEps = std::numeric_limits<double>::epsilon();
}  // namespace

// --- orientation error --------------------------------------------------------------------------

// current = exp(angle * axis) * desired, so log(R R_d^T) = angle * axis for angle in [0, pi).
// atan2 gives the angle to a few ulps of pi, so 10 eps * pi bounds the error at every angle.
TEST(OrientationError, KnownAxisAngleIncludingNearPi) {
  std::mt19937 rng(1);
  const double angles[] = {0.0, 1e-12, 1e-8, 1e-4, 0.3, 1.0, 2.0, 3.0, kPi - 1e-6, kPi - 1e-9};
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Quaterniond desired = random_rotation(rng);
    const Eigen::Vector3d axis = random_unit_vector(rng);
    for (double angle : angles) {
      const Eigen::Quaterniond current =
          Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis)) * desired;
      const Eigen::Vector3d error = ci::orientation_error(current, desired);
      EXPECT_LE((error - angle * axis).norm(), 10 * kEps * kPi) << "angle " << angle;
    }
  }
}

// Exactly pi: both directions of the axis are the same rotation; the error must have norm pi and
// lie along the axis.
TEST(OrientationError, HalfTurnHasNormPiAlongTheAxis) {
  std::mt19937 rng(2);
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Quaterniond desired = random_rotation(rng);
    const Eigen::Vector3d axis = random_unit_vector(rng);
    const Eigen::Quaterniond current = Eigen::Quaterniond(Eigen::AngleAxisd(kPi, axis)) * desired;
    const Eigen::Vector3d error = ci::orientation_error(current, desired);
    EXPECT_NEAR(error.norm(), kPi, 1e-9);
    EXPECT_NEAR(std::abs(error.normalized().dot(axis)), 1.0, 1e-9);
  }
}

// q and -q are the same rotation: every sign combination gives the same (short-way) error.
TEST(OrientationError, QuaternionSignDoesNotMatter) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Quaterniond current = random_rotation(rng);
    const Eigen::Quaterniond desired = random_rotation(rng);
    const Eigen::Quaterniond current_flipped(-current.coeffs());
    const Eigen::Quaterniond desired_flipped(-desired.coeffs());
    const Eigen::Vector3d error = ci::orientation_error(current, desired);
    EXPECT_LE(error.norm(), kPi + 1e-12);
    EXPECT_LE((ci::orientation_error(current_flipped, desired) - error).norm(), 1e-12);
    EXPECT_LE((ci::orientation_error(current, desired_flipped) - error).norm(), 1e-12);
    EXPECT_LE((ci::orientation_error(current_flipped, desired_flipped) - error).norm(), 1e-12);
  }
}

TEST(PoseError, TranslationIsCurrentMinusDesired) {
  const ci::Pose current{Eigen::Vector3d(0.3, -0.1, 0.5), Eigen::Quaterniond::Identity()};
  const ci::Pose desired{Eigen::Vector3d(0.2, 0.1, 0.5),
                         Eigen::Quaterniond(Eigen::AngleAxisd(0.25, Eigen::Vector3d::UnitZ()))};
  const ci::Vector6d error = ci::pose_error(current, desired);
  EXPECT_NEAR(error[0], 0.1, 1e-15);
  EXPECT_NEAR(error[1], -0.2, 1e-15);
  EXPECT_NEAR(error[2], 0.0, 1e-15);
  // R R_d^T = Rz(-0.25).
  EXPECT_NEAR(error[5], -0.25, 1e-15);
  EXPECT_NEAR(error.segment<2>(3).norm(), 0.0, 1e-15);
}

// --- filter gain --------------------------------------------------------------------------------

// After `time` seconds of steps of dt, (1 - a)^(time/dt) of the step remains: 1 - fraction.
TEST(FilterGain, ReachesFractionAfterTimeAtAnyRate) {
  for (double rate : {250.0, 500.0, 1000.0, 333.0}) {
    const double dt = 1.0 / rate;
    const double time = 0.2, fraction = 0.95;
    const double a = ci::filter_gain(dt, time, fraction);
    double value = 0.0;
    const int steps = static_cast<int>(std::lround(time * rate));
    for (int k = 0; k < steps; ++k) value = (1.0 - a) * value + a * 1.0;
    // The step count is exact only when time * rate is an integer; 333 Hz is off by a third of a
    // step, so the expected value is evaluated at steps * dt.
    const double expected = 1.0 - std::pow(1.0 - fraction, steps * dt / time);
    EXPECT_NEAR(value, expected, 1e-12) << rate << " Hz";
    if (std::abs(steps * dt - time) < 1e-12) {
      EXPECT_NEAR(value, fraction, 1e-12) << rate << " Hz";
    }
  }
}

TEST(FilterGain, ZeroTimeMeansNoFilterAndFractionOneIsImmediate) {
  EXPECT_EQ(ci::filter_gain(0.001, 0.0, 0.95), 1.0);
  EXPECT_EQ(ci::filter_gain(0.001, 0.1, 1.0), 1.0);
  // Small dt / time keeps its precision (expm1/log1p): a = 1 - exp(-x) with x = ln 2 dt / T,
  // whose series x - x^2/2 + x^3/6 is exact to 1e-30 here; naive 1 - pow() is off by ~1e-17.
  const double a = ci::filter_gain(1e-6, 10.0, 0.5);
  const double x = std::log(2.0) * 1e-7;
  EXPECT_NEAR(a, x - x * x / 2 + x * x * x / 6, 1e-22);
}

// --- limits -------------------------------------------------------------------------------------

TEST(ClipNorm, ScalesOnlyLongVectorsAndKeepsDirection) {
  Eigen::Vector3d v(3.0, 4.0, 0.0);
  EXPECT_FALSE(ci::clip_norm(v, 5.0));
  EXPECT_EQ(v, Eigen::Vector3d(3.0, 4.0, 0.0));
  EXPECT_TRUE(ci::clip_norm(v, 1.0));
  EXPECT_NEAR(v.norm(), 1.0, 1e-15);
  EXPECT_NEAR(v.x() / v.y(), 0.75, 1e-15);
}

// Each joint is limited on its own: a joint within its bound gets its whole change (so one slow
// joint does not delay the others' damping), a joint beyond it moves by exactly its bound.
TEST(LimitRate, BoundsEveryJointOnItsOwn) {
  std::mt19937 rng(4);
  for (int trial = 0; trial < 1000; ++trial) {
    const int n = 7;
    const ci::JointVector previous = random_joints(n, rng, 50.0);
    const ci::JointVector max_step = random_joints(n, rng, 2.0).cwiseAbs();
    ci::JointVector tau = previous + random_joints(n, rng, 5.0);
    const ci::JointVector desired = tau;
    const bool limited = ci::limit_rate(previous, max_step, tau);
    EXPECT_EQ(limited, ((desired - previous).cwiseAbs().array() > max_step.array()).any());
    for (int i = 0; i < n; ++i) {
      const double change = desired[i] - previous[i];
      if (std::abs(change) <= max_step[i]) {
        EXPECT_EQ(tau[i], desired[i]) << "joint " << i;
      } else {
        // previous + step is rounded once when stored: one ulp of the result.
        const double ulp = std::nextafter(std::abs(tau[i]), INFINITY) - std::abs(tau[i]);
        EXPECT_NEAR(tau[i] - previous[i], std::copysign(max_step[i], change), ulp) << "joint " << i;
      }
    }
  }
}

TEST(SaturateTorque, ClampsEachJoint) {
  ci::JointVector tau(3);
  tau << 10, -20, 5;
  ci::JointVector limit(3);
  limit << 12, 12, 2;
  EXPECT_TRUE(ci::saturate_torque(limit, tau));
  EXPECT_EQ(tau, (ci::JointVector(3) << 10, -12, 2).finished());
  EXPECT_FALSE(ci::saturate_torque(limit, tau));
}

// --- damping from stiffness ----------------------------------------------------------------------

TEST(Damping, DiagonalIsTwoZetaSqrtK) {
  ci::Matrix6d k = ci::Matrix6d::Zero();
  k.diagonal() << 100, 400, 900, 4, 16, 0;
  ci::Vector6d zeta;
  zeta << 1, 0.5, 0.7, 1, 2, 1;
  const ci::Matrix6d d = ci::damping_from_stiffness(k, zeta);
  ci::Vector6d expected;
  expected << 20, 20, 42, 4, 16, 0;
  EXPECT_LE((d.diagonal() - expected).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ((d - ci::Matrix6d(d.diagonal().asDiagonal())).cwiseAbs().maxCoeff(), 0.0);
}

// Full K: with zeta = 1, D^2 = 4 K (D = 2 sqrt(K)); with zeta per axis, D is the congruence
// 2 Z^1/2 sqrt(K) Z^1/2, symmetric positive semi-definite.
TEST(Damping, FullStiffnessUsesMatrixSquareRoot) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 100; ++trial) {
    const ci::Matrix6d k = random_stiffness(rng);
    const ci::Matrix6d d = ci::damping_from_stiffness(k, ci::Vector6d::Ones());
    EXPECT_LE((d * d - 4.0 * k).cwiseAbs().maxCoeff(), 1e-9 * k.cwiseAbs().maxCoeff());
    EXPECT_LE((d - d.transpose()).cwiseAbs().maxCoeff(), 1e-9 * d.cwiseAbs().maxCoeff());

    ci::Vector6d zeta;
    for (int i = 0; i < 6; ++i) zeta[i] = uniform(rng, 0.2, 2.0);
    const ci::Matrix6d d_zeta = ci::damping_from_stiffness(k, zeta);
    const ci::Matrix6d z_root = zeta.cwiseSqrt().asDiagonal();
    EXPECT_LE((d_zeta - z_root * d * z_root).cwiseAbs().maxCoeff(), 1e-9 * d.cwiseAbs().maxCoeff());
    EXPECT_GE(Eigen::SelfAdjointEigenSolver<ci::Matrix6d>(d_zeta).eigenvalues()[0],
              -1e-9 * d.cwiseAbs().maxCoeff());
  }
}

// --- stiffness saturation -----------------------------------------------------------------------

TEST(SaturateStiffness, DiagonalIsClampedPerAxis) {
  ci::Matrix6d k = ci::Matrix6d::Zero();
  k.diagonal() << 100, 6000, -0.0, 10, 600, 50;
  EXPECT_TRUE(ci::saturate_stiffness(k, 50, 5000, 20, 500));
  ci::Vector6d expected;
  expected << 100, 5000, 50, 20, 500, 50;
  EXPECT_EQ(k.diagonal(), expected);
  EXPECT_FALSE(ci::saturate_stiffness(k, 50, 5000, 20, 500));
}

// Full K: the block eigenvalues land inside the limits, the principal axes stay, and the result
// is still positive semi-definite even with translation-rotation coupling.
TEST(SaturateStiffness, FullMatrixClampsBlockEigenvaluesAndStaysPsd) {
  std::mt19937 rng(6);
  for (int trial = 0; trial < 200; ++trial) {
    ci::Matrix6d k = random_stiffness(rng, 10, 4000);
    const Eigen::Matrix3d translation_before = k.topLeftCorner<3, 3>();
    ci::saturate_stiffness(k, 200, 1500, 30, 150);
    EXPECT_LE((k - k.transpose()).cwiseAbs().maxCoeff(), 1e-9);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> translation(k.topLeftCorner<3, 3>());
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> rotation(k.bottomRightCorner<3, 3>());
    EXPECT_GE(translation.eigenvalues().minCoeff(), 200 - 1e-9);
    EXPECT_LE(translation.eigenvalues().maxCoeff(), 1500 + 1e-9);
    EXPECT_GE(rotation.eigenvalues().minCoeff(), 30 - 1e-9);
    EXPECT_LE(rotation.eigenvalues().maxCoeff(), 150 + 1e-9);
    EXPECT_GE(Eigen::SelfAdjointEigenSolver<ci::Matrix6d>(k).eigenvalues()[0], -1e-9);
    // Principal axes unchanged: the saturated block commutes with the original one.
    const Eigen::Matrix3d t = k.topLeftCorner<3, 3>();
    EXPECT_LE((t * translation_before - translation_before * t).cwiseAbs().maxCoeff(),
              1e-9 * 4000 * 4000);
  }
}

// --- nullspace projector ------------------------------------------------------------------------

// lambda = 0: J N tau_0 = 0 exactly up to round-off. The error of the normal equations grows with
// cond(J)^2 * eps; cond < 100 bounds it by about 1e4 * 2.2e-16 * |tau_0| ~ 1e-10 for |tau_0| ~ 50.
TEST(NullspaceProjector, ExactProjectorAnnihilatesTaskSpace) {
  std::mt19937 rng(7);
  ci::NullspaceProjector projector;
  for (int n : {6, 7, 9, 12}) {
    for (int trial = 0; trial < 200; ++trial) {
      const ci::Jacobian jacobian = random_jacobian(n, rng);
      const ci::JointVector tau_0 = random_joints(n, rng, 50.0);
      ci::JointVector projected(n);
      projector.project(jacobian, 0.0, tau_0, projected);
      const ci::Vector6d task = jacobian * projected;
      EXPECT_LE(task.cwiseAbs().maxCoeff(), 1e-10) << "n = " << n;
      // Idempotent and symmetric (an orthogonal projector).
      const ci::JointMatrix n_matrix = law_reference::nullspace_matrix(projector, jacobian, 0.0);
      EXPECT_LE((n_matrix * n_matrix - n_matrix).cwiseAbs().maxCoeff(), 1e-10);
      EXPECT_LE((n_matrix - n_matrix.transpose()).cwiseAbs().maxCoeff(), 1e-10);
      if (n == 6) {
        EXPECT_LE(projected.cwiseAbs().maxCoeff(), 1e-10);
      }
    }
  }
}

// lambda > 0 gives I - J^T (J J^T + lambda^2 I)^-1 J, here evaluated with an explicit inverse.
// When n < 6 the 6x6 matrix has eigenvalues as small as lambda^2, so the explicit inverse loses
// about eps * |J|^2 / lambda^2; the tolerance follows that with a factor of ten.
TEST(NullspaceProjector, DampedProjectorMatchesFormula) {
  std::mt19937 rng(8);
  ci::NullspaceProjector projector;
  for (int n : {3, 5, 6, 7}) {
    for (int trial = 0; trial < 100; ++trial) {
      const ci::Jacobian jacobian = random_jacobian(n, rng);
      const double lambda = uniform(rng, 0.001, 0.5);
      const Eigen::MatrixXd j = jacobian;
      const Eigen::MatrixXd gram =
          j * j.transpose() + lambda * lambda * Eigen::MatrixXd::Identity(6, 6);
      const Eigen::MatrixXd expected =
          Eigen::MatrixXd::Identity(n, n) - j.transpose() * gram.inverse() * j;
      const Eigen::MatrixXd actual = law_reference::nullspace_matrix(projector, jacobian, lambda);
      EXPECT_LE((actual - expected).cwiseAbs().maxCoeff(), 1e-14 / (lambda * lambda) + 1e-11)
          << "n = " << n << ", lambda = " << lambda;
    }
  }
}

// Fewer than six joints: a full-rank J leaves no nullspace, N = 0 (J J^T is singular here, which
// is why this case is solved through J^T J).
TEST(NullspaceProjector, FewerThanSixJointsHaveNoNullspace) {
  std::mt19937 rng(9);
  ci::NullspaceProjector projector;
  for (int n = 1; n < 6; ++n) {
    const ci::Jacobian jacobian = random_jacobian(n, rng);
    const ci::JointMatrix n_matrix = law_reference::nullspace_matrix(projector, jacobian, 0.0);
    EXPECT_LE(n_matrix.cwiseAbs().maxCoeff(), 1e-12) << "n = " << n;
  }
}

// --- dynamics-aware pieces
// ------------------------------------------------------------------------

// The dynamically consistent projector: a projected torque causes no end-effector acceleration,
// J M^-1 N tau_0 = 0 (lambda = 0), for any positive definite M. Round-off as for the kinematic one,
// with M's condition number (below 100 here) on top.
TEST(NullspaceProjector, DynamicallyConsistentProjectionCausesNoTaskAcceleration) {
  std::mt19937 rng(10);
  ci::NullspaceProjector projector;
  for (int trial = 0; trial < 100; ++trial) {
    const int n = 7;
    const ci::Jacobian jacobian = random_jacobian(n, rng);
    ci::JointMatrix a(n, n);
    for (Eigen::Index i = 0; i < a.size(); ++i) a.data()[i] = uniform(rng, -1, 1);
    const ci::JointMatrix mass = a * a.transpose() + 0.5 * ci::JointMatrix::Identity(n, n);
    const ci::JointMatrix projector_matrix =
        law_reference::nullspace_matrix(projector, jacobian, mass, 0.0);
    const ci::JointVector tau_0 = random_joints(n, rng, 50.0);
    const ci::Vector6d acceleration =
        jacobian * mass.llt().solve(ci::JointVector(projector_matrix * tau_0));
    EXPECT_LE(acceleration.cwiseAbs().maxCoeff(), 1e-9);
    // It is a projector (idempotent), though not a symmetric one.
    EXPECT_LE((projector_matrix * projector_matrix - projector_matrix).cwiseAbs().maxCoeff(), 1e-9);
  }
}

// Inertia-shaped damping: with diagonal inertia and stiffness it is d = 2 zeta sqrt(m k) per axis,
// and in general, in coordinates where the inertia is the identity (Lambda = L L^T), it is twice
// the square root of the stiffness there: (L^-1 D L^-T)^2 = 4 L^-1 K L^-T for zeta = 1.
TEST(Damping, InertiaShapedDampingIsCriticalPerMode) {
  ci::Matrix6d inertia = ci::Matrix6d::Zero(), stiffness = ci::Matrix6d::Zero();
  inertia.diagonal() << 2, 3, 4, 0.1, 0.2, 0.3;
  stiffness.diagonal() << 500, 600, 700, 50, 60, 70;
  ci::Vector6d zeta;
  zeta << 1, 0.7, 0.5, 1, 1.2, 0.8;
  const ci::Matrix6d damping = law_reference::inertia_shaped_damping(stiffness, zeta, inertia);
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(damping(i, i), 2 * zeta[i] * std::sqrt(inertia(i, i) * stiffness(i, i)), 1e-9);
  }
  EXPECT_LE((damping - ci::Matrix6d(damping.diagonal().asDiagonal())).cwiseAbs().maxCoeff(), 1e-9);

  std::mt19937 rng(11);
  for (int trial = 0; trial < 50; ++trial) {
    const ci::Matrix6d k = random_stiffness(rng);
    const ci::Matrix6d m = random_stiffness(rng, 0.5, 5.0);  // any SPD matrix serves as inertia
    const ci::Matrix6d d = law_reference::inertia_shaped_damping(k, ci::Vector6d::Ones(), m);
    const Eigen::LLT<ci::Matrix6d> llt(m);
    const ci::Matrix6d lower = llt.matrixL();
    const ci::Matrix6d l_inverse = lower.inverse();
    const ci::Matrix6d d_normalised = l_inverse * d * l_inverse.transpose();
    const ci::Matrix6d k_normalised = l_inverse * k * l_inverse.transpose();
    EXPECT_LE((d_normalised * d_normalised - 4 * k_normalised).cwiseAbs().maxCoeff(),
              1e-8 * k_normalised.cwiseAbs().maxCoeff());
    EXPECT_LE((d - d.transpose()).cwiseAbs().maxCoeff(), 1e-8 * d.cwiseAbs().maxCoeff());
  }
}
