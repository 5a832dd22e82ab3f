#include "cartesian_impedance/model/start_configuration.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "cartesian_impedance/core/error.hpp"

namespace cartesian_impedance {

namespace {

constexpr double kPi = 3.14159265358979323846;

// splitmix64: a fixed sequence on every machine (std::uniform_real_distribution's is not).
class Random {
 public:
  explicit Random(std::uint64_t seed) : state_(seed) {}
  double uniform() {  // [0, 1)
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) * 0x1.0p-53;
  }

 private:
  std::uint64_t state_;
};

double clamp01(double x) {
  return std::min(1.0, std::max(0.0, x));
}

// 1 on [low, high], falling linearly to `floor` at `low - width` and `high + width`.
double plateau(double x, double low, double high, double width, double floor) {
  const double outside = x < low ? low - x : (x > high ? x - high : 0.0);
  return 1.0 - (1.0 - floor) * clamp01(outside / width);
}

struct Evaluation {
  double score = -1.0;  // -1: not evaluable
  double scaled_singular_value = 0.0;
  double singular_value = 0.0;
  double limit_distance = std::numeric_limits<double>::infinity();
  int closest_joint = -1;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d tool_axis = Eigen::Vector3d::UnitZ();  // the tool frame's z, base frame
};

class Scorer {
 public:
  Scorer(const RobotModel& model, const StartSearch& options)
      : model_(model),
        options_(options),
        workspace_(model),
        kinematics_(workspace_.make_kinematics()),
        zero_(JointVector::Zero(model.num_joints())) {
    const Eigen::Vector3d gravity = model.gravity_base();
    up_ = gravity.norm() > 1e-9 ? Eigen::Vector3d(-gravity.normalized()) : Eigen::Vector3d::UnitZ();
    front_ = Eigen::Vector3d::UnitX() - up_.x() * up_;  // base x in the horizontal plane
    if (front_.norm() > 1e-6) front_.normalize();
    const int n = model.num_joints();
    const JointLimits& limits = model.limits();
    low_.resize(n);
    high_.resize(n);
    ramp_.resize(n);
    step_.resize(n);
    for (int i = 0; i < n; ++i) {
      const double lower = limits.position_lower[i], upper = limits.position_upper[i];
      if (std::isfinite(lower) && std::isfinite(upper)) {
        const double half = 0.5 * (upper - lower);
        low_[i] = std::min(lower + options.limit_margin, lower + half);
        high_[i] = std::max(upper - options.limit_margin, upper - half);
        ramp_[i] = std::max(0.25 * (half - options.limit_margin), 1e-9);
        step_[i] = std::min(0.2, 0.1 * (upper - lower));
      } else {  // continuous: every angle is reached within one turn
        low_[i] = -kPi;
        high_[i] = kPi;
        ramp_[i] = std::numeric_limits<double>::infinity();
        step_[i] = 0.2;
      }
    }
  }

  int num_joints() const { return model_.num_joints(); }
  double low(int i) const { return low_[i]; }
  double high(int i) const { return high_[i]; }
  double step(int i) const { return step_[i]; }

  JointVector sample(Random& random) const {
    JointVector q(num_joints());
    for (int i = 0; i < num_joints(); ++i) q[i] = low_[i] + (high_[i] - low_[i]) * random.uniform();
    return q;
  }

  // Flange distance from the base origin [m], or -1 if the model cannot be evaluated at q.
  double distance(const JointVector& q) {
    Pose pose;
    if (!workspace_.compute_pose(q, pose)) return -1.0;
    return pose.position.norm();
  }

  void set_reach(double reach) { reach_ = reach; }
  double reach() const { return reach_; }

  Evaluation evaluate(const JointVector& q) {
    Evaluation e;
    if (!workspace_.compute(q, zero_, kinematics_, ModelTerms::none)) return e;
    const Jacobian& jacobian = kinematics_.jacobian;
    scaled_ = jacobian;
    scaled_.topRows<3>() /= reach_;
    e.scaled_singular_value = smallest_singular_value(scaled_);
    e.singular_value = smallest_singular_value(jacobian);

    const JointLimits& limits = model_.limits();
    double limit_factor = 1.0;
    for (int i = 0; i < num_joints(); ++i) {
      const double d = std::min(q[i] - limits.position_lower[i], limits.position_upper[i] - q[i]);
      if (!std::isfinite(d)) continue;
      if (d < e.limit_distance) {
        e.limit_distance = d;
        e.closest_joint = i;
      }
      limit_factor *= clamp01((d - options_.limit_margin) / ramp_[i]);
    }

    e.position = kinematics_.pose.position;
    e.tool_axis = kinematics_.pose.orientation * Eigen::Vector3d::UnitZ();
    // Heights and directions against gravity, so that a base frame mounted sideways or upside
    // down still prefers a flange above the mounting plane and a tool pointing down.
    const double height = e.position.dot(up_);
    const Eigen::Vector3d out = e.position - height * up_;  // from the base axis, horizontal
    const double horizontal = out.norm();
    const double tool_down = -e.tool_axis.dot(up_);
    const double tool_out = horizontal > 1e-9 ? e.tool_axis.dot(out) / horizontal : 0.0;
    const double front =
        horizontal > 1e-9 && front_.norm() > 0.5 ? front_.dot(out) / horizontal : 1.0;
    // Room in every direction: the flange a table's half width (0.15 m) and more out from the
    // base, at a height where a table below it and a push down do not reach the floor, neither
    // folded onto the base nor stretched out.
    const double ready =
        plateau(horizontal / reach_, 0.25, 0.6, 0.2, 0.5) *
        plateau(height / reach_, 0.2, 0.6, 0.2, 0.5) *
        plateau(e.position.norm() / reach_, 0.35, 0.8, 0.35, 0.6) *
        (0.8 + 0.2 * clamp01(front)) *                               // in front (+x)
        (0.6 + 0.4 * clamp01(std::max(tool_down, 0.5 * tool_out)));  // tool down, or outward
    e.score = e.scaled_singular_value * limit_factor * ready;
    return e;
  }

 private:
  double smallest_singular_value(const Jacobian& jacobian) {
    svd_.compute(jacobian);
    const auto& values = svd_.singularValues();
    return values[values.size() - 1];
  }

  const RobotModel& model_;
  StartSearch options_;
  ModelWorkspace workspace_;
  Kinematics kinematics_;
  JointVector zero_;
  JointVector low_, high_, ramp_, step_;
  double reach_ = 1.0;
  Eigen::Vector3d up_, front_;
  Jacobian scaled_;
  Eigen::JacobiSVD<Eigen::MatrixXd> svd_;
};

struct Candidate {
  JointVector q;
  Evaluation evaluation;
};

// Coordinate search: each joint in turn tries a step either way, keeps what raises the score;
// the steps halve when no joint gains.
void refine(Scorer& scorer, Candidate& candidate) {
  const int n = scorer.num_joints();
  JointVector step(n);
  for (int i = 0; i < n; ++i) step[i] = scorer.step(i);
  for (int round = 0; round < 200 && step.maxCoeff() > 1e-3; ++round) {
    bool improved = false;
    for (int i = 0; i < n; ++i) {
      for (const double sign : {1.0, -1.0}) {
        JointVector q = candidate.q;
        q[i] = std::min(scorer.high(i), std::max(scorer.low(i), q[i] + sign * step[i]));
        const Evaluation e = scorer.evaluate(q);
        if (e.score > candidate.evaluation.score) {
          candidate.q = q;
          candidate.evaluation = e;
          improved = true;
          break;
        }
      }
    }
    if (!improved) step *= 0.5;
  }
}

std::string describe(const RobotModel& model, const Candidate& c, double reach) {
  const Evaluation& e = c.evaluation;
  char limit[160] = "no joint limited";
  if (e.closest_joint >= 0) {
    std::snprintf(limit, sizeof(limit), "%.3g from the nearest joint limit (%s)", e.limit_distance,
                  model.joint_names()[static_cast<std::size_t>(e.closest_joint)].c_str());
  }
  char text[512];
  std::snprintf(text, sizeof(text),
                "smallest singular value %.3g (%.3g with translation per %.3g m of reach), %s, "
                "flange at (%.3f, %.3f, %.3f) m (%.0f %% of the reach), tool z axis (%.2f, %.2f, "
                "%.2f)",
                e.singular_value, e.scaled_singular_value, reach, limit, e.position.x(),
                e.position.y(), e.position.z(), 100.0 * e.position.norm() / reach, e.tool_axis.x(),
                e.tool_axis.y(), e.tool_axis.z());
  return text;
}

void check_options(const StartSearch& options) {
  const auto fail = [](const std::string& field, double value, const std::string& bound) {
    throw Error("find_start_configuration: StartSearch::" + field + " = " + format_number(value) +
                " must be " + bound);
  };
  if (options.samples < 1) fail("samples", options.samples, ">= 1");
  if (options.refined < 1) fail("refined", options.refined, ">= 1");
  if (!(options.singular_threshold >= 0.0) || !std::isfinite(options.singular_threshold)) {
    fail("singular_threshold", options.singular_threshold, "finite and >= 0");
  }
  if (!(options.limit_margin >= 0.0) || !std::isfinite(options.limit_margin)) {
    fail("limit_margin", options.limit_margin, "finite and >= 0");
  }
}

}  // namespace

StartChoice find_start_configuration(const RobotModel& model, const StartSearch& options) {
  check_options(options);
  Scorer scorer(model, options);
  Random random(options.seed);
  std::vector<JointVector> samples;
  samples.reserve(static_cast<std::size_t>(options.samples));
  // The reach first: it scales the translation rows of every score.
  double reach = 0.0;
  for (int s = 0; s < options.samples; ++s) {
    samples.push_back(scorer.sample(random));
    reach = std::max(reach, scorer.distance(samples.back()));
  }
  scorer.set_reach(reach > 1e-6 ? reach : 1.0);

  std::vector<Candidate> best;  // the `refined` highest scores, best first
  for (const JointVector& q : samples) {
    Candidate candidate{q, scorer.evaluate(q)};
    if (candidate.evaluation.score < 0.0) continue;
    const auto place = std::find_if(best.begin(), best.end(), [&](const Candidate& b) {
      return candidate.evaluation.score > b.evaluation.score;
    });
    if (static_cast<int>(place - best.begin()) >= options.refined) continue;
    best.insert(place, candidate);
    if (static_cast<int>(best.size()) > options.refined) best.pop_back();
  }

  const Candidate* chosen = nullptr;
  double best_singular_value = 0.0;
  for (Candidate& candidate : best) {
    refine(scorer, candidate);
    const Evaluation& e = candidate.evaluation;
    best_singular_value = std::max(best_singular_value, e.singular_value);
    const bool acceptable = e.singular_value >= options.singular_threshold &&
                            e.limit_distance >= options.limit_margin && e.score > 0.0;
    if (acceptable && (chosen == nullptr || e.score > chosen->evaluation.score)) {
      chosen = &candidate;
    }
  }
  if (chosen == nullptr) {
    throw Error("find_start_configuration: no configuration of '" + model.robot_name() +
                "' found with a smallest Jacobian singular value of at least " +
                format_number(options.singular_threshold) + " and every joint at least " +
                format_number(options.limit_margin) +
                " inside its limits (best smallest singular value found: " +
                format_number(best_singular_value) + " of " + std::to_string(options.samples) +
                " samples); give a start configuration (start_q) yourself");
  }
  StartChoice choice;
  choice.q = chosen->q;
  choice.smallest_singular_value = chosen->evaluation.singular_value;
  choice.scaled_singular_value = chosen->evaluation.scaled_singular_value;
  choice.limit_distance = chosen->evaluation.limit_distance;
  choice.reach = scorer.reach();
  choice.score = chosen->evaluation.score;
  choice.flange_position = chosen->evaluation.position;
  choice.description = describe(model, *chosen, scorer.reach());
  return choice;
}

}  // namespace cartesian_impedance
