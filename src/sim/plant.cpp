// The plant of a Simulation (plant.hpp): the model error written into the MuJoCo model once, and
// the sensors and drives between the engine's state and what the controller reads and commands.

#include "cartesian_impedance/sim/plant.hpp"

#include <cmath>
#include <string>
#include <vector>

#include "cartesian_impedance/core/checks.hpp"
#include "cartesian_impedance/core/error.hpp"
#include "plant_state.hpp"

namespace cartesian_impedance::sim {

PlantOptions PlantOptions::realistic(std::uint64_t seed) {
  PlantOptions plant;
  plant.seed = seed;
  plant.inertia = {0.7, 1.3};
  plant.center_of_mass_offset = 0.01;
  plant.friction = {0.5, 1.5};
  plant.damping = {0.8, 1.2};
  plant.armature = {0.8, 1.2};
  plant.measurement_delay = 0.001;
  plant.position_noise = 1e-5;
  plant.velocity_noise = 0.005;
  plant.position_resolution = 2.0 * M_PI / 524288.0;  // a 19-bit encoder
  plant.actuation_delay = 0.001;
  plant.torque_noise = 0.05;
  plant.torque_sensor_noise = 0.05;
  return plant;
}

namespace {
bool exact(const Spread& spread) {
  return spread.low == 1.0 && spread.high == 1.0;
}
}  // namespace

namespace detail {
bool changes_model(const PlantOptions& plant) noexcept {
  return !exact(plant.inertia) || plant.center_of_mass_offset != 0.0 || !exact(plant.friction) ||
         !exact(plant.damping) || !exact(plant.armature);
}
}  // namespace detail

bool PlantOptions::nominal() const noexcept {
  return !detail::changes_model(*this) && measurement_delay == 0.0 && position_noise == 0.0 &&
         velocity_noise == 0.0 && position_resolution == 0.0 && actuation_delay == 0.0 &&
         torque_noise == 0.0 && torque_sensor_noise == 0.0;
}

PlantOptions plant_from_name(const std::string& name, std::uint64_t seed) {
  if (name == "nominal") return PlantOptions{};
  if (name == "realistic") return PlantOptions::realistic(seed);
  throw Error("plant '" + name + "' is not known (valid: nominal, realistic)");
}

namespace detail {
namespace {

void check_spread(const Spread& spread, const char* field) {
  // A factor of 0 would leave a link without mass; beyond 10 it is not an error of a model.
  if (!std::isfinite(spread.low) || !std::isfinite(spread.high) || spread.low < 0.1 ||
      spread.high > 10.0 || spread.low > spread.high) {
    throw Error(std::string("SimulationOptions.plant.") + field + " = [" +
                format_number(spread.low) + ", " + format_number(spread.high) +
                "] is not a range within [0.1, 10] (low <= high)");
  }
}

void check_amount(double value, double high, const char* field, const char* unit) {
  if (!std::isfinite(value) || value < 0.0 || value > high) {
    throw Error(std::string("SimulationOptions.plant.") + field + " = " + format_number(value) +
                " " + unit + " is not within [0, " + format_number(high) + "]");
  }
}

// Whole timesteps of `delay`.
int steps_of(double delay, double timestep) {
  return static_cast<int>(std::lround(delay / timestep));
}

}  // namespace

void check_plant(const PlantOptions& plant) {
  check_spread(plant.inertia, "inertia");
  check_spread(plant.friction, "friction");
  check_spread(plant.damping, "damping");
  check_spread(plant.armature, "armature");
  check_amount(plant.center_of_mass_offset, 0.1, "center_of_mass_offset", "m");
  check_amount(plant.measurement_delay, 1.0, "measurement_delay", "s");
  check_amount(plant.actuation_delay, 1.0, "actuation_delay", "s");
  check_amount(plant.position_noise, 0.1, "position_noise", "rad");
  check_amount(plant.velocity_noise, 10.0, "velocity_noise", "rad/s");
  check_amount(plant.position_resolution, 0.1, "position_resolution", "rad");
  check_amount(plant.torque_noise, 100.0, "torque_noise", "Nm");
  check_amount(plant.torque_sensor_noise, 100.0, "torque_sensor_noise", "Nm");
}

std::vector<int> perturb_model(mjModel* m, const std::vector<int>& joint_ids,
                               const std::vector<int>& exact_bodies, const PlantOptions& plant) {
  std::mt19937_64 random(plant.seed);
  auto draw = [&random](const Spread& spread) {
    return std::uniform_real_distribution<double>(spread.low, spread.high)(random);
  };
  // The moving links: every body below an exchanged joint's body, except the exact ones (what
  // a user attached: a known load).
  std::vector<bool> moving(static_cast<std::size_t>(m->nbody), false);
  for (const int joint : joint_ids) moving[static_cast<std::size_t>(m->jnt_bodyid[joint])] = true;
  for (int body = 1; body < m->nbody; ++body) {
    if (moving[static_cast<std::size_t>(m->body_parentid[body])]) {
      moving[static_cast<std::size_t>(body)] = true;
    }
  }
  for (const int body : exact_bodies) moving[static_cast<std::size_t>(body)] = false;
  std::vector<int> perturbed;
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int body = 1; body < m->nbody; ++body) {
    if (!moving[static_cast<std::size_t>(body)] || m->body_mass[body] <= 0.0) continue;
    const double factor = draw(plant.inertia);
    m->body_mass[body] *= factor;
    for (int k = 0; k < 3; ++k) m->body_inertia[3 * body + k] *= factor;
    if (plant.center_of_mass_offset > 0.0) {
      // Uniform in the ball: a direction on the sphere, a radius r cbrt(u).
      double direction[3] = {normal(random), normal(random), normal(random)};
      const double length = std::sqrt(direction[0] * direction[0] + direction[1] * direction[1] +
                                      direction[2] * direction[2]);
      const double radius = plant.center_of_mass_offset * std::cbrt(unit(random));
      for (int k = 0; k < 3; ++k) {
        m->body_ipos[3 * body + k] += length > 0.0 ? radius * direction[k] / length : 0.0;
      }
    }
    perturbed.push_back(body);
  }
  for (const int joint : joint_ids) {
    const int dof = m->jnt_dofadr[joint];
    m->dof_frictionloss[dof] *= draw(plant.friction);
    m->dof_damping[dof] *= draw(plant.damping);
    m->dof_armature[dof] *= draw(plant.armature);
  }
  return perturbed;
}

void PlantState::configure(const PlantOptions& plant, double timestep, int joints) {
  plant_ = plant;
  measurement_steps_ = steps_of(plant.measurement_delay, timestep);
  actuation_steps_ = steps_of(plant.actuation_delay, timestep);
  senses_ = measurement_steps_ > 0 || plant.position_noise > 0.0 || plant.velocity_noise > 0.0 ||
            plant.position_resolution > 0.0 || plant.torque_sensor_noise > 0.0;
  actuates_ = actuation_steps_ > 0 || plant.torque_noise > 0.0;
  q_ring_.assign(static_cast<std::size_t>(measurement_steps_ + 1), JointVector::Zero(joints));
  dq_ring_ = q_ring_;
  sensed_ring_ = q_ring_;
  tau_ring_.assign(static_cast<std::size_t>(actuation_steps_ + 1), JointVector::Zero(joints));
}

void PlantState::restart(const JointVector& q, const JointVector& dq, const JointVector& sensed,
                         bool reseed) {
  for (JointVector& entry : q_ring_) entry = q;
  for (JointVector& entry : dq_ring_) entry = dq;
  for (JointVector& entry : sensed_ring_) entry = sensed;
  for (JointVector& entry : tau_ring_) entry.setZero();
  q_head_ = 0;
  tau_head_ = 0;
  if (reseed) {
    random_.seed(plant_.seed ^ 0x9e3779b97f4a7c15ULL);
    sensor_random_.seed(plant_.seed ^ 0x5851f42d4c957f2dULL);
  }
  normal_.reset();
  sensor_normal_.reset();
}

void PlantState::measure(const JointVector& true_q, const JointVector& true_dq,
                         const JointVector& true_torque, JointVector& q, JointVector& dq,
                         JointVector& torque) noexcept {
  if (!senses_) {
    q = true_q;
    dq = true_dq;
    torque = true_torque;
    return;
  }
  // The ring holds the last measurement_steps_ + 1 states; the oldest is read.
  q_ring_[q_head_] = true_q;
  dq_ring_[q_head_] = true_dq;
  sensed_ring_[q_head_] = true_torque;
  q_head_ = (q_head_ + 1) % q_ring_.size();
  q = q_ring_[q_head_];
  dq = dq_ring_[q_head_];
  torque = sensed_ring_[q_head_];
  // Its own generator: the torque sensors leave the other readings' noise as it was.
  for (Eigen::Index i = 0; i < torque.size(); ++i) {
    torque[i] += plant_.torque_sensor_noise * sensor_normal_(sensor_random_);
  }
  for (Eigen::Index i = 0; i < q.size(); ++i) {
    q[i] += plant_.position_noise * normal_(random_);
    dq[i] += plant_.velocity_noise * normal_(random_);
    if (plant_.position_resolution > 0.0) {
      q[i] = plant_.position_resolution * std::round(q[i] / plant_.position_resolution);
    }
  }
}

void PlantState::actuate(const JointVector& command, JointVector& tau) noexcept {
  tau_ring_[tau_head_] = command;
  tau_head_ = (tau_head_ + 1) % tau_ring_.size();
  tau = tau_ring_[tau_head_];
  for (Eigen::Index i = 0; i < tau.size(); ++i) tau[i] += plant_.torque_noise * normal_(random_);
}

}  // namespace detail
}  // namespace cartesian_impedance::sim
