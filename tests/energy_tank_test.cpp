// The energy tank (safety.energy_tank) as properties of the controller, without a simulation: a
// unit point mass whose joints are the Cartesian axes (J = I, the rotation held still), integrated
// exactly over each cycle under the torque the controller holds for it. With the reference fixed,
// the tank's ledger then balances to the integrator's own error: kinetic + spring + tank never
// grows by more than what a spring force held for a cycle adds (1/2 dx^T K dx) and the damper's
// share of the same (1/2 dt^2 (D v)^T F), whatever the stiffness schedule.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "cartesian_impedance/core/controller.hpp"
#include "support/random_cases.hpp"

namespace ci = cartesian_impedance;
using random_cases::uniform;

namespace {

constexpr double kDt = 0.001;

// Filters off, no limit in the way of the law (the torque is -K e - D v exactly), no nullspace
// (pseudo_inverse_damping 0: with J = I the projector is zero), unit-mass damping: the point mass
// below is the arm the law assumes.
ci::Parameters point_mass_parameters() {
  ci::Parameters p;
  p.dynamics.inertia_shaped_damping = false;
  p.filter.pose.time = p.filter.stiffness.time = p.filter.nullspace.time = p.filter.wrench.time =
      0.0;
  p.limits.pose_error = {10.0, M_PI};
  p.limits.joint_torque = ci::JointVector::Constant(1, 1e4);
  p.limits.joint_torque_rate = ci::JointVector::Constant(1, 1e6);
  p.nullspace.stiffness = ci::JointVector::Constant(1, 0.0);
  p.nullspace.pseudo_inverse_damping = 0.0;
  p.minimum_damping = {0.0, 0.0, 0.0};
  p.stiffness.translation.setConstant(200.0);
  p.safety.energy_tank = {true, 0.005, 0.005};
  return p;
}

// A unit point mass moving in x, y, z; its orientation is held still (the rotational joints are
// locked, so the law's torque on them does no work). One cycle integrates the force the law holds
// for dt exactly: x += v dt + F dt^2 / 2, v += F dt, so the kinetic energy grows by F . dx exactly.
struct PointMass {
  Eigen::Vector3d position = Eigen::Vector3d(0.4, 0.0, 0.5);
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();

  ci::RobotState state() const {
    ci::RobotState robot = ci::make_robot_state(6);
    robot.jacobian = ci::Jacobian::Identity(6, 6);
    robot.q.head<3>() = position;
    robot.dq.head<3>() = velocity;
    robot.pose.position = position;
    robot.pose.orientation = orientation;
    return robot;
  }
  void step(const ci::JointVector& tau) {
    const Eigen::Vector3d force = tau.head<3>();
    position += velocity * kDt + 0.5 * force * kDt * kDt;
    velocity += force * kDt;
  }
};

// The energy of the spring -K clip(e), clip(e) = e shortened to at most c: 1/2 e^T K e within c,
// growing by c u^T K u per metre beyond it (u = e / |e|). It is the spring's potential for an
// isotropic K (the force is its gradient); an anisotropic clipped spring has none.
double spring_energy(const Eigen::Matrix3d& stiffness, const Eigen::Vector3d& error, double clip) {
  const double length = error.norm();
  if (length <= clip) return 0.5 * error.dot(stiffness * error);
  const Eigen::Vector3d clipped = (clip / length) * error;
  return 0.5 * clipped.dot(stiffness * clipped) +
         (length - clip) / clip * clipped.dot(stiffness * clipped);
}

// The tank's ledger over one run, cycle by cycle. E_k = 1/2 |v_k|^2 + V_k(e_k) + the level after
// cycle k paid for its stiffness change and before the damping of cycle k refills it (that refill
// belongs to the motion of the cycle that follows). With the reference fixed:
//   E_{k+1} - E_k = [V_k(e_{k+1}) - V_k(e_k) - F_spring,k . dx] - 1/2 dt^2 (D_k v_k)^T F_k
//                   - what the full tank spilled,
// because the cost of cycle k+1's change is exactly what the spring's energy gains from it,
// V_{k+1}(e_{k+1}) - V_k(e_{k+1}), and the refill v_k^T D_k v_k dt differs from the damper's work
// on dx by the second term. The two terms are the integration error: what a force held for a
// cycle does differently from one that follows the motion. The first is 1/2 dx^T K_k dx within
// the clip and at most that beyond it (the clipped spring is softer).
struct Ledger {
  int cycles = 0;
  int rises_beyond_integration = 0;   // E grew by more than the integration error
  int unbalanced = 0;                 // the ledger's equation above missed by more than round-off
  int level_outside = 0;              // the level left [0, capacity]
  int waited = 0;                     // cycles with stiffness_change_scale < 1
  double largest_excess = -INFINITY;  // largest E_{k+1} - E_k - integration error [J]
  double energy_growth = 0.0;         // E at the end - E at the start [J]
  double integration = 0.0;           // sum of the integration error bounds [J]
};

class LedgerKeeper {
 public:
  LedgerKeeper(const ci::Parameters& parameters, const Eigen::Vector3d& reference)
      : capacity_(parameters.safety.energy_tank.capacity),
        clip_(parameters.limits.pose_error.translation),
        tank_(parameters.safety.energy_tank.enabled),
        reference_(reference),
        level_(parameters.safety.energy_tank.initial) {}

  // After controller.update() at `arm`'s state.
  void record(const ci::CartesianImpedanceController& controller, const PointMass& arm) {
    const ci::ControllerState& state = controller.state();
    const Eigen::Vector3d error = arm.position - reference_;
    const Eigen::Matrix3d stiffness = state.stiffness_base().topLeftCorner<3, 3>();
    const double paid_level = tank_ ? level_ - state.safety.tank_draw : 0.0;
    const double energy =
        0.5 * arm.velocity.squaredNorm() + spring_energy(stiffness, error, clip_) + paid_level;
    const bool spilled = tank_ && state.safety.tank_level >= capacity_;
    if (ledger.cycles > 0) {
      const double rise = energy - energy_;
      const Eigen::Vector3d dx = error - error_;
      const double spring_term = spring_energy(stiffness_, error, clip_) -
                                 spring_energy(stiffness_, error_, clip_) - spring_force_.dot(dx);
      const double damper_term = 0.5 * kDt * kDt * damper_force_.dot(force_);
      // What one cycle's integration adds, bounded (|.| on the damper's term, which has either
      // sign) and exactly (the ledger's equation); round-off: 1e-12 of the energies involved.
      const double bound = 0.5 * dx.dot(stiffness_ * dx) + std::abs(damper_term);
      const double round_off = 1e-12 * (1.0 + std::abs(energy) + std::abs(energy_));
      ledger.largest_excess = std::max(ledger.largest_excess, rise - bound);
      ledger.rises_beyond_integration += rise > bound + round_off;
      if (!spilled_ && std::abs(rise - (spring_term - damper_term)) > round_off)
        ++ledger.unbalanced;
      ledger.integration += bound;
      ledger.energy_growth += rise;
    }
    ledger.level_outside +=
        tank_ && !(state.safety.tank_level >= 0.0 && state.safety.tank_level <= capacity_);
    ledger.waited += state.safety.stiffness_change_scale < 1.0;
    ++ledger.cycles;
    energy_ = energy;
    spilled_ = spilled;
    level_ = state.safety.tank_level;
    error_ = error;
    stiffness_ = stiffness;
    // The spring's force on the arm is -K clip(e); F_spring . dx is minus its work.
    Eigen::Vector3d clipped = error;
    if (error.norm() > clip_) clipped *= clip_ / error.norm();
    spring_force_ = stiffness * clipped;
    damper_force_ = state.damping_base().topLeftCorner<3, 3>() * arm.velocity;
    force_ = controller.torque().head<3>();
  }

  Ledger ledger;

 private:
  double capacity_;
  double clip_;
  bool tank_;
  Eigen::Vector3d reference_;
  double level_;
  double energy_ = 0.0;
  bool spilled_ = false;
  Eigen::Vector3d error_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d stiffness_ = Eigen::Matrix3d::Zero();
  Eigen::Vector3d spring_force_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d damper_force_ = Eigen::Vector3d::Zero(), force_ = Eigen::Vector3d::Zero();
};

// A random stiffness within `largest` [N/m]: diagonal or a full symmetric matrix with a
// translation-rotation coupling, every second one.
ci::Matrix6d random_stiffness(std::mt19937& rng, double largest) {
  if (uniform(rng, 0.0, 1.0) < 0.5) {
    ci::Vector6d diagonal;
    for (int i = 0; i < 3; ++i) diagonal[i] = uniform(rng, 0.0, largest);
    for (int i = 3; i < 6; ++i) diagonal[i] = uniform(rng, 0.0, 0.1 * largest);
    return diagonal.asDiagonal();
  }
  return random_cases::random_stiffness(rng, 0.0, largest);
}

// One seeded run: the point mass starts up to 30 mm off a fixed reference at up to 0.1 m/s, and
// the stiffness is commanded anew at random cycles (a fresh random matrix, or a jump between a
// soft and a stiff value, on a filter that is off or 50 ms), the damping ratio now and then
// too; in the base frame or the end effector's, which is turned, and switched between them. With
// `clip` [m], the pose error is clipped there (limits.pose_error.translation), the arm starts 1.5
// to 3 times as far off and the stiffness stays isotropic (the clipped spring has a potential
// then).
Ledger random_schedule(unsigned seed, bool tank, double clip = 0.0) {
  std::mt19937 rng(seed);
  ci::Parameters p = point_mass_parameters();
  const bool clipped = clip > 0.0;
  if (clipped) p.limits.pose_error.translation = clip;
  p.safety.energy_tank.enabled = tank;
  p.safety.energy_tank.initial = uniform(rng, 0.0, p.safety.energy_tank.capacity);
  p.filter.stiffness.time = uniform(rng, 0.0, 1.0) < 0.5 ? 0.0 : 0.05;
  p.stiffness.frame = uniform(rng, 0.0, 1.0) < 0.5 ? ci::Frame::base : ci::Frame::end_effector;
  p.damping_ratio.translation.setConstant(uniform(rng, 0.1, 1.0));
  PointMass arm;
  arm.orientation = random_cases::random_rotation(rng);
  ci::CartesianImpedanceController controller(6, p);
  controller.start(arm.state());
  const Eigen::Vector3d reference = arm.position;
  const double offset = clipped ? uniform(rng, 1.5, 3.0) * clip : uniform(rng, 0.0, 0.03);
  arm.position += offset * random_cases::random_unit_vector(rng);
  arm.velocity = 0.1 * uniform(rng, 0.0, 1.0) * random_cases::random_unit_vector(rng);
  const double largest = p.limits.stiffness.translation.max;
  LedgerKeeper keeper(p, reference);
  for (int k = 0; k < 3000; ++k) {
    const double draw = uniform(rng, 0.0, 1.0);
    if (draw < 0.05 && !clipped) {
      // Now and then in the other frame: the same numbers there are another spring in the base
      // frame, which the filter moves to as the tank pays.
      const ci::Matrix6d stiffness = random_stiffness(rng, largest);
      if (uniform(rng, 0.0, 1.0) < 0.3) {
        controller.set_stiffness_matrix(
            stiffness, uniform(rng, 0.0, 1.0) < 0.5 ? ci::Frame::base : ci::Frame::end_effector);
      } else {
        controller.set_stiffness_matrix(stiffness);
      }
    } else if (draw < 0.15) {
      // The pumping kind: soft or stiff, isotropic.
      const double k_t = uniform(rng, 0.0, 1.0) < 0.5 ? 0.04 * largest : 0.6 * largest;
      controller.set_stiffness(
          (ci::Vector6d() << k_t, k_t, k_t, 0.1 * k_t, 0.1 * k_t, 0.1 * k_t).finished());
    } else if (draw < 0.16) {
      controller.set_damping_ratio(ci::Vector6d::Constant(uniform(rng, 0.1, 1.0)));
    }
    EXPECT_EQ(controller.update(arm.state(), kDt), ci::Status::ok);
    keeper.record(controller, arm);
    arm.step(controller.torque());
  }
  return keeper.ledger;
}

ci::Vector6d translation(double k, double rotation = 50.0) {
  return (ci::Vector6d() << k, k, k, rotation, rotation, rotation).finished();
}

}  // namespace

// Over seeded random stiffness schedules with the reference fixed, the total energy (kinetic +
// spring + tank) never grows by more than the cycle's integration error, and the ledger balances
// to round-off wherever the tank did not spill over its capacity.
TEST(EnergyTank, TotalEnergyNeverGrowsBeyondTheIntegrationError) {
  int waited = 0;
  for (unsigned seed = 1; seed <= 24; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Ledger ledger = random_schedule(seed, true);
    EXPECT_EQ(ledger.rises_beyond_integration, 0)
        << "largest excess " << ledger.largest_excess << " J";
    EXPECT_EQ(ledger.unbalanced, 0);
    EXPECT_LE(ledger.energy_growth, ledger.integration);
    waited += ledger.waited;
  }
  // The schedules are adversarial enough that the tank had to hold raises back.
  EXPECT_GT(waited, 1000);
}

// The mutant: the same schedules without the tank create energy beyond the integration error (in
// one cycle by 0.05 mJ to 0.9 J, a raise at a large error), so the property above can fail.
TEST(EnergyTank, WithoutItTheSameSchedulesCreateEnergy) {
  int created = 0;
  for (unsigned seed = 1; seed <= 24; ++seed) {
    const Ledger ledger = random_schedule(seed, false);
    created += ledger.rises_beyond_integration > 0 && ledger.largest_excess > 1e-6;
  }
  EXPECT_EQ(created, 24);
}

// Beyond limits.pose_error the spring's force stays at its value at the clip, so a raise there
// stores more than 1/2 e_c^T dK e_c: c u^T dK u for every metre beyond. The tank charges that
// too, or a schedule that keeps the arm beyond the clip would gain energy with every raise.
TEST(EnergyTank, BeyondThePoseErrorClipARaiseCostsWhatTheClippedSpringStores) {
  for (unsigned seed = 1; seed <= 24; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Ledger ledger = random_schedule(seed, true, 0.02);
    EXPECT_EQ(ledger.rises_beyond_integration, 0)
        << "largest excess " << ledger.largest_excess << " J";
    EXPECT_EQ(ledger.unbalanced, 0);
  }
}

TEST(EnergyTank, LevelStaysWithinZeroAndCapacity) {
  for (unsigned seed = 1; seed <= 24; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_EQ(random_schedule(seed, true).level_outside, 0);
  }
}

// A raise the tank cannot pay for whole takes what is in it, and no more: at rest (no damping
// refills it in the same cycle) the tank is then empty, not a rounding error below empty
// (level - cost * (level / cost) is negative for about one level and cost in twenty).
TEST(EnergyTank, APartialRaiseEmptiesTheTankExactly) {
  std::mt19937 rng(17);
  int below = 0;
  for (int trial = 0; trial < 200; ++trial) {
    ci::Parameters p = point_mass_parameters();
    p.safety.energy_tank.initial = uniform(rng, 1e-4, p.safety.energy_tank.capacity);
    PointMass arm;
    ci::CartesianImpedanceController controller(6, p);
    controller.start(arm.state());
    arm.position += uniform(rng, 0.01, 0.02) * random_cases::random_unit_vector(rng);
    ASSERT_EQ(controller.update(arm.state(), kDt), ci::Status::ok);
    controller.set_stiffness(translation(uniform(rng, 2000.0, 3000.0)));
    ASSERT_EQ(controller.update(arm.state(), kDt), ci::Status::ok);
    const ci::SafetyState& safety = controller.state().safety;
    ASSERT_LT(safety.stiffness_change_scale, 1.0);
    EXPECT_EQ(safety.tank_draw, p.safety.energy_tank.initial);
    below += !(safety.tank_level >= 0.0);
    EXPECT_EQ(safety.tank_level, 0.0) << "trial " << trial;
  }
  EXPECT_EQ(below, 0);
}

// A raise from 200 to 3000 N/m while the arm rests 10 mm off its reference would store 0.14 J in
// the spring; with the tank empty none of it is applied, and as the soft spring pulls the arm in,
// the damping refills the tank and the raise goes on as far as that pays for, until it is done.
TEST(EnergyTank, RaiseWithAnEmptyTankWaitsAndCompletesOnceDampingRefillsIt) {
  ci::Parameters p = point_mass_parameters();
  p.safety.energy_tank.initial = 0.0;
  PointMass arm;
  ci::CartesianImpedanceController controller(6, p);
  controller.start(arm.state());
  arm.position.x() += 0.01;
  ASSERT_EQ(controller.update(arm.state(), kDt), ci::Status::ok);
  arm.step(controller.torque());
  controller.set_stiffness(translation(3000.0));
  ASSERT_EQ(controller.update(arm.state(), kDt), ci::Status::ok);
  const ci::SafetyState& safety = controller.state().safety;
  EXPECT_EQ(safety.stiffness_change_scale, 0.0);
  EXPECT_EQ(controller.state().filtered.stiffness(0, 0), 200.0);
  EXPECT_EQ(safety.tank_draw, 0.0);
  double level = safety.tank_level, drawn = 0.0, filled = level, completed_at = -1.0;
  int partial = 0;
  for (int k = 1; k <= 3000 && completed_at < 0.0; ++k) {
    arm.step(controller.torque());
    ASSERT_EQ(controller.update(arm.state(), kDt), ci::Status::ok);
    const ci::SafetyState& now = controller.state().safety;
    // Never more than the tank held.
    EXPECT_LE(now.tank_draw, level + 1e-18) << "cycle " << k;
    drawn += now.tank_draw;
    filled += now.tank_level - (level - now.tank_draw);
    partial += now.stiffness_change_scale > 0.0 && now.stiffness_change_scale < 1.0;
    level = now.tank_level;
    if (controller.state().filtered.stiffness(0, 0) == 3000.0) completed_at = k * kDt;
  }
  EXPECT_GT(partial, 10) << "the raise should have gone on a little at a time";
  ASSERT_GT(completed_at, 0.0) << "the raise never completed";
  // The damping paid for it: what was drawn came out of what the damping put in.
  EXPECT_LE(drawn, filled + 1e-15);
}

// Lowering K from 3000 to 200 N/m at rest 13.2 mm off the reference gives the tank the spring's
// 1/2 dK |e|^2; raising it back at the same pose costs exactly that, and the tank is empty again.
// A full tank keeps no more than its capacity.
TEST(EnergyTank, LoweringReturnsTheSpringsEnergy) {
  ci::Parameters p = point_mass_parameters();
  p.stiffness.translation.setConstant(3000.0);
  p.safety.energy_tank = {true, 1.0, 0.0};
  PointMass arm;
  ci::CartesianImpedanceController controller(6, p);
  controller.start(arm.state());
  const Eigen::Vector3d error(0.01, -0.005, 0.007);
  arm.position += error;
  ASSERT_EQ(controller.update(arm.state(), kDt), ci::Status::ok);
  EXPECT_EQ(controller.state().safety.tank_level, 0.0);
  const double returned = 0.5 * 2800.0 * error.squaredNorm();
  controller.set_stiffness(translation(200.0));
  ASSERT_EQ(controller.update(arm.state(), kDt), ci::Status::ok);
  EXPECT_NEAR(controller.state().safety.tank_draw, -returned, 1e-15);
  EXPECT_NEAR(controller.state().safety.tank_level, returned, 1e-15);
  controller.set_stiffness(translation(3000.0));
  ASSERT_EQ(controller.update(arm.state(), kDt), ci::Status::ok);
  EXPECT_EQ(controller.state().safety.stiffness_change_scale, 1.0);
  EXPECT_EQ(controller.state().filtered.stiffness(0, 0), 3000.0);
  EXPECT_NEAR(controller.state().safety.tank_draw, returned, 1e-15);
  EXPECT_NEAR(controller.state().safety.tank_level, 0.0, 1e-15);

  p.safety.energy_tank = {true, 0.005, 0.0};
  ci::CartesianImpedanceController capped(6, p);
  capped.start(arm.state());
  arm.position += error;
  ASSERT_EQ(capped.update(arm.state(), kDt), ci::Status::ok);
  capped.set_stiffness(translation(200.0));
  ASSERT_EQ(capped.update(arm.state(), kDt), ci::Status::ok);
  EXPECT_EQ(capped.state().safety.tank_level, 0.005);
}

// With safety.energy_tank.enabled = false the law is the law without a tank: the commanded raise
// at once (filters off), the torque -K e - 2 zeta sqrt(K) v, the tank neither drawn nor filled.
TEST(EnergyTank, DisabledGivesTheUntouchedLaw) {
  ci::Parameters p = point_mass_parameters();
  p.safety.energy_tank = {false, 0.005, 0.0};
  std::mt19937 rng(5);
  PointMass arm;
  ci::CartesianImpedanceController controller(6, p);
  controller.start(arm.state());
  const Eigen::Vector3d reference = arm.position;
  arm.position += Eigen::Vector3d(0.01, 0.004, -0.006);
  for (int k = 0; k < 2000; ++k) {
    if (k % 50 == 0) controller.set_stiffness(translation(uniform(rng, 0.0, 3000.0)));
    ASSERT_EQ(controller.update(arm.state(), kDt), ci::Status::ok);
    const ci::ControllerState& state = controller.state();
    const ci::Vector6d k_diagonal = state.commanded.stiffness.diagonal();
    EXPECT_EQ(state.filtered.stiffness.diagonal(), k_diagonal);
    const ci::Vector6d zeta = state.filtered.damping_ratio;
    const Eigen::Vector3d expected =
        -k_diagonal.head<3>().cwiseProduct(arm.position - reference) -
        (2.0 * zeta.head<3>().cwiseProduct(k_diagonal.head<3>().cwiseSqrt()))
            .cwiseProduct(arm.velocity);
    EXPECT_LE((controller.torque().head<3>() - expected).norm(), 1e-12 * (1.0 + expected.norm()));
    EXPECT_EQ(state.safety.tank_level, 0.0);
    EXPECT_EQ(state.safety.tank_draw, 0.0);
    EXPECT_EQ(state.safety.stiffness_change_scale, 1.0);
    arm.step(controller.torque());
  }
}

// schedule() gives K and D directly (a learned policy or the published controller's API), and the
// tank stays out of it: an empty tank does not hold a raise back, a lowering returns nothing.
TEST(EnergyTank, ScheduleBypassesIt) {
  ci::Parameters p = point_mass_parameters();
  p.safety.energy_tank.initial = 0.0;
  PointMass arm;
  ci::CartesianImpedanceController controller(6, p);
  controller.start(arm.state());
  const ci::Pose reference{arm.position, arm.orientation};
  arm.position += Eigen::Vector3d(0.01, 0.0, 0.0);
  arm.velocity = Eigen::Vector3d(-0.05, 0.0, 0.0);
  for (const double k : {3000.0, 200.0}) {
    ci::ScheduledImpedance impedance;
    impedance.reference = reference;
    impedance.stiffness = translation(k).asDiagonal();
    impedance.damping = ci::Vector6d::Constant(20.0).asDiagonal();
    impedance.nullspace_q = ci::JointVector::Zero(6);
    impedance.nullspace_stiffness = ci::JointVector::Zero(6);
    impedance.nullspace_damping = ci::JointVector::Zero(6);
    impedance.wrench.setZero();
    controller.schedule(impedance);
    ASSERT_EQ(controller.update(arm.state(), kDt), ci::Status::ok);
    const ci::SafetyState& safety = controller.state().safety;
    EXPECT_EQ(safety.tank_level, 0.0);
    EXPECT_EQ(safety.tank_draw, 0.0);
    EXPECT_EQ(safety.stiffness_change_scale, 1.0);
    EXPECT_NEAR(controller.torque()[0], -k * 0.01 - 20.0 * -0.05, 1e-12) << "K = " << k;
  }
}
