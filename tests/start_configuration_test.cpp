// find_start_configuration(): the start the library chooses for a robot given by its URDF alone,
// on the robots the project ships.

#include <gtest/gtest.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "cartesian_impedance/model/start_configuration.hpp"
#include "support/model_fixtures.hpp"

namespace {

namespace ci = cartesian_impedance;
using model_fixtures::kPi;

struct ShippedRobot {
  const char* name;
  const char* urdf;
  const char* base;
  const char* tip;
};

const ShippedRobot kRobots[] = {
    {"panda", "/models/panda/panda.urdf", "panda_link0", "panda_link8"},
    {"iiwa14", "/models/iiwa14/iiwa14.urdf", "iiwa_link_0", "iiwa_link_ee"},
    {"ur5e", "/models/ur5e/ur5e.urdf", "base_link", "tool0"},
    {"planar3", "/models/planar3/planar3.urdf", "base_link", "tool0"},
};

ci::RobotModel load(const ShippedRobot& robot) {
  return ci::RobotModel::from_urdf_file(std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + robot.urdf,
                                        robot.base, robot.tip);
}

// The smallest singular value of J(q) with its translation rows divided by `reach`.
double scaled_singular_value(const ci::RobotModel& model, const ci::JointVector& q, double reach) {
  ci::ModelWorkspace workspace(model);
  ci::Kinematics kinematics = workspace.make_kinematics();
  EXPECT_TRUE(workspace.compute(q, ci::JointVector::Zero(q.size()), kinematics));
  Eigen::MatrixXd jacobian = kinematics.jacobian;
  jacobian.topRows(3) /= reach;
  const Eigen::VectorXd values = Eigen::JacobiSVD<Eigen::MatrixXd>(jacobian).singularValues();
  return values[values.size() - 1];
}

// Lower and upper bounds a start may take: the limits minus check_configuration()'s margin,
// continuous joints within one turn.
void sampling_box(const ci::RobotModel& model, double margin, ci::JointVector& low,
                  ci::JointVector& high) {
  const ci::JointLimits& limits = model.limits();
  low = (limits.position_lower.array() + margin).max(-kPi).matrix();
  high = (limits.position_upper.array() - margin).min(kPi).matrix();
  for (int i = 0; i < model.num_joints(); ++i) {
    if (!std::isfinite(limits.position_lower[i])) low[i] = -kPi;
    if (!std::isfinite(limits.position_upper[i])) high[i] = kPi;
    // Joints with a range of more than a turn (the UR5e's +-2 pi) repeat every pose within one.
  }
}

TEST(StartConfiguration, ShippedRobotsStartWellConditionedInsideTheirLimits) {
  for (const ShippedRobot& robot : kRobots) {
    SCOPED_TRACE(robot.name);
    const ci::RobotModel model = load(robot);
    const ci::StartChoice choice = ci::find_start_configuration(model);
    ASSERT_EQ(choice.q.size(), model.num_joints());

    // check_configuration() with its default thresholds, which the finder uses too, has nothing
    // to say about it, and agrees with the reported figures.
    const ci::ConfigurationCheck check = ci::check_configuration(model, choice.q);
    EXPECT_TRUE(check.warnings.empty()) << check.warnings.front();
    EXPECT_NEAR(check.singular_values[check.singular_values.size() - 1],
                choice.smallest_singular_value, 1e-12);
    EXPECT_GE(choice.smallest_singular_value, 0.02);
    EXPECT_DOUBLE_EQ(check.limit_distance, choice.limit_distance);
    EXPECT_GE(choice.limit_distance, 0.1);
    const ci::JointLimits& limits = model.limits();
    EXPECT_TRUE((choice.q.array() >= limits.position_lower.array() + 0.1).all());
    EXPECT_TRUE((choice.q.array() <= limits.position_upper.array() - 0.1).all());
    EXPECT_FALSE(choice.description.empty());

    // A "ready" pose: the flange above the base plane, neither folded onto the base nor
    // stretched out (then its reach would be the largest seen).
    EXPECT_GT(choice.flange_position.z(), 0.0);
    EXPECT_GT(choice.flange_position.norm(), 0.2 * choice.reach);
    EXPECT_LT(choice.flange_position.norm(), 0.95 * choice.reach);

    // Against a large random sample of the same box (another generator and seed): the chosen
    // start's conditioning is at least 0.7 of the best found there. The finder trades some of it
    // for a ready pose and for distance from the limits, so it need not beat the sample (it
    // reaches 0.8 to 1.0 of it on these robots), but a start that merely passes the threshold is
    // far below (the Panda's midpoint of its limits: 0.65; q = 0 and the others' midpoints: 0).
    ci::JointVector low, high;
    sampling_box(model, 0.1, low, high);
    std::mt19937 generator(7);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    double best = 0.0;
    for (int s = 0; s < 20000; ++s) {
      ci::JointVector q(model.num_joints());
      for (int i = 0; i < q.size(); ++i) q[i] = low[i] + (high[i] - low[i]) * unit(generator);
      best = std::max(best, scaled_singular_value(model, q, choice.reach));
    }
    EXPECT_NEAR(scaled_singular_value(model, choice.q, choice.reach), choice.scaled_singular_value,
                1e-12);
    EXPECT_GE(choice.scaled_singular_value, 0.7 * best)
        << "best of 20000 random configurations: " << best;

    // What a finder that returned q = 0 or the middle of the limits would give: far worse.
    const ci::JointVector middle = 0.5 * (low + high);
    EXPECT_GT(choice.scaled_singular_value,
              2.0 * scaled_singular_value(model, ci::JointVector::Zero(model.num_joints()),
                                          choice.reach));
    EXPECT_GT(choice.scaled_singular_value,
              1.2 * scaled_singular_value(model, middle, choice.reach));
  }
}

TEST(StartConfiguration, IsDeterministic) {
  for (const ShippedRobot& robot : kRobots) {
    SCOPED_TRACE(robot.name);
    const ci::RobotModel model = load(robot);
    const ci::StartChoice first = ci::find_start_configuration(model);
    const ci::StartChoice second = ci::find_start_configuration(load(robot));
    EXPECT_EQ(first.q, second.q);
    EXPECT_EQ(first.description, second.description);
    // Another seed finds another, equally acceptable start.
    ci::StartSearch other;
    other.seed = 12345;
    const ci::StartChoice third = ci::find_start_configuration(model, other);
    EXPECT_TRUE(ci::check_configuration(model, third.q).warnings.empty());
  }
}

TEST(StartConfiguration, PandaIsAsWellConditionedAsItsReadyKeyframe) {
  const ci::RobotModel model = load(kRobots[0]);
  const ci::StartChoice choice = ci::find_start_configuration(model);
  // The keyframe 'ready' of models/panda/panda.xml, chosen by hand.
  const ci::JointVector ready =
      (ci::JointVector(7) << 0, -kPi / 4, 0, -3 * kPi / 4, 0, kPi / 2, kPi / 4).finished();
  const ci::ConfigurationCheck check = ci::check_configuration(model, ready);
  const double ready_value = check.singular_values[check.singular_values.size() - 1];
  EXPECT_GE(choice.smallest_singular_value, 0.8 * ready_value) << "chosen: " << choice.description;
  EXPECT_GE(choice.scaled_singular_value, 0.8 * scaled_singular_value(model, ready, choice.reach));
}

TEST(StartConfiguration, RefusesBadOptionsAndSaysWhenNothingIsGoodEnough) {
  const ci::RobotModel model = load(kRobots[3]);
  const auto message = [&](const ci::StartSearch& options) -> std::string {
    try {
      ci::find_start_configuration(model, options);
    } catch (const ci::Error& error) {
      return error.what();
    }
    return "";
  };
  ci::StartSearch options;
  options.samples = 0;
  EXPECT_NE(message(options).find("StartSearch::samples = 0 must be >= 1"), std::string::npos);
  options = {};
  options.refined = -1;
  EXPECT_NE(message(options).find("StartSearch::refined = -1 must be >= 1"), std::string::npos);
  options = {};
  options.limit_margin = std::nan("");
  EXPECT_NE(message(options).find("StartSearch::limit_margin"), std::string::npos);
  // The planar arm's largest smallest singular value is below 10: nothing passes.
  options = {};
  options.singular_threshold = 10.0;
  const std::string none = message(options);
  EXPECT_NE(none.find("no configuration of 'planar3' found"), std::string::npos) << none;
  EXPECT_NE(none.find("best smallest singular value found: 0."), std::string::npos) << none;
}

}  // namespace
