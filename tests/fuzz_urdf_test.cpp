// Mutation fuzzing of the URDF loader, from the project's own robot descriptions. Every input
// must either load into a model that computes a finite pose, Jacobian, mass matrix and gravity at
// q = 0 and at random q within its limits, or be rejected with cartesian_impedance::Error;
// anything else (another exception, a crash, a hang, a sanitizer report) fails. Deterministic:
// fixed seeds.

#include <console_bridge/console.h>
#include <gtest/gtest.h>

#include <cmath>
#include <exception>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <typeinfo>
#include <vector>

#include "cartesian_impedance/core/error.hpp"
#include "cartesian_impedance/model/robot_model.hpp"
#include "support/mutator.hpp"

namespace ci = cartesian_impedance;

namespace {

std::string read_source_file(const std::string& relative) {
  std::ifstream file(std::string(CARTESIAN_IMPEDANCE_SOURCE_DIR) + "/" + relative);
  return std::string(std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>());
}

struct Robot {
  const char* file;
  const char* base;
  const char* tip;
};
constexpr Robot kRobots[] = {{"models/panda/panda.urdf", "panda_link0", "panda_link8"},
                             {"models/iiwa14/iiwa14.urdf", "iiwa_link_0", "iiwa_link_ee"}};

fuzz::Format urdf_format() {
  fuzz::Format format;
  format.extremes = {"nan",
                     "-nan",
                     "inf",
                     "-inf",
                     "1e308",
                     "-1e308",
                     "1e309",
                     "1e400",
                     "-0",
                     "-0.0",
                     "5e-324",
                     "1e-400",
                     "99999999999999999999",
                     "1000",
                     "-1000",
                     "1000.5",
                     "1e6",
                     "1e7",
                     "0x10",
                     "",
                     "1 2",
                     "1 2 3 4",
                     "0",
                     "1e-12",
                     "1e9",
                     "1e10",
                     "-1"};
  format.tokens = {"<a>",
                   "</a>",
                   "<a/>",
                   "<!-- ",
                   " -->",
                   "<![CDATA[",
                   "]]>",
                   "<?xml version=\"1.0\"?>",
                   "<?pi x?>",
                   "<!DOCTYPE r>",
                   "'",
                   "\"",
                   "<",
                   ">",
                   "/>",
                   "&amp;",
                   "&#120;",
                   "&#x",
                   "=",
                   " ",
                   "\n",
                   "\xEF\xBB\xBF",
                   std::string(1, '\0'),
                   "\xC3",
                   "\xF0",
                   "\x7F",
                   "<link name=\"extra\"/>",
                   "<joint name=\"extra\" type=\"fixed\"><parent link=\"extra\"/>"
                   "<child link=\"extra\"/></joint>"};
  format.nest = [](std::size_t count, std::mt19937& random) {
    static const std::vector<std::pair<std::string, std::string>> kPairs{
        {"<a>", "</a>"}, {"<a x='>'>", "</a>"}, {"<gazebo>", "</gazebo>"}, {"<a", ""}};
    const auto& [open, close] =
        kPairs[std::uniform_int_distribution<std::size_t>(0, kPairs.size() - 1)(random)];
    std::string text;
    text.reserve(count * (open.size() + close.size()));
    for (std::size_t i = 0; i < count; ++i) text += open;
    if (std::uniform_int_distribution<int>(0, 1)(random)) {
      for (std::size_t i = 0; i < count; ++i) text += close;
    }
    return text;
  };
  format.units = fuzz::xml_elements;
  return format;
}

// q within the model's limits where they are finite and not absurdly wide, else in [-pi, pi].
ci::JointVector random_q(const ci::RobotModel& model, std::mt19937& random) {
  const ci::JointLimits& limits = model.limits();
  ci::JointVector q(model.num_joints());
  for (int i = 0; i < model.num_joints(); ++i) {
    double lower = limits.position_lower[i], upper = limits.position_upper[i];
    if (!std::isfinite(lower) || !std::isfinite(upper) || upper - lower > 1e3) {
      lower = -3.14159;
      upper = 3.14159;
    }
    q[i] = std::uniform_real_distribution<double>(lower, upper)(random);
  }
  return q;
}

// One input through the property; counts the outcome in `run`.
void check_input(const std::string& input, const Robot& robot, std::mt19937& random,
                 fuzz::Run& run) {
  try {
    const ci::RobotModel model = ci::RobotModel::from_urdf_string(input, robot.base, robot.tip);
    if (model.num_joints() < 1 || model.num_joints() > ci::kMaxJoints) {
      run.failed("accepted with " + std::to_string(model.num_joints()) + " joints", input);
      return;
    }
    ci::ModelWorkspace workspace(model);
    ci::Kinematics kinematics = workspace.make_kinematics();
    const ci::JointVector zero = ci::JointVector::Zero(model.num_joints());
    for (int sample = 0; sample < 4; ++sample) {
      const ci::JointVector q = sample == 0 ? zero : random_q(model, random);
      ci::JointVector dq = zero;
      for (int i = 0; sample > 0 && i < dq.size(); ++i) {
        dq[i] = std::uniform_real_distribution<double>(-1.0, 1.0)(random);
      }
      // compute() checks that everything it returns is finite.
      if (!workspace.compute(q, dq, kinematics, true)) {
        run.failed("accepted, but compute() fails at q = [" + std::to_string(q[0]) + ", ...]",
                   input);
        return;
      }
    }
  } catch (const ci::Error&) {
    run.rejected();
    return;
  } catch (const std::exception& other) {
    run.failed(std::string("threw ") + typeid(other).name() + ": " + other.what(), input);
    return;
  } catch (...) {
    run.failed("threw something that is not a std::exception", input);
    return;
  }
  run.accepted();
}

// urdfdom's warnings (the loader lets them through) would drown the log; errors are captured by
// the loader whatever the level.
class QuietConsole {
 public:
  QuietConsole() : level_(console_bridge::getLogLevel()) {
    console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  }
  ~QuietConsole() { console_bridge::setLogLevel(level_); }
  QuietConsole(const QuietConsole&) = delete;
  QuietConsole& operator=(const QuietConsole&) = delete;

 private:
  console_bridge::LogLevel level_;
};

}  // namespace

TEST(FuzzUrdf, MutatedRobotDescriptionsLoadOrAreRejectedWithError) {
  const QuietConsole quiet;
  std::vector<std::string> seeds;
  for (const Robot& robot : kRobots) {
    seeds.push_back(read_source_file(robot.file));
    ASSERT_GT(seeds.back().size(), 1000u) << robot.file;
  }
  fuzz::Mutator mutator(seeds, urdf_format(), 20240601u);
  std::mt19937 random(7);
  fuzz::Run run("urdf");
  constexpr int kInputs = 3000;
  for (int i = 0; i < kInputs; ++i) {
    const std::size_t index = static_cast<std::size_t>(i) % seeds.size();
    check_input(mutator.next(index), kRobots[index], random, run);
  }
  run.finish();
}
